"""The local plan's rules at the edges the other local-plan tests leave open (docs/model.md
section 5.1; mobility/local.py): a robot already outside a leash, what a robot keeps of an
Ack it hears again, the measurement's times, the fade limits without a useful measurement,
the halves only where a robot cannot answer alone, the records and the lists' steps, and
rule 5's shorter steps and slides."""

from __future__ import annotations

import numpy as np
import pytest
from netsim.mobility.keep import FADE_SIGMAS, fade_travel_m
from netsim.mobility.local import (
    Fade,
    Halves,
    Lists,
    Memory,
    answered_by_halves,
    cut_for_walls,
    leash_radius,
    let_go,
    link_records,
    plan_local,
    silence_of,
    walls_of,
)
from netsim.mobility.steps import StepLimits

from netsim.radio.propagation import LogDistanceParams
from netsim.world.maps import OccupancyMap
from tests.test_coverage_local_fade import heard_over_steps, measured_memory, measured_pair
from tests.test_coverage_local_map import LIMITS as MAP_LIMITS
from tests.test_coverage_local_map import ORIGIN, RES, floor_plan, heard_at

RC = 100.0
V = 2.0
LIMITS = StepLimits(period_s=1.0, range_m=RC, margin_m=1.0, speed_max_mps=V, side_m=2000.0)
T0 = 10.0

RADIO = LogDistanceParams(shadowing_sigma_db=4.0)
SIGMA, DCORR, FADE_DB = 4.0, 10.0, 8.0
SURE = float(RADIO.effective_range_m(4.0 * SIGMA))


def all_heard(pos, sent):
    n = len(pos)
    m = Memory(n)
    m.xy[:] = np.broadcast_to(pos[None, :, :], (n, n, 2))
    m.sent_s[:] = float(sent)
    np.fill_diagonal(m.sent_s, -np.inf)
    return m


def fade() -> Fade:
    return Fade(RADIO, SIGMA, DCORR, FADE_DB, SURE, 1.0, 1.0, 3, FADE_SIGMAS)


def ends_within_leashes(pos, plan, m, kept, limits=LIMITS):
    """For each robot that moves: whether its step ends inside every leash it keeps at t1."""
    end = pos + plan.velocity_mps * limits.period_s
    radius = leash_radius(m, T0 + limits.period_s, limits)
    d = np.hypot(*(end[:, None, :] - m.xy).transpose(2, 0, 1))
    moved = np.hypot(*plan.velocity_mps.T) > 0
    return ~moved | ~(kept & (d > radius)).any(axis=1)


# -- rule 2: a robot already outside a leash ----------------------------------------------


def test_leash_a_robot_outside_its_leash_at_t1_but_within_it_now_steps_back_inside():
    """A robot within what it answers for now but beyond its leash at t1 may still move: it
    must end inside the leash, and a step toward the kept robot does."""
    pos = np.array([[0.0, 0.0], [97.5, 0.0]])
    m = all_heard(pos, T0 - 0.1)  # beyond robot 0's leash at t1, within what it answers for now
    kept = m.known(T0, 20.0)
    plan = plan_local(pos, np.array([[2.0, 0.0], [0.0, 0.0]]), m, kept, T0, LIMITS)
    assert plan.velocity_mps[0].tolist() == pytest.approx([2.0, 0.0])
    assert not plan.held[0]
    assert ends_within_leashes(pos, plan, m, kept).all()


def test_leash_a_robot_outside_two_leashes_no_step_can_meet_holds():
    """Two kept robots on either side whose leashes at t1 leave no room between them: a robot
    already outside both cannot end inside both, so it holds rather than end outside one."""
    pos = np.array([[0.0, 0.0], [-97.5, 0.0], [97.5, 0.0]])
    m = all_heard(pos, T0 - 0.1)
    m.sent_s[1, 2] = m.sent_s[2, 1] = -np.inf  # out of range of each other
    kept = m.known(T0, 20.0)
    for wish in ([0.0, 2.0], [2.0, 0.0], [-2.0, 1.0]):
        plan = plan_local(pos, np.array([wish, [0.0, 0.0], [0.0, 0.0]]), m, kept, T0, LIMITS)
        assert (plan.velocity_mps[0] == 0).all() and plan.held[0], wish
        assert ends_within_leashes(pos, plan, m, kept).all()


# -- rule 3: hold, as the plan reports it -------------------------------------------------


def test_hold_a_robot_whose_reach_is_zero_holds_and_one_that_wishes_nothing_is_not_held():
    """A robot left no reach holds (and is counted held when it wished to move); a robot that
    cannot answer for a link but wishes nothing is not counted held: it did not want to go."""
    pos = np.array([[0.0, 0.0], [50.0, 0.0]])
    m = all_heard(pos, T0 - 0.1)
    kept = m.known(T0, 20.0)
    wish = np.array([[0.0, 2.0], [0.0, 2.0]])
    plan = plan_local(pos, wish, m, kept, T0, LIMITS, np.array([0.0, 2.0]))
    assert (plan.velocity_mps[0] == 0).all() and plan.held[0]
    assert plan.velocity_mps[1, 1] > 0 and not plan.held[1]
    far = np.array([[0.0, 0.0], [96.0, 0.0]])
    m = all_heard(far, T0 - 0.1)
    m.sent_s[0, 1] = T0 - 3.0  # robot 0 can no longer answer for the link now
    plan = plan_local(far, np.zeros((2, 2)), m, m.known(T0, 20.0), T0, LIMITS)
    assert not plan.held.any()


# -- what a robot knows ------------------------------------------------------------------


def test_knowledge_an_ack_heard_again_at_a_later_step_changes_nothing():
    """A robot keeps the latest Ack it heard of each robot: the same Ack, still in its table at
    the next step (its sender has since started a new leg), leaves what it learnt of that
    Ack as it was: the leg's velocity, which held until the step after the Ack, and the
    shadowing measured when it was first heard."""
    m = Memory(2)
    vel = np.array([[0.0, 0.0], [1.0, 0.0]])
    robot, other, xy = np.array([0]), np.array([1]), np.array([[10.0, 0.0]])
    heard = np.array([9.5])
    m.hear(robot, other, xy, heard, 0.1, vel, np.array([9.0, 9.0]), 10.1, np.array([2.0]), np.array([6.0]))
    m.hear(robot, other, xy, heard, 0.1, vel * 3, np.array([10.1, 10.1]), 11.1, np.array([5.0]), np.array([1.0]))
    assert m.until_s[0, 1] == 10.1
    assert m.leg_velocity_mps[0, 1].tolist() == [1.0, 0.0] and m.leg_from_s[0, 1] == 9.0
    assert m.vel[0, 1].tolist() == [1.0, 0.0]
    assert m.x_db[0, 1] == 2.0 and m.margin_db[0, 1] == 6.0


def test_fade_a_measurement_dates_from_the_earliest_its_ack_can_have_been_sent():
    """The travel since a measurement counts from the earliest time its Ack can have been sent
    (its reception less the channel's largest delay): a later time would count less travel
    than the pair can have made."""
    m = Memory(2)
    m.hear(np.array([0]), np.array([1]), np.array([[10.0, 0.0]]), np.array([9.5]), 0.3, x_db=np.array([1.0]))
    assert m.measured_s[0, 1] == pytest.approx(9.2)
    assert m.measured_s[0, 1] == m.sent_s[0, 1]


# -- rules 2 and 3 with a measurement ------------------------------------------------------


def test_fade_a_measurement_no_longer_than_the_sure_distance_keeps_the_link_as_without_one():
    """Where the measured shadowing gives a length R no longer than the sure distance, the
    link is answered for as without a measurement: within the sure distance, no bound on
    travel."""
    f = fade()
    m = measured_pair(20.0, 14.0, T0 - 0.5)
    margin = float(m.margin_db[0, 1])
    assert 0.0 < margin < FADE_DB
    assert float(RADIO.effective_range_m(14.0 + margin)) < SURE
    keep, travel = f.limits(m, T0, T0 + 1.0, f.speed_mps)
    assert keep[0, 1] == SURE - 1.0 and travel[0, 1] == np.inf


def test_fade_the_travel_limit_counts_the_robots_own_leg_since_the_measurement():
    """A robot's own travel since a measurement is its leg's speed over the leg (the cap
    before it): the faster its own leg, the shorter the step the link leaves it."""
    f = fade()
    v = f.speed_mps
    steps = []
    for own in (0.0, v):
        m = measured_pair(45.0, 0.0, T0 - 1.5)
        m.leg_velocity_mps[:] = 0.0
        m.leg_from_s[:] = T0 - 5.0
        m.leg_velocity_mps[0, 0] = (own, 0.0)
        m.leg_from_s[0, 0] = T0 - 1.0
        _, travel = f.limits(m, T0, T0 + 1.0, v)
        steps.append(travel[0, 1])
    allowed = float(fade_travel_m(np.array([FADE_DB]), np.zeros(1), SIGMA, DCORR)[0])
    assert steps[0] == pytest.approx(allowed - v * 0.5 - v * 1.0, rel=1e-9)
    assert steps[0] - steps[1] == pytest.approx(v * 1.0, rel=1e-9)


# -- rule 2 by halves ---------------------------------------------------------------------


def test_halves_a_robot_that_can_answer_alone_for_a_link_does_not_take_its_half():
    """Halves are for a link a robot cannot answer for alone (rule 3): within its leash it
    keeps the link by its leash, whatever the halves would allow."""
    pos = np.array([[0.0, 0.0], [50.0, 0.0]])
    m = all_heard(pos, T0 - 0.1)
    kept = m.known(T0, 20.0)
    n = len(pos)
    halves = Halves(np.ones((n, n), bool), np.full((n, n, 2), 25.0), np.full((n, n), 30.0), np.full((n, n), 1.0))
    assert not answered_by_halves(pos, m, kept, T0, LIMITS, halves).any()
    m.sent_s[0, 1] = T0 - 30.0  # robot 0 can no longer answer for it now
    assert answered_by_halves(pos, m, kept, T0, LIMITS, halves).tolist() == [[False, True], [False, False]]


def test_halves_the_larger_id_reads_the_record_only_in_the_smaller_ids_list_of_the_latest_step():
    """Both ends of a link must read the same record: the larger id reads the smaller id's
    list of the latest step, and only when the latest Ack it heard carried that list; from an
    older list of it, it reads no record."""
    m = Memory(2)
    m.xy[0, 1], m.xy[1, 0] = (45.0, 0.0), (0.0, 0.0)
    m.sent_s[0, 1] = m.sent_s[1, 0] = T0 - 2.5
    m.x_db[0, 1], m.x_db[1, 0] = 6.0, 5.0
    lists = Lists(2, 3)
    lists.take(m, T0 - 2.0, 20.0)
    m.x_db[0, 1] = 7.0
    lists.take(m, T0 - 1.0, 20.0)
    # Robot 1 heard robot 0 last between the two steps: it holds robot 0's older list.
    sent = m.sent_s.copy()
    sent[1, 0] = T0 - 1.5
    held = lists.heard(m.known(T0, 20.0), sent, 20.0)
    assert held.which[1, 0] == 0
    x, since = link_records(held, 2)
    assert x[0, 1] == 7.0
    assert np.isnan(x[1, 0]) and since[1, 0] == -np.inf
    sent[1, 0] = T0 - 0.5
    x, _ = link_records(lists.heard(m.known(T0, 20.0), sent, 20.0), 2)
    assert x[1, 0] == 7.0


# -- the lists ----------------------------------------------------------------------------


def test_lists_an_ack_sent_as_a_list_was_taken_carries_the_list_of_the_step_before():
    """An Ack that can have been sent at the very instant of a step carries, for sure, only the
    list of the step strictly before it."""
    m = Memory(2)
    m.sent_s[0, 1] = m.sent_s[1, 0] = 0.5
    lists = Lists(2, 4)
    for t in (1.0, 2.0, 3.0):
        lists.take(m, t, 20.0)
    sent = np.array([[-np.inf, 2.0], [2.0 + 1e-9, -np.inf]])
    held = lists.heard(m.known(3.5, 20.0), sent, 20.0)
    assert held.which[0, 1] == 0 and held.which[1, 0] == 1


def test_lists_the_lists_a_robot_held_are_named_by_their_steps_once_old_lists_are_dropped():
    """The holdings an Ack carries name each list by its step, also once the oldest lists have
    been dropped (and name none where the list held is no longer kept): a robot two hops out
    is read from the list its neighbour truly held."""
    n = 3
    m = Memory(n)
    m.sent_s[:] = 0.5
    np.fill_diagonal(m.sent_s, -np.inf)
    depth = 2
    lists = Lists(n, depth)
    for step in range(5):
        # Robot 0 last heard robot 2 just after the step before this one.
        m.sent_s[0, 2] = step - 1 + 0.5 if step else 0.5
        lists.take(m, float(step), 20.0)
    held = lists.heard(m.known(5.0, 20.0), m.sent_s, 20.0)
    ring = len(held.held)
    assert held.held[4 % ring, 0, 2] == 3
    assert held.held[3 % ring, 0, 2] == 2
    # Robot 1's latest Ack robot 0 heard is older than every list still kept: it names none.
    assert held.held[4 % ring, 0, 1] == -1
    assert set(held.steps.tolist()) == {3, 4}


# -- rule 5: a shorter step still ends inside the leashes ---------------------------------


def test_walls_a_shorter_step_is_taken_only_if_it_ends_inside_the_leashes():
    """A robot outside a leash at t1 whose step back inside meets a wall near another kept
    robot may not take a part of the step that clears the wall but ends outside the leash:
    it holds."""
    pos = np.array([[10.0, 10.0], [108.7, 10.0], [12.0, 20.0]])
    m = all_heard(pos, T0 - 0.1)  # robot 1 is beyond robot 0's leash at t1
    m.sent_s[1, 2] = m.sent_s[2, 1] = -np.inf
    kept = m.known(T0, 20.0)
    move = np.array([[2.0, 0.0], [0.0, 0.0], [0.0, 0.0]])
    occupied = np.zeros((60, 240), bool)
    open_map = walls_of(occupied, (0.0, 0.0), 0.5)
    out = cut_for_walls(pos, move, m, kept, T0 + 1.0, LIMITS, open_map)
    assert out[0].tolist() == [2.0, 0.0]
    # A wall cell beside the far end of the step, inside the hull of the whole step and of
    # robot 2's disk, outside that of half the step.
    occupied[24, 23] = True
    walled = walls_of(occupied, (0.0, 0.0), 0.5)
    out = cut_for_walls(pos, move, m, kept, T0 + 1.0, LIMITS, walled)
    assert (out[0] == 0).all()


def test_walls_a_robot_tries_an_eighth_of_its_step_before_it_holds():
    """Rule 5 tries the whole step, half, a quarter and an eighth of it: a wall beside the
    link that only an eighth of the step keeps clear of still lets the robot make that
    eighth."""
    pos = np.array([[10.0, 10.0], [12.0, 20.0]])
    m = all_heard(pos, T0 - 0.1)
    kept = m.known(T0, 20.0)
    move = np.array([[2.0, 0.0], [0.0, 0.0]])
    occupied = np.zeros((300, 1200), bool)
    occupied[119, 108] = True  # off the hull of an eighth of the step alone
    out = cut_for_walls(pos, move, m, kept, T0 + 1.0, LIMITS, walls_of(occupied, (0.0, 0.0), 0.1))
    assert out[0].tolist() == [0.25, 0.0]


# -- shadowing: the measurement and the records -------------------------------------------


def test_shadowing_a_robot_that_may_have_moved_past_the_sender_measures_as_at_no_distance():
    """Where the robot's own motion since the Ack can exceed the distance it measures, the
    shortest the distance can have been is none: X as at zero distance, the largest it can
    be, never one read at a longer distance."""
    f = fade()
    sender = np.array([[100.0, 100.0]])
    power = np.array([-30.0])
    at_sender, _ = f.measure(sender, sender, power, np.array([0.0]), 0.0, 0.5)
    near = sender + np.array([[1.0, 0.0]])
    x, _ = f.measure(near, sender, power, np.array([-10.0]), 0.0, 0.5)  # may have passed the sender since
    assert x[0] == at_sender[0]


def test_lists_a_record_is_the_shadowing_measured_on_a_robot_remembered_at_the_epoch():
    """A robot's records of an epoch are the shadowing it measured on the robots it
    remembered then: a measurement kept of a robot it has forgotten is no record."""
    m = Memory(2)
    m.sent_s[0, 1] = m.sent_s[1, 0] = 0.5
    m.x_db[0, 1], m.x_db[1, 0] = 3.0, 4.0
    m.sent_s[0, 1] = -30.0  # robot 0 forgot robot 1
    lists = Lists(2, 4)
    for t in (1.0, 2.0, 3.0):
        lists.take(m, t, 20.0)
    held = lists.heard(m.known(3.5, 20.0), m.sent_s, 20.0)
    assert held.records_from == 0
    assert np.isnan(held.records_db[0, 1]) and held.records_db[1, 0] == 4.0


def test_hold_a_robot_that_wishes_nothing_stays_where_it_is_even_outside_a_leash():
    """A robot that wishes no motion makes none, though it stands outside a leash at t1: a
    robot that holds answers for nothing, the other end keeps the link."""
    pos = np.array([[0.0, 0.0], [97.5, 0.0]])
    m = all_heard(pos, T0 - 0.1)
    kept = m.known(T0, 20.0)
    plan = plan_local(pos, np.zeros((2, 2)), m, kept, T0, LIMITS)
    assert (plan.velocity_mps == 0).all() and not plan.held.any()


def test_walls_a_slide_toward_a_wall_is_ended_short_of_it_and_then_tested():
    """A slide is ended short of the walls before rule 5 tests it: a robot near the corridor's
    far wall, sliding up the corridor, goes as far as the wall lets it, not only the fraction
    of the unshortened slide that stays off the wall."""
    occ = floor_plan()
    pos = np.array([[15.55, 30.8], [14.75, 20.0]])  # just below the corridor's far wall
    m = heard_at(pos, T0)
    kept = m.known(T0, 20.0)
    move = np.array([[1.6, 1.0], [0.0, 0.0]])
    occupancy = OccupancyMap(occ, ~occ, RES, ORIGIN)
    slid = cut_for_walls(pos, move, m, kept, T0 + 1.0, MAP_LIMITS, walls_of(occ, ORIGIN, RES), occupancy)
    assert slid[0] == pytest.approx([0.0, 0.7], abs=1e-5)
    assert (slid[1] == 0).all()


# -- rule 1 under shadowing ---------------------------------------------------------------


def measured_line(x_db: float = 6.0, at_m: float = 42.7):
    """Robots 0, 2 and 1 on a line (0 at the origin, 2 at ``at_m``, 1 at 60 m), each having
    heard the others in Acks sent 0.2 s before t0, all at the speed cap since before the
    window, every link measured at ``x_db``: the detour of the link 0-1 is 0-2 and 2-1.
    Returns the positions, the memory, what the robots hold and the rule."""
    f = fade()
    pos = np.array([[0.0, 0.0], [60.0, 0.0], [at_m, 0.0]])
    m = measured_memory(pos, x_db, T0 - 0.2)
    m.leg_velocity_mps[:] = (f.speed_mps, 0.0)
    m.leg_from_s[:] = T0 - 5.0
    return pos, m, heard_over_steps(m), f


def test_detour_a_robots_own_measured_link_counts_the_pair_travel_from_the_windows_start():
    """Over the release's window, the robot's own measured link of a detour is certified over
    the pair's travel from the window's start, as the links the lists report are: a link
    beyond the sure distance that stays up over the travel since the measurement but not
    over the travel since the window opened is no detour's link."""
    pos, m, held, f = measured_line()
    v = f.speed_mps
    window = silence_of(1.0, 0.05, 0.001, 0.0).window_s
    assert np.hypot(*(pos[2] - pos[1])) < SURE < np.hypot(*(pos[2] - pos[0]))
    assert let_go(pos, m, held, T0, v, 7.5, SURE, fade=f)[0, 1]
    assert not let_go(pos, m, held, T0, v, 7.5, SURE, fade=f, window_s=window)[0, 1]


def test_detour_a_link_within_the_sure_distance_counts_whatever_its_measurement_allows():
    """A detour's link within the sure distance is up whatever shadowing was measured on it:
    a measurement only ever lengthens what a link is certified up to."""
    pos, m, held, f = measured_line(x_db=0.0, at_m=17.3)
    assert np.hypot(*(pos[2] - pos[0])) < SURE < np.hypot(*(pos[2] - pos[1]))
    assert let_go(pos, m, held, T0, f.speed_mps, 7.5, SURE, fade=f)[0, 1]
    # A deep fade measured on the link 0-2 by both ends, robot 0's own since the records.
    m.x_db[2, 0] = 30.0
    held = heard_over_steps(m)
    m.x_db[0, 2] = 30.0
    assert held.records_db[0, 2] == 0.0
    assert let_go(pos, m, held, T0, f.speed_mps, 7.5, SURE, fade=f)[0, 1]
