"""Benchmark: the sweep runner's speed-up and its own overhead per run.

A sweep of ``--runs`` short runs (the default scenario, shortened so that a run takes
about a second) on 1 and 2 local workers. For each: wall time, speed-up over 1 worker,
and the runner's overhead per run: ``(wall x workers - sum of the runs' own wall times) /
runs``, also as a fraction of the mean run time (target: under 5 % for runs of a second
or more). Each sweep writes to a fresh temporary directory.

    python benchmarks/sweep_runner.py            # 200 runs
    python benchmarks/sweep_runner.py --runs 50
"""

from __future__ import annotations

import argparse
import tempfile
import time

from netsim.tools import sweep as sweepmod
from netsim.tools.args import Parser


def main() -> None:
    p = Parser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--runs", type=int, default=200)
    p.add_argument("--duration", type=float, default=150.0, help="simulated seconds per run (about 1 s of wall)")
    args = p.parse_args()
    sweep = sweepmod.parse(
        {
            "name": "bench",
            "replications": args.runs,
            "base": {"duration_s": args.duration, "output": {"position_interval_s": 0.0}},
            "grid": {"seed": [1]},
        }
    )
    print(f"{'workers':>8}{'runs':>6}{'wall s':>9}{'speed-up':>10}{'mean run s':>12}", end="")
    print(f"{'overhead/run s':>16}{'overhead %':>12}")
    base_wall = None
    for workers in (1, 2):
        with tempfile.TemporaryDirectory() as out:
            start = time.perf_counter()
            report = sweepmod.run_sweep(sweep, out, workers=workers, progress=False)
            wall = time.perf_counter() - start
            runs = sweepmod.load(out)
        assert report.done == args.runs and not report.failed
        own = runs["wall_s"].sum()
        overhead = (wall * workers - own) / args.runs
        mean_run = own / args.runs
        base_wall = base_wall or wall
        print(
            f"{workers:>8}{args.runs:>6}{wall:>9.1f}{base_wall / wall:>9.2f}x{mean_run:>12.3f}{overhead:>16.4f}"
            f"{100 * overhead / mean_run:>11.1f}%"
        )


if __name__ == "__main__":
    main()
