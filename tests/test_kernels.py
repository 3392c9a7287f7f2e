"""The hot path's compiled loops compute exactly what the numpy code computes (compared
with ``==``): the range query (netsim/_kernels.py); and a whole run gives the same tables
either way (the neighbour tables' loops: test_neighbour_kernels.py)."""

import numpy as np
import pytest

from netsim.radio.spatial import RangeIndex
from netsim.state import RobotState

pytest.importorskip("numba")

from netsim import _kernels as core_kernels  # noqa: E402
from netsim.compiled import compiled_copy  # noqa: E402
from tests.oracles import near_pairs as pairs_oracle  # noqa: E402
from tests.oracles import radio as oracle  # noqa: E402


def core(kind: str):
    """The engine core's kernels as plain Python or compiled."""
    return compiled_copy("netsim._kernels") if kind == "compiled" else core_kernels


BOTH = pytest.mark.parametrize("kind", ["plain", "compiled"])
# The plain loops run as Python, slowly on the bigger cases: those run with the slow tests,
# the compiled ones in the quick loop.
PLAIN_SLOW = pytest.param("plain", marks=pytest.mark.slow)


def _moving_state(rng, n, side, torus):
    st = RobotState(n, side, rng.uniform(20.0, 60.0, n), torus=torus)
    st.place(rng.uniform(0, side, (n, 2)))
    return st


def _queries(rng, st, count):
    """``count`` range queries ``(t, i)`` at increasing times, a third of the robots asked
    turning onto a new leg first."""
    t = 0.0
    for _ in range(count):
        t += float(rng.exponential(0.5))
        i = int(rng.integers(st.n))
        if rng.random() < 0.3:
            st.set_leg(i, t, rng.uniform(-8, 8, 2), cause="waypoint")
        yield t, i


def _index_kernels():
    """The range index's loops, plain Python and compiled."""
    return (("plain", core_kernels), ("compiled", compiled_copy("netsim._kernels")))


@pytest.mark.parametrize("torus", [False, True])
@pytest.mark.parametrize("compiled", ["0", "1"])
def test_positions_are_each_legs_law(monkeypatch, torus, compiled):
    """A robot's position is its leg's origin plus its velocity times the time since the
    leg began, folded onto the torus (unless asked unfolded): the oracle's numpy law bit for
    bit, for every robot, rows by list, array (negative ones too) and int, on the plain and
    the compiled path; a bad index is an error, not a read outside the state."""
    monkeypatch.setenv("NETSIM_COMPILED", compiled)
    rng = np.random.default_rng(11)
    st = _moving_state(rng, 40, 300.0, torus)

    def same(a, b):
        return a.shape == b.shape and a.tobytes() == b.tobytes()

    for t, _ in _queries(rng, st, 60):
        rows = rng.integers(-st.n, st.n, size=int(rng.integers(0, 6)))
        assert same(st.positions_at(t), oracle.positions(st, t))
        assert same(st.positions_at(t, fold=False), oracle.positions(st, t, fold=False))
        assert same(st.positions_at(t, rows), oracle.positions(st, t, rows))
        assert same(st.positions_at(t, list(rows)), oracle.positions(st, t, rows))
        assert same(st.positions_at(t, rows.astype(np.int32)), oracle.positions(st, t, rows))
        assert same(st.positions_at(t, rows[::-1][::2]), oracle.positions(st, t, rows[::-1][::2]))  # a strided view
        i = int(rng.integers(st.n))
        assert same(st.positions_at(t, i), oracle.positions(st, t, i))
        assert same(st.positions_at(t, np.int64(i)), oracle.positions(st, t, i))
        assert same(np.array(st.position(i, t)), oracle.positions(st, t, i))
    for bad, error in (([st.n], IndexError), ([-st.n - 1], IndexError), ([0.5], TypeError), ([[0, 1]], ValueError)):
        with pytest.raises(error):
            st.positions_at(t, bad)
    with pytest.raises(TypeError, match="flatnonzero"):
        st.positions_at(t, np.ones(st.n, bool))


@pytest.mark.parametrize("compiled", ["0", "1"])
def test_a_position_on_a_torus_has_one_representation(monkeypatch, compiled):
    """On a torus a coordinate is in ``[0, side)``: a point a hair below 0, whose remainder
    rounds up to the side, is at 0, for the state and for the positions folded in bulk."""
    from netsim.geometry import in_box

    monkeypatch.setenv("NETSIM_COMPILED", compiled)
    st = RobotState(2, 10.0, 1.0, torus=True)
    st.origin_m[:] = [[-1e-17, 5.0], [3.0, -1e-300]]
    assert (-1e-17) % 10.0 == 10.0  # the case: the remainder rounds up to the side
    assert st.positions_at(0.0).tolist() == [[0.0, 5.0], [3.0, 0.0]]
    assert in_box(st.origin_m, 10.0).tolist() == [[0.0, 5.0], [3.0, 0.0]]


@pytest.mark.parametrize("compiled", ["0", "1"])
def test_a_pairs_travel_is_its_two_robots_travel_summed(monkeypatch, compiled):
    """The shadowing's clock of a pair is the sum of its robots' path lengths, in either
    order, bit for bit; a pair that names no robot is refused, not read out of bounds."""
    monkeypatch.setenv("NETSIM_COMPILED", compiled)
    rng = np.random.default_rng(7)
    st = _moving_state(rng, 12, 300.0, False)
    st.set_legs(np.arange(12), 3.0, rng.uniform(-8, 8, (12, 2)))
    a, b = rng.integers(0, 12, 40), rng.integers(0, 12, 40)
    each = st.travelled_m(9.5, slice(None))
    pair = st.pair_travelled_m(9.5, a, b)
    assert pair.tobytes() == (each[a] + each[b]).tobytes()
    assert pair.tobytes() == st.pair_travelled_m(9.5, b, a).tobytes()
    with pytest.raises(IndexError, match=r"\(3, 12\) out of range for 12 robots"):
        st.pair_travelled_m(9.5, [0, 3], [1, 12])


def test_the_odometer_is_the_sum_of_each_legs_travel():
    """A robot's path length is the sum over its legs of ``|v|`` times the leg's time, with
    the one ``|v|`` the shadowing's clock takes (numpy's complex abs), whichever way its legs
    began: one at a time, many at once, toward a point, or stopping at it. Bit for bit."""
    rng = np.random.default_rng(13)
    st = _moving_state(rng, 30, 300.0, False)
    t = 0.0
    for _ in range(200):
        t += float(rng.exponential(0.5))
        i = int(rng.integers(st.n))
        way = rng.integers(4)
        if way == 0:
            st.set_leg(i, t, rng.uniform(-8, 8, 2), cause="waypoint")
        elif way == 1:
            rows = rng.choice(st.n, size=int(rng.integers(1, 8)), replace=False)
            st.set_legs(rows, t, rng.uniform(-8, 8, (len(rows), 2)))
        elif way == 2:
            st.head_to(i, t, rng.uniform(0, 300, 2), float(rng.uniform(0.5, 9)))
        else:
            st.arrive(i, t, st.positions_at(t, i))
    t += 1.0
    assert st.travelled_m(t, slice(None)).tobytes() == oracle.distance_travelled(st.legs(), t).tobytes()


@pytest.mark.parametrize("compiled", ["0", "1"])
def test_points_on_legs_are_each_legs_law(monkeypatch, compiled):
    """A leg table's point of leg ``k`` at its own time is the leg's origin plus its
    velocity times the time since the leg began (numpy's law, bit for bit), on both paths:
    with one time for all rows and with a time per row."""
    from netsim.trajectory import points_on_legs

    monkeypatch.setenv("NETSIM_COMPILED", compiled)
    rng = np.random.default_rng(12)
    p, v, t0 = rng.uniform(-500, 500, (30, 2)), rng.uniform(-9, 9, (30, 2)), rng.uniform(0, 50, 30)
    rows = rng.integers(0, 30, 200)
    times = t0[rows] + rng.exponential(20.0, 200)
    law = p[rows] + v[rows] * (times - t0[rows])[:, None]
    assert points_on_legs(p, v, t0, rows, times, 30).tobytes() == law.tobytes()
    law = p[rows] + v[rows] * (77.5 - t0[rows])[:, None]
    assert points_on_legs(p, v, t0, rows, 77.5, 30).tobytes() == law.tobytes()


@pytest.mark.parametrize("torus", [False, True])
@pytest.mark.parametrize("which", [PLAIN_SLOW, "compiled"])
def test_range_query_equals_the_oracle(torus, which):
    """Robots within range of a sender, and their distances, are the oracle's bit for bit
    (plain Python and compiled), on the plane and on a torus, from the neighbour list and
    from the full scan."""
    rng = np.random.default_rng(3)
    n, side = 200, 400.0
    st = _moving_state(rng, n, side, torus)
    index = RangeIndex(st)
    index.kernels = dict(_index_kernels())[which]
    checked = 0
    for t, i in _queries(rng, st, 300):
        radius = None if rng.random() < 0.8 else float(rng.choice([30.0, 1000.0]))
        a_ids, a_d = index.within(t, i, radius)
        r = float(st.range_m[i]) if radius is None else radius
        b_ids, b_d = oracle.within(st, t, i, r, np.delete(np.arange(n), i))
        assert a_ids.tolist() == b_ids.tolist()
        assert a_d.tobytes() == b_d.tobytes()
        checked += len(a_ids)
    assert checked > 500


@pytest.mark.parametrize("torus", [False, True])
@pytest.mark.parametrize("which", [PLAIN_SLOW, "compiled"])
def test_range_query_without_distances_equals_the_oracle(torus, which):
    """The query a transmission makes when nothing asks the distances: the oracle's
    receivers, and whether all are alive (some robots switched off)."""
    rng = np.random.default_rng(5)
    n, side = 200, 400.0
    st = _moving_state(rng, n, side, torus)
    index = RangeIndex(st)
    index.kernels = dict(_index_kernels())[which]
    dead_seen = 0
    for t, i in _queries(rng, st, 300):
        st.alive[:] = rng.random(n) > 0.02
        a_ids, a_alive = index.within_alive(t, i)
        b_ids = oracle.within(st, t, i, float(st.range_m[i]), np.delete(np.arange(n), i))[0]
        assert a_ids.tolist() == b_ids.tolist()
        assert a_alive is bool(st.alive[b_ids].all())
        dead_seen += not a_alive
    assert dead_seen > 10


@pytest.mark.slow
def test_runs_equal_with_and_without_compiled_loops(monkeypatch):
    """A run's tables are the same with the compiled loops as with the numpy code."""
    from netsim.run import execute
    from tests.fixtures import make_config

    cfg = make_config(
        seed=2,
        duration_s=30.0,
        world={"n_robots": 40, "side_m": 300.0},
        channel={"range_m": 80.0, "latency_jitter_s": 0.01},
        output={"position_interval_s": 0.0},
    )
    frames = {}
    for flag in ("0", "1"):
        monkeypatch.setenv("NETSIM_COMPILED", flag)
        frames[flag] = execute(cfg).frames
    assert frames["0"].keys() == frames["1"].keys()
    for name in frames["0"]:
        assert frames["0"][name].equals(frames["1"][name]), name


@pytest.mark.parametrize("by_power", [False, True])
def test_frame_end_equals_the_oracle(by_power):
    """A frame's end (netsim/radio/_mac_kernels.py, plain and compiled), by overlap or by
    SINR, leaves the medium's arrays and finds the same half-duplex and collision losses and
    the same robots newly idle, with the same busy times, as the oracle."""
    from netsim.radio import _mac_kernels

    compiled = compiled_copy("netsim.radio._mac_kernels")

    rng = np.random.default_rng(5)
    n = 60
    for _ in range(200):
        cover = rng.integers(1, 3, n)
        transmitting = rng.random(n) < 0.1
        tx_seq, cover_seq = rng.integers(0, 12, n), rng.integers(0, 12, n)
        busy_s, busy_since = rng.random(n), rng.random(n)
        i = int(rng.integers(n))
        transmitting[i] = True
        others = np.delete(np.arange(n), i)
        disturbed = np.sort(rng.choice(others, int(rng.integers(0, 20)), replace=False))
        rx = np.sort(rng.choice(disturbed, int(rng.integers(0, len(disturbed) + 1)), replace=False))
        hd_start, col_start = rng.random(len(rx)) < 0.2, rng.random(len(rx)) < 0.2
        sinr_db = np.round(rng.normal(10.0, 3.0, len(rx)), 1) if by_power else np.empty(0)
        frame = (i, 6, 1.0 + rng.random(), disturbed, rx, hd_start, col_start, by_power, sinr_db, 10.0)
        runs = []
        for end in (oracle.end_frame, _mac_kernels.end_frame, compiled.end_frame):
            medium = (cover.copy(), transmitting.copy(), tx_seq, cover_seq, busy_s.copy(), busy_since)
            out = (np.zeros(n, bool), np.zeros(n, bool), np.zeros(n + 1, np.int64))
            m = end(medium, frame, out)
            runs.append((m, medium, out))
        m1, medium1, out1 = runs[0]
        for m2, medium2, out2 in runs[1:]:
            assert m1 == m2
            assert all(np.array_equal(x, y) for x, y in zip(medium1, medium2))
            assert np.array_equal(out1[0][: len(rx)], out2[0][: len(rx)])
            assert np.array_equal(out1[1][: len(rx)], out2[1][: len(rx)])
            assert out1[2][:m1].tolist() == out2[2][:m2].tolist()


@pytest.mark.parametrize("which", ["plain", "compiled"])
def test_busy_time_counts_the_stretch_still_sensed(which):
    """The medium's busy time through now (Medium.busy_fraction's, _mac_kernels.busy_times):
    a robot sensing a frame or sending one has the stretch since it began added, the same
    sum a frame's end adds when it falls idle; an idle robot has its total alone."""
    from netsim.radio import _mac_kernels

    kernels = _mac_kernels if which == "plain" else compiled_copy("netsim.radio._mac_kernels")
    rng = np.random.default_rng(8)
    n = 40
    cover = rng.integers(0, 2, n)
    transmitting = rng.random(n) < 0.3
    busy_s, busy_since = rng.random(n), rng.random(n)
    medium = (cover, transmitting, np.zeros(n, np.int64), np.zeros(n, np.int64), busy_s, busy_since)
    out = np.empty(n)
    now = 1.0 + rng.random()
    kernels.busy_times(medium, now, out)
    on = (cover > 0) | transmitting
    assert on.any() and (~on).any()
    assert np.array_equal(out[on], busy_s[on] + (now - busy_since[on]))
    assert np.array_equal(out[~on], busy_s[~on])


@pytest.mark.slow
def test_medium_runs_equal_plain_and_compiled(monkeypatch):
    """A run on a CSMA medium under the unit disk gives the same tables with its loops
    compiled as with them plain Python."""
    from netsim.run import execute
    from tests.fixtures import make_config

    cfg = make_config(
        seed=2,
        duration_s=8.0,
        world={"n_robots": 40, "side_m": 300.0},
        channel={"range_m": 80.0, "mac": "csma"},
        protocol={"ack_period_s": 0.05, "ack_jitter_s": 0.01, "tau_s": 0.5},
        output={"position_interval_s": 0.0},
    )
    frames = {}
    for flag in ("0", "1"):
        monkeypatch.setenv("NETSIM_COMPILED", flag)
        frames[flag] = execute(cfg).frames
    assert frames["1"]["medium"]["dropped_collision"].sum() > 100
    for name in frames["0"]:
        assert frames["0"][name].equals(frames["1"][name]), name


@pytest.mark.parametrize("which", ["plain", "compiled"])
def test_reception_counts_equal_numpy(which):
    """The channel's count of receptions (``count_each``) and alive check (``all_set``),
    plain and compiled, equal numpy's fancy increment and ``mask[ids].all()``."""
    k = dict(_index_kernels())[which]
    rng = np.random.default_rng(5)
    a, b = np.zeros(300, dtype=np.int64), np.zeros(300, dtype=np.int64)
    for _ in range(200):
        ids = np.sort(rng.choice(300, int(rng.integers(0, 40)), replace=False)).astype(np.int64)
        k.count_each(a, ids)
        b[ids] += 1
        mask = rng.random(300) < 0.97
        assert k.all_set(mask, ids) == bool(mask[ids].all())
    assert a.tolist() == b.tolist()


@pytest.mark.slow
@BOTH
@pytest.mark.parametrize("torus", [False, True])
def test_near_pairs_finds_every_kd_tree_pair(torus, kind):
    """The grid's pairs within r, plain and compiled, are the KD-tree's (every one of them,
    each once, i < j), plus at most pairs further than r by a relative 1e-9: uniform,
    clustered and sparse layouts, a torus narrower than three ranges, r larger than the
    area."""
    rng = np.random.default_rng(11)
    side = 1000.0
    layouts = [
        rng.uniform(0, side, (250, 2)),
        np.concatenate([rng.normal(300, 5, (100, 2)), rng.normal(700, 30, (100, 2))]) % side,
        rng.uniform(0, side, (30, 2)),
        np.round(rng.uniform(0, side, (300, 2)) / 50) * 50 % side,  # a lattice: distances exactly r
    ]
    for pos in layouts:
        for r in (50.0, 120.0, 400.0, 2000.0):
            box = side if torus else None
            got = core(kind).near_pairs(pos, r, side if torus else 0.0)
            want = {tuple(p) for p in pairs_oracle.kd_tree_pairs(pos, r, box).tolist()}
            found = [tuple(p) for p in got.tolist()]
            assert len(found) == len(set(found))
            assert all(i < j for i, j in found)
            assert want <= set(found)
            d = pos[got[:, 1]] - pos[got[:, 0]]
            if torus:
                d -= side * np.rint(d / side)
            assert np.all(d[:, 0] ** 2 + d[:, 1] ** 2 <= r * r * (1 + 1e-9))


@pytest.mark.parametrize("which", ["plain", "compiled"])
def test_neighbour_lists_equal_the_oracle(which):
    """The range index's lists per robot (both directions of each pair, ascending) are the
    oracle's lexsort's, with robots that have no neighbour and pairs in any order."""
    k = dict(_index_kernels())[which]
    rng = np.random.default_rng(4)
    for n in (1, 2, 50, 300):
        for m in (0, 1, 40, 2000):
            if n < 2 and m:
                continue
            a = rng.integers(0, n, m)
            b = (a + rng.integers(1, max(n, 2), m)) % n
            pairs = np.unique(np.column_stack([np.minimum(a, b), np.maximum(a, b)]), axis=0)
            pairs = pairs[rng.permutation(len(pairs))].astype(np.int64).reshape(-1, 2)
            got, want = k.neighbour_lists(pairs, n), oracle.neighbour_lists(pairs, n)
            assert got[0].tolist() == want[0].tolist() and got[1].tolist() == want[1].tolist()


@pytest.mark.parametrize("compiled", ["0", "1"])
def test_near_pairs_with_outliers_lines_and_bad_positions(monkeypatch, compiled):
    """Candidate pairs where a grid of range-sized cells would need far more cells than
    robots (a cluster with one robot far away; robots on a long line), plain and compiled,
    are the KD-tree's; positions that are not finite are refused."""
    from netsim.geometry import near_pairs

    monkeypatch.setenv("NETSIM_COMPILED", compiled)
    rng = np.random.default_rng(12)
    cluster = np.vstack([rng.uniform(0, 1000, (2000 if compiled == "1" else 300, 2)), [[1e6, 1e6]]])
    line = np.column_stack([np.sort(rng.uniform(0, 1e10, 100)), np.zeros(100)])
    line[50:60, 0] = line[50, 0] + np.arange(10) * 0.5
    diagonal = np.column_stack([line[:, 0], line[:, 0]])
    for pos, r in ((cluster, 10.0), (line, 1.0), (diagonal, 1.0)):
        span = pos.max(axis=0) - pos.min(axis=0)
        assert (span[0] // r + 1) * (span[1] // r + 1) > 16 * len(pos) + 64
        got = {tuple(p) for p in near_pairs(pos, r, None).tolist()}
        want = {tuple(p) for p in pairs_oracle.kd_tree_pairs(pos, r, None).tolist()}
        assert got == want and len(want) >= 9
    bad = rng.uniform(0, 100, (50, 2))
    bad[7] = np.nan
    with pytest.raises(ValueError, match="finite"):
        near_pairs(bad, 10.0, None)


@BOTH
@pytest.mark.parametrize("torus", [False, True])
def test_near_pairs_at_a_range_of_zero_or_far_below_the_side(torus, kind):
    """A range of zero (coincident robots alone are pairs) and a range so small that
    range-sized cells would be far more than the robots: the KD-tree's pairs."""
    rng = np.random.default_rng(13)
    side = 1000.0
    lattice = np.round(rng.uniform(0, side, (100, 2)) / 100) * 100 % side
    spread = rng.uniform(0, side, (100, 2))
    # Pairs half a metre apart, some across the torus's edge.
    spread[:10] = np.column_stack([rng.uniform(0, side, 10), np.full(10, side - 0.2)])
    pos = np.vstack([lattice, spread, (spread + 0.5 * np.array([0.6, 0.8])) % side])
    for r in (0.0, 1.0, 150.0):
        got = {tuple(p) for p in core(kind).near_pairs(pos, r, side if torus else 0.0).tolist()}
        want = {tuple(p) for p in pairs_oracle.kd_tree_pairs(pos, r, side if torus else None).tolist()}
        assert got == want and len(want) > 10


def reach_layouts(rng, side):
    """Positions and per-robot ranges for the reach tests: uniform, clustered, sparse; a
    lattice (distances exactly a range); pairs a relative 1e-7 and 1e-12 either side of
    the sender's range; equal and unequal ranges."""
    lattice = np.round(rng.uniform(0, side, (300, 2)) / 50) * 50 % side
    base = rng.uniform(100, side - 100, (100, 2))
    angle = rng.uniform(0, 2 * np.pi, 100)
    bound = []
    for eps in (1e-7, -1e-7, 1e-12, -1e-12, 0.0):
        d = 50.0 * (1 + eps)
        bound.append(base + d * np.column_stack([np.cos(angle), np.sin(angle)]))
    yield lattice, np.full(len(lattice), 50.0)
    pos = np.vstack([base, *bound]) % side
    yield pos, np.full(len(pos), 50.0)
    yield pos, rng.choice([50.0, 30.0, 80.0], len(pos))
    yield rng.uniform(0, side, (400, 2)), rng.uniform(40.0, 160.0, 400)
    clustered = np.concatenate([rng.normal(300, 5, (150, 2)), rng.normal(700, 30, (150, 2))]) % side
    yield clustered, np.full(300, 20.0)
    yield rng.uniform(0, side, (30, 2)), np.full(30, 120.0)
    yield rng.uniform(0, side, (40, 2)), np.full(40, 2000.0)  # the range larger than the area
    yield rng.uniform(0, side, (2, 2)), np.full(2, 900.0)


@pytest.mark.parametrize("kind", [PLAIN_SLOW, "compiled"])
@pytest.mark.parametrize("torus", [False, True])
def test_reach_keys_equal_the_oracle(monkeypatch, torus, kind):
    """``receiver * n + sender`` for every sender reaching its receiver, ascending, plain and
    compiled (netsim.topology.reach_keys: neighbour lists of the pairs within the largest
    range), is the oracle's from the KD-tree's pairs: uniform, clustered, sparse and lattice
    layouts, distances a hair either side of the range, unequal ranges, a range larger than
    the area; on a torus also positions outside ``[0, side)`` and a torus narrower than
    three ranges."""
    from netsim.topology import reach_keys

    monkeypatch.setenv("NETSIM_COMPILED", "1" if kind == "compiled" else "0")
    rng = np.random.default_rng(31)
    side = 1000.0
    box = side if torus else None
    hits = 0
    for pos, ranges in reach_layouts(rng, side):
        if torus:
            pos = pos + side * rng.integers(-2, 3, pos.shape)  # unwrapped: the same robots
        got = reach_keys(pos, ranges, box)
        want = pairs_oracle.reach_keys(pos, ranges, box)
        assert got.tolist() == want.tolist()
        hits += len(want)
    assert hits > 1000


@pytest.mark.slow
@pytest.mark.parametrize("torus", [False, True])
def test_reach_keys_from_the_range_index_lists_equal_numpy(torus):
    """The pairs in reach from the range index's neighbour lists (the clustering's samples)
    are the numpy ones: the layouts above standing still (distances a hair either side of
    the range, unequal ranges, a range larger than the area), and robots moving, the lists
    built earlier and still valid."""
    rng = np.random.default_rng(32)
    side = 1000.0
    box = side if torus else None
    hits = 0
    for pos, ranges in reach_layouts(rng, side):
        st = RobotState(len(pos), side, ranges, torus=torus)
        st.place(pos % side if torus else pos)
        at = st.positions_at(0.0)
        got = core_kernels.reach_keys_in_lists(at, st.range_m, side if torus else 0.0, *RangeIndex(st).lists(0.0))
        assert got.tolist() == pairs_oracle.reach_keys(at, st.range_m, box).tolist()
        hits += len(got)
    st = _moving_state(rng, 300, 600.0, torus)
    index, t, rebuilds = RangeIndex(st), 0.0, []
    for _ in range(60):
        t += float(rng.exponential(0.3))
        i = int(rng.integers(300))
        st.set_leg(i, t, rng.uniform(-8, 8, 2), cause="waypoint")
        at = st.positions_at(t)
        got = core_kernels.reach_keys_in_lists(at, st.range_m, 600.0 if torus else 0.0, *index.lists(t))
        assert got.tolist() == pairs_oracle.reach_keys(at, st.range_m, 600.0 if torus else None).tolist()
        rebuilds.append(index.rebuilds)
        hits += len(got)
    # Rebuilt along the way, and lists built earlier answered later queries.
    assert hits > 5000 and len(set(rebuilds)) > 3 and any(a == b for a, b in zip(rebuilds, rebuilds[1:]))


@pytest.mark.parametrize("torus", [False, True])
def test_hops_from_the_range_index_lists_equal_numpy(torus):
    """Hop distances from a robot (and towards it) searched over the range index's lists are
    the numpy search's over every pair in reach: unequal ranges (one-way links), robots
    out of reach of all (inf), moving robots with lists built earlier; a search for one
    target gives its hops."""
    from netsim.topology import hop_distances
    from tests.oracles import protocols as protocols_oracle

    rng = np.random.default_rng(33)
    st = _moving_state(rng, 250, 900.0, torus)
    index, t, finite = RangeIndex(st), 0.0, 0
    for _ in range(40):
        t += float(rng.exponential(0.5))
        i = int(rng.integers(250))
        st.set_leg(i, t, rng.uniform(-8, 8, 2), cause="waypoint")
        for towards in (False, True):
            node = int(rng.integers(250))
            got = hop_distances(st, t, node, towards, index=index)
            want = protocols_oracle.hop_distances(st, t, node, towards)
            assert hop_distances(st, t, node, towards).tobytes() == want.tobytes()  # lists built here
            assert got.tobytes() == want.tobytes()
            finite += int(np.isfinite(got).sum())
            # A search for one robot ends there with its hops, and leaves none beyond them.
            for target in rng.integers(250, size=5).tolist():
                one = hop_distances(st, t, node, towards, index=index, target=target)
                assert one[target] == want[target]
                assert (one[np.isfinite(one)] <= want[target]).all()
                assert (one[np.isfinite(one)] == want[np.isfinite(one)]).all()
    assert 0 < finite < 40 * 2 * 250  # some paths, and some robots out of reach


def brute_reach_keys(pos: np.ndarray, ranges: np.ndarray) -> list[int]:
    """``receiver * n + sender`` for every sender within its range of the receiver
    (``hypot <= r_sender``), every ordered pair tried: the plane's reference."""
    n = len(pos)
    d = np.hypot(pos[:, None, 0] - pos[None, :, 0], pos[:, None, 1] - pos[None, :, 1])
    receiver, sender = np.nonzero((d <= ranges[None, :]) & ~np.eye(n, dtype=bool))
    return sorted((receiver * n + sender).tolist())


@pytest.mark.parametrize("compiled", ["0", "1"])
def test_reach_keys_where_the_grid_would_not_fit(monkeypatch, compiled):
    """:func:`netsim.topology.reach_keys`, plain and compiled, is every pair in reach where a
    grid of range-sized cells would need far more cells than robots, for no robot or one,
    and elsewhere."""
    from netsim.topology import reach_keys

    monkeypatch.setenv("NETSIM_COMPILED", compiled)
    rng = np.random.default_rng(32)
    cluster = np.vstack([rng.uniform(0, 1000, (200, 2)), [[1e6, 1e6]]])
    spread = rng.uniform(0, 1000, (300, 2))
    for pos in (cluster, spread, np.empty((0, 2)), np.zeros((1, 2))):
        ranges = rng.uniform(5.0, 60.0, len(pos))
        assert reach_keys(pos, ranges).tolist() == brute_reach_keys(pos, ranges)
    assert len(reach_keys(spread, 60.0)) > 100


@pytest.mark.parametrize("compiled", ["0", "1"])
def test_reach_keys_at_exactly_the_range_on_every_path(monkeypatch, compiled):
    """Two robots whose distance (hypot) is exactly the range, its square a hair above the
    range's: in reach with the grid plain (NETSIM_COMPILED=0) and compiled, among many
    robots and beside one far away (coarser cells), and by the oracle."""
    from netsim.topology import reach_keys

    monkeypatch.setenv("NETSIM_COMPILED", compiled)
    rng = np.random.default_rng(5)
    r = 40.0
    while True:
        a = rng.uniform(100, 900, 2)
        angle = rng.uniform(0, 2 * np.pi)
        b = a + r * np.array([np.cos(angle), np.sin(angle)])
        d = a - b
        if np.hypot(*d) == r and d @ d > r * r:
            break
    pair = np.array([a, b])
    many = np.vstack([pair, rng.uniform(0, 1000, (400, 2))])
    far = np.vstack([pair, [[1e7, 1e7]]])
    for pos in (pair, many, far):
        ranges = np.full(len(pos), r)
        want = brute_reach_keys(pos, ranges)
        assert {1, len(pos)} <= set(want)
        assert reach_keys(pos, r).tolist() == want
        assert pairs_oracle.reach_keys(pos, ranges, None).tolist() == want


@pytest.mark.parametrize("torus", [False, True])
def test_near_pairs_order_is_by_robot_then_cells_then_ids(torus):
    """The grid's pairs come in one fixed order (the link solvers emit events in it): by
    robot ``i``, then its cells row by row (``dy, dx = -1, 0, 1``, wrapped on a torus),
    then the other robot's id in the cell; a layout of one cell and a torus narrower than
    three cells included."""
    rng = np.random.default_rng(33)
    side = 1000.0
    for n, r in ((300, 50.0), (300, 120.0), (40, 400.0), (60, 2000.0)):
        pos = rng.uniform(0, side, (n, 2))
        box = side if torus else 0.0
        cells_x, cells_y, cell, start, members = core_kernels.grid(pos, r, box)
        want = []
        for i in range(n):
            cy, cx = divmod(int(cell[i]), cells_x)
            seen = set()
            for dy in (-1, 0, 1):
                for dx in (-1, 0, 1):
                    ny, nx = cy + dy, cx + dx
                    if torus:
                        ny, nx = ny % cells_y, nx % cells_x
                    elif not (0 <= ny < cells_y and 0 <= nx < cells_x):
                        continue
                    c = ny * cells_x + nx
                    if c in seen:  # one cell (or a torus of one): each cell once
                        continue
                    seen.add(c)
                    for j in members[start[c] : start[c + 1]].tolist():
                        d = pos[j] - pos[i]
                        if torus:
                            d -= box * np.rint(d / box)
                        if j > i and d[0] * d[0] + d[1] * d[1] <= r * r * (1.0 + 1e-9):
                            want.append((i, j))
        got = [tuple(p) for p in core_kernels.near_pairs(pos, r, box).tolist()]
        assert got == want and len(want) > 20


@pytest.mark.parametrize("torus", [False, True])
def test_senders_in_list_equal_numpy(torus):
    """Per robot, the senders of its neighbour list that reach it (the samples' truth, one
    robot at a time: ``senders_in_list``, in room for the longest list) are the numpy ones:
    the reach layouts, distances a hair either side of the range included."""
    rng = np.random.default_rng(33)
    side = 1000.0
    box = side if torus else 0.0
    hits = 0
    for pos, ranges in reach_layouts(rng, side):
        st = RobotState(len(pos), side, ranges, torus=torus)
        st.place(pos % side if torus else pos)
        at = st.positions_at(0.0)
        indptr, indices = RangeIndex(st).lists(0.0)
        want = pairs_oracle.reach_keys(at, st.range_m, side if torus else None)
        n = len(pos)
        out = np.empty(core_kernels.longest_list(indptr), np.int64)
        assert len(out) == int(np.diff(indptr).max())
        for a in range(n):
            k = core_kernels.senders_in_list(at, st.range_m, box, indptr, indices, a, out)
            assert out[:k].tolist() == (want[want // n == a] % n).tolist()
            hits += k
    assert hits > 1000


@BOTH
def test_sort_range_sorts_the_range_alone_as_numpy_sorts_it(kind):
    """``sort_range`` sorts ``a[lo:hi]`` in place, ids or floats, short (insertion) or long
    (heap), duplicates included, and leaves the rest of the array as it was."""
    rng = np.random.default_rng(4)
    for length in (0, 1, 2, 5, 31, 32, 33, 64, 257):
        for values in (rng.integers(0, 40, length + 6), rng.permutation(length + 6).astype(float)):
            a = values.copy()
            core(kind).sort_range(a, 3, 3 + length)
            want = values.copy()
            want[3 : 3 + length] = np.sort(values[3 : 3 + length])
            assert a.tolist() == want.tolist(), (length, values.dtype)


@BOTH
def test_range_at_margin_inverts_the_path_loss_law(kind):
    """The law's inverse, one kernel for the radio's ranges and the plans' fade rule: at the
    distance it gives, the path loss exceeds ``PL(d0)`` by the margin; no margin gives
    ``d0``; a negative margin or NaN gives 0 (never in reach)."""
    from netsim.radio._kernels import path_loss_db

    k = core(kind)
    for margin in (0.0, 3.0, 20.0, 61.5):
        d = k.range_at_margin_m(margin, 1.0, 3.0)
        assert path_loss_db(d, 1.0, 40.0, 30.0) - 40.0 == pytest.approx(margin, abs=1e-9)
    assert k.range_at_margin_m(0.0, 2.0, 3.0) == 2.0
    # Shadowing and walls against a budget of 30 dB: margins of -0.1 dB, NaN and 10 dB.
    shadowing, walls = np.array([25.1, np.nan, 15.0]), np.array([5.0, 0.0, 5.0])
    out = np.empty(3)
    k.ranges_at_loss_m(shadowing, walls, 30.0, 1.0, 2.0, out)
    assert out.tolist() == [0.0, 0.0, 10.0**0.5]
    assert k.range_at_loss_m(15.0, 5.0, 30.0, 1.0, 2.0) == 10.0**0.5
    # The margin is (budget - X) - W, the order the link solvers' ranges were always
    # computed in: with these numbers budget - (X + W) differs in its last bit.
    assert (35.3 - -0.09) - 10.0 != 35.3 - (-0.09 + 10.0)
    assert k.range_at_loss_m(-0.09, 10.0, 35.3, 1.0, 2.0) == k.range_at_margin_m((35.3 - -0.09) - 10.0, 1.0, 2.0)


@BOTH
def test_component_labels_are_scipys_connected_components(kind):
    """The components of a network, one kernel for the metrics, the coverage plan and the
    environment: the labels scipy's connected_components gives (numbered in the order of
    each component's lowest robot), isolated robots and repeated links included."""
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import connected_components

    rng = np.random.default_rng(8)
    for n, m in ((1, 0), (7, 3), (60, 40), (200, 150)):
        a, b = rng.integers(0, n, m), rng.integers(0, n, m)
        want = connected_components(csr_matrix((np.ones(m), (a, b)), shape=(n, n)), directed=False)[1]
        assert core(kind).component_labels(n, a, b).tolist() == want.tolist()


def test_the_radios_laws_give_the_same_bits_plain_and_compiled():
    """The log-distance law and a pair's shadowing moved on (the two transcendental rules of
    a frame's decision) give the same bits run as plain Python and compiled, so a small run
    and a large one decide a frame alike on any CPU."""
    import netsim.radio._kernels as plain

    rng = np.random.default_rng(17)
    d = rng.uniform(0.1, 400.0, 5000)
    x0, z = rng.normal(0.0, 4.0, 5000), rng.normal(size=5000)
    laws, steps = [], []
    for k in (plain, compiled_copy("netsim.radio._kernels")):
        laws.append(np.array([k.path_loss_db(float(v), 1.0, 40.0, 31.7) for v in d]))
        x, s = x0.copy(), np.zeros(5000)
        for pos in range(5000):
            k.moved_on(x, s, pos, float(d[pos] / 7.0), 4.0, 9.0, float(z[pos]))
        steps.append(x)
    assert laws[0].tobytes() == laws[1].tobytes()
    assert steps[0].tobytes() == steps[1].tobytes()


def test_a_range_past_every_float_is_infinite_on_both_paths():
    """The inverse law of a margin larger than any float range gives inf, plain and
    compiled (Python's power would raise), and the largest finite ones agree."""
    for k in (core_kernels, compiled_copy("netsim._kernels")):
        assert k.range_at_margin_m(4000.0, 1.0, 1.0) == np.inf
        assert k.range_at_margin_m(3000.0, 1.0, 1.0) == 1e300
        assert k.range_at_margin_m(-1.0, 1.0, 1.0) == 0.0


@pytest.mark.parametrize("compiled", ["0", "1"])
def test_a_pairs_key_is_its_lower_id_then_its_higher(monkeypatch, compiled):
    """The key of an unordered pair, as the shadowing's table and a frame's decision name it:
    the lower id in the high 32 bits, the higher in the low ones, whichever end comes first
    (ids up to 2**31 - 1), on both paths."""
    from netsim.radio.shadowing import pair_keys, split_keys

    monkeypatch.setenv("NETSIM_COMPILED", compiled)
    rng = np.random.default_rng(41)
    a, b = rng.integers(0, 2**31, 500), rng.integers(0, 2**31, 500)
    a[:3], b[:3] = [0, 2**31 - 1, 5], [2**31 - 1, 0, 5]
    keys = pair_keys(a, b)
    assert keys.tolist() == pair_keys(b, a).tolist()
    assert keys.tolist() == [(min(x, y) << 32) | max(x, y) for x, y in zip(a.tolist(), b.tolist())]
    low, high = split_keys(keys)
    assert low.tolist() == np.minimum(a, b).tolist() and high.tolist() == np.maximum(a, b).tolist()


@BOTH
def test_a_cell_at_the_radius_is_covered_and_the_share_counts_every_cell(kind):
    """The covered fraction's last step, the one rule both the coverage table and the
    environments' score use: a distance equal to the radius counts, the share is of every
    cell given, and no cell gives NaN."""
    share = core(kind).share_within
    assert share(np.array([1.0, 2.0, 3.0, np.inf]), 2.0) == 0.5
    assert share(np.array([2.0 + 1e-12]), 2.0) == 0.0
    assert np.isnan(share(np.zeros(0), 2.0))


def test_lower_bound_is_numpys_searchsorted_left_side():
    """One lower bound for every kernel (the sweep's rows, the Acks' lists, the shadowing
    table's slots): numpy's left side within ``[lo, hi)``, a NaN placed last as numpy
    places it, compiled and plain alike."""
    rng = np.random.default_rng(5)
    for kernels in (core_kernels, compiled_copy("netsim._kernels")):
        for _ in range(200):
            a = np.sort(rng.integers(-5, 6, rng.integers(0, 12))).astype(float)
            lo = int(rng.integers(0, len(a) + 1))
            hi = int(rng.integers(lo, len(a) + 1))
            for x in (*rng.uniform(-7, 7, 3), *a[:2], np.inf, -np.inf, np.nan):
                assert kernels.lower_bound(a, lo, hi, x) == lo + np.searchsorted(a[lo:hi], x), (a, lo, hi, x)
