"""The periodic-beacon workload the benchmarks share: random waypoint (speeds 0.5–5 m/s,
pause 2 s, from uniform positions at rest), range 100 m on a square giving a mean degree of
10, latency 1 ms, no sampled positions."""

from __future__ import annotations

import math

RANGE_M = 100.0
DEGREE = 10.0
DURATION_S = 100.0


def side_for(n: int) -> float:
    """The square's side that gives ``n`` robots of range ``RANGE_M`` a mean degree of ``DEGREE``."""
    return RANGE_M * math.sqrt(n * math.pi / DEGREE)


def workload_config(n: int, duration_s: float = DURATION_S, channel: dict | None = None, **sections: dict):
    """The workload's configuration for ``n`` robots; ``channel`` and ``sections`` add keys."""
    from netsim.config import from_dict

    return from_dict(
        {
            "seed": 1,
            "duration_s": duration_s,
            "world": {"n_robots": n, "side_m": side_for(n)},
            "mobility": {"speed_min_mps": 0.5, "speed_max_mps": 5.0, "pause_s": 2.0, "stationary_start": False},
            "channel": {"range_m": RANGE_M, "latency_s": 0.001, **(channel or {})},
            "output": {"position_interval_s": 0.0},
            **sections,
        }
    )
