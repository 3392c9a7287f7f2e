"""The local plan on a map (docs/model.md 5.1, rules 5 "Walls" and 7 "Turns", and "A map";
5.3): rule 5 against a robot that holds, turns and who knows who holds, the argument on a
floor plan, rule 1 through a door, the pull announced as a robot can carry it out on a map,
and the controller's wiring of these rules in a run on a map."""

from __future__ import annotations

import numpy as np
import pytest
from netsim.mobility.local import (
    Lists,
    Memory,
    cut_for_walls,
    let_go,
    step_clear_of_walls,
    turn_takers,
    walls_of,
)
from netsim.mobility.steps import StepLimits

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


def heard_scene(rng, pos, heard):
    """What robots at ``pos`` heard of each other where ``heard``: Acks sent up to 0.2 s
    before ``T0``, each robot then within ``V (T0 - s)`` of where it was heard; and the
    lists they hold (:class:`Lists`, taken 3 s before)."""
    n = len(pos)
    sent = np.where(heard, T0 - rng.choice([0.0, 0.0, 0.05, 0.2], (n, n)), -np.inf)
    m = Memory(n)
    m.sent_s[:] = sent
    m.xy[:] = near_point(
        rng, np.broadcast_to(pos[None], (n, n, 2)).reshape(-1, 2), V * np.where(heard, T0 - sent, 0.0).ravel()
    ).reshape(n, n, 2)
    lists = Lists(n, 1)
    lists.take(m, T0 - 3.0, 20.0)
    return m, lists.heard(m.known(T0, 20.0), m.sent_s, 20.0)


def heard_at(pos, sent_s):
    """Each robot's memory of the others at their true positions ``pos``, in Acks sent at
    ``sent_s``."""
    m = Memory(len(pos))
    m.xy[:] = pos[None, :, :]
    m.sent_s[:] = sent_s
    np.fill_diagonal(m.sent_s, -np.inf)
    return m


def corridor_pair(sent_s):
    """Robot 0 at (20, 30) and robot 1 at (40, 30), in the floor plan's corridor, each heard
    by the other at its true position in an Ack sent at ``sent_s``."""
    pos = np.array([[20.0, 30.0], [40.0, 30.0]])
    m = heard_at(pos, sent_s)
    return pos, m, m.known(T0, 20.0)


def test_walls_a_robot_moves_along_the_corridor_against_a_neighbour_that_holds():
    """Rule 5 with rule 7: robot 0 keeps robot 1, 20 m along a 3 m corridor, and answers for
    the link against robot 1 holding where it stands. Heard exactly, robot 1 stands at a
    point, and robot 0 makes its whole step; heard 1 s earlier, robot 1 can stand anywhere
    within 2 m of where it was heard, a disk that meets the corridor's walls, and robot 0
    holds."""
    walls = walls_of(floor_plan(), ORIGIN, RES)
    move = np.array([[1.5, 0.4], [0.0, 0.0]])
    t1 = T0 + LIMITS.period_s
    pos, m, kept = corridor_pair(T0)
    assert cut_for_walls(pos, move, m, kept, t1, LIMITS, walls)[0] == pytest.approx([1.5, 0.4])
    pos, m, kept = corridor_pair(T0 - 1.0)
    assert (cut_for_walls(pos, move, m, kept, t1, LIMITS, walls)[0] == 0).all()


def test_walls_a_robot_held_by_a_doors_frame_slides_along_the_corridor():
    """Rule 5's slide: robot 0, in the corridor, sees robot 1 in the room below through its
    door. Its step up and to the right, and every fraction of it tried, would put the
    door's frame between them; its part to the right alone too. Without the map the robot
    holds; with it, it makes its step's part up the corridor, along which robot 1 stays in
    sight."""
    from netsim.world.maps import OccupancyMap

    occ = floor_plan()
    walls = walls_of(occ, ORIGIN, RES)
    pos = np.array([[15.55, 30.0], [14.75, 20.0]])
    m = heard_at(pos, T0)
    kept = m.known(T0, 20.0)
    move = np.array([[1.6, 1.0], [0.0, 0.0]])
    t1 = T0 + LIMITS.period_s
    assert (cut_for_walls(pos, move, m, kept, t1, LIMITS, walls) == 0).all()
    slid = cut_for_walls(pos, move, m, kept, t1, LIMITS, walls, OccupancyMap(occ, ~occ, RES, ORIGIN))
    assert slid[0] == pytest.approx([0.0, 1.0]) and (slid[1] == 0).all()


def test_turns_of_two_robots_that_keep_each_other_the_outranked_one_holds():
    """Rule 7: a robot moves only if it outranks every robot it keeps. Robots 0 and 1 keep
    each other, 2 keeps 1 alone, 3 nobody: of 0 and 1 the higher ranked moves, 2 moves only
    when it outranks 1, and 3 always moves."""
    kept = np.zeros((4, 4), bool)
    kept[0, 1] = kept[1, 0] = kept[2, 1] = True
    for rank, movers in (([3, 2, 1, 0], [0, 3]), ([0, 1, 2, 3], [1, 2, 3]), ([1, 0, 2, 3], [0, 2, 3])):
        assert np.flatnonzero(turn_takers(kept, np.array(rank))).tolist() == movers


@pytest.mark.parametrize("seed", range(6))
def test_walls_a_link_both_ends_keep_stays_clear_of_walls_at_every_instant_of_the_step(seed):
    """Rules 5 and 7, the argument on a map: robots in the floor plan's rooms and corridor,
    each knowing the others within ``v (t0 - s)`` of where it heard them and keeping those
    it knows no certified detour to (rule 1); the robots that take their turn move, each
    step cut by rule 5 from what the robot knows. For every link both ends keep, the
    segment between the two robots, moving along their steps, is clear of walls at every
    instant (shapely, 41 instants) and within range at the step's end, a robot that would
    hold trying the steps of SLIDES (its step's part along each axis, the step turned); and links whose
    mover answered against the other holding, where answering whatever the other does would
    not pass, are among them."""
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
    m, held = heard_scene(rng, pos, heard)
    kept = heard & ~let_go(pos, m, held, T0, V, 7.5, RC, walls)
    wish = rng.normal(0, 2.0, (n, 2)) * turn_takers(kept, rng.permutation(n))[:, None]
    t1 = T0 + LIMITS.period_s
    from netsim.world.maps import OccupancyMap

    move = cut_for_walls(pos, wish, m, kept, t1, LIMITS, walls, OccupancyMap(occ, ~occ, RES, ORIGIN))
    free = ~kept.any(axis=1)
    assert (move[free] == wish[free]).all()  # a robot keeping no link moves as it wished
    against_holder = 0
    for i, j in zip(*np.nonzero(np.triu(kept & kept.T, 1))):
        if not (move[i] != 0).any() and not (move[j] != 0).any():
            continue
        for f in np.linspace(0.0, 1.0, 41):
            seg = LineString([pos[i] + f * move[i], pos[j] + f * move[j]])
            assert not seg.intersects(shapes), (i, j, f)
        assert np.hypot(*(pos[i] + move[i] - pos[j] - move[j])) <= RC
        a, b = (i, j) if (move[i] != 0).any() else (j, i)
        # Whatever the other end did (within its reach over the step), the link could meet a wall.
        e1 = V * (t1 - m.sent_s[a, b])
        against_holder += not step_clear_of_walls(walls, pos[a : a + 1], move[a : a + 1], m.xy[a, b][None], e1)[0]
    assert against_holder >= 1


def test_detour_on_a_map_through_a_door_passing_its_frame_by_centimetres():
    """Rule 1 on a map: robot 0, in a room, lets go of robot 1, in the corridor, through
    robot 2, whose link to robot 0 passes the door's frame 12 cm off (the walls' test is
    exact: within half a cell's diagonal of a wall is not "near"); with robot 2 a little
    farther along, that link meets the frame and the link (0, 1) is kept. The kernels agree
    with the oracle."""
    walls = walls_of(floor_plan(), ORIGIN, RES)

    def lets_go(x2):
        pos = np.array([[4.1, 24.0], [20.0, 30.0], [x2, 30.0]])
        m = heard_at(pos, T0 - 0.01)
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
    gives rule 1 and rule 5 the map's walls (rule 5 the map too, for its slides), robots take
    turns, every robot announces its wish as it can carry it out (within its reach), and the
    real network never splits."""
    import netsim.mobility.coverage as coverage

    from netsim import config
    from netsim.metrics import components_at_link_events
    from netsim.run import execute
    from netsim.tools.validate import coverage_settings

    seen = {"let_go": 0, "waiting": 0, "announced": []}
    let_go_, cut_, within_ = coverage.let_go, coverage.cut_for_walls, coverage.within_reach
    turns_ = coverage.turn_takers

    def spy_let_go(pos, knows, heard, t0, speed, band, range_m, walls, *rest):
        seen["let_go"] += walls.on and walls.field.size > 10_000
        return let_go_(pos, knows, heard, t0, speed, band, range_m, walls, *rest)

    def spy_cut(pos, move, knows, kept, t1, limits, walls, occupancy=None):
        seen["cut"] = seen.get("cut", 0) + (walls.on and occupancy is not None)
        return cut_(pos, move, knows, kept, t1, limits, walls, occupancy)

    def spy_turns(known, rank):
        out = turns_(known, rank)
        seen["waiting"] += int((~out).sum())
        return out

    def spy_within(occupancy, pos, wish, period, reach):
        out = within_(occupancy, pos, wish, period, reach)
        seen["announced"].append(float(np.hypot(*out.T).max(initial=0.0)) * period / reach)
        return out

    monkeypatch.setattr(coverage, "let_go", spy_let_go)
    monkeypatch.setattr(coverage, "cut_for_walls", spy_cut)
    monkeypatch.setattr(coverage, "within_reach", spy_within)
    monkeypatch.setattr(coverage, "turn_takers", spy_turns)
    keys = coverage_settings("office, line of sight", "local", 20, 0.0, 1, 60.0)
    r = execute(config.load(None, [*keys, "world.placement=connected", "world.centre_side_m=60"]))
    assert seen["let_go"] > 20 and seen["cut"] > 20 and seen["waiting"] > 100
    assert len(seen["announced"]) > 20 and max(seen["announced"]) <= 1.0 + 1e-9
    links = r.frames["links"]
    _, counts = components_at_link_events(
        *(links[c].to_numpy() for c in ("a", "b", "t_up_s", "t_down_s", "censored_end")), 20
    )
    assert counts.max() == 1


def test_walls_a_slide_stays_inside_the_area():
    """Rule 5's slide keeps the area: robot 0, 0.5 m from the area's east side, keeps robot
    1 far west along a line that a wall cell just south of it would cut were robot 0 to
    step south. Its step south and every fraction of it are held; of the slides, the
    step's part along y is the same step and the step turned toward the east would leave
    the area: what it makes ends inside the area."""
    from netsim.world.maps import OccupancyMap

    occ = np.zeros((120, 120), bool)
    occ[19, 20] = True  # x 10-10.5 m, y 9.5-10 m
    limits = StepLimits(period_s=1.0, range_m=RC, margin_m=1.0, speed_max_mps=V, side_m=20.0)
    walls = walls_of(occ, ORIGIN, RES)
    pos = np.array([[19.5, 10.01], [0.5, 10.01]])
    m = heard_at(pos, T0)
    move = np.array([[0.0, -1.5], [0.0, 0.0]])
    slid = cut_for_walls(pos, move, m, m.known(T0, 20.0), T0 + 1.0, limits, walls, OccupancyMap(occ, ~occ, RES, ORIGIN))
    end = pos[0] + slid[0]
    assert (slid[0] != 0).any() and 0.0 <= end[0] <= 20.0 and 0.0 <= end[1] <= 20.0
