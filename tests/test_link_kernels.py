"""The link solvers' crossings (netsim/links/_kernels.py), plain and compiled, are the numpy
oracle's (tests/oracles/links.py), compared with ``==``, on the plane and on a torus; and
link lifetimes are the same either way."""

import math

import numpy as np
import pandas as pd
import pytest

from netsim.compiled import compiled_copy
from netsim.links import lifetimes
from netsim.trajectory import LegTable
from tests.oracles.links import in_range, roots, solve_piece
from tests.oracles.near_pairs import wrap

pytest.importorskip("numba")

from netsim.links import _kernels as _link_kernels  # noqa: E402


def _legs(rng, n, per_robot):
    """Random legs, some on a grid of times and velocities so that ties, parallel legs
    (no relative motion) and crossings exactly on a piece's edge occur."""

    def mixed(size, uniform, grid):
        return np.where(rng.random(size) < 0.5, uniform(size), grid(size))

    rows = []
    for r in range(n):
        t = np.sort(np.r_[0.0, mixed(per_robot - 1, lambda k: rng.uniform(0, 50, k), lambda k: rng.integers(0, 50, k))])
        v = mixed((per_robot, 2), lambda k: rng.uniform(-5, 5, k), lambda k: rng.integers(-2, 3, k))
        p = mixed((per_robot, 2), lambda k: rng.uniform(0, 200, k), lambda k: rng.integers(0, 4, k) * 50.0)
        rows += [(t[k], r, p[k, 0], p[k, 1], v[k, 0], v[k, 1]) for k in range(per_robot)]
    legs = pd.DataFrame(rows, columns=["t_s", "robot", "x_m", "y_m", "vx_mps", "vy_mps"])
    table = LegTable(legs, n)
    table.t, table.p, table.v = (np.array(x, float, order="C") for x in (table.t, table.p, table.v))
    return legs, table


def _solved(table, la, lb, radius, t_start, length, kernels, box=None):
    found = []

    def emit(t, a, b, k, phase):
        a = np.asarray(a, np.int64)
        phase = np.broadcast_to(np.asarray(phase, np.int8), a.shape)
        k = np.broadcast_to(np.asarray(k, np.int8), a.shape)
        for row in zip(np.asarray(t, float).tolist(), a.tolist(), np.asarray(b).tolist(), k.tolist(), phase.tolist()):
            found.append(row)

    pairs = np.arange(len(la), dtype=np.int64)
    if kernels is not None:
        lifetimes._solve_legs(table, la, lb, radius, t_start, length, pairs, pairs + 1000, emit, box, kernels)
    else:
        # The numpy oracle.
        origin = np.maximum(table.t[la], table.t[lb])
        pa = table.p[la] + table.v[la] * (origin - table.t[la])[:, None]
        pb = table.p[lb] + table.v[lb] * (origin - table.t[lb])[:, None]
        v = table.v[la] - table.v[lb]
        solve_piece(wrap(pa - pb, box), v, radius, origin, t_start, length, pairs, pairs + 1000, emit, box)
    return found


@pytest.mark.parametrize("kind", ["plain", "compiled"])
@pytest.mark.parametrize("scalar_window", [True, False])
def test_plane_crossings_equal_numpy(scalar_window, kind):
    """Every crossing of pairs on straight legs, its time and its phase, and their order,
    plain and compiled, are the numpy solver's bit for bit, for one window shared by all
    pairs and for a window of each pair's own."""
    rng = np.random.default_rng(5)
    _, table = _legs(rng, 40, 4)
    m = 4000
    la = rng.integers(0, len(table.t), m)
    lb = rng.integers(0, len(table.t), m)
    radius = np.where(rng.random(m) < 0.5, rng.uniform(10, 120, m), 50.0)
    if scalar_window:
        t_start, length = 20.0, 12.5
    else:
        # Windows that start, end or are halved exactly at a crossing, or miss it by less
        # than the solver's slack: the edge cases of the clipping and of the phase.
        origin = np.maximum(table.t[la], table.t[lb])
        d = table.at(la, 0.0) - table.at(lb, 0.0) + (table.v[la] - table.v[lb]) * origin[:, None]
        t_in, _ = roots(d, table.v[la] - table.v[lb], radius)
        at = np.where(np.isnan(t_in), 25.0, origin + t_in)
        length = rng.choice([0.0, 2.0, 10.0, 12.5], m)
        shift = rng.choice([0.0, 1.0, 0.5, 0.3e-10, -0.3e-10, 0.7], m)
        t_start = np.maximum(at - shift * length + rng.choice([0.0, 0.3e-10, -0.3e-10], m), origin)
    kernels = compiled_copy("netsim.links._kernels") if kind == "compiled" else _link_kernels
    got = _solved(table, la, lb, radius, t_start, length, kernels)
    want = _solved(table, la, lb, radius, t_start, length, None)
    assert got == want
    assert len(want) > 200  # crossings were found


@pytest.mark.parametrize("kind", [pytest.param("plain", marks=pytest.mark.slow), "compiled"])
@pytest.mark.parametrize("side", [150.0, 60.0])
def test_torus_crossings_equal_numpy(side, kind):
    """On a torus every image of the other robot that the path can reach counts: every
    crossing, its time and its phase, plain and compiled, are the numpy oracle's bit for
    bit, on a side near the range (several images in reach) and a wide one."""
    rng = np.random.default_rng(11)
    _, table = _legs(rng, 30, 3)
    m = 2000
    la = rng.integers(0, len(table.t), m)
    lb = rng.integers(0, len(table.t), m)
    radius = np.where(rng.random(m) < 0.5, rng.uniform(10, 40, m), 25.0)
    t_start = rng.uniform(0, 40, m)
    length = rng.choice([0.0, 2.0, 10.0, 30.0], m)
    kernels = compiled_copy("netsim.links._kernels") if kind == "compiled" else _link_kernels
    got = _solved(table, la, lb, radius, t_start, length, kernels, side)
    want = _solved(table, la, lb, radius, t_start, length, None, side)
    assert got == want
    assert len(want) > 200


@pytest.mark.slow
def test_link_lifetimes_equal_with_crossings_plain_or_compiled(monkeypatch):
    """The link lifetimes of random legs are the same rows, bit for bit, whether the
    crossings are solved compiled or as plain Python."""
    legs, _ = _legs(np.random.default_rng(9), 60, 5)
    frames = []
    for flag in ("1", "0"):
        monkeypatch.setenv("NETSIM_COMPILED", flag)
        frames.append(lifetimes.link_lifetimes(legs, 40.0, 60.0))
    assert len(frames[0]) > 50
    pd.testing.assert_frame_equal(frames[0], frames[1], check_exact=True)


@pytest.mark.parametrize("kind", ["plain", "compiled"])
@pytest.mark.parametrize("box", [None, 100.0])
def test_in_range_equals_numpy(box, kind):
    """Whether two robots are linked at an instant (the state set at the start and at a
    jump), plain and compiled, is the numpy oracle's, on the plane and on a torus, for
    distances drawn near the range (where rounding decides)."""
    rng = np.random.default_rng(3)
    n = 400
    pos = np.where(rng.random((n, 2)) < 0.5, rng.uniform(0, 100, (n, 2)), rng.integers(0, 5, (n, 2)) * 25.0)
    a, b = rng.integers(0, n, 5000), rng.integers(0, n, 5000)
    d = pos[a] - pos[b]
    if box is not None:
        d = d - box * np.round(d / box)
    radius = np.where(rng.random(5000) < 0.5, np.hypot(d[:, 0], d[:, 1]), rng.choice([25.0, 50.0, 30.0], 5000))
    kernels = compiled_copy("netsim.links._kernels") if kind == "compiled" else _link_kernels
    got = kernels.in_range(pos, a, b, radius, box or 0.0)
    want = in_range(pos, a, b, radius, box)
    assert (got == want).all()
    assert 0.2 < want.mean() < 0.95


@pytest.mark.parametrize("compiled", [False, True])
def test_a_pair_comes_into_range_and_leaves_it_at_the_roots_of_its_path(compiled):
    """``disk_crossing_times``, the one rule of when a pair on straight legs enters and
    leaves the disk (the link solvers and the walls' chunks): the two roots of ``|d + w t| =
    r`` counted from the origin given, entry first; NaN for a pair at rest (in range or not)
    and for a path that only touches the disk or misses it."""
    from netsim import _kernels as core

    k = compiled_copy("netsim._kernels") if compiled else core
    assert k.disk_crossing_times(2.0, -10.0, 0.0, 1.0, 0.0, 5.0) == (7.0, 17.0)
    assert k.disk_crossing_times(0.0, 10.0, 0.0, -2.0, 0.0, 5.0) == (2.5, 7.5)
    for args in ((0.0, 1.0, 1.0, 0.0, 0.0, 5.0), (0.0, 9.0, 9.0, 0.0, 0.0, 5.0), (0.0, -10.0, 5.0, 1.0, 0.0, 5.0)):
        assert all(math.isnan(t) for t in k.disk_crossing_times(*args)), args
    assert all(math.isnan(t) for t in k.disk_crossing_times(0.0, -10.0, 6.0, 1.0, 0.0, 5.0))


@pytest.mark.parametrize("compiled", [False, True])
def test_a_step_leaves_its_disk_where_a_pair_leaves_range(compiled, monkeypatch):
    """A plan's step from inside a disk is cut where the path leaves it by the link solvers'
    own roots (``disk_crossing_times``), to the bit, a hair short (``SAFETY``) and clipped to
    [0, 1]: a robot at rest or on an unbounded leash may take its whole step, a path that only
    touches the circle none."""
    from netsim.mobility.steps import SAFETY, step_limit

    from netsim import _kernels as core

    monkeypatch.setenv("NETSIM_COMPILED", "1" if compiled else "0")
    offset = np.array([[0.0, 0.0], [3.0, 4.0], [5.0, 0.0], [5.0, 0.0], [3.0, 0.0]])
    radius = np.array([1.0, 5.0, 5.0, 5.0, np.inf])
    move = np.array([[4.0, 0.0], [0.0, 0.0], [0.0, 3.0], [-20.0, 0.0], [7.0, 1.0]])
    assert step_limit(offset, radius, move).tolist() == [0.25 * SAFETY, SAFETY, 0.0, 0.5 * SAFETY, SAFETY]
    rng = np.random.default_rng(7)
    radius = rng.uniform(1.0, 200.0, 2000)
    angle = rng.uniform(0.0, 2 * np.pi, 2000)
    offset = (radius * rng.uniform(0.0, 1.0, 2000))[:, None] * np.column_stack([np.cos(angle), np.sin(angle)])
    move = rng.normal(0.0, 1.0, (2000, 2)) * 10 ** rng.uniform(-3.0, 3.0, (2000, 1))
    roots = [core.disk_crossing_times(0.0, *o, *m, r)[1] for o, m, r in zip(offset, move, radius)]
    assert np.array_equal(step_limit(offset, radius, move), np.clip(np.array(roots) * SAFETY, 0.0, 1.0))


@pytest.mark.parametrize("compiled", [False, True])
def test_a_point_is_beyond_its_disk_as_the_rule_of_in_range_says(compiled, monkeypatch):
    """``beyond`` (the local plan's leashes) decides ``hypot(p - c) > r`` by ``reaches``:
    the same answer as the comparison at the disk's edge (within a few ulps of it), for a
    negative radius (every point beyond) and where a NaN enters (none)."""
    from netsim.geometry import beyond

    monkeypatch.setenv("NETSIM_COMPILED", "1" if compiled else "0")
    rng = np.random.default_rng(11)
    centres = rng.uniform(-500.0, 500.0, (3000, 2))
    points = rng.uniform(-500.0, 500.0, (3000, 2))
    radius = np.hypot(*(points - centres).T) * (1.0 + rng.integers(-3, 4, 3000) * 2.0**-52)
    radius[:300] = rng.uniform(-50.0, 800.0, 300)
    radius[300:320] = np.nan
    points[320:340, 0] = np.nan
    radius[340:360] = -1.0
    got = beyond(points, centres, radius, 3000)
    with np.errstate(invalid="ignore"):
        want = np.hypot(*(points - centres).T) > radius
    assert np.array_equal(got, want)
    assert 0.2 < want[360:].mean() < 0.8 and want[340:360].all() and not got[300:340].any()
