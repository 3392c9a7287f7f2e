"""Static uniform deployments against random geometric graph results (docs/validation.md 11-12)."""

import math

import numpy as np
import pytest

from netsim.placement import uniform
from netsim.topology import geometric_edges


def test_mean_degree_on_the_unit_square_with_border():
    """Item 11: E[degree] = (n - 1)(pi r^2 - 8 r^3 / 3 + r^4 / 2)."""
    n, r, reps = 100, 0.1, 300
    rng = np.random.default_rng(11)
    degrees = []
    for _ in range(reps):
        edges = geometric_edges(uniform(rng, n, 1.0), r)
        degrees.append(2 * len(edges) / n)
    theory = (n - 1) * (math.pi * r**2 - 8 * r**3 / 3 + r**4 / 2)
    se = np.std(degrees) / math.sqrt(reps)
    assert abs(np.mean(degrees) - theory) < 4 * se


def test_no_isolated_robot_on_a_torus():
    """Item 12: P(min degree >= 1) = (1 - (1 - pi r^2)^(n - 1))^n on a torus."""
    n, r, reps = 50, 0.16, 600
    rng = np.random.default_rng(12)
    ok = 0
    for _ in range(reps):
        edges = geometric_edges(uniform(rng, n, 1.0), r, side_m=1.0)
        deg = np.bincount(np.array([e[:2] for e in edges]).ravel(), minlength=n) if edges else np.zeros(n)
        ok += bool(deg.min() >= 1)
    theory = (1 - (1 - math.pi * r**2) ** (n - 1)) ** n
    assert 0.2 < theory < 0.9
    assert ok / reps == pytest.approx(theory, abs=4 * math.sqrt(theory * (1 - theory) / reps))


@pytest.mark.parametrize("torus", [False, True])
def test_reach_keys_are_the_directed_pairs(torus):
    """``reach_keys`` lists ``receiver * n + sender`` for exactly the directed pairs of
    ``geometric_pairs`` (sender reaches receiver), ascending, with unequal ranges, on the
    plane and on a torus."""
    from netsim.topology import geometric_pairs, reach_keys

    rng = np.random.default_rng(4)
    n, side = 80, 300.0
    pos = rng.uniform(0, side, (n, 2))
    ranges = rng.uniform(20.0, 60.0, n)
    src, dst, _ = geometric_pairs(pos, ranges, side if torus else None, directed=True)
    keys = reach_keys(pos, ranges, side if torus else None)
    assert keys.tolist() == sorted((dst * n + src).tolist())
    assert len(keys) > n
