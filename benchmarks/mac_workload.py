"""Benchmark: the Ack workload on a shared medium (``channel.mac``) against the channel of
infinite capacity, in the same invocation.

Workload (benchmarks/ack_workload.py's): random waypoint (speeds 0.5-5 m/s, pause 2 s,
uniform start), range 100 m, the square's side chosen for a mean degree of about 10, Acks
(64 bytes, 704 us at 1 Mb/s with the 802.11b preamble) at 1 Hz, 100 simulated seconds,
latency 1 ms, no loss. Every case runs in a fresh subprocess; cases alternate
(none, csma, none, csma, ...) over ``--repeat`` rounds and the table gives each case's
median wall and CPU time, the ratio to ``none`` and what the medium did.

    python benchmarks/mac_workload.py                       # N = 1,000 and 10,000
    python benchmarks/mac_workload.py --n 1000 --repeat 3 --mac none aloha csma
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import time

from workload import DURATION_S, workload_config

from netsim.tools.args import Parser


def run_case(n: int, mac: str, duration_s: float) -> dict:
    from netsim.run import build, collect, summarize

    cfg = workload_config(
        n,
        duration_s,
        channel={"mac": mac},
        protocol={"model": "ack", "ack_period_s": 1.0, "ack_jitter_s": 0.05, "tau_s": 3.0},
    )
    wall, cpu = time.perf_counter(), time.process_time()
    sim = build(cfg)
    sim.run()
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    summary = summarize(sim, collect(sim), wall)
    return {
        "wall_s": wall,
        "cpu_s": cpu,
        "receptions": summary["acks_received"],
        "collisions": summary.get("acks_dropped_collision", 0),
        "half_duplex": summary.get("acks_dropped_half_duplex", 0),
        "utilisation": summary.get("channel_utilisation", 0.0),
        "delivery": summary["ack_delivery_ratio"],
    }


def main() -> None:
    p = Parser(description=__doc__.split("\n\n")[0])
    p.add_argument("--n", type=int, nargs="+", default=[1000, 10_000])
    p.add_argument("--mac", nargs="+", default=["none", "csma"])
    p.add_argument("--repeat", type=int, default=2)
    p.add_argument("--duration", type=float, default=DURATION_S)
    p.add_argument("--child", help=argparse.SUPPRESS)
    args = p.parse_args()
    if args.child:
        n, mac = args.child.split(",")
        print(json.dumps(run_case(int(n), mac, args.duration)))
        return
    print(f"Ack workload, {args.duration:g} simulated s, median of {args.repeat} alternated runs each")
    head = f"{'N':>6} {'mac':>6} {'wall s':>8} {'cpu s':>8} {'x none':>7} {'receptions':>11} {'rx/s (cpu)':>11}"
    print(head + f" {'collisions':>10} {'half dup':>9} {'util':>6} {'delivery':>8}")
    for n in args.n:
        runs: dict[str, list[dict]] = {m: [] for m in args.mac}
        for _ in range(args.repeat):
            for mac in args.mac:
                out = subprocess.run(
                    [sys.executable, __file__, "--child", f"{n},{mac}", "--duration", str(args.duration)],
                    capture_output=True,
                    text=True,
                    check=True,
                )
                runs[mac].append(json.loads(out.stdout.strip().splitlines()[-1]))
        base = statistics.median(r["wall_s"] for r in runs[args.mac[0]])
        for mac in args.mac:
            r = runs[mac]
            wall = statistics.median(x["wall_s"] for x in r)
            cpu = statistics.median(x["cpu_s"] for x in r)
            last = r[-1]
            print(
                f"{n:>6} {mac:>6} {wall:>8.2f} {cpu:>8.2f} {wall / base:>7.2f} {last['receptions']:>11,}"
                f" {last['receptions'] / cpu:>11,.0f} {last['collisions']:>10,} {last['half_duplex']:>9,}"
                f" {last['utilisation']:>6.3f} {last['delivery']:>8.4f}"
            )


if __name__ == "__main__":
    main()
