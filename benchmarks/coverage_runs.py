"""Benchmark: whole coverage runs (``coverage.members = "spread"``) from dense starts.

For each N: a dense random start (a central square of side ``40 sqrt(N)`` m, about 20
neighbours per robot), range 100 m, on a square large enough that a connected team
cannot cover it all (2.5 km for 200 robots, 5 km for 1,000), the full clustering
protocol, until ``--duration``. Prints one row per N: wall time of the whole run, the
control steps taken and their rate (per wall second of the whole run, and per second
spent in the coverage controller itself), the time spent sampling the covered fraction,
the settling time (from the start of control to when the stopping rule ended it), the
final covered fraction of the area and of ``min(1, U(N) / A)``, and the components at
the start and at the end.

The covered fraction is sampled exactly (``coverage.area_method = "exact"``) at 200
robots and on the grid at 1,000 (an exact sample takes about 0.7 s there); the final
value in the table is exact in both cases.

    python benchmarks/coverage_runs.py                 # N = 200 and 1000
    python benchmarks/coverage_runs.py --n 200 --duration 900
"""

from __future__ import annotations

import argparse
import math
import time

from netsim import config as cfgmod
from netsim import metrics as metrics
from netsim.run import build
from netsim.tools.args import Parser

SIDE_M = {200: 2500.0, 1000: 5000.0}


def timed(fn, account: list):
    def wrapper(step):
        start = time.perf_counter()
        fn(step)
        account[0] += time.perf_counter() - start

    return wrapper


def one_run(n: int, duration_s: float, seed: int) -> dict:
    side = SIDE_M.get(n, 100.0 * math.sqrt(25 * n))
    overrides = [
        f"world.n_robots={n}",
        f"world.side_m={side}",
        'world.placement="centre"',
        f"world.centre_side_m={40 * math.sqrt(n):.1f}",
        'mobility.model="static"',
        "channel.range_m=100",
        "coverage.enabled=true",
        f'coverage.area_method="{"exact" if n <= 300 else "grid"}"',
        "protocol.message_rate_hz=0",
        "output.position_interval_s=0",
        f"duration_s={duration_s}",
        f"seed={seed}",
    ]
    start = time.perf_counter()
    sim = build(cfgmod.load(None, overrides))
    ctl = sim.models["coverage"]
    loop = sim.models["control"]
    control_s, sampling_s = [0.0], [0.0]
    loop._controllers = [(o, k, w, timed(c, control_s)) for o, k, w, c in loop._controllers]
    sample = ctl.sample

    def timed_sample(t):
        t0 = time.perf_counter()
        row = sample(t)
        sampling_s[0] += time.perf_counter() - t0
        return row

    ctl.sample = timed_sample
    sim.run(progress=False)
    wall = time.perf_counter() - start
    pos = sim.state.positions_at(sim.env.now)
    covered, err = metrics.covered_fraction_exact(pos, 100.0, side)
    bound = metrics.bound_fraction(n, 100.0, side)
    steps = loop.steps
    comps = [s.components for s in ctl.steps]
    return {
        "N": n,
        "side m": side,
        "wall s": wall,
        "steps": steps,
        "steps/s": steps / wall,
        "steps/s ctl": steps / control_s[0] if control_s[0] else math.nan,
        "sampling s": sampling_s[0],
        "settled s": ctl.settled_s - sim.config.coverage.start_s,
        "covered": covered,
        "of bound": covered / bound,
        "comp start": comps[0] if comps else math.nan,
        "comp end": int(metrics.components(pos, 100.0).max() + 1),
    }


def main() -> None:
    p = Parser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--n", type=int, nargs="+", default=[200, 1000])
    p.add_argument("--duration", type=float, default=1500.0, help="simulated seconds per run")
    p.add_argument("--seed", type=int, default=1)
    args = p.parse_args()
    cols = ["N", "side m", "wall s", "steps", "steps/s", "steps/s ctl", "sampling s", "settled s", "covered"]
    cols += ["of bound", "comp start", "comp end"]
    print("".join(f"{c:>12}" for c in cols))
    for n in args.n:
        row = one_run(n, args.duration, args.seed)
        print("".join(f"{row[c]:>12.4g}" if isinstance(row[c], float) else f"{row[c]:>12}" for c in cols), flush=True)


if __name__ == "__main__":
    main()
