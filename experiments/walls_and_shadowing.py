"""Cluster stability and message delivery in an office against open space, and against
shadowing: what walls and log-normal shadowing do to the clustering protocol.

A sweep (``netsim.tools.sweep``) of ``world.map`` (open space, the office map) x
``channel.shadowing_sigma_db``, under the log-distance radio with an implied range of
``--range`` metres (the sensitivity is set for it, other radio keys at their defaults,
5 dB per wall), random waypoint without the stationary start (it has no closed form on a
map), the clustering protocol with random messages, with replications. Writes to ``--out``:

- ``walls_and_shadowing.csv``: per point, each metric's mean, standard deviation and 95 %
  confidence interval over replications (the per-run rows are in ``sweep/runs/``);
- ``walls_and_shadowing.png``: leaders, role changes per robot per minute, mean leader
  tenure and message delivery ratio against sigma, one line for open space, one for the office.

Killed, it resumes where it stopped: finished runs are kept in ``--out/sweep``.

    python experiments/walls_and_shadowing.py
    python experiments/walls_and_shadowing.py --reps 10 --workers 2 --sigmas 0 2 4 6 8
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from netsim.tools import sweep as sweepmod
from netsim.tools.args import Parser
from netsim.tools.sweep_figure import draw_aggregate

METRICS = {
    "leaders_time_mean": "leaders (time-weighted mean)",
    "role_changes_per_robot_per_min": "role changes per robot per minute",
    "mean_leader_tenure_s": "mean leader tenure (s)",
    "message_delivery_ratio": "message delivery ratio",
}
TX_POWER_DBM, REFERENCE_LOSS_DB, EXPONENT = 20.0, 40.0, 3.0  # the radio's defaults


def sensitivity_for(range_m: float) -> float:
    """The sensitivity whose implied range is ``range_m`` (reference distance 1 m)."""
    return TX_POWER_DBM - REFERENCE_LOSS_DB - 10.0 * EXPONENT * math.log10(range_m)


def main(argv=None) -> None:
    p = Parser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--n", type=int, default=60, help="robots")
    p.add_argument("--side", type=float, default=200.0, help="side of the area, m (at most the map's 200 m)")
    p.add_argument("--range", type=float, default=40.0, help="implied range of the radio, m")
    p.add_argument("--duration", type=float, default=300.0, help="simulated seconds per run")
    p.add_argument("--speed-max", type=float, default=2.0, help="random waypoint's top speed, m/s")
    p.add_argument("--sigmas", type=float, nargs="+", default=[0.0, 4.0, 8.0], help="shadowing sigma values, dB")
    p.add_argument("--maps", nargs="+", default=["", "office"], help='maps ("" for open space)')
    sweepmod.add_runner_arguments(p, "walls_and_shadowing", reps=5)
    args = p.parse_args(argv)
    if not 0 < args.range:
        p.error("--range must be > 0")
    sweep = sweepmod.parse(
        {
            "name": "walls_and_shadowing",
            "replications": args.reps,
            "base": {
                "seed": args.seed,
                "duration_s": args.duration,
                "world": {"n_robots": args.n, "side_m": args.side},
                "mobility": {"speed_min_mps": 0.5, "speed_max_mps": args.speed_max, "stationary_start": False},
                "channel": {"propagation": "log_distance", "sensitivity_dbm": sensitivity_for(args.range)},
                "protocol": {"model": "clustering", "message_rate_hz": 0.5},
                "output": {"position_interval_s": 0.0},
            },
            "grid": {"world.map": args.maps, "channel.shadowing_sigma_db": args.sigmas},
        }
    )
    out = Path(args.out)
    report = sweepmod.run_sweep(sweep, out / "sweep", workers=args.workers, scheduler=args.scheduler)
    print(report.text())
    runs = sweepmod.load(out / "sweep")
    runs["world.map"] = runs["world.map"].fillna("")
    agg = sweepmod.aggregate(runs, ["world.map", "channel.shadowing_sigma_db"], list(METRICS))
    agg.to_csv(out / "walls_and_shadowing.csv", index=False)
    draw_aggregate(
        agg,
        "channel.shadowing_sigma_db",
        "world.map",
        METRICS,
        out / "walls_and_shadowing.png",
        f"{args.n} robots, implied range {args.range:g} m, {args.side:g} m square, {args.reps} replications, 95 % CI",
        xlabel="shadowing sigma (dB)",
        series_label=lambda world_map: f"{world_map} map" if world_map else "open space",
    )
    print(f"wrote {out / 'walls_and_shadowing.csv'} and {out / 'walls_and_shadowing.png'}")


if __name__ == "__main__":
    sweepmod.run_script(main, resumable=True)
