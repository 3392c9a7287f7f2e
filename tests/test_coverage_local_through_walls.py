"""The local plan on a map whose walls let power through (log-distance with
``wall_loss_db``; docs/model.md 5.1, rules 1 and 5 "through walls"): the walls as boxes, a
segment crossing no more walls than the boxes its hull meets, the count against its oracle,
rule 5 and rule 1 certifying a link through walls, and the argument on a floor plan."""

from __future__ import annotations

import numpy as np
import pytest
from netsim.mobility.local import Lists, cut_for_walls, let_go, through_walls, turn_takers, wall_boxes, walls_of

from netsim.compiled import load
from netsim.world.los import walls_crossed
from netsim.world.maps import OccupancyMap, load_map
from tests.oracles import local as oracle
from tests.test_coverage_local_map import LIMITS, ORIGIN, RC, RES, T0, V, floor_plan, free_points, heard_at, heard_scene

# The plan's range through 1, 2 and 3 walls (5 dB a wall, exponent 3: 30 m / 10^(5k/30)).
THROUGH_M = RC / 10 ** (5.0 * np.arange(1, 4) / 30.0)


def ranges(k: np.ndarray) -> np.ndarray:
    """The range of a link that crosses ``k`` walls (0 beyond the table)."""
    return np.r_[RC, THROUGH_M, 0.0][np.minimum(k, len(THROUGH_M) + 1)]


def boxes_met(walls, p, move, q, e) -> np.ndarray:
    """How many of the walls' boxes the hull of each step from ``p`` to ``p + move`` and
    the disk ``D(q, e)`` meets, as rule 5 counts them."""
    kernel = load("netsim.mobility._local_kernels", 0).boxes_met
    out = np.empty(len(p), np.int64)
    for k, (a, m, c, r) in enumerate(zip(p, move, q, np.broadcast_to(e, (len(p),)))):
        disks = np.array([[a[0], a[1], 0.0], [a[0] + m[0], a[1] + m[1], 0.0], [c[0], c[1], r]])
        out[k] = kernel(walls.rects, disks, 3, walls.clearance_m)
    return out


@pytest.mark.parametrize("occupied", ["office", "floor plan"])
def test_wall_boxes_cover_the_occupied_cells_exactly_once(occupied):
    occ = load_map("office").occupied if occupied == "office" else floor_plan()
    boxes = wall_boxes(occ, (0.0, 0.0), 1.0).astype(int)
    painted = np.zeros(occ.shape, int)
    for x0, x1, y0, y1 in boxes:
        painted[y0:y1, x0:x1] += 1
    assert (painted == occ).all()


def test_walls_a_segment_crosses_no_more_walls_than_the_boxes_its_hull_meets():
    """The count rule 5 reads is an upper bound of what the radio counts (runs of occupied
    cells along the segment, netsim.world.los), and is that count on most segments of the
    office map (a box per straight stretch of wall)."""
    office = load_map("office")
    walls = walls_of(office.occupied, office.origin_m, office.resolution_m, THROUGH_M)
    rng = np.random.default_rng(3)
    rows, cols = np.nonzero(office.free)
    pick = rng.integers(0, len(rows), (3000, 2))
    frac = rng.uniform(0.04, 0.96, (3000, 2, 2))
    res = office.resolution_m
    pts = np.stack([office.origin_m[k] + ((cols, rows)[k][pick] + frac[..., k]) * res for k in (0, 1)], axis=-1)
    p, q = pts[:, 0], pts[:, 1]
    q = p + (q - p) * np.minimum(1.0, 40.0 / np.hypot(*(q - p).T))[:, None]  # links of the radio's reach
    radio = walls_crossed(office, p, q)
    met = boxes_met(walls, p, q - p, p, 0.0)
    assert (met >= radio).all()
    assert (radio > 0).mean() > 0.5 and (met == radio).mean() > 0.8


def test_walls_the_boxes_a_hull_meets_agree_with_the_oracle():
    """The kernel's count of boxes against the oracle's (the hull's distance to each box by
    ternary search), on hulls of a point and a disk across the floor plan's walls."""
    occ = floor_plan()
    walls = walls_of(occ, ORIGIN, RES, THROUGH_M)
    rng = np.random.default_rng(5)
    p = free_points(occ, rng, 400)
    q = free_points(occ, rng, 400)
    q = p + (q - p) * np.minimum(1.0, 25.0 / np.hypot(*(q - p).T))[:, None]
    e = rng.uniform(0.0, 3.0, 400)
    want = oracle.walls_met(walls, p, q, 0.0, e)
    assert (boxes_met(walls, p, np.zeros_like(p), q, e) == want).all()
    assert len(np.unique(want)) >= 4


@pytest.mark.slow
def test_walls_rule_5_through_walls_is_its_definition():
    """Rule 5 through walls (:func:`through_walls`) against its statement, on random steps
    and disks across the floor plan: both ``|p - q| + e`` and ``|p + move - q| + fall``
    within the range through as many walls as the hull of the step and the disk meets, less
    the margin. The cases hold a mix of answers, with ``e`` and ``fall`` apart."""
    occ = floor_plan()
    walls = walls_of(occ, ORIGIN, RES, THROUGH_M)
    rng = np.random.default_rng(11)
    p = free_points(occ, rng, 600)
    q = free_points(occ, rng, 600)
    q = p + (q - p) * np.minimum(1.0, rng.uniform(6.0, 18.0, 600) / np.hypot(*(q - p).T))[:, None]
    move = rng.uniform(-2.0, 2.0, (600, 2))
    e = rng.uniform(0.0, 1.5, 600)
    fall = e + rng.uniform(0.0, 3.0, 600)
    met = boxes_met(walls, p, move, q, e)
    r = np.where(met == 0, -np.inf, ranges(met)) - LIMITS.margin_m
    start = np.hypot(*(p - q).T) + e <= r
    end = np.hypot(*(p + move - q).T) + fall <= r
    assert (through_walls(walls, p, move, q, e, LIMITS, fall) == (start & end)).all()
    assert (start & end).sum() > 100 and (start & ~end).sum() > 10 and len(np.unique(met)) >= 4


def test_walls_rule_5_through_walls_answers_for_a_link_exactly_at_its_range():
    """At the boundary: robot 1 stands 11 m east of robot 0 through one wall, known within
    0.5 m, and the range through one wall is 12.5 m, so with the 1 m margin both ends of
    the step are exactly at the range: answered for. A hair more uncertainty is not."""
    walls = walls_of(floor_plan(), ORIGIN, RES, np.array([12.5]))
    p, q, move = np.array([[8.0, 10.0]]), np.array([[19.0, 10.0]]), np.zeros((1, 2))
    e = np.array([0.5])
    assert boxes_met(walls, p, move, q, e)[0] == 1
    assert 11.0 + e[0] == 12.5 - LIMITS.margin_m
    assert through_walls(walls, p, move, q, e, LIMITS, e)[0]
    assert not through_walls(walls, p, move, q, e, LIMITS, e + 1e-12)[0]
    assert not through_walls(walls, p, move, q, e + 1e-12, LIMITS, e)[0]


def test_walls_a_robot_moves_keeping_a_link_through_a_wall_within_its_range_through_walls():
    """Rule 5 through walls: robot 0 keeps robot 1 in the next room, 11 m east through one
    wall (20 m reach through one). A step along the room keeps every segment to where robot
    1 stands within that wall and 20 m less the margin: it is made; were walls a cut (the
    unit disk), the robot would hold. A step 7 m west would end 18 m off, beyond 20 m less
    the margin (1 m) and robot 1's travel by the step's end (2 m): half of it is made."""
    occ = floor_plan()
    pos = np.array([[8.0, 10.0], [19.0, 10.0]])
    m = heard_at(pos, T0)
    kept = m.known(T0, 20.0)
    t1 = T0 + LIMITS.period_s
    short, long_ = np.array([[0.0, 1.5], [0.0, 0.0]]), np.array([[-7.0, 0.0], [0.0, 0.0]])
    through = walls_of(occ, ORIGIN, RES, THROUGH_M)
    assert cut_for_walls(pos, short, m, kept, t1, LIMITS, through)[0] == pytest.approx([0.0, 1.5])
    assert (cut_for_walls(pos, short, m, kept, t1, LIMITS, walls_of(occ, ORIGIN, RES))[0] == 0).all()
    assert cut_for_walls(pos, long_, m, kept, t1, LIMITS, through)[0] == pytest.approx([-3.5, 0.0])


def test_walls_a_link_through_more_walls_than_the_table_holds_its_robot():
    """A link whose hull meets more walls' boxes than the plan has a range for is not
    answered for: robot 0 keeps robot 1 two rooms east, 17 m off through two walls. With a
    range through two walls of 22 m its short step is made; with a table that stops at one
    wall (however long that range) it holds, rather than take the last range there is."""
    occ = floor_plan()
    pos = np.array([[8.0, 10.0], [25.0, 10.0]])
    m = heard_at(pos, T0)
    kept = m.known(T0, 20.0)
    t1 = T0 + LIMITS.period_s
    move = np.array([[0.0, 1.5], [0.0, 0.0]])
    two = walls_of(occ, ORIGIN, RES, np.array([25.0, 22.0]))
    assert boxes_met(two, pos[:1], move[:1], pos[1:], np.zeros(1))[0] == 2
    assert cut_for_walls(pos, move, m, kept, t1, LIMITS, two)[0] == pytest.approx([0.0, 1.5])
    one = walls_of(occ, ORIGIN, RES, np.array([25.0]))
    assert (cut_for_walls(pos, move, m, kept, t1, LIMITS, one)[0] == 0).all()


def test_walls_a_link_through_a_wall_beyond_its_range_at_the_start_holds_its_robot():
    """Rule 5 through walls answers for the whole step, its start too: robot 0 starts 19.8 m
    from robot 1 through one wall, beyond 20 m less the margin (1 m), and its step would
    end 17.1 m off, within it even with robot 1's travel by the step's end (2 m). Every
    segment from the step's first instants is too long: it holds."""
    occ = floor_plan()
    pos = np.array([[0.55, 10.0], [19.9, 14.0]])
    m = heard_at(pos, T0)
    move = np.array([[2.5, 1.0], [0.0, 0.0]])
    walls = walls_of(occ, ORIGIN, RES, THROUGH_M)
    assert np.hypot(*(pos[0] - pos[1])) > THROUGH_M[0] - LIMITS.margin_m
    assert np.hypot(*(pos[0] + move[0] - pos[1])) + 2.0 < THROUGH_M[0] - LIMITS.margin_m
    assert (cut_for_walls(pos, move, m, m.known(T0, 20.0), T0 + LIMITS.period_s, LIMITS, walls) == 0).all()


def test_detour_through_a_wall_lets_go_of_a_longer_link_through_walls():
    """Rule 1 through walls: robot 0 (room A) and robot 1 (room B, 16 m east through one
    wall) have a detour through robot 2, in room A 6 m from robot 0 and 10 m from robot 1
    through the same wall: robot 0 lets go of robot 1 when walls let power through, and
    keeps it when a wall cuts every link. The kernels agree with the oracle."""
    occ = floor_plan()
    pos = np.array([[2.0, 10.0], [18.0, 10.0], [8.0, 12.0]])
    m = heard_at(pos, T0 - 0.01)
    lists = Lists(3, 1)
    lists.take(m, T0 - 1.0, 20.0)
    heard = lists.heard(m.known(T0, 20.0), m.sent_s, 20.0)
    for through, lets_go in ((THROUGH_M, True), ((), False)):
        walls = walls_of(occ, ORIGIN, RES, through)
        out = let_go(pos, m, heard, T0, V, 7.5, RC, walls)
        assert (out == oracle.let_go(pos, m, heard, T0, V, 7.5, RC, walls)).all()
        assert out[0, 1] == lets_go


@pytest.mark.parametrize("seed", range(4))
def test_walls_a_link_both_ends_keep_stays_up_through_walls_at_every_instant_of_the_step(seed):
    """Rules 1, 5 and 7 through walls, the argument on the floor plan: robots across the rooms
    and the corridor, linked where the radio links them (within the range through the walls
    their segment crosses), each knowing the others within ``v (t0 - s)`` of where it heard
    them and keeping those it knows no certified detour to; the robots that take their turn
    move, each step cut by rule 5. For every link both ends keep, the segment between the
    two robots moving along their steps stays within the range through the walls it crosses
    at every instant (41 instants); and some of those links cross a wall while a robot moves.
    The kernels of rule 1 agree with the oracle."""
    occ = floor_plan()
    office = OccupancyMap(occ, ~occ, RES, ORIGIN)
    walls = walls_of(occ, ORIGIN, RES, THROUGH_M)
    rng = np.random.default_rng(seed)
    n = 40
    pos = free_points(occ, rng, n)
    a, b = np.triu_indices(n, 1)
    up = np.zeros((n, n), bool)
    d = np.hypot(*(pos[a] - pos[b]).T)
    up[a, b] = d <= ranges(walls_crossed(office, pos[a], pos[b])) - 2.0
    heard = up | up.T
    m, held = heard_scene(rng, pos, heard)
    gone = let_go(pos, m, held, T0, V, 7.5, RC, walls)
    assert (gone == oracle.let_go(pos, m, held, T0, V, 7.5, RC, walls)).all()
    kept = heard & ~gone
    wish = rng.normal(0, 2.0, (n, 2)) * turn_takers(kept, rng.permutation(n))[:, None]
    move = cut_for_walls(pos, wish, m, kept, T0 + LIMITS.period_s, LIMITS, walls, office)
    through = 0
    for i, j in zip(*np.nonzero(np.triu(kept & kept.T, 1))):
        if not (move[i] != 0).any() and not (move[j] != 0).any():
            continue
        f = np.linspace(0.0, 1.0, 41)[:, None]
        pi, pj = pos[i] + f * move[i], pos[j] + f * move[j]
        k = walls_crossed(office, pi, pj)
        assert (np.hypot(*(pi - pj).T) <= ranges(k)).all(), (i, j)
        through += bool((k > 0).any())
    assert through >= 1


@pytest.mark.slow
def test_a_local_run_through_walls_spreads_and_never_splits(monkeypatch):
    """The controller's wiring: a local-plan run on the office map at 5 dB a wall, from a
    connected start whose links cross walls, gives rules 1 and 5 the range through walls; its
    robots move while keeping links through walls (where a wall cutting every link held them
    to a metre), and the real network never splits."""
    import netsim.mobility.local as local

    from netsim import config
    from netsim.metrics import components_at_link_events
    from netsim.run import execute
    from netsim.tools.validate import coverage_settings

    certified = []
    through_ = local.through_walls

    def spy(walls, *rest):
        out = through_(walls, *rest)
        certified.append(int(out.sum()))
        return out

    monkeypatch.setattr(local, "through_walls", spy)
    keys = coverage_settings("office, 5 dB a wall", "local", 20, 0.0, 1, 120.0)
    r = execute(config.load(None, [*keys, "world.placement=connected", "world.centre_side_m=60"]))
    assert sum(certified) > 50
    assert r.summary["distance_mean_m"] > 10.0
    links = r.frames["links"]
    _, counts = components_at_link_events(
        *(links[c].to_numpy() for c in ("a", "b", "t_up_s", "t_down_s", "censored_end")), 20
    )
    assert counts.max() == 1
