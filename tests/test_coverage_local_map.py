"""The local plan on a map (docs/model.md 5.1, rule 5 "Walls" and "A map"; 5.3): the map's
convex regions of free space, the region two ends of a link share, rule 5 by region, rule 1
with links in one region, the pull announced as a robot can carry it out on a map, and the
controller's wiring of these rules in a run on a map."""

from __future__ import annotations

import numpy as np
import pytest
from netsim.mobility.local import (
    Lists,
    Memory,
    cut_for_walls,
    free_rectangles,
    let_go,
    shared_regions,
    walls_of,
)
from netsim.mobility.steps import StepLimits

from netsim.compiled import load
from tests.oracles import local as oracle

RES = 0.5
ORIGIN = (0.0, 0.0)
V = 2.0
RC = 30.0
LIMITS = StepLimits(period_s=1.0, range_m=RC, margin_m=1.0, speed_max_mps=V, side_m=100.0)
T0 = 10.0


def floor_plan() -> np.ndarray:
    """A 100 m x 60 m floor at 0.5 m a cell (row 0 at the bottom): a 3 m corridor along y in
    [28.5, 31.5) between two rows of 10 m wide rooms, each with a 1.5 m door onto it; an
    outer wall one cell thick."""
    h, w = 120, 200
    occ = np.zeros((h, w), bool)
    occ[:1, :] = occ[-1:, :] = occ[:, :1] = occ[:, -1:] = True
    occ[56, :] = occ[63, :] = True  # the corridor's walls, y = 28 and 31.5
    for x in range(20, 200, 20):  # rooms 10 m wide
        occ[:56, x] = occ[64:, x] = True
    for x in range(0, 200, 20):  # a 1.5 m door in each room's corridor-side wall
        occ[56, x + 8 : x + 11] = occ[63, x + 8 : x + 11] = False
    return occ


def wall_shapes(occ):
    from shapely import box, unary_union

    rows, cols = np.nonzero(occ)
    return unary_union(
        [
            box(ORIGIN[0] + c * RES, ORIGIN[1] + r * RES, ORIGIN[0] + (c + 1) * RES, ORIGIN[1] + (r + 1) * RES)
            for r, c in zip(rows, cols)
        ]
    )


def free_points(occ, rng, k):
    """``k`` points uniform over the free cells, at least 2 cm from every cell's side."""
    rows, cols = np.nonzero(~occ)
    pick = rng.integers(0, len(rows), k)
    frac = rng.uniform(0.04, 0.96, (k, 2))
    return np.c_[ORIGIN[0] + (cols[pick] + frac[:, 0]) * RES, ORIGIN[1] + (rows[pick] + frac[:, 1]) * RES]


def near_point(rng, p, e):
    """A point within ``e`` of each row of ``p``."""
    a = rng.uniform(0, 2 * np.pi, len(p))
    r = e * np.sqrt(rng.random(len(p)))
    return p + np.c_[r * np.cos(a), r * np.sin(a)]


def test_regions_are_rectangles_of_free_cells_that_hold_every_free_cell():
    """The map's regions: every one a rectangle of free cells (so convex, and clear of walls),
    every free cell in one, largest first, and on the floor plan the corridor and the rooms
    among them whole."""
    occ = floor_plan()
    rects = free_rectangles(~occ)
    covered = np.zeros_like(occ)
    for i0, i1, j0, j1 in rects.tolist():
        assert (~occ[j0 : j1 + 1, i0 : i1 + 1]).all()
        covered[j0 : j1 + 1, i0 : i1 + 1] = True
    assert (covered == ~occ).all()
    area = (rects[:, 1] - rects[:, 0] + 1) * (rects[:, 3] - rects[:, 2] + 1)
    assert (np.diff(area) <= 0).all()
    as_rows = {tuple(r) for r in rects.tolist()}
    assert (1, 198, 57, 62) in as_rows  # the corridor
    assert (1, 19, 1, 55) in as_rows  # the first room
    assert (8, 10, 1, 118) in as_rows  # the strip through the first doors


def test_regions_a_disk_said_held_lies_in_the_region_and_one_said_missed_misses_it():
    """Where a robot within ``e`` of ``q`` can be, against a region: said held, every point of
    the disk in a cell that is not a wall lies in the region's (shrunk) rectangle; said
    missed, the disk misses it (shapely, exact); both answers given often. The kernel agrees
    with its numpy oracle."""
    from shapely import Point, box

    occ = floor_plan()
    walls = walls_of(occ, ORIGIN, RES)
    shapes = wall_shapes(occ)
    rng = np.random.default_rng(3)
    q = free_points(occ, rng, 300)
    e = rng.uniform(0, 3, 300)
    from netsim.compiled import load

    kern = load("netsim.mobility._local_kernels", None)
    said = {0: 0, 1: 0}
    for k in range(len(q)):
        disk = Point(q[k]).buffer(e[k] * 1.001 + 1e-9, 64).difference(shapes)
        for r in range(len(walls.rects)):
            held = kern.region_holds(walls, r, q[k, 0], q[k, 1], e[k])
            assert held == oracle.region_holds(walls, r, q[k], e[k])
            rect = box(*walls.rects[r][[0, 2, 1, 3]])
            if held == 1:
                assert disk.difference(rect).area < 1e-6
                said[1] += 1
            elif held == 0:
                assert not Point(q[k]).buffer(e[k] * 0.999, 64).intersects(rect)
                said[0] += 1
    assert said[1] > 150 and said[0] > 1000


def test_shared_region_holds_both_robots_and_both_ends_name_the_same_one():
    """The region two ends of a link share (:func:`shared_regions`), each from its own exact
    position and what it knows of the other (within ``e`` of where it heard it): where one
    names a region, it holds both true positions; where both name one, it is the same; and
    on the floor plan both name one for most pairs within a few metres' knowledge."""
    occ = floor_plan()
    walls = walls_of(occ, ORIGIN, RES)
    rng = np.random.default_rng(4)
    a = free_points(occ, rng, 3000)
    b = np.r_[free_points(occ, rng, 1500), near_point(rng, a[1500:], 12.0)]
    inside = (b[:, 0] > 0.5) & (b[:, 0] < 99.5) & (b[:, 1] > 0.5) & (b[:, 1] < 59.5)
    rows = np.flatnonzero(inside)
    cols = np.floor(np.asarray(b[rows]) / RES).astype(int)
    rows = rows[~occ[cols[:, 1], cols[:, 0]]]
    a, b = a[rows], b[rows]
    ea, eb = rng.choice([0.0, 0.05, 0.5, 2.0], (2, len(a)))
    qa, qb = near_point(rng, a, ea), near_point(rng, b, eb)
    from_a = shared_regions(walls, a, qb, eb)
    from_b = shared_regions(walls, b, qa, ea)
    for side in (from_a, from_b):
        named = np.flatnonzero(side >= 0)
        rect = walls.rects[side[named]]
        for p in (a[named], b[named]):
            assert (
                (rect[:, 0] <= p[:, 0]) & (p[:, 0] <= rect[:, 1]) & (rect[:, 2] <= p[:, 1]) & (p[:, 1] <= rect[:, 3])
            ).all()
    both = (from_a >= 0) & (from_b >= 0)
    assert (from_a[both] == from_b[both]).all()
    assert both.sum() > 300


def corridor_pair(sent_s):
    """Robot 0 at (20, 30) and robot 1 at (40, 30), in the floor plan's corridor, each heard
    by the other at its true position in an Ack sent at ``sent_s``."""
    pos = np.array([[20.0, 30.0], [40.0, 30.0]])
    m = Memory(2)
    m.xy[:] = pos[None, :, :]
    m.sent_s[:] = sent_s
    np.fill_diagonal(m.sent_s, -np.inf)
    return pos, m, m.known(T0, 20.0)


def without_regions(walls):
    return walls._replace(bucket_start=np.zeros_like(walls.bucket_start), bucket_regions=np.zeros(0, np.int64))


def test_walls_by_region_a_robot_moves_in_the_corridor_it_shares_with_its_neighbour():
    """Rule 5 by region: robot 0 keeps robot 1, 20 m along a 3 m corridor, heard exactly. No
    disk of the speed cap's radius fits in the corridor, so answering alone it holds; by the
    region both share (the corridor) it moves, sliding along the corridor's wall where its
    wish runs into it, and ends in the corridor."""
    walls = walls_of(floor_plan(), ORIGIN, RES)
    pos, m, kept = corridor_pair(T0)
    move = np.array([[1.5, 1.2], [0.0, 0.0]])
    t1 = T0 + LIMITS.period_s
    alone = cut_for_walls(pos, move, m, kept, t1, LIMITS, without_regions(walls))
    assert (alone[0] == 0).all()
    moved = cut_for_walls(pos, move, m, kept, t1, LIMITS, walls)
    assert moved[0, 0] == pytest.approx(1.5)
    end = pos[0] + moved[0]
    assert 28.5 < end[1] < 31.5 and end[1] > 30.9


def test_walls_a_robot_that_cannot_tell_the_region_answers_alone():
    """Rule 5 by region needs the other end's place at the step's start: robot 1 heard 3 s
    ago (6 m of uncertainty, reaching into the rooms) gives no shared region, and robot 0
    holds."""
    walls = walls_of(floor_plan(), ORIGIN, RES)
    pos, m, kept = corridor_pair(T0 - 3.0)
    move = np.array([[1.5, 0.0], [0.0, 0.0]])
    assert (cut_for_walls(pos, move, m, kept, T0 + LIMITS.period_s, LIMITS, walls)[0] == 0).all()


@pytest.mark.parametrize("seed", range(6))
def test_walls_a_link_both_ends_keep_stays_clear_of_walls_at_every_instant_of_the_step(seed):
    """Rule 5, the argument on a map: robots in the floor plan's rooms and corridor, each
    knowing the others within ``v (t0 - s)`` of where it heard them and keeping those it
    knows no certified detour to (rule 1); every robot's step cut by rule 5 from what it
    knows. For every link both ends keep, the segment between the
    two robots, both moving along their steps, is clear of walls at every instant (shapely,
    41 instants) and within range at the step's end; and links answered by region, with
    both ends moving, are among them."""
    from shapely import LineString

    occ = floor_plan()
    walls, shapes = walls_of(occ, ORIGIN, RES), wall_shapes(occ)
    rng = np.random.default_rng(seed)
    n = 40
    pos = free_points(occ, rng, n)
    pos[:30, 1] = rng.uniform(28.7, 31.3, 30)  # most of them in the corridor
    d = np.hypot(*(pos[:, None] - pos[None]).transpose(2, 0, 1))
    clear = ~np.array(
        [[LineString([pos[i], pos[j]]).intersects(shapes) if i != j else True for j in range(n)] for i in range(n)]
    )
    heard = (d <= RC - 2.0) & clear
    sent = np.where(heard, T0 - rng.choice([0.0, 0.0, 0.05, 0.2], (n, n)), -np.inf)
    m = Memory(n)
    m.sent_s[:] = sent
    # Robot j was within V (T0 - s) of where i heard it.
    m.xy[:] = near_point(
        rng, np.broadcast_to(pos[None], (n, n, 2)).reshape(-1, 2), V * np.where(heard, T0 - sent, 0.0).ravel()
    ).reshape(n, n, 2)
    lists = Lists(n, 1)
    lists.take(m, T0 - 3.0, 20.0)
    kept = heard & ~let_go(pos, m, lists.heard(m.known(T0, 20.0), m.sent_s, 20.0), T0, V, 7.5, RC, walls)
    wish = rng.normal(0, 2.0, (n, 2))
    t1 = T0 + LIMITS.period_s
    move = cut_for_walls(pos, wish, m, kept, t1, LIMITS, walls)
    region_pairs = 0
    for i, j in zip(*np.nonzero(np.triu(kept & kept.T, 1))):
        if not (move[i] != 0).any() and not (move[j] != 0).any():
            continue
        for f in np.linspace(0.0, 1.0, 41):
            seg = LineString([pos[i] + f * move[i], pos[j] + f * move[j]])
            assert not seg.intersects(shapes), (i, j, f)
        assert np.hypot(*(pos[i] + move[i] - pos[j] - move[j])) <= RC
        e1 = V * (t1 - m.sent_s[[i, j], [j, i]])
        region_pairs += (move[i] != 0).any() and (move[j] != 0).any() and (e1 > 1.5).all() and abs(pos[i, 1] - 30) < 1.5
    assert region_pairs >= 1


def test_detour_on_a_map_through_a_door_passing_its_frame_by_centimetres():
    """Rule 1 on a map: robot 0, in a room, lets go of robot 1, in the corridor, through
    robot 2, whose link to robot 0 passes the door's frame 12 cm off (the walls' test is
    exact: within half a cell's diagonal of a wall is not "near"); with robot 2 a little
    farther along, that link meets the frame and the link (0, 1) is kept. The kernels agree
    with the oracle."""
    walls = walls_of(floor_plan(), ORIGIN, RES)

    def lets_go(x2):
        pos = np.array([[4.1, 24.0], [20.0, 30.0], [x2, 30.0]])
        m = Memory(3)
        m.xy[:] = pos[None, :, :]
        m.sent_s[:] = T0 - 0.01
        np.fill_diagonal(m.sent_s, -np.inf)
        lists = Lists(3, 1)
        lists.take(m, T0 - 1.0, 20.0)
        heard = lists.heard(m.known(T0, 20.0), m.sent_s, 20.0)
        out = let_go(pos, m, heard, T0, V, 7.5, RC, walls)
        assert (out == oracle.let_go(pos, m, heard, T0, V, 7.5, RC, walls)).all()
        return out[0, 1]

    # The frame's corner (5.5, 28.5) is |(1.4, 4.5) x (1.7, 6)| / |(1.7, 6)| = 0.12 m from the
    # line (4.1, 24) -> (5.8, 30).
    assert lets_go(5.8)
    assert not lets_go(6.2)


def test_pull_on_a_map_announces_the_step_the_robot_can_make():
    """Rule 4 on a map: a robot announces its wish as it could carry it out, capped at its
    reach and ended short of the walls: a wish of 40 m/s along the corridor announces the
    reach (2 m/s), one straight into the corridor's wall next to it almost nothing."""
    from netsim.mobility.geodesic import within_reach

    from netsim.world.maps import OccupancyMap

    occ = floor_plan()
    m = OccupancyMap(occ, ~occ, RES, ORIGIN)
    pos = np.array([[20.0, 30.0], [20.0, 31.0]])
    wish = np.array([[40.0, 0.0], [0.0, 40.0]])
    out = within_reach(m, pos, wish, 1.0, 2.0)
    assert out[0] == pytest.approx([2.0, 0.0])
    assert 0.0 <= out[1, 1] < 0.51 and out[1, 0] == 0.0


@pytest.mark.slow
def test_a_local_run_on_a_map_uses_the_map_rules(monkeypatch):
    """The controller's wiring: a local-plan run on the office map, from a connected start,
    gives rule 1 and rule 5 the map's walls with its regions, rule 5 moves robots by region
    that would hold answering alone, every robot announces its wish as it can carry it out
    (within its reach), and the real network never splits."""
    import netsim.mobility.coverage as coverage

    from netsim import config
    from netsim.metrics import components_at_link_events
    from netsim.run import execute
    from netsim.tools.validate import coverage_settings

    seen = {"let_go": 0, "by_region": 0, "announced": []}
    let_go_, cut_, within_ = coverage.let_go, coverage.cut_for_walls, coverage.within_reach

    def spy_let_go(pos, knows, heard, t0, speed, band, range_m, walls, *rest):
        seen["let_go"] += walls.on and len(walls.bucket_regions) > 0 and len(walls.rects) > 100
        return let_go_(pos, knows, heard, t0, speed, band, range_m, walls, *rest)

    def spy_cut(pos, move, knows, kept, t1, limits, walls):
        out = cut_(pos, move, knows, kept, t1, limits, walls)
        alone = cut_(pos, move, knows, kept, t1, limits, without_regions(walls))
        seen["by_region"] += int(((np.hypot(*out.T) > 0) & (np.hypot(*alone.T) == 0)).sum())
        return out

    def spy_within(occupancy, pos, wish, period, reach):
        out = within_(occupancy, pos, wish, period, reach)
        seen["announced"].append(float(np.hypot(*out.T).max(initial=0.0)) * period / reach)
        return out

    monkeypatch.setattr(coverage, "let_go", spy_let_go)
    monkeypatch.setattr(coverage, "cut_for_walls", spy_cut)
    monkeypatch.setattr(coverage, "within_reach", spy_within)
    keys = coverage_settings("office, line of sight", "local", 20, 0.0, 1, 60.0)
    r = execute(config.load(None, [*keys, "world.placement=connected", "world.centre_side_m=60"]))
    assert seen["let_go"] > 20 and seen["by_region"] > 10
    assert len(seen["announced"]) > 20 and max(seen["announced"]) <= 1.0 + 1e-9
    links = r.frames["links"]
    _, counts = components_at_link_events(
        *(links[c].to_numpy() for c in ("a", "b", "t_up_s", "t_down_s", "censored_end")), 20
    )
    assert counts.max() == 1


def test_each_bucket_lists_exactly_the_regions_that_meet_it():
    """A region is found from any point in it through its cells' buckets (bucket_of), so
    every bucket a region's cells fall in lists it, and no other bucket does."""
    rng = np.random.default_rng(5)
    occupied = rng.random((29, 41)) < 0.2
    res = 0.5
    walls = walls_of(occupied, (3.0, -2.0), res)
    k = walls.bucket_cells
    assert k > 1  # buckets of several cells, so that a region's span may start mid-bucket
    kernels = load("netsim.mobility._local_kernels", None)
    h, w = occupied.shape
    listed = {
        b: set(walls.bucket_regions[walls.bucket_start[b] : walls.bucket_start[b + 1]].tolist())
        for b in range(len(walls.bucket_start) - 1)
    }
    meets: dict[int, set[int]] = {b: set() for b in listed}
    for r, (i0, i1, j0, j1) in enumerate(free_rectangles(~occupied).tolist()):
        for j in range(j0, j1 + 1):
            for i in range(i0, i1 + 1):
                x, y = 3.0 + (i + 0.5) * res, -2.0 + (j + 0.5) * res
                meets[kernels.bucket_of(walls, x, y)].add(r)
    assert listed == meets
    assert len(listed) == ((h + k - 1) // k) * ((w + k - 1) // k)
