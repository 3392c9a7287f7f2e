"""Coverage with the global and the local plan (``coverage.plan``), from dense starts, on the
unit disk (docs/model.md section 5, "Local plan").

Each run: ``N`` robots placed in a central square of side ``40 sqrt(N)`` m (about twenty
neighbours each) of an area of side ``500 sqrt(N)`` m (so that ``U(N)`` stays well below
the area), range 100 m, coverage on from ``coverage.start_s``, ``duration`` seconds. Per
run it prints the covered fraction of the bound at the end (``covered_of_bound_all``),
the number of components of the true network (from ``links.parquet``, at every link
event) when control starts and the largest after, and when control settled.

    python benchmarks/coverage_plans.py                         # N = 20, 60, 100, 200; loss 0, 0.3; local
    python benchmarks/coverage_plans.py --n 60 --loss 0 --plans global local --seeds 1 2
"""

from __future__ import annotations

import argparse
import math
import time

from netsim import config as cfgmod
from netsim.metrics import components_at_link_events
from netsim.run import execute


def one_run(plan: str, n: int, loss: float, seed: int, duration_s: float, extra: list[str]) -> dict:
    overrides = [
        f"world.n_robots={n}",
        f"world.side_m={500 * math.sqrt(n):.1f}",
        'world.placement="centre"',
        f"world.centre_side_m={40 * math.sqrt(n):.1f}",
        'mobility.model="static"',
        "channel.range_m=100",
        f"channel.loss_probability={loss}",
        "coverage.enabled=true",
        f'coverage.plan="{plan}"',
        "protocol.message_rate_hz=0",
        "output.position_interval_s=0",
        f"duration_s={duration_s}",
        f"seed={seed}",
        *extra,
    ]
    cfg = cfgmod.load(None, overrides)
    start = time.perf_counter()
    result = execute(cfg)
    wall = time.perf_counter() - start
    links = result.frames["links"]
    times, counts = components_at_link_events(
        links["a"].to_numpy(),
        links["b"].to_numpy(),
        links["t_up_s"].to_numpy(),
        links["t_down_s"].to_numpy(),
        links["censored_end"].to_numpy(),
        n,
    )
    control_s = cfg.coverage.start_s
    before = counts[times <= control_s]
    after = counts[times > control_s]
    s = result.summary
    return {
        "plan": plan,
        "N": n,
        "loss": loss,
        "seed": seed,
        "of bound": s["covered_of_bound_all_final"],
        "components at start": int(before[-1]) if len(before) else 1,
        "largest after": int(after.max()) if len(after) else int(before[-1]),
        "settled s": s["control_settled_s"],
        "wall s": wall,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n", type=int, nargs="+", default=[20, 60, 100, 200])
    ap.add_argument("--loss", type=float, nargs="+", default=[0.0, 0.3])
    ap.add_argument("--plans", nargs="+", default=["local"])
    ap.add_argument("--seeds", type=int, nargs="+", default=[1])
    ap.add_argument("--duration", type=float, default=900.0)
    ap.add_argument("--set", action="append", default=[], help="extra configuration override key=value")
    args = ap.parse_args()
    cols = ["plan", "N", "loss", "seed", "of bound", "components at start", "largest after", "settled s", "wall s"]
    print(" | ".join(cols), flush=True)
    for plan in args.plans:
        for n in args.n:
            for loss in args.loss:
                for seed in args.seeds:
                    row = one_run(plan, n, loss, seed, args.duration, args.set)
                    print(
                        f"{row['plan']} | {n} | {loss:g} | {seed} | {row['of bound']:.3f} | "
                        f"{row['components at start']} | {row['largest after']} | {row['settled s']:.0f} | "
                        f"{row['wall s']:.0f}",
                        flush=True,
                    )


if __name__ == "__main__":
    main()
