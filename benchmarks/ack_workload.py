"""Benchmark: the Ack workload alone, netsim against the same model hand-written in SimPy.

Workload: random waypoint (speeds 0.5-5 m/s, pause 2 s, uniform start), range 100 m, the square's side
chosen for a mean degree of about 10 (``N pi R^2 / side^2 = 10``), Acks at 1 Hz, 100
simulated seconds, latency 1 ms, no loss.

The hand-written baseline is what a SimPy user would write: one robot object and one
process per robot for motion and for beacons, an O(N) scan over all robots per Ack, and
one kernel event (a process) per reception that updates a dict-based neighbour table.

Every case runs in a fresh subprocess so that its peak memory (max RSS) is its own.

    python benchmarks/ack_workload.py                 # N = 100, 1,000, 10,000
    python benchmarks/ack_workload.py --n 100 1000    # a subset
    python benchmarks/ack_workload.py --protocol clustering   # the full protocol too
"""

from __future__ import annotations

import argparse
import json
import math
import resource
import subprocess
import sys
import time

from netsim.tools.args import Parser

RANGE_M = 100.0
DEGREE = 10.0
DURATION_S = 100.0
SPEED_MIN, SPEED_MAX, PAUSE = 0.5, 5.0, 2.0
LATENCY_S = 0.001


def side_for(n: int) -> float:
    return RANGE_M * math.sqrt(n * math.pi / DEGREE)


def run_netsim(n: int, protocol: str) -> dict:
    from netsim.config import from_dict
    from netsim.run import build

    cfg = from_dict(
        {
            "seed": 1,
            "duration_s": DURATION_S,
            "world": {"n_robots": n, "side_m": side_for(n)},
            # Uniform placement at rest, as the hand-written baseline starts: the same workload.
            "mobility": {
                "speed_min_mps": SPEED_MIN,
                "speed_max_mps": SPEED_MAX,
                "pause_s": PAUSE,
                "stationary_start": False,
            },
            "channel": {"range_m": RANGE_M, "latency_s": LATENCY_S},
            "protocol": {"model": protocol, "ack_period_s": 1.0, "ack_jitter_s": 0.05, "tau_s": 3.0},
            "output": {"position_interval_s": 0.0},
        }
    )
    start = time.perf_counter()
    sim = build(cfg)
    sim.run()
    wall = time.perf_counter() - start
    c = sim.channel.counters_for("ack")
    return {"wall_s": wall, "receptions": int(c.received.sum()), "acks": int(c.sent.sum())}


def run_handwritten(n: int) -> dict:
    import numpy as np
    import simpy

    side = side_for(n)
    r2 = RANGE_M * RANGE_M
    rng = np.random.default_rng(1)

    class Robot:
        def __init__(self, ident):
            self.ident = ident
            self.x0, self.y0 = rng.uniform(0, side, 2)
            self.vx = self.vy = 0.0
            self.t0 = 0.0
            self.neighbours = {}
            self.received = 0

        def pos(self, t):
            dt = t - self.t0
            return self.x0 + self.vx * dt, self.y0 + self.vy * dt

    def mover(env, robot):
        while True:
            x, y = robot.pos(env.now)
            dx, dy = rng.uniform(0, side) - x, rng.uniform(0, side) - y
            speed = rng.uniform(SPEED_MIN, SPEED_MAX)
            dist = math.hypot(dx, dy)
            robot.x0, robot.y0, robot.t0 = x, y, env.now
            robot.vx, robot.vy = dx / dist * speed, dy / dist * speed
            yield env.timeout(dist / speed)
            robot.x0, robot.y0 = robot.pos(env.now)
            robot.vx = robot.vy = 0.0
            robot.t0 = env.now
            yield env.timeout(PAUSE)

    def deliver(env, receiver, sender):
        yield env.timeout(LATENCY_S)
        receiver.neighbours[sender] = env.now
        receiver.received += 1

    def beacon(env, robot, robots):
        yield env.timeout(rng.uniform(0, 1.0))
        while True:
            x, y = robot.pos(env.now)
            for other in robots:
                if other is not robot:
                    ox, oy = other.pos(env.now)
                    if (ox - x) ** 2 + (oy - y) ** 2 <= r2:
                        env.process(deliver(env, other, robot.ident))
            yield env.timeout(1.0 + rng.uniform(-0.05, 0.05))

    start = time.perf_counter()
    env = simpy.Environment()
    robots = [Robot(i) for i in range(n)]
    for robot in robots:
        env.process(mover(env, robot))
        env.process(beacon(env, robot, robots))
    env.run(until=DURATION_S)
    wall = time.perf_counter() - start
    return {"wall_s": wall, "receptions": sum(r.received for r in robots), "acks": None}


def child(args) -> None:
    result = run_handwritten(args.n[0]) if args.case == "handwritten" else run_netsim(args.n[0], args.case)
    result["peak_mib"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(json.dumps(result))


def measure(case: str, n: int) -> dict:
    out = subprocess.run(
        [sys.executable, __file__, "--child", case, "--n", str(n)], capture_output=True, text=True, check=True
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    p = Parser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--n", type=int, nargs="+", default=[100, 1000, 10_000])
    p.add_argument("--protocol", nargs="+", default=["ack"], help="netsim protocol stacks to measure")
    p.add_argument(
        "--handwritten-max-n",
        type=int,
        default=1000,
        help="skip the O(N^2) hand-written baseline above this N (default 1000)",
    )
    p.add_argument("--child", help=argparse.SUPPRESS)
    args = p.parse_args()
    if args.child:
        args.case = args.child
        child(args)
        return
    header = (
        f"{'case':<14}{'N':>8}{'side m':>9}{'wall s':>10}{'receptions':>13}"
        f"{'recv/wall s':>14}{'peak MiB':>10}{'speed-up':>10}"
    )
    print(header)
    print("-" * len(header))
    for n in args.n:
        rows = {}
        for case in args.protocol:
            rows[case] = measure(case, n)
        if n <= args.handwritten_max_n:
            rows["handwritten"] = measure("handwritten", n)
        base = rows.get("handwritten")
        for case, r in rows.items():
            rate = r["receptions"] / r["wall_s"]
            ratio = ""
            if base and case != "handwritten":
                ratio = f"{rate / (base['receptions'] / base['wall_s']):.1f}x"
            print(
                f"{case:<14}{n:>8}{side_for(n):>9.0f}{r['wall_s']:>10.2f}{r['receptions']:>13,}{rate:>14,.0f}"
                f"{r['peak_mib']:>10.0f}{ratio:>10}"
            )
        if not base:
            print(f"{'handwritten':<14}{n:>8}   skipped (O(N^2) scan; above --handwritten-max-n)")
        sys.stdout.flush()


if __name__ == "__main__":
    main()
