"""Benchmark: whole runs with the radio at N = 1,000, against the unit disk, in one invocation.

The workload of ``benchmarks/ack_workload.py``: random waypoint (speeds 0.5-5 m/s, pause 2 s,
uniform start at rest), Acks at 1 Hz, 100 simulated seconds, mean degree about 10 without
walls or shadowing. Cases:

- ``unit_disk``: range 100 m on a square of side ``100 sqrt(N pi / 10)`` (the baseline);
- ``log_distance + shadowing``: the same square, the default radio (implied range 100 m)
  with shadowing sigma = 4 dB (reach 341 m);
- ``unit_disk, 200 m square``: the office map's square without the map, range 11.3 m (the
  same mean degree), for reference;
- ``office map, log_distance``: that square on the office map, implied range 11.3 m,
  5 dB per wall (links solved exactly from the map, docs/radio.md);
- ``office map, unit_disk + line of sight``: the same, with the unit disk of 11.3 m;
- ``building map``: a floor of 40 m x 40 m at 5 cm per pixel (the scale of a SLAM map of a
  real building, :func:`netsim.world.examples.building_floor`), ``--n-building`` robots
  (100) at 0.1-0.5 m/s (pause 2 s), the same mean degree: log-distance with 5 dB per wall,
  and the unit disk with line of sight.

Each wall time is build + run + collecting the tables (links included), measured in this
process one after another (numba's compiled code is cached on disk; a warm-up run loads
it first); the process's CPU time beside it, which other jobs on the machine disturb less.
Prints a table with each case's ratios to the baseline.

    python benchmarks/radio_runs.py [--n 1000] [--duration 100] [--n-building 100] [--only WORD]
"""

from __future__ import annotations

import math
import tempfile
import time
import warnings

from netsim.tools.args import Parser

DEGREE = 10.0


MOBILITY = {"speed_min_mps": 0.5, "speed_max_mps": 5.0, "pause_s": 2.0, "stationary_start": False}


def config(n: int, duration: float, side: float, channel: dict, world: dict | None = None, mobility=None):
    from netsim.config import from_dict

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return from_dict(
            {
                "seed": 1,
                "duration_s": duration,
                "world": {"n_robots": n, "side_m": side, **(world or {})},
                "mobility": mobility or MOBILITY,
                "channel": {"latency_s": 0.001, **channel},
                "protocol": {"model": "ack", "ack_period_s": 1.0, "ack_jitter_s": 0.05, "tau_s": 3.0},
                "output": {"position_interval_s": 0.0},
            }
        )


def building_yaml(folder):
    """The building floor written as a ``map_saver`` map in ``folder``."""
    from pathlib import Path

    from netsim.world.examples import BUILDING_RESOLUTION_M, building_floor
    from netsim.world.maps import save_map

    return save_map(Path(folder) / "building.yaml", *building_floor(), BUILDING_RESOLUTION_M)


def timed(cfg) -> dict:
    from netsim.run import build, collect

    start = time.perf_counter()
    cpu0 = time.process_time()
    sim = build(cfg)
    sim.run()
    t_run = time.perf_counter() - start
    frames = collect(sim)
    wall = time.perf_counter() - start
    cpu = time.process_time() - cpu0
    acks = sim.channel.counters_for("ack")
    return {
        "wall_s": wall,
        "cpu_s": cpu,
        "run_s": t_run,
        "tables_s": wall - t_run,
        "receptions": int(acks.received.sum()),
        "links": len(frames["links"]),
    }


def main() -> None:
    ap = Parser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=1000)
    ap.add_argument("--duration", type=float, default=100.0)
    ap.add_argument("--n-building", type=int, default=100)
    ap.add_argument("--only", default="", help="run only the cases whose name contains this (and the baseline)")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="netsim-bench-") as folder:
        measure_all(args, folder)


def measure_all(args, folder) -> None:
    """Every case, the building's map written in ``folder``; prints the table."""
    n, T = args.n, args.duration
    side = 100.0 * math.sqrt(n * math.pi / DEGREE)
    office_side = 200.0
    r_office = office_side * math.sqrt(DEGREE / (n * math.pi))
    # Sensitivity for an implied range of r_office with the other keys at their defaults.
    sens = 20.0 - 40.0 - 30.0 * math.log10(r_office)
    cases = [
        ("unit_disk", config(n, T, side, {"range_m": 100.0})),
        (
            "log_distance + shadowing 4 dB",
            config(n, T, side, {"propagation": "log_distance", "shadowing_sigma_db": 4.0}),
        ),
        (f"unit_disk, {office_side:g} m square", config(n, T, office_side, {"range_m": r_office})),
        (
            "office map, log_distance",
            config(n, T, office_side, {"propagation": "log_distance", "sensitivity_dbm": sens}, {"map": "office"}),
        ),
        ("office map, unit_disk + line of sight", config(n, T, office_side, {"range_m": r_office}, {"map": "office"})),
    ]
    nb, b_side = args.n_building, 40.0
    r_b = b_side * math.sqrt(DEGREE / (nb * math.pi))
    sens_b = 20.0 - 40.0 - 30.0 * math.log10(r_b)
    slow = {"speed_min_mps": 0.1, "speed_max_mps": 0.5, "pause_s": 2.0, "stationary_start": False}
    building = {"map": str(building_yaml(folder))}
    cases += [
        (
            f"building map (5 cm), {nb} robots, log_distance",
            config(nb, T, b_side, {"propagation": "log_distance", "sensitivity_dbm": sens_b}, building, slow),
        ),
        (
            f"building map (5 cm), {nb} robots, unit_disk + line of sight",
            config(nb, T, b_side, {"range_m": r_b}, building, slow),
        ),
    ]
    cases = [c for i, c in enumerate(cases) if i == 0 or args.only in c[0]]
    timed(config(50, 5.0, 200.0, {"propagation": "log_distance", "shadowing_sigma_db": 4.0}, {"map": "office"}))
    timed(config(50, 5.0, 200.0, {"range_m": 20.0}, {"map": "office"}))
    rows = []
    for name, cfg in cases:
        r = timed(cfg)
        rows.append((name, r))
        print(f"{name}: {r['wall_s']:.1f} s", flush=True)
    base = rows[0][1]["wall_s"]
    base_cpu = rows[0][1]["cpu_s"]
    print()
    print(f"N = {n}, {T:g} s simulated; office map: side {office_side:g} m, implied range {r_office:.1f} m")
    print(f"building map: N = {nb}, side {b_side:g} m, range {r_b:.2f} m, robots at 0.1-0.5 m/s")
    print(
        "| case | wall (s) | run (s) | tables (s) | x unit disk | CPU (s) | x unit disk, CPU | Ack receptions "
        "| link lifetimes |"
    )
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for name, r in rows:
        print(
            f"| {name} | {r['wall_s']:.1f} | {r['run_s']:.1f} | {r['tables_s']:.1f} | {r['wall_s'] / base:.2f} | "
            f"{r['cpu_s']:.1f} | {r['cpu_s'] / base_cpu:.2f} | {r['receptions']:,} | {r['links']:,} |"
        )


if __name__ == "__main__":
    main()
