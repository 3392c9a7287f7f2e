"""Virtual-force laws: symmetry, range, and the spring's zero at sqrt(3) r_c."""

import math

import numpy as np
import pytest
from netsim.mobility.forces import LAWS, SQRT3, border_forces, pair_resultants

RC = 10.0


def pair_force(p_i, p_j, law, range_m, gain):
    """The force on a robot at ``p_i`` from one at ``p_j``, through :func:`pair_resultants`."""
    return pair_resultants(1, np.zeros(1, np.int64), [p_i], [p_j], law, range_m, gain)[0]


@pytest.mark.parametrize("name", sorted(LAWS))
@pytest.mark.parametrize("d", [3.0, 12.0, 17.0, 19.9])
def test_forces_are_equal_and_opposite_along_the_joining_line(name, d):
    law = LAWS[name]
    a, b = np.array([1.0, 2.0]), np.array([1.0, 2.0]) + d * np.array([0.6, 0.8])
    fa, fb = pair_force(a, b, law, RC, 1.0), pair_force(b, a, law, RC, 1.0)
    assert fa == pytest.approx(-fb)
    cross = fa[0] * 0.8 - fa[1] * 0.6
    assert cross == pytest.approx(0.0, abs=1e-12)


@pytest.mark.parametrize("name", sorted(LAWS))
def test_no_force_at_or_beyond_twice_the_range(name):
    law = LAWS[name]
    assert np.all(law(np.array([2 * RC, 2 * RC + 1, 100.0]), RC, 3.0) == 0.0)


def test_spring_is_zero_at_the_hexagonal_spacing_and_changes_sign():
    law = LAWS["spring"]
    assert float(law(SQRT3 * RC, RC, 2.0)) == pytest.approx(0.0, abs=1e-12)
    assert float(law(SQRT3 * RC - 1, RC, 2.0)) > 0  # repulsive when closer
    assert float(law(SQRT3 * RC + 1, RC, 2.0)) < 0  # attractive between target and 2 r_c


def test_repulsion_law_only_pushes_and_stops_at_the_target():
    law = LAWS["repulsion"]
    d = np.linspace(0.1, 2 * RC, 200)
    f = law(d, RC, 1.0)
    assert (f >= 0).all() and (f[d >= SQRT3 * RC] == 0).all()


def test_inverse_square_is_zero_at_target_and_strong_up_close():
    law = LAWS["inverse_square"]
    assert float(law(SQRT3 * RC, RC, 1.0)) == pytest.approx(0.0, abs=1e-12)
    assert float(law(1.0, RC, 1.0)) > 10 * float(law(8.0, RC, 1.0)) > 0


def test_resultant_of_a_hexagonal_ring_is_zero():
    ring = [SQRT3 * RC * np.array([math.cos(a), math.sin(a)]) for a in np.arange(6) * math.pi / 3]
    f = pair_resultants(1, np.zeros(6, np.int64), np.zeros((6, 2)), np.array(ring), LAWS["spring"], RC, 1.0)[0]
    assert f == pytest.approx([0.0, 0.0], abs=1e-9)


def test_robots_at_one_point_push_nowhere():
    f = pair_resultants(2, np.array([0, 1]), np.ones((2, 2)), np.ones((2, 2)), LAWS["inverse_square"], RC, 1.0)
    assert np.isfinite(f).all() and (f == 0).all()


def test_border_pushes_inward_only_near_the_border():
    f = border_forces(np.array([[1.0, 50.0], [99.0, 50.0], [50.0, 50.0]]), 100.0, RC, 1.0)
    assert f[0, 0] > 0 and f[1, 0] < 0
    assert f[2] == pytest.approx([0.0, 0.0])
    margin = SQRT3 * RC / 2
    assert f[0] == pytest.approx([margin - 1.0, 0.0])
