"""Two policies in the coverage environment (netsim.envs.coverage_v0), as baselines for learning.

- ``random``: every agent draws its velocity uniformly from the action box at every step;
- ``forces``: a hand-written policy that reads the observation only: each agent is pulled
  toward (pushed away from) every neighbour its Acks told it of, by a spring whose rest
  length is ``rest x range`` (shorter than the range, so that links hold), and pushed in
  from the border within half a range of it, as the coverage controller's virtual forces
  (mobility/forces.py) but over heard neighbours and told positions alone.

Each policy runs ``--episodes`` episodes of ``--cycles`` steps (seeds 0, 1, ...) with
``--n`` robots from a dense start. Printed and written to ``--out``:

- ``learn_coverage.csv``: per policy and episode, the covered fraction of the area at the
  end (the union of the disks, exact: netsim.metrics.covered_fraction_exact), the same as a
  fraction of the most a connected team can cover (``min(1, U(N) / A)``), the components of
  the true network at the end, and the episode's return;
- ``learn_coverage.png``: the covered fraction of the bound against time, per policy
  (mean over episodes), beside the last frame of the forces policy (``render()``).

    python experiments/learn_coverage.py
    python experiments/learn_coverage.py --n 30 --cycles 400 --episodes 5 --out results

It needs the optional extra ``rl`` (PettingZoo and Gymnasium): ``pip install -e ".[rl]"`` in
the repository's folder.
"""

from __future__ import annotations

import importlib.util
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pandas as pd

from netsim import metrics
from netsim.errors import NetsimInputError
from netsim.tools.args import Parser
from netsim.tools.figures import pyplot
from netsim.tools.interrupt import kept_if_interrupted
from netsim.tools.output import claim_dir, write_atomically
from netsim.tools.sweep import run_script

Policy = Callable[[dict[str, np.ndarray]], dict[str, np.ndarray]]
# The libraries of the optional extra `rl` (pyproject.toml) that the environment loads.
RL = ("gymnasium", "pettingzoo")


def check_rl() -> None:
    """Refuse in one line, before anything is written, when the environment's libraries are
    not installed (their import failed in a traceback)."""
    missing = [m for m in RL if importlib.util.find_spec(m) is None]
    if missing:
        raise NetsimInputError(
            f"needs {' and '.join(missing)}, of the optional extra 'rl': pip install -e \".[rl]\" in the "
            "repository's folder"
        )


def random_policy(env, rng: np.random.Generator) -> Policy:
    box = env.action_space(env.possible_agents[0])

    def act(obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        return {a: rng.uniform(box.low, box.high).astype(np.float32) for a in obs}

    return act


def forces_policy(env, gain: float = 0.2, rest: float = 0.8) -> Policy:
    """The spring policy (module notes), from observations alone."""
    p = env.params
    k, roles = p.max_neighbours, len(env.role_names)
    target, margin, vmax = rest * p.range_m, 0.5 * p.range_m, np.float32(p.speed_max_mps)

    def act(obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        out = {}
        for agent, o in obs.items():
            xy = o[:2].astype(float)
            rows = o[4 + roles :].reshape(k, 4).astype(float)
            rel = rows[rows[:, 3] > 0, :2]
            d = np.hypot(rel[:, 0], rel[:, 1])
            ok = d > 0
            # Along the line from the neighbour: positive pushes away, negative pulls.
            pull = gain * (target - d[ok])
            f = -(pull[:, None] * rel[ok] / d[ok, None]).sum(axis=0)
            f += gain * (np.clip(margin - xy, 0.0, None) - np.clip(margin - (p.side_m - xy), 0.0, None))
            out[agent] = np.clip(f, -vmax, vmax).astype(np.float32)
        return out

    return act


def episode(env, policy: Policy, seed: int) -> tuple[list[float], dict, float, np.ndarray | None]:
    """One episode: the covered fraction of the bound at every step, the end's figures, the return."""
    p = env.params
    obs, infos = env.reset(seed=seed)
    radius = env.radius_m
    bound = metrics.bound_fraction(p.n_robots, radius, p.side_m, p.range_m)
    curve = [infos[env.agents[0]]["covered_fraction"] / bound]
    total = 0.0
    frame = None
    while env.agents:
        obs, rewards, _, _, infos = env.step(policy(obs))
        info = next(iter(infos.values()))
        total += next(iter(rewards.values()))
        curve.append(info["covered_fraction"] / bound)
        if not env.agents and env.render_mode:
            frame = env.render()
    pos = info["positions_m"]
    covered, error = metrics.covered_fraction_exact(pos, radius, p.side_m)
    end = {
        "covered_fraction": covered,
        "covered_error": error,
        "covered_of_bound": covered / bound,
        "components": int(info["components"]),
    }
    return curve, end, total, frame


def main(argv: list[str] | None = None) -> int:
    parser = Parser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=20, help="robots")
    parser.add_argument("--cycles", type=int, default=300, help="steps per episode")
    parser.add_argument("--episodes", type=int, default=3, help="episodes per policy (seeds 0, 1, ...)")
    parser.add_argument("--out", type=Path, default=Path("learn_coverage"), help="directory for the CSV and PNG")
    args = parser.parse_args(argv)
    check_rl()
    from netsim.envs import coverage_v0

    env = coverage_v0.parallel_env(n_robots=args.n, max_cycles=args.cycles, render_mode="rgb_array")
    if args.episodes < 1:
        raise NetsimInputError(f"--episodes {args.episodes}: must be at least 1")
    # Claimed before the episodes (a folder that cannot take the results would lose them),
    # and given up, if they fail, as it was.
    with claim_dir(args.out, "--out") as out:
        return learn(env, args, out)


def learn(env, args, out: Path) -> int:
    """Both policies' episodes, their table and figure written in ``out``."""
    policies = {"random": random_policy(env, np.random.default_rng(0)), "forces": forces_policy(env)}
    rows, curves, frame = [], {}, None
    for name, policy in policies.items():
        runs = []
        for seed in range(args.episodes):
            curve, end, total, last = episode(env, policy, seed)
            runs.append(curve)
            rows.append({"policy": name, "episode": seed, **end, "return": total})
            frame = last if name == "forces" else frame
        curves[name] = np.mean(runs, axis=0)
    table = pd.DataFrame(rows)
    bound = metrics.bound_fraction(args.n, env.radius_m, env.params.side_m, env.params.range_m)
    print(f"N = {args.n}, {args.cycles} steps of {env.params.step_s:g} s; bound min(1, U(N)/A) = {bound:.3f}")
    summary = table.groupby("policy", sort=False).agg(
        covered_fraction=("covered_fraction", "mean"),
        covered_of_bound=("covered_of_bound", "mean"),
        components=("components", "mean"),
        episode_return=("return", "mean"),
    )
    print(summary.to_string(float_format=lambda v: f"{v:.3f}"))
    # Each file whole or not at all: an interrupt says which is in place.
    csv, png = out / "learn_coverage.csv", out / "learn_coverage.png"
    write_atomically(csv, lambda tmp: table.to_csv(tmp, index=False))
    with kept_if_interrupted(f"{Path(__file__).name}: interrupted; {csv} is written, {png.name} is not"):
        draw(curves, frame, env.params.step_s, png)
    print(f"wrote {csv} and {png}")
    return 0


def draw(curves: dict[str, np.ndarray], frame: np.ndarray | None, step_s: float, path: Path) -> None:
    """The covered fraction of the bound against time per policy, beside the last frame."""
    plt = pyplot()
    fig, (ax, pic) = plt.subplots(1, 2, figsize=(11, 4.6))
    for name, curve in curves.items():
        ax.plot(np.arange(len(curve)) * step_s, curve, label=name)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("covered fraction / bound (grid)")
    ax.set_ylim(0, 1.05)
    ax.legend()
    ax.grid(alpha=0.3)
    if frame is not None:
        pic.imshow(frame)
    pic.set_axis_off()
    pic.set_title("forces policy, end of the last episode", fontsize=9)
    fig.tight_layout()
    write_atomically(path, lambda tmp: fig.savefig(tmp, dpi=120, format="png"))


if __name__ == "__main__":
    run_script(lambda: sys.exit(main()))
