"""Connected coverage against the number of robots: the global plan, the local plan and the
paper's ``follow`` controller, on the unit disk, under shadowing and on a map, in one figure.

A sweep (``netsim.tools.sweep``) of mode x radio x ``world.n_robots`` (x ``coverage.law``
if more than one is asked). Every run is the scenario of ``netsim validate``'s coverage
items and of ``experiments/coverage_targets.py``
(:func:`netsim.tools.validate.coverage_settings`): a dense random static start in the
middle of the area (a square of side ``40 sqrt(N)`` m, about 20 neighbours per robot; 40 m
on the office map), an area large enough that a connected team cannot cover it
(``500 sqrt(N)`` m a side in open space), range 100 m (30 m on the office map); groups
form, then the team spreads by virtual forces until the stopping rule ends control. On the
office map the start is connected on the run's own links (``world.placement =
"connected"``, in the free region of the area's centre), and the bound is over the free
region's area (docs/model.md 5.3).

The modes: ``global`` (``coverage.members = "spread"``, ``coverage.plan = "global"``: one
plan for the whole team, from true positions), ``local`` (``coverage.plan = "local"``: each
robot decides from the Acks it heard) and ``follow`` (``coverage.members = "follow"``:
the paper's controller, members follow their leader). The radios are those of
``netsim.tools.validate.COVERAGE_RADIOS``: the unit disk, log-distance with 4 dB
shadowing, the office map with line of sight, and with 5 dB per wall.

Writes to ``--out``:

- ``coverage_vs_n.csv``: per point, the mean, standard deviation and 95 % confidence
  interval over replications of the final covered fraction of the bound
  ``min(1, U(N) / A)`` (on the map ``A`` is the free region's area) and of the area, how
  far the number of components rose during control above its value at control start
  (``grew``: the real network, the channel's links, at every control step), the fraction
  of runs connected at the end, the settling time and the distance travelled per robot;
- ``coverage_vs_n.png``: one column per radio; the covered fraction of the bound (with
  the targets of docs/model.md 5.2 on the unit disk: 75 % global, 60 % local) and
  ``grew`` against N, one line per mode.

Killed, it resumes where it stopped: finished runs are kept in ``--out/sweep``.

    python experiments/coverage_vs_n.py --workers 2
    python experiments/coverage_vs_n.py --n 20 60 --map-n 10 20 --reps 1 --radios "unit disk"
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

import numpy as np
import pandas as pd

from netsim.config import parse_override
from netsim.errors import NetsimInputError
from netsim.tools import sweep as sweepmod
from netsim.tools.args import Parser
from netsim.tools.figures import pyplot
from netsim.tools.validate import COVERAGE_FLOOR, COVERAGE_RADIOS, coverage_settings

MODES = {
    "global": ["coverage.members=spread", "coverage.plan=global"],
    "local": ["coverage.members=spread", "coverage.plan=local"],
    "follow": ["coverage.members=follow", "coverage.plan=global"],
}
METRICS = [
    "covered_of_bound_all_final",
    "covered_fraction_all_final",
    "grew",
    "connected_final",
    "settling_s",
    "distance_mean_m",
]
# What every run shares; everything else is the point's.
BASE_KEYS = ("seed", "duration_s")


def point(radio: str, mode: str, n: int, law: str, loss: float, duration_s: float) -> dict:
    """The configuration keys of one point: the validate scenario, the mode's keys, the law."""
    settings = [*coverage_settings(radio, "global", n, loss, 0, duration_s), *MODES[mode], f"coverage.law={law}"]
    if radio.startswith("office"):
        settings.append("world.placement=connected")
    keys: dict = {}
    for text in settings:
        keys.update(sweepmod.flatten(parse_override(text)))
    return {k: v for k, v in keys.items() if k not in BASE_KEYS}


def _key(keys: dict) -> tuple:
    return tuple(sorted((k, repr(v)) for k, v in keys.items()))


def plot(agg: pd.DataFrame, path: Path, radios: list[str], title: str) -> None:
    plt = pyplot()
    fig, axes = plt.subplots(2, len(radios), figsize=(4.6 * len(radios), 7.0), squeeze=False, constrained_layout=True)
    several_laws = agg["coverage.law"].nunique() > 1
    for col, radio in enumerate(radios):
        top, bottom = axes[0, col], axes[1, col]
        for (mode, law), g in agg[agg["radio"] == radio].groupby(["mode", "coverage.law"], sort=False):
            g = g.sort_values("world.n_robots")
            label = f"{mode} ({law})" if several_laws else mode
            for ax, metric in ((top, "covered_of_bound_all_final"), (bottom, "grew")):
                mean = g[f"{metric}_mean"]
                low, high = g[f"{metric}_ci_low"].fillna(mean), g[f"{metric}_ci_high"].fillna(mean)
                if metric == "grew":
                    low = low.clip(lower=0)
                err = [mean - low, high - mean]
                ax.errorbar(g["world.n_robots"], mean, yerr=err, marker="o", capsize=3, label=label)
        if radio == "unit disk":
            for plan, floor in COVERAGE_FLOOR.items():
                top.axhline(floor, color="k", lw=1, ls=":" if plan == "local" else "--", label=f"target, {plan}")
        top.set_ylim(0, 1.05)
        top.set_title(radio)
        bottom.set_ylim(-0.2, max(1.0, bottom.get_ylim()[1]))
        for ax in (top, bottom):
            ax.set_xlabel("robots N")
            ax.grid(alpha=0.3)
    axes[0, 0].set_ylabel("covered fraction of min(1, U(N) / A) at the end")
    axes[1, 0].set_ylabel("components gained during control (real links)")
    axes[0, 0].legend(fontsize=7)
    fig.suptitle(title)
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv=None) -> None:
    p = Parser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--n", type=int, nargs="+", default=[20, 60, 100, 200], help="numbers of robots in open space")
    p.add_argument("--map-n", type=int, nargs="+", default=[10, 20, 40], help="numbers of robots on the office map")
    p.add_argument("--modes", nargs="+", default=list(MODES), help=f"of {list(MODES)}")
    p.add_argument(
        "--radios",
        nargs="+",
        default=["unit disk", "shadowing 4 dB", "office, line of sight"],
        help=f"of {list(COVERAGE_RADIOS)}",
    )
    p.add_argument("--laws", nargs="+", default=["spring"], help="coverage.law values")
    p.add_argument("--loss", type=float, default=0.0, help="channel.loss_probability")
    p.add_argument("--duration", type=float, default=600.0, help="simulated seconds per run")
    sweepmod.add_runner_arguments(p, "coverage_vs_n", reps=3)
    args = p.parse_args(argv)
    if min(args.n + args.map_n) < 2:
        raise NetsimInputError("--n and --map-n: at least 2 robots")
    # Checked here, not by argparse's choices: its usage block would make the error several lines.
    for option, given, known in (("--modes", args.modes, MODES), ("--radios", args.radios, COVERAGE_RADIOS)):
        unknown = [x for x in given if x not in known]
        if unknown:
            raise NetsimInputError(f"{option} {unknown[0]!r}: not one of {list(known)}")
    for option, value in (("--reps", args.reps), ("--workers", args.workers)):
        if value < 1:
            raise NetsimInputError(f"{option} {value}: at least 1")
    if not args.duration > 0:
        raise NetsimInputError(f"--duration {args.duration:g}: must be positive")
    labelled = {}
    for radio in args.radios:
        for mode in args.modes:
            for n in args.map_n if radio.startswith("office") else args.n:
                for law in args.laws:
                    keys = point(radio, mode, n, law, args.loss, args.duration)
                    labelled[_key(keys)] = (radio, mode, keys)
    points = tuple(keys for _, _, keys in labelled.values())
    base = {"seed": args.seed, "duration_s": args.duration}
    sweep = sweepmod.parse(
        {"name": "coverage_vs_n", "replications": args.reps, "base": base, "grid": {"coverage.law": args.laws}}
    )
    sweep = dataclasses.replace(sweep, points=points)
    out = Path(args.out)
    report = sweepmod.run_sweep(sweep, out / "sweep", workers=args.workers, scheduler=args.scheduler)
    print(report.text())
    # This invocation's runs only: the directory may keep runs of other options.
    label = {run.run_id: labelled[_key(run.point)][:2] for run in sweep.runs()}
    runs = sweepmod.load(out / "sweep")
    runs = runs[runs["run_id"].isin(label)].reset_index(drop=True)
    runs["radio"] = [label[r][0] for r in runs["run_id"]]
    runs["mode"] = [label[r][1] for r in runs["run_id"]]
    runs["grew"] = (runs["components_max_during_control"] - runs["components_start"]).clip(lower=0).astype(float)
    runs["connected_final"] = runs["connected_final"].astype(float)
    runs["settling_s"] = runs["control_settled_s"].astype(float) - runs["coverage.start_s"]
    agg = sweepmod.aggregate(runs, ["radio", "mode", "coverage.law", "world.n_robots"], METRICS)
    order = {r: k for k, r in enumerate(args.radios)}
    agg = agg.sort_values(["radio", "mode", "world.n_robots"], key=lambda s: s.map(order) if s.name == "radio" else s)
    agg.to_csv(out / "coverage_vs_n.csv", index=False)
    plot(
        agg,
        out / "coverage_vs_n.png",
        [r for r in args.radios if r in set(agg["radio"])],
        f"dense start, {args.duration:g} s, loss {args.loss:g}, {args.reps} replications, 95 % CI",
    )
    show = ["radio", "mode", "coverage.law", "world.n_robots", "covered_of_bound_all_final_mean", "grew_mean"]
    show += ["connected_final_mean", "settling_s_mean", "distance_mean_m_mean"]
    print(agg[show].to_string(index=False, float_format=lambda x: f"{x:.3g}"))
    print(f"wrote {out / 'coverage_vs_n.csv'} and {out / 'coverage_vs_n.png'}")
    if np.any(agg["grew_mean"] > 0):
        print("note: the real network gained components during control in some runs (grew > 0)")


if __name__ == "__main__":
    sweepmod.run_script(main, resumable=True)
