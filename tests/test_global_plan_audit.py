"""The global plan's rules (docs/model.md section 5, "Staying connected"; mobility/steps.py,
mobility/spread.py, mobility/keep.py, mobility/bridges.py), each checked where the other
tests leave it free: a plan that broke one of them would still pass them."""

from __future__ import annotations

import numpy as np
import pytest
from netsim.mobility.spread import plan_spread
from netsim.mobility.steps import StepLimits, box_limit

from netsim.area import Bounds

RC = 100.0


def test_box_limit_ends_every_step_inside_the_area_to_the_last_bit():
    """A step cut exactly at the border can end an ulp beyond it, by the rounding of
    ``pos + s move``: the cut keeps a hair inside, so that no robot ever leaves the area."""
    # Steps whose exact cut at the border rounds past it.
    pos = np.array([[14.706304965369288, 863.6400902455757], [950.1350121123174, 30.53207158355553]])
    move = np.array([[-46.28471496553606, -22.652982829784406], [-35.750689211548554, -100.09725579335709]])
    s = box_limit(pos, move, Bounds.square(1000.0))
    end = pos + s[:, None] * move
    assert ((end >= 0.0) & (end <= 1000.0)).all()
    assert s == pytest.approx([14.706304965369288 / 46.28471496553606, 30.53207158355553 / 100.09725579335709])


def test_a_robot_whose_kept_neighbour_holds_may_use_the_whole_link():
    """When only one end of a kept link may move, it ends within the link's limit of the
    other, not within half of it: the holding end keeps no half of its own."""
    pos = np.array([[500.0, 500.0], [550.0, 500.0]])
    mobile = np.array([False, True])
    wish = np.array([[0.0, 0.0], [2.0, 0.0]])
    plan = plan_spread(pos, mobile, np.array([-1, 0]), wish, StepLimits(1.0, RC, 1.0, 2.0, 1000.0))
    assert plan.velocity_mps[1] == pytest.approx([2.0, 0.0])
    assert not plan.held[1]


def test_a_step_into_the_border_slides_along_it():
    """The wished end point is brought into the area by projection, not by cutting the
    step where it meets the border: a robot pushed obliquely into a border keeps the part
    of its step along it."""
    pos = np.array([[3.0, 500.0]])
    wish = np.array([[-2.0, 1.0]])
    plan = plan_spread(pos, np.array([True]), np.array([-1]), wish, StepLimits(5.0, RC, 1.0, 2.0, 1000.0))
    end = pos + plan.velocity_mps * 5.0
    # The wish is capped to the reach before the projection.
    assert end[0] == pytest.approx([0.0, 500.0 + 10.0 / np.sqrt(5.0)], abs=1e-6)


def test_robots_at_one_spot_keep_their_link():
    """Two robots at the very same spot are linked (length 0): the forest keeps that link
    like any other, so pushed apart over a long step they still end within range."""
    pos = np.array([[500.0, 500.0], [500.0, 500.0]])
    wish = np.array([[-2.0, 0.0], [2.0, 0.0]])
    limits = StepLimits(40.0, RC, 1.0, 2.0, 1000.0)  # each reach beyond half the range: unkept, the link breaks
    plan = plan_spread(pos, np.array([True, True]), np.array([-1, -1]), wish, limits)
    assert plan.bridges == 1
    end = pos + plan.velocity_mps * limits.period_s
    assert np.hypot(*(end[1] - end[0])) <= RC - 1.0
    assert plan.velocity_mps[:, 0] == pytest.approx([-49.5 / 40.0, 49.5 / 40.0], rel=1e-6)


def test_a_link_longer_than_its_keep_pulls_no_robot_that_stays():
    """A kept link already longer than its keep length has no slack, not a negative one:
    robots that wish to stay are pulled by nothing and hold."""
    pos = np.array([[500.0, 500.0], [599.5, 500.0]])
    plan = plan_spread(
        pos, np.array([True, True]), np.array([-1, -1]), np.zeros((2, 2)), StepLimits(1.0, RC, 1.0, 2.0, 1000.0)
    )
    assert (plan.velocity_mps == 0.0).all()


def test_a_member_that_does_not_move_needs_no_command():
    """Only a robot that moves needs its leader's command: a member the plan leaves still
    names no commander, so its leader sends it nothing and a miss is not counted."""
    pos = np.array([[500.0, 500.0], [550.0, 500.0]])
    wish = np.array([[0.0, 0.0], [0.0, 0.0]])
    plan = plan_spread(pos, np.array([True, True]), np.array([-1, 0]), wish, StepLimits(1.0, RC, 1.0, 2.0, 1000.0))
    assert plan.commander.tolist() == [-1, -1]
    moved = plan_spread(
        pos, np.array([True, True]), np.array([-1, 0]), wish + [0.0, 1.0], StepLimits(1.0, RC, 1.0, 2.0, 1000.0)
    )
    assert moved.commander.tolist() == [-1, 0]


def test_a_robot_capped_by_its_speed_alone_is_not_held():
    """The speed cap shortens a wish before the plan: a robot that moves at the cap, no
    link or border in its way, was not held (the control table counts holds for
    connectivity and the border)."""
    pos = np.array([[500.0, 500.0]])
    plan = plan_spread(
        pos, np.array([True]), np.array([-1]), np.array([[5.0, 0.0]]), StepLimits(1.0, RC, 1.0, 2.0, 1000.0)
    )
    assert plan.velocity_mps[0] == pytest.approx([2.0, 0.0])
    assert not plan.held[0]


def test_the_radio_rules_keep_a_link_of_length_zero_too():
    """On the disk, a link between robots at one spot weighs more than nothing, so the
    forest keeps it (a sparse graph drops a weight of zero as no edge)."""
    from types import SimpleNamespace

    from netsim.mobility.keep import LinkRules
    from netsim.mobility.spread import forest_rows

    pos = np.array([[500.0, 500.0], [500.0, 500.0]])
    robots = SimpleNamespace(n=2, range_m=np.full(2, RC))
    links = LinkRules(None, robots, None, 1.0, 8.0).candidates(pos, 0.0)
    assert (links.weight > 0).all()
    assert forest_rows(2, links).tolist() == [0]


def test_a_favourable_link_within_the_sure_distance_keeps_its_longer_fade_limit():
    """A short link with favourable shadowing may grow past the sure distance while its
    fade budget lasts: it is kept as a disk link only where that would not shorten it."""
    from netsim.radio.propagation import effective_range_m
    from tests.test_coverage_radio import shadowed_rules

    pos = np.array([[0.0, 0.0], [20.0, 0.0]])
    rules, params = shadowed_rules(pos, x_db=[-10.0], anchor_m=[0.0], travelled_m=[0.0, 0.0])
    c = rules.candidates(pos, 0.0)
    sure = float(effective_range_m(params, 16.0))
    longer = float(effective_range_m(params, -10.0 + 8.0))
    assert 20.0 < sure - 1.0 < longer
    assert c.keep_m[0] == pytest.approx(longer)
    assert np.isfinite(c.travel_m[0])


def test_a_sure_link_withstands_the_worst_shadowing_and_ranks_by_its_margin_alone():
    """A link within the sure distance is kept with no bound on travel, so what it must
    withstand at every instant (walls swept on a map) is the worst clipped shadowing, and
    the travel since its shadowing was measured does not weaken it in the forest's eyes."""
    from netsim.radio.propagation import effective_range_m
    from tests.test_coverage_radio import shadowed_rules

    pos = np.array([[0.0, 0.0], [20.0, 0.0], [0.0, 20.0]])
    rules, params = shadowed_rules(pos, x_db=[12.0, 12.0], anchor_m=[0.0, 0.0], travelled_m=[0.0, 0.0, 3.0])
    c = rules.candidates(pos, 0.0)
    assert np.isinf(c.travel_m).all()
    assert c.reserve_db.tolist() == [16.0, 16.0]
    assert c.range_m == pytest.approx([float(effective_range_m(params, 16.0))] * 2)
    assert c.weight[0] == c.weight[1]


def test_a_pair_whose_shadowing_was_never_measured_is_no_candidate():
    """Only links the channel brought up are kept: a pair with no measured shadowing is
    left out, however near (its unknown shadowing is not taken as the worst one)."""
    from tests.test_coverage_radio import shadowed_rules

    pos = np.array([[0.0, 0.0], [10.0, 0.0], [0.0, 10.0]])
    rules, _ = shadowed_rules(pos, x_db=[np.nan, 0.0], anchor_m=[0.0, 0.0], travelled_m=[0.0, 0.0, 0.0])
    c = rules.candidates(pos, 0.0)
    assert list(zip(c.i.tolist(), c.j.tolist())) == [(0, 2)]


def test_on_a_map_without_shadowing_a_link_keeps_the_margin_inside_its_range():
    """Under wall loss without shadowing a kept link ends the step at most its range
    (with the walls crossed now) less margin_m, as on the disk."""
    from types import SimpleNamespace

    from netsim.mobility.keep import LinkRules

    from netsim.radio.propagation import LogDistanceParams, effective_range_m
    from netsim.world.maps import OccupancyMap

    params = LogDistanceParams()
    free = np.zeros((80, 80), bool)
    m = OccupancyMap(free, ~free, 0.5, (0.0, 0.0))
    compiled = SimpleNamespace(log=SimpleNamespace(params=params), shadow=None, walls=SimpleNamespace(wall_loss_db=5.0))
    robots = SimpleNamespace(n=2, range_m=np.full(2, RC))
    rules = LinkRules(SimpleNamespace(compiled=compiled, map=m), robots, None, 1.0, 8.0)
    pos = np.array([[5.0, 20.0], [25.0, 20.0]])
    c = rules.candidates(pos, 0.0)
    assert list(zip(c.i.tolist(), c.j.tolist())) == [(0, 1)]
    assert c.keep_m[0] == pytest.approx(float(effective_range_m(params, 0.0)) - 1.0)


def wall_loss_rules(blocks, side_m=200.0, resolution_m=0.5):
    """LinkRules of log-distance path loss with 5 dB per wall, no shadowing, on a map whose
    occupied cells are the rectangles ``blocks`` ((x0, x1, y0, y1), metres)."""
    from types import SimpleNamespace

    from netsim.mobility.keep import LinkRules

    from netsim.radio.propagation import LogDistanceParams
    from netsim.world.maps import OccupancyMap

    params = LogDistanceParams(wall_loss_db=5.0)
    cells = int(side_m / resolution_m)
    occupied = np.zeros((cells, cells), bool)
    for x0, x1, y0, y1 in blocks:
        occupied[int(y0 / resolution_m) : int(y1 / resolution_m), int(x0 / resolution_m) : int(x1 / resolution_m)] = (
            True
        )
    m = OccupancyMap(occupied, ~occupied, resolution_m, (0.0, 0.0))
    compiled = SimpleNamespace(log=SimpleNamespace(params=params), shadow=None, walls=SimpleNamespace(wall_loss_db=5.0))
    robots = SimpleNamespace(n=2, range_m=np.full(2, RC))
    return LinkRules(SimpleNamespace(compiled=compiled, map=m), robots, None, 1.0, 8.0), m, params


def test_a_link_is_lost_where_a_wall_comes_between_robots_still_too_far_for_it():
    """A wall that comes between two robots cuts the link's range at that instant: the
    link is lost there if they are then farther apart than the range through the wall,
    even though they are within it by the time the wall has passed."""
    from netsim.mobility.steps import Candidates

    from netsim.radio.propagation import effective_range_m
    from netsim.world.los import walls_crossed

    rules, m, params = wall_loss_rules([(30.0, 32.0, 103.5, 104.0)])
    pos = np.array([[20.0, 100.0], [100.0, 140.0]])
    move = np.array([[0.0, 0.0], [-40.0, -40.0]])
    d = np.array([float(np.hypot(*(pos[1] - pos[0])))])
    link = Candidates(
        np.array([0]), np.array([1]), d, d, np.array([99.0]), np.array([np.inf]), np.array([RC]), np.zeros(1)
    )
    scale = rules.cut_for_walls(pos, move, np.array([False, False]), link, np.array([0]), 1.0)
    assert scale[0] == 1.0 and 0.0 < scale[1] < 0.5
    t = np.linspace(0.0, 1.0, 2001)[:, None]
    b = pos[1] + move[1] * scale[1] * t
    walls = walls_crossed(m, np.broadcast_to(pos[0], b.shape), b)
    assert (np.hypot(*(b - pos[0]).T) <= effective_range_m(params, 0.0, walls)).all()
    uncut = pos[1] + move[1] * t
    uncut_walls = walls_crossed(m, np.broadcast_to(pos[0], uncut.shape), uncut)
    assert not (np.hypot(*(uncut - pos[0]).T) <= effective_range_m(params, 0.0, uncut_walls)).all()


def test_a_robot_that_misses_its_command_is_not_cut_for_the_partner_it_waits_for():
    """When a commanded robot holds (a missed command) and the link would be lost, only
    the robot that still moves is cut: the holding one's own step is not what breaks it."""
    from tests.test_coverage_radio import one_link, wall_rules

    rules, _ = wall_rules([(9.5, 10.0, 8.5, 9.0)])
    pos = np.array([[0.0, 10.0], [20.0, 10.0]])
    move = np.array([[0.0, 3.0], [0.0, -3.0]])
    scale = rules.cut_for_walls(pos, move, np.array([True, False]), one_link(pos), np.array([0]), 1.0)
    assert scale[0] == 1.0 and scale[1] < 1.0


def test_a_shadowed_link_withstands_its_measured_shadowing_plus_its_budget():
    """What a kept link must withstand at every instant (walls swept on a map) is its
    measured shadowing plus its budget, and its range is the distance at which that
    leaves the link up."""
    from netsim.radio.propagation import effective_range_m
    from tests.test_coverage_radio import shadowed_rules

    pos = np.array([[0.0, 0.0], [40.0, 0.0]])
    rules, params = shadowed_rules(pos, x_db=[2.0], anchor_m=[5.0], travelled_m=[3.0, 2.5])
    c = rules.candidates(pos, 0.0)
    assert c.reserve_db[0] == pytest.approx(2.0 + 8.0)
    assert c.range_m[0] == pytest.approx(float(effective_range_m(params, 10.0)))


def test_on_a_map_a_pair_of_long_range_robots_is_a_candidate_beyond_the_shortest_range():
    """With unequal ranges a link joins robots up to the smaller of their two ranges apart:
    two robots of the longer range, farther apart than the shortest range, are linked."""
    from types import SimpleNamespace

    from netsim.mobility.keep import LinkRules

    from netsim.world.maps import OccupancyMap

    free = np.zeros((200, 200), bool)
    m = OccupancyMap(free, ~free, 0.5, (0.0, 0.0))
    compiled = SimpleNamespace(log=None, shadow=None, walls=None)
    robots = SimpleNamespace(n=3, range_m=np.array([30.0, 50.0, 50.0]))
    rules = LinkRules(SimpleNamespace(compiled=compiled, map=m), robots, None, 1.0, 8.0)
    pos = np.array([[10.0, 10.0], [20.0, 50.0], [60.0, 50.0]])
    c = rules.candidates(pos, 0.0)
    assert list(zip(c.i.tolist(), c.j.tolist())) == [(1, 2)]
    assert c.keep_m[0] == 49.0


def test_a_missed_command_at_either_end_of_a_link_is_checked():
    """The second robot of a link may miss its command as well as the first: the step is
    cut so that the link keeps line of sight while it holds and its partner moves."""
    from tests.test_coverage_radio import line_of_sight_throughout, one_link, wall_rules

    rules, m = wall_rules([(9.5, 10.0, 8.5, 9.0)])
    pos = np.array([[20.0, 10.0], [0.0, 10.0]])
    move = np.array([[0.0, -3.0], [0.0, 3.0]])
    held_second = move * [[1.0], [0.0]]
    assert line_of_sight_throughout(m, pos, move)
    assert not line_of_sight_throughout(m, pos, held_second)
    scale = rules.cut_for_walls(pos, move, np.array([False, True]), one_link(pos), np.array([0]), 1.0)
    assert scale[0] < 1.0 and scale[1] == 1.0
    assert line_of_sight_throughout(m, pos, move * scale[:, None] * [[1.0], [0.0]])


def test_follow_a_member_out_of_its_leaders_range_holds():
    """In follow mode a member moves only on its leader's command, which it hears only in
    range: one cut off from its leader holds while the leader moves."""
    from netsim.mobility.bridges import plan_follow

    pos = np.array([[500.0, 500.0], [650.0, 500.0]])
    plan = plan_follow(pos, np.array([0, 0]), np.array([[1.0, 0.0], [0.0, 0.0]]), StepLimits(1.0, RC, 1.0, 2.0, 1000.0))
    assert plan.velocity_mps.tolist() == [[1.0, 0.0], [0.0, 0.0]]
    assert plan.commander.tolist() == [-1, -1]


def test_cuts_for_walls_compound_over_rounds_so_a_chain_moves_part_of_its_step():
    """A cut for one link can make the next link of a chain fail: the next round cuts the
    already shortened step further (a fraction of it), so the rounds converge and every
    robot keeps part of its step instead of running out of rounds and holding."""
    from types import SimpleNamespace

    from netsim.mobility.steps import Candidates

    from tests.test_coverage_radio import line_of_sight_throughout, wall_rules

    rules, m = wall_rules([(9.0, 11.0, 10.0, 12.0), (24.0, 26.0, 20.0, 22.0), (15.0, 17.0, 30.0, 31.0)])
    rules.state = SimpleNamespace(n=3, range_m=np.full(3, 30.0))
    pos = np.array(
        [
            [15.062367424949942, 11.981595329829393],
            [12.308138513407732, 36.56534584897861],
            [17.59104661683086, 31.139310680608354],
        ]
    )
    move = np.array(
        [
            [-2.2323074875075894, -2.0213667961056054],
            [11.50712701362459, -5.890916178451385],
            [-1.6896342565095768, -1.498139721093692],
        ]
    )
    i, j = np.array([0, 1]), np.array([1, 2])
    d = np.hypot(*(pos[i] - pos[j]).T)
    links = Candidates(i, j, d, d, np.full(2, 29.0), np.full(2, np.inf), np.full(2, 30.0))
    scale = rules.cut_for_walls(pos, move, np.zeros(3, bool), links, np.array([0, 1]), 1.0)
    assert (scale > 0.0).all() and (scale < 1.0).all()
    cut = move * scale[:, None]
    for a, b in zip(i, j):
        assert line_of_sight_throughout(m, pos[[a, b]], cut[[a, b]])
        assert np.hypot(*(pos[b] + cut[b] - pos[a] - cut[a])) <= 30.0


def test_follow_a_leader_is_not_held_back_by_its_bridging_gateway_at_the_border():
    """A bridging gateway rides toward its leaders rather than with its group, so the
    border it stands at does not shorten its leader's step as a rigid member's would."""
    from netsim.mobility.bridges import plan_follow

    pos = np.array([[500.0, 950.0], [580.0, 999.5], [660.0, 950.0]])
    wish = np.array([[0.0, 2.0], [0.0, 0.0], [0.0, 0.0]])
    plan = plan_follow(pos, np.array([0, 0, 2]), wish, StepLimits(1.0, RC, 1.0, 2.0, 1000.0))
    assert plan.bridges == 1
    assert plan.velocity_mps[0] == pytest.approx([0.0, 2.0])
    assert not plan.held[0]
    assert plan.velocity_mps[1, 1] < 0.0
