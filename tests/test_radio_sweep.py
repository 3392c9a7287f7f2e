"""Walls crossed over time between two moving robots: the sweep against brute force."""

import numpy as np
import pytest

from netsim.compiled import load
from netsim.world.los import walls_crossed
from netsim.world.maps import OccupancyMap, load_map
from netsim.world.sweep import map_grid, sweep_walls, vertex_index
from tests.building_map import building_map


def _brute(occupancy, p0, vp, q0, vq, times, pair):
    """The count of ``walls_crossed`` at each ``times[m]`` for pair ``pair[m]``."""
    t = times[:, None]
    return walls_crossed(occupancy, p0[pair] + vp[pair] * t, q0[pair] + vq[pair] * t)


def _mismatches(occupancy, p0, vp, q0, vq, duration, step_s, away_s=1e-6):
    """Instants on a grid of ``step_s`` (midway; more than ``away_s`` from the rows' ends) at which
    the sweep's count differs from the traversal's; checks the rows' shape too."""
    s = sweep_walls(occupancy, p0, vp, q0, vq, duration)
    k = len(p0)
    for i in range(k):
        rows = np.flatnonzero(s.pair == i)
        assert len(rows) >= 1
        assert s.t0_s[rows[0]] == 0.0 and s.t1_s[rows[-1]] == duration[i]
        assert np.all(s.t1_s[rows[:-1]] == s.t0_s[rows[1:]])
        assert np.all(s.t1_s[rows] > s.t0_s[rows]) or duration[i] == 0
        assert np.all(s.walls[rows[1:]] != s.walls[rows[:-1]])
    counts = np.ceil(duration / step_s).astype(np.int64)
    pair = np.repeat(np.arange(k), counts)
    # Off the round instants: where the robots meet (a segment of no length) the count is
    # the cell's alone, an instant that no row of open intervals describes.
    times = (np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts) + 0.5) * step_s
    times = np.minimum(times, np.repeat(duration, counts))
    # Each instant's row, and how far it is from the row's ends: a pair's rows are
    # consecutive (pairs ascending), and so are its instants.
    assert np.all(np.diff(s.pair) >= 0)
    bounds = np.searchsorted(s.pair, np.arange(k + 1), side="left")
    first = np.cumsum(counts) - counts
    row = np.empty(len(times), dtype=np.int64)
    for i in range(k):
        mine = slice(first[i], first[i] + counts[i])
        row[mine] = bounds[i] + np.searchsorted(s.t1_s[bounds[i] : bounds[i + 1]], times[mine], side="left")
    row = np.minimum(row, len(s.pair) - 1)
    away = (np.abs(times - s.t0_s[row]) > away_s) & (np.abs(times - s.t1_s[row]) > away_s)
    truth = _brute(occupancy, p0, vp, q0, vq, times, pair)
    wrong = away & (truth != s.walls[row])
    return int(wrong.sum()), int(away.sum())


def _random_pairs(occupancy, k, speed_mps, duration_s, seed, corner_share=0.5):
    """Random pairs on the map; a share of them pass through a mixed grid vertex (a wall's
    corner or edge) at a random instant, some with an end passing through it."""
    rng = np.random.default_rng(seed)
    h, w = occupancy.shape
    res = occupancy.resolution_m
    side = np.array([w, h]) * res
    margin = speed_mps * duration_s + 0.5
    p0 = rng.uniform(margin, side - margin, (k, 2))
    q0 = rng.uniform(margin, side - margin, (k, 2))
    vp = rng.uniform(-1, 1, (k, 2)) * speed_mps
    vq = rng.uniform(-1, 1, (k, 2)) * speed_mps
    duration = np.full(k, duration_s)
    index = vertex_index(occupancy.occupied)
    rows = np.repeat(np.arange(h + 1), np.diff(index.row_ptr))
    inner = (index.cols * res > margin) & (index.cols * res < side[0] - margin)
    inner &= (rows * res > margin) & (rows * res < side[1] - margin)
    vx = np.flatnonzero(inner)
    for i in range(int(k * corner_share)):
        m = vx[rng.integers(len(vx))]
        corner = np.array([index.cols[m], rows[m]], float) * res + np.array(occupancy.origin_m)
        tc = rng.uniform(0, duration_s)
        # The segment at tc runs through the corner (or starts at it, for some pairs).
        direction = rng.normal(size=2)
        direction /= np.hypot(*direction)
        pc = corner - direction * (0.0 if i % 5 == 0 else rng.uniform(0.5, margin))
        qc = corner + direction * rng.uniform(0.5, margin)
        p0[i] = pc - vp[i] * tc
        q0[i] = qc - vq[i] * tc
    return p0, vp, q0, vq, duration


def _grid_aligned_pairs(occupancy, speed_mps, duration_s, corners=8, seed=5):
    """Degenerate motions about wall corners (vertices with one blocked cell of four): a
    robot standing on the corner or on one of its grid lines, robots moving along a grid
    line through it (the segment lying on the line), side by side, or on a diagonal."""
    rng = np.random.default_rng(seed)
    res = occupancy.resolution_m
    h, w = occupancy.shape
    b = np.pad(occupancy.occupied, 1, mode="edge").astype(int)
    around = b[:-1, :-1] + b[:-1, 1:] + b[1:, :-1] + b[1:, 1:]
    vy, vx = np.nonzero(around == 1)
    inner = (vx > 4 / res) & (vx < w - 4 / res) & (vy > 4 / res) & (vy < h - 4 / res)
    chosen = rng.choice(np.flatnonzero(inner), corners, replace=False)
    v = speed_mps
    rows = []
    for c in chosen:
        cx, cy = vx[c] * res + occupancy.origin_m[0], vy[c] * res + occupancy.origin_m[1]
        rows += [
            ((cx, cy), (0, 0), (cx + 1.5, cy - 1.0), (-v, v)),
            ((cx, cy), (0, 0), (cx - 1.5, cy + 1.0), (v, -v)),
            ((cx, cy + 0.3 * res), (0, 0), (cx + 1.0, cy + 1.0), (-v, 0.1 * v)),
            ((cx - 1.5, cy), (v, 0), (cx + 1.5, cy), (-v, 0)),
            ((cx - 2.0, cy), (v, 0), (cx - 1.0, cy), (v, 0)),
            ((cx, cy - 2.0), (0, v), (cx, cy - 1.0), (0, v)),
            ((cx - 1.0, cy - 1.0), (v, v), (cx + 1.0, cy + 1.0), (-v, -v)),
            ((cx - 1.0, cy), (0, 0), (cx + 1.0, cy + 1.0), (0, 0)),
        ]
    p0, vp, q0, vq = (np.array([r[n] for r in rows], float) for n in range(4))
    return p0, vp, q0, vq, np.full(len(rows), duration_s)


@pytest.fixture(scope="module")
def building():
    return building_map()


@pytest.mark.slow
@pytest.mark.parametrize("name", ["office", "cave"])
def test_sweep_matches_brute_force_on_shipped_maps(name):
    """On the shipped maps, the sweep's count equals walls_crossed at every instant of a fine
    grid (away from the sweep's own breakpoints), for random pairs and pairs passing corners."""
    occupancy = load_map(name)
    wrong, seen = _mismatches(occupancy, *_random_pairs(occupancy, 30, 2.0, 10.0, seed=1), step_s=1e-3)
    assert seen > 250_000
    assert wrong == 0


@pytest.mark.slow
def test_sweep_matches_brute_force_on_a_building_map(building):
    """On a 40 m x 40 m map of 5 cm cells (robots at 0.1-0.5 m/s), the sweep's count equals
    walls_crossed at every instant of a 1 ms grid away from its breakpoints."""
    wrong, seen = _mismatches(building, *_random_pairs(building, 60, 0.5, 20.0, seed=2), step_s=1e-3)
    assert seen > 1_000_000
    assert wrong == 0


@pytest.mark.slow
def test_sweep_matches_brute_force_on_grid_aligned_motion(building):
    """Robots standing on vertices and grid lines, or moving along grid lines: the sweep
    still equals walls_crossed between its breakpoints."""
    for occupancy in (building, load_map("office")):
        wrong, seen = _mismatches(occupancy, *_grid_aligned_pairs(occupancy, 0.3, 10.0, corners=4), step_s=1e-3)
        assert seen > 250_000
        assert wrong == 0


def test_sweep_finds_a_change_at_a_wall_corner():
    """A segment swept across a wall's corner changes count exactly there, though neither
    end crosses a grid line between cells of different state (only the vertex tells)."""
    wall = np.zeros((4, 6), dtype=bool)
    wall[1:, 3] = True
    m = OccupancyMap(wall, ~wall, 1.0, (0.0, 0.0))
    s = sweep_walls(m, [[0.5, 0.5]], [[0.0, 1.0]], [[5.5, 0.5]], [[0.0, 0.0]], [2.0])
    assert s.t1_s.tolist() == [1.0, 2.0]
    assert s.walls.tolist() == [0, 1]


def test_sweep_finds_corner_events_on_a_building_map(building):
    """Pairs passing wall corners on the 5 cm map (a quick version of the brute-force check,
    at 10 ms)."""
    wrong, seen = _mismatches(building, *_random_pairs(building, 20, 0.5, 10.0, seed=3, corner_share=1.0), step_s=1e-2)
    assert seen > 10_000
    assert wrong == 0


def test_sweep_limit_caps_the_count(building):
    """With ``limit``, counts above it come out as ``limit + 1`` and the rest exactly."""
    args = _random_pairs(building, 20, 0.5, 10.0, seed=4)
    full = sweep_walls(building, *args)
    capped = sweep_walls(building, *args, limit=0)
    t = 0.5 * (capped.t0_s + capped.t1_s)
    p0, vp, q0, vq, _ = args
    truth = _brute(building, p0, vp, q0, vq, t, capped.pair)
    assert np.array_equal(capped.walls, np.minimum(truth, 1))
    assert full.walls.max() > 1


def _candidates(occupancy, p0, vp, q0, vq, duration, prune):
    """Each pair's candidate instants (:func:`netsim.world._sweep_kernels.candidates`),
    sorted, with the walk over the map's vertices pruned or not."""
    kernels = load("netsim.world._sweep_kernels", 0)
    grid = map_grid(occupancy)
    origin, res = np.asarray(occupancy.origin_m, float), occupancy.resolution_m
    out = []
    for k in range(len(p0)):
        g0, k0 = (p0[k] - origin) / res, (q0[k] - origin) / res
        found = kernels.candidates(grid, g0, vp[k] / res, k0, vq[k] / res, float(duration[k]), prune)
        out.append(np.sort(found))
    return out


def _mixed_vertices_m(occupancy, count, rng):
    """``count`` of the map's mixed vertices (blocked and clear cells meet), drawn without
    replacement, in metres."""
    index = vertex_index(occupancy.occupied)
    rows = np.repeat(np.arange(occupancy.shape[0] + 1), np.diff(index.row_ptr))
    chosen = rng.choice(len(index.cols), count, replace=False)
    cells = np.column_stack([index.cols[chosen], rows[chosen]]).astype(float)
    return cells * occupancy.resolution_m + np.asarray(occupancy.origin_m, float)


def _radial_pairs(occupancy, speed_mps, duration_s, count=40, seed=6):
    """A robot at rest and one moving straight away from it, both on a line through a mixed
    vertex (the vertex stays on the segment's line), at random headings and along the axes."""
    rng = np.random.default_rng(seed)
    p0, vp, q0, vq = (np.zeros((count, 2)) for _ in range(4))
    for n, vertex in enumerate(_mixed_vertices_m(occupancy, count, rng)):
        angle = rng.uniform(0, 2 * np.pi) if n % 2 else rng.integers(4) * np.pi / 2
        u = np.array([np.cos(angle), np.sin(angle)]).round(15 if n % 2 else 0)
        p0[n] = vertex - u * rng.uniform(0.5, 30.0)
        q0[n] = vertex + u * rng.uniform(-3.0, 30.0)
        vq[n] = u * speed_mps
    return p0, vp, q0, vq, np.full(count, duration_s)


def _close_parallel_pairs(occupancy, count=40, seed=9):
    """Two robots a tenth of a millimetre apart on a line through a mixed vertex, moving
    alike along it across the vertex (it stays on the segment's line however short the
    segment), at random headings off the axes."""
    rng = np.random.default_rng(seed)
    p0, vp, q0, vq = (np.zeros((count, 2)) for _ in range(4))
    for n, vertex in enumerate(_mixed_vertices_m(occupancy, count, rng)):
        angle = rng.uniform(0.1, np.pi / 2 - 0.1) + rng.integers(4) * np.pi / 2
        u = np.array([np.cos(angle), np.sin(angle)])
        p0[n] = vertex - u * rng.uniform(0.2, 1.0)
        q0[n] = p0[n] + u * 1e-4
        vp[n] = vq[n] = u * 1.0
    return p0, vp, q0, vq, np.full(count, 2.0)


def _long_pairs(occupancy, count, seed=7):
    """Pairs far apart on the whole map over a 4 m chunk at up to 5 m/s, a share with one
    robot at rest, some turning through a heading along an axis."""
    rng = np.random.default_rng(seed)
    h, w = occupancy.shape
    lo = np.asarray(occupancy.origin_m, float)
    hi = lo + np.array([w, h]) * occupancy.resolution_m
    p0 = rng.uniform(lo, hi, (count, 2))
    q0 = rng.uniform(lo, hi, (count, 2))
    vp = rng.uniform(-5.0, 5.0, (count, 2))
    vq = rng.uniform(-5.0, 5.0, (count, 2))
    vp[::3] = 0.0
    # Level at mid-chunk: the heading crosses the x axis.
    q0[1::5, 1] = p0[1::5, 1] - (vq[1::5, 1] - vp[1::5, 1]) * 0.4
    speed = np.maximum(np.hypot(*vp.T), np.hypot(*vq.T))
    return p0, vp, q0, vq, 4.0 / speed


@pytest.mark.parametrize("which", ["office", "building"])
def test_pruned_vertex_walk_finds_every_candidate(which, building):
    """Passing over the vertices along straight walls (no root solved) leaves exactly the
    candidates of solving every vertex: for random and long pairs, pairs passing wall
    corners, ends on grid lines and vertices, and vertices staying on the segment's line
    (a long segment, or one so short that any vertex near its line may stay on it)."""
    occupancy = building if which == "building" else load_map("office")
    aligned = _grid_aligned_pairs(occupancy, 0.3, 10.0, corners=4)
    # Ends a hair off the grid's lines: rows within the span's margin of an end's height.
    hair = np.array([[0.0, 5e-8], [-5e-8, 0.0]]) * occupancy.resolution_m
    shifted = (aligned[0] + hair[np.arange(len(aligned[0])) % 2], aligned[1], aligned[2] - hair[0], *aligned[3:])
    motions = [
        _random_pairs(occupancy, 60, 2.0, 2.0, seed=8, corner_share=1.0),
        aligned,
        shifted,
        _radial_pairs(occupancy, 1.5, 2.0),
        _long_pairs(occupancy, 300),
        _close_parallel_pairs(occupancy),
    ]
    found = 0
    for motion in motions:
        full = _candidates(occupancy, *motion, prune=False)
        pruned = _candidates(occupancy, *motion, prune=True)
        for a, b in zip(full, pruned, strict=True):
            assert np.array_equal(a, b)
        found += sum(len(a) for a in full)
    assert found > 1000
