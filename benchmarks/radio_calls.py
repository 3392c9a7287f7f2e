"""Microbenchmark: the cost of one radio call for k candidate pairs (k = 10, 100, 1,000).

What the channel would pay per transmission with the radio wing: the received power of k
candidate pairs (log-distance), with shadowing (a table already holding 50,000 pairs, as
1,000 robots with ~100 candidates each would), walls crossed on the office map, and the
whole chain deciding receivability. Pairs are drawn uniformly within ``--length`` metres of
each other on the office map's free space.

    python benchmarks/radio_calls.py                 # segments up to 30 m and 100 m
    python benchmarks/radio_calls.py --length 50
"""

from __future__ import annotations

import sys
import time

import numpy as np

from netsim.radio.fast import CompiledChain
from netsim.radio.propagation import LogDistanceParams, Pairs, log_distance, unit_disk
from netsim.radio.shadowing import PairShadowing
from netsim.tools.args import Parser
from netsim.world.free_space import sample_free
from netsim.world.los import walls_crossed
from netsim.world.maps import load_map


def per_call_us(fn, min_time_s=0.3) -> float:
    fn()
    n, t0 = 0, time.perf_counter()
    while time.perf_counter() - t0 < min_time_s:
        fn()
        n += 1
    return (time.perf_counter() - t0) / n * 1e6


# Enough draws for any batch the table asks; a batch the map cannot give is refused.
DRAWS_MAX = 4_000_000


def batch(m, rng, k, length_m, n_robots=1000):
    """k distinct pairs (a radio call's pairs are) among n_robots robots placed in free
    space, each at most length_m apart."""
    pos = sample_free(m, rng, n_robots, 200.0)
    draws = 20 * k
    while True:
        a = rng.integers(0, n_robots, draws)
        b = rng.integers(0, n_robots, draws)
        d = np.hypot(*(pos[a] - pos[b]).T)
        ok = np.flatnonzero((d <= length_m) & (a != b))
        key = np.minimum(a[ok], b[ok]) * n_robots + np.maximum(a[ok], b[ok])
        ok = ok[np.sort(np.unique(key, return_index=True)[1])]
        if len(ok) >= k or draws >= min(2_000 * k, DRAWS_MAX):
            break
        draws *= 4
    if len(ok) < k:
        found = f"only {len(ok)} distinct pairs within {length_m:g} m"
        print(f"radio_calls.py: error: {found}; asked for {k}", file=sys.stderr)
        raise SystemExit(2)
    return pos, a[ok[:k]], b[ok[:k]]


def measure(m, rng, k: int, length_m: float) -> dict:
    """Microseconds per call for k pairs at most length_m apart."""
    params = LogDistanceParams(shadowing_sigma_db=6.0, path_loss_exponent=3.0)
    pos, a, b = batch(m, rng, k, length_m)
    pairs = Pairs.between(a, b, pos, np.zeros(len(pos)))
    sh = PairShadowing(6.0, 10.0, np.random.default_rng(2))
    # A table already holding 50,000 other pairs, as in a 1,000-robot run.
    sh.sample(np.arange(50_000) + 10_000, np.arange(50_000) + 70_000, np.zeros(50_000))
    sh.sample(a, b, np.zeros(len(a)))
    plain, shadowed, full = log_distance(params), log_distance(params, sh), log_distance(params, sh, m)
    disk = unit_disk(length_m, m)
    sh2 = PairShadowing(6.0, 10.0, np.random.default_rng(2))
    sh2.sample(np.arange(50_000) + 10_000, np.arange(50_000) + 70_000, np.zeros(50_000))
    sh2.sample(a, b, np.zeros(len(a)))
    fused_full = CompiledChain(log_distance(params, sh2, m), 1000)
    fused_shadow = CompiledChain(log_distance(params, sh2), 1000)
    fused_disk = CompiledChain(disk, 1000)
    travel = [0.0]

    def moved():
        travel[0] += 0.1  # the pairs move between calls: every look is an update
        return pairs._replace(travel_m=np.full(len(a), travel[0]))

    return {
        "length_m": length_m,
        "k": len(a),
        "cells/seg": float(np.mean(np.abs(np.floor(pos[a] / 0.25) - np.floor(pos[b] / 0.25)).sum(axis=1))),
        "power": per_call_us(lambda: plain.received_dbm(pairs)),
        "+shadowing": per_call_us(lambda: shadowed.received_dbm(moved())),
        "walls": per_call_us(lambda: walls_crossed(m, pairs.pos_a, pairs.pos_b)),
        "chain": per_call_us(lambda: full.receivable(moved())),
        "disk+LOS": per_call_us(lambda: disk.receivable(pairs)),
        "c:shadow": per_call_us(lambda: fused_shadow.receivable(moved())),
        "c:chain": per_call_us(lambda: fused_full.receivable(moved())),
        "c:disk+LOS": per_call_us(lambda: fused_disk.receivable(pairs)),
    }


def main() -> None:
    ap = Parser(description=__doc__.splitlines()[0])
    ap.add_argument("--length", type=float, nargs="*", default=[30.0, 100.0], help="largest pair distance, m")
    ap.add_argument("--k", type=int, nargs="*", default=[10, 100, 1000])
    args = ap.parse_args()
    m = load_map("office")
    rng = np.random.default_rng(1)
    rows = [measure(m, rng, k, length) for length in args.length for k in args.k]
    cols = list(rows[0])
    print(" ".join(f"{c:>10}" for c in cols))
    for r in rows:
        print(" ".join(f"{r[c]:10.0f}" if c in ("length_m", "k", "cells/seg") else f"{r[c]:10.1f}" for c in cols))
    print(
        "microseconds per call (all k pairs at once). power: log-distance alone; +shadowing: with a moving"
        " pair's shadowing; walls: walls crossed on the office map; chain:"
        " log-distance + shadowing + walls deciding receivability; disk+LOS: unit disk needing line of sight;"
        " c:*: the same through CompiledChain"
    )


if __name__ == "__main__":
    main()
