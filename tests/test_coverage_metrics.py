"""The coverage metric itself (docs/validation.md items 14 and 15)."""

import math

import numpy as np
import pytest

from netsim.coverage import (
    KERSHNER_DENSITY,
    LENS_AREA_AT_HEX_SPACING,
    components,
    covered_fraction,
    hex_lattice,
    hexagonality,
    nearest_spacing,
    random_coverage,
)


def test_reference_constants():
    assert KERSHNER_DENSITY == pytest.approx(1.2092, abs=1e-4)
    assert LENS_AREA_AT_HEX_SPACING == pytest.approx(0.1812, abs=1e-4)


def test_hexagonal_lattice_covers_everything_with_kershner_density():
    """Item 14: centres on a triangular lattice of spacing sqrt(3) r leave no point farther
    than r; disk area over covered area tends to 2 pi / (3 sqrt 3)."""
    r = 10.0
    lattice = hex_lattice(40, 40, math.sqrt(3) * r)
    # An interior window, away from the lattice's ragged edge.
    lo, side = 100.0, 400.0
    inside = lattice[
        (lattice[:, 0] > lo - 2 * r)
        & (lattice[:, 0] < lo + side + 2 * r)
        & (lattice[:, 1] > lo - 2 * r)
        & (lattice[:, 1] < lo + side + 2 * r)
    ]
    frac, bound = covered_fraction(inside - lo, r, side, cells=800)
    assert frac == 1.0
    # Density: cells of area (3 sqrt 3 / 2) r^2, one disk each.
    cell = 3 * math.sqrt(3) / 2 * r**2
    assert math.pi * r**2 / cell == pytest.approx(KERSHNER_DENSITY, rel=1e-12)
    # No point farther than r, and some points at almost exactly r (the cell corners).
    pts = np.random.default_rng(0).uniform(lo, lo + side, (20_000, 2))
    from scipy.spatial import cKDTree

    d, _ = cKDTree(lattice).query(pts)
    assert d.max() <= r + 1e-9 and d.max() > 0.99 * r
    assert hexagonality(lattice, math.sqrt(3) * r) == pytest.approx(1.0)
    assert np.median(nearest_spacing(lattice)) == pytest.approx(math.sqrt(3) * r)


def test_lens_area_at_hexagonal_spacing():
    """Item 14: two disks of radius r, sqrt(3) r apart, share 0.1812 r^2."""
    r = 1.0
    c = np.array([[2.0, 2.0], [2.0 + math.sqrt(3), 2.0]])
    # Area within r of both = area(A) + area(B) - area(A or B).
    side = 5.0
    union, _ = covered_fraction(c, r, side, cells=2000)
    lens = 2 * math.pi * r**2 - union * side**2
    assert lens == pytest.approx(LENS_AREA_AT_HEX_SPACING, rel=0.01)


def test_random_deployment_coverage_on_a_torus():
    """Item 15: n uniform centres cover 1 - (1 - pi r^2 / A)^n (on a torus: no border)."""
    n, r, side, reps = 40, 8.0, 100.0, 40
    rng = np.random.default_rng(15)
    fractions = [covered_fraction(rng.uniform(0, side, (n, 2)), r, side, cells=300, torus=True)[0] for _ in range(reps)]
    theory = random_coverage(n, r, side**2)
    assert 0.3 < theory < 0.9
    assert np.mean(fractions) == pytest.approx(theory, abs=4 * np.std(fractions) / math.sqrt(reps) + 0.002)


def test_covered_fraction_error_bound_holds():
    """The grid estimate of one disk is within its stated bound of the exact area."""
    frac, bound = covered_fraction([[50.0, 50.0]], 20.0, 100.0, cells=100)
    assert abs(frac - math.pi * 400 / 10_000) <= bound


def test_components_and_random_hexagonality():
    pos = np.array([[0, 0], [5, 0], [10, 0], [100, 0], [104, 0]], dtype=float)
    labels = components(pos, 6.0)
    assert len(set(labels)) == 2 and labels[0] == labels[2] != labels[3] == labels[4]
    random_pts = np.random.default_rng(1).uniform(0, 300, (300, 2))
    assert hexagonality(random_pts, 30.0) < 0.5
