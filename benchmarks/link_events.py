"""Benchmark: the cost of solving link events during the run, against solving them after it.

Workload (as benchmarks/ack_workload.py): random waypoint (speeds 0.5-5 m/s, pause 2 s,
uniform start at rest), range 100 m, the square's side chosen for a mean degree of about
10 (``N pi R^2 / side^2 = 10``), latency 1 ms, no loss, 100 simulated seconds, no sampled
positions. Each case is the whole run (build, run, collect: the tables included) in a
fresh subprocess, the same invocation three ways:

- ``post-hoc``: nobody subscribes; links.parquet is solved after the run (the default);
- ``runtime``: a subscriber counts ``link_up`` and ``link_down``, so link events are solved
  during the run and links.parquet is their record;
- ``runtime+live`` (with ``--live``): the same, and the live networkx topology with its
  time-averaged levels.

Printed: wall and CPU time of each case (the CPU time of its process: steadier than the
wall time on a shared machine) with their ratios to ``post-hoc``, the lifetimes in
links.parquet, the link events announced, and the load average when the case ended.

    python benchmarks/link_events.py                         # N = 1,000 and 10,000, protocols none and ack
    python benchmarks/link_events.py --n 1000 --protocol ack --live
    python benchmarks/link_events.py --n 1000 10000 --protocol none --repeat 5   # modes in turn, median ratios
    python benchmarks/link_events.py --map office --n 100 1000 --protocol none ack --repeat 3

With ``--map office`` the robots move on the office map (200 m x 200 m), the unit disk with
line of sight, the range chosen for a mean degree of 10 without walls
(``200 sqrt(10 / (N pi))``: 11.3 m at N = 1,000): links are solved exactly between walls
(docs/radio.md), after the run or during it (netsim/links/walled_links.py).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import time

from workload import DEGREE, workload_config

from netsim.tools.args import Parser

MAP_SIDE_M = 200.0


def config_for(n: int, protocol: str, mode: str, world_map: str):
    events = {"live_topology": mode == "runtime+live"}
    if not world_map:
        return workload_config(n, protocol={"model": protocol}, events=events)
    from netsim.config import from_dict

    return from_dict(
        {
            "seed": 1,
            "duration_s": 100.0,
            "world": {"n_robots": n, "side_m": MAP_SIDE_M, "map": world_map},
            "mobility": {"speed_min_mps": 0.5, "speed_max_mps": 5.0, "pause_s": 2.0, "stationary_start": False},
            "channel": {"range_m": MAP_SIDE_M * math.sqrt(DEGREE / (n * math.pi)), "latency_s": 0.001},
            "protocol": {"model": protocol},
            "events": events,
            "output": {"position_interval_s": 0.0},
        }
    )


def run_case(n: int, protocol: str, mode: str, world_map: str = "") -> dict:
    from netsim.run import build, collect, summarize

    cfg = config_for(n, protocol, mode, world_map)
    start, cpu = time.perf_counter(), time.process_time()
    sim = build(cfg)
    counted = [0]
    if mode != "post-hoc":

        def count(_ev):
            counted[0] += 1

        sim.events.on("link_up", count)
        sim.events.on("link_down", count)
    sim.run()
    frames = collect(sim)
    wall = time.perf_counter() - start
    summarize(sim, frames, wall)
    cpu = time.process_time() - cpu
    links = frames["links"]
    return {
        "wall_s": wall,
        "cpu_s": cpu,
        "lifetimes": len(links),
        "announced": counted[0],
        "windows": sim.links.windows if sim.links is not None else 0,
    }


def _case(n: int, protocol: str, mode: str, world_map: str) -> dict:
    out = subprocess.run(
        [sys.executable, __file__, "--case", f"{n},{protocol},{mode},{world_map}"],
        capture_output=True,
        text=True,
        check=True,
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv=None) -> int:
    p = Parser(description=__doc__.splitlines()[0])
    p.add_argument("--n", type=int, nargs="*", default=[1000, 10000])
    p.add_argument("--protocol", nargs="*", default=["none", "ack"])
    p.add_argument("--live", action="store_true", help="also measure the live topology")
    p.add_argument("--repeat", type=int, default=1, help="run the modes in turn this many times")
    p.add_argument("--map", default="", help='run on this map ("office"), the unit disk with line of sight')
    p.add_argument("--case", help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.case:
        n, protocol, mode, world_map = args.case.split(",")
        print(json.dumps(run_case(int(n), protocol, mode, world_map)))
        return 0
    modes = ["post-hoc", "runtime"] + (["runtime+live"] if args.live else [])
    print(
        f"{'protocol':<9} {'N':>6} {'mode':<13} {'wall s':>8} {'ratio':>6} {'CPU s':>8} {'ratio':>6}"
        f" {'lifetimes':>10} {'announced':>10} {'load':>5}"
    )
    print("-" * 90)
    for protocol in args.protocol:
        for n in args.n:
            ratios: dict[str, list[tuple[float, float]]] = {mode: [] for mode in modes}
            for _turn in range(args.repeat):
                base = base_cpu = 0.0
                for mode in modes:
                    r = _case(n, protocol, mode, args.map)
                    if mode == "post-hoc":
                        base, base_cpu = r["wall_s"], r["cpu_s"]
                    ratios[mode].append((r["wall_s"] / base, r["cpu_s"] / base_cpu))
                    print(
                        f"{protocol:<9} {n:>6} {mode:<13} {r['wall_s']:>8.2f} {r['wall_s'] / base:>5.2f}x"
                        f" {r['cpu_s']:>8.2f} {r['cpu_s'] / base_cpu:>5.2f}x"
                        f" {r['lifetimes']:>10,} {r['announced']:>10,} {os.getloadavg()[0]:>5.1f}",
                        flush=True,
                    )
            if args.repeat > 1:
                for mode in modes[1:]:
                    wall = statistics.median(w for w, _ in ratios[mode])
                    cpu = statistics.median(c for _, c in ratios[mode])
                    print(f"{protocol:<9} {n:>6} {mode:<13} {'median':>8} {wall:>5.2f}x {'median':>8} {cpu:>5.2f}x")
    return 0


if __name__ == "__main__":
    sys.exit(main())
