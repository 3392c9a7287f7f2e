"""Cluster stability against speed and pause: how many leaders, how often roles change,
how long a leader lasts.

A sweep (``netsim.tools.sweep``) of ``mobility.speed_max_mps`` x ``mobility.pause_s`` for a fixed
number of robots and range, with replications, writes to ``--out``:

- ``cluster_stability.csv``: per point, each metric's mean, standard deviation and 95 %
  confidence interval over replications (the per-run rows are in ``sweep/runs/``);
- ``cluster_stability.png``: each metric against the maximum speed, one line per pause.

Killed, it resumes where it stopped: finished runs are kept in ``--out/sweep``.

    python experiments/cluster_stability.py
    python experiments/cluster_stability.py --reps 10 --workers 2 --speeds 1 5 10 20
"""

from __future__ import annotations

import argparse
from pathlib import Path

from netsim.tools import sweep as sweepmod
from netsim.tools.args import Parser
from netsim.tools.sweep_figure import draw_aggregate

METRICS = {
    "leaders_time_mean": "leaders (time-weighted mean)",
    "role_changes_per_robot_per_min": "role changes per robot per minute",
    "mean_leader_tenure_s": "mean leader tenure (s)",
}


def main(argv=None) -> None:
    p = Parser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--n", type=int, default=50, help="robots")
    p.add_argument("--side", type=float, default=1000.0, help="side of the area, m")
    p.add_argument("--range", type=float, default=150.0, help="communication range, m")
    p.add_argument("--duration", type=float, default=300.0, help="simulated seconds per run")
    p.add_argument("--speed-min", type=float, default=0.5)
    p.add_argument("--speeds", type=float, nargs="+", default=[1.0, 2.5, 5.0, 10.0, 20.0], help="speed_max values")
    p.add_argument("--pauses", type=float, nargs="+", default=[0.0, 30.0])
    sweepmod.add_runner_arguments(p, "cluster_stability", reps=5)
    args = p.parse_args(argv)
    if any(v < args.speed_min for v in args.speeds):
        p.error("every --speeds value must be at least --speed-min")
    sweep = sweepmod.parse(
        {
            "name": "cluster_stability",
            "replications": args.reps,
            "base": {
                "seed": args.seed,
                "duration_s": args.duration,
                "world": {"n_robots": args.n, "side_m": args.side},
                "mobility": {"speed_min_mps": args.speed_min},
                "channel": {"range_m": args.range},
                "protocol": {"model": "clustering", "message_rate_hz": 0.0},
                "output": {"position_interval_s": 0.0},
            },
            "grid": {"mobility.speed_max_mps": args.speeds, "mobility.pause_s": args.pauses},
        }
    )
    out = Path(args.out)
    report = sweepmod.run_sweep(sweep, out / "sweep", workers=args.workers, scheduler=args.scheduler)
    print(report.text())
    agg = sweepmod.aggregate(
        sweepmod.load(out / "sweep"), ["mobility.pause_s", "mobility.speed_max_mps"], list(METRICS)
    )
    agg.to_csv(out / "cluster_stability.csv", index=False)
    draw_aggregate(
        agg,
        "mobility.speed_max_mps",
        "mobility.pause_s",
        METRICS,
        out / "cluster_stability.png",
        f"{args.n} robots, range {args.range:g} m, {args.side:g} m square, {args.reps} replications, 95 % CI",
        xlabel="maximum speed (m/s)",
        series_label=lambda pause: f"pause {pause:g} s",
    )
    print(f"wrote {out / 'cluster_stability.csv'} and {out / 'cluster_stability.png'}")


if __name__ == "__main__":
    sweepmod.run_script(main, resumable=True)
