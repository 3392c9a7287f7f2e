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
import time

from netsim import config as cfgmod
from netsim.run import execute
from netsim.tools.args import Parser
from netsim.tools.validate import coverage_outcome, coverage_settings


def one_run(plan: str, n: int, loss: float, seed: int, duration_s: float, extra: list[str]) -> dict:
    cfg = cfgmod.load(None, coverage_settings("unit disk", plan, n, loss, seed, duration_s) + extra)
    start = time.perf_counter()
    result = execute(cfg)
    wall = time.perf_counter() - start
    o = coverage_outcome(result.frames, result.summary, n, cfg.coverage.start_s, duration_s)
    return {
        "plan": plan,
        "N": n,
        "loss": loss,
        "seed": seed,
        "of bound": o["of_bound"],
        "components at start": o["components_at_start"],
        "largest after": o["components_max"],
        "settled s": result.summary["control_settled_s"],
        "wall s": wall,
    }


def main() -> None:
    ap = Parser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
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
