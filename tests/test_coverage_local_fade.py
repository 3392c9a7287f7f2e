"""The local plan under shadowing (docs/model.md section 5.1, "Radios"; mobility/local.py,
"Shadowing"): each robot keeps links by the shadowing it measured on the Acks it heard, with
the global plan's fade-margin rule (mobility/_fade_kernels.py). One test per rule."""

from __future__ import annotations

import numpy as np
import pytest
from netsim.mobility.keep import FADE_SIGMAS, fade_travel_m, plausible_change_db
from netsim.mobility.local import Fade, Lists, Memory, answered_by_halves, let_go, plan_local
from netsim.mobility.steps import StepLimits

from netsim.radio.propagation import LogDistanceParams

RADIO = LogDistanceParams(shadowing_sigma_db=4.0)
SIGMA, DCORR, FADE_DB = 4.0, 10.0, 8.0
SURE = float(RADIO.effective_range_m(4.0 * SIGMA))
PERIOD = 1.0
T0 = 10.0


def fade() -> Fade:
    return Fade(RADIO, SIGMA, DCORR, FADE_DB, SURE, 1.0, PERIOD, 3, FADE_SIGMAS)


def limits(f: Fade) -> StepLimits:
    return StepLimits(period_s=PERIOD, range_m=SURE, margin_m=1.0, speed_max_mps=f.speed_mps, side_m=5000.0)


def measured_pair(distance_m: float, x_db: float, sent_s: float) -> Memory:
    """Two robots, 0 at the origin and 1 at ``distance_m``, each having heard the other's Ack
    sent at ``sent_s`` with the pair's shadowing ``x_db`` (the power it gives, as received)."""
    m = Memory(2)
    m.xy[0, 1] = (distance_m, 0.0)
    m.xy[1, 0] = (0.0, 0.0)
    m.sent_s[0, 1] = m.sent_s[1, 0] = sent_s
    m.measured_s[:] = m.sent_s
    power = RADIO.tx_power_dbm - float(RADIO.path_loss_db(distance_m)) - x_db
    m.x_db[0, 1] = m.x_db[1, 0] = x_db
    m.margin_db[0, 1] = m.margin_db[1, 0] = power - RADIO.sensitivity_dbm
    return m


def record_margins(m: Memory, pos: np.ndarray, x_db: float | None = None) -> None:
    """Each robot's margin on each Ack it remembers, as the power the pair's distance and
    shadowing (``x_db``, default the one it measured) give."""
    d = np.hypot(*(pos[:, None] - pos[None]).transpose(2, 0, 1))
    x = m.x_db if x_db is None else np.full(d.shape, x_db)
    m.margin_db[:] = RADIO.tx_power_dbm - RADIO.path_loss_db(np.maximum(d, 1.0)) - x - RADIO.sensitivity_dbm
    np.fill_diagonal(m.margin_db, np.nan)


def measured_memory(pos: np.ndarray, x_db: float, sent_s: float) -> Memory:
    """Robots at ``pos``, each having heard every other in an Ack sent at ``sent_s``, every
    link measured at ``x_db``, with the margins that gives (:func:`record_margins`)."""
    n = len(pos)
    m = Memory(n)
    m.xy[:] = pos[None, :, :]
    sent = np.full((n, n), sent_s)
    np.fill_diagonal(sent, -np.inf)
    m.sent_s[:] = m.measured_s[:] = sent
    m.x_db[:] = x_db
    np.fill_diagonal(m.x_db, np.nan)
    record_margins(m, pos)
    return m


def test_fade_keeps_a_link_as_far_as_its_measured_shadowing_allows():
    """A kept link with a measurement is answered for up to where its margin with the
    measured X is B = min(fade_margin_db, margin), less margin_m: the farther the worse the
    measured shadowing; a link never measured, or left no travel, is answered for only up to
    the sure distance."""
    f = fade()
    keeps = []
    for x in (-4.0, 0.0, 4.0):
        m = measured_pair(40.0, x, T0 - 0.5)
        keep, travel = f.limits(m, T0, T0 + PERIOD, f.speed_mps)
        margin = RADIO.tx_power_dbm - float(RADIO.path_loss_db(40.0)) - x - RADIO.sensitivity_dbm
        budget = min(FADE_DB, margin)
        want = float(RADIO.effective_range_m(x + budget)) - 1.0
        assert keep[0, 1] == pytest.approx(want, rel=1e-12)
        assert np.isfinite(travel[0, 1])
        keeps.append(keep[0, 1])
    assert keeps[0] > keeps[1] > keeps[2] > SURE
    never = Memory(2)
    never.sent_s[0, 1] = T0 - 0.5
    keep, travel = f.limits(never, T0, T0 + PERIOD, f.speed_mps)
    assert keep[0, 1] == SURE - 1.0 and travel[0, 1] == np.inf
    stale = measured_pair(40.0, 0.0, T0 - 30.0)  # the pair may have travelled too far since
    keep, travel = f.limits(stale, T0, T0 + PERIOD, f.speed_mps)
    assert keep[0, 1] == SURE - 1.0 and travel[0, 1] == np.inf


def test_fade_step_keeps_the_pair_travel_within_the_travel_limit():
    """The travel limit: a robot's step on a measured link beyond the sure distance is no
    longer than the travel B allows less both robots' largest travel since the Ack, so
    v (t0 - s) + |step| + v (t1 - s) <= fade_travel_m(B, X); and over that travel the
    plausible change stays within B."""
    f = fade()
    lim = limits(f)
    for x, sent in ((0.0, T0 - 0.2), (0.0, T0 - 1.2), (-3.0, T0 - 0.6), (2.0, T0 - 1.0)):
        m = measured_pair(45.0, x, sent)
        keep, travel = f.limits(m, T0, T0 + PERIOD, f.speed_mps)
        m.keep_m = keep
        kept = np.array([[False, True], [True, False]])
        reach = Fade.reach(travel, kept)
        pos = np.array([[0.0, 0.0], [45.0, 0.0]]) + 1000.0
        m.xy[0, 1], m.xy[1, 0] = pos[1], pos[0]
        wish = np.array([[-5.0, 0.0], [5.0, 0.0]])  # both pull away as fast as they can
        plan = plan_local(pos, wish, m, kept, T0, lim, reach)
        step = np.hypot(*(plan.velocity_mps * PERIOD).T)
        budget = min(FADE_DB, float(m.margin_db[0, 1]))
        allowed = float(fade_travel_m(np.array([budget]), np.array([x]), SIGMA, DCORR)[0])
        worst = f.speed_mps * ((T0 - sent) + (T0 + PERIOD - sent))
        assert (step + worst <= allowed * (1 + 1e-9)).all(), (x, step, worst, allowed)
        assert float(plausible_change_db(np.array([step[0] + worst]), np.array([x]), SIGMA, DCORR)[0]) <= budget + 1e-9
        assert (step > 0).all()


def test_shadowing_is_measured_from_the_power_the_robot_received():
    """X = P_t - PL(d) - P_r from the power the robot itself received, d the shortest the
    distance can have been at sending (the robot's largest motion since taken off): exact
    when the robot has not moved, and never below the true X (only shorter links kept)."""
    f = fade()
    rng = np.random.default_rng(3)
    k = 200
    sender = rng.uniform(0, 200, (k, 2))
    at_send = rng.uniform(0, 200, (k, 2))
    x_true = rng.normal(0, SIGMA, k)
    d = np.hypot(*(sender - at_send).T)
    power = RADIO.tx_power_dbm - RADIO.path_loss_db(d) - x_true
    x, margin = f.measure(at_send, sender, power, np.zeros(k), 0.0, 0.5)
    assert np.allclose(x, x_true, atol=1e-9)
    assert np.allclose(margin, power - RADIO.sensitivity_dbm)
    age = rng.uniform(0, 2, k)
    angle = rng.uniform(0, 2 * np.pi, k)
    moved = at_send + (0.5 * age * rng.random(k))[:, None] * np.c_[np.cos(angle), np.sin(angle)]
    x_moved, _ = f.measure(moved, sender, power, -age, 0.0, 0.5)
    assert (x_moved >= x_true - 1e-9).all()
    # No power received, nothing measured.
    x_none, _ = f.measure(at_send[:3], sender[:3], np.full(3, np.nan), np.zeros(3), 0.0, 0.5)
    assert np.isnan(x_none).all()


def test_a_robot_uses_only_the_powers_it_received():
    """A robot's measurement of a pair is the one it made on the Ack it heard (Memory.hear
    takes it with the Ack, NaN for a robot never heard), and what it learns of its
    neighbours' links is the measurement each of them made (the Ack's list), never its own
    nor the other end's."""
    n = 3
    m = Memory(n)
    robot, other = np.array([0, 1, 1, 2]), np.array([1, 0, 2, 1])
    xy = np.zeros((4, 2))
    heard = np.full(4, T0 - 0.5)
    x = np.array([1.0, 2.0, 3.0, 4.0])  # each robot's own measurement of each Ack it heard
    m.hear(robot, other, xy, heard, 0.001, x_db=x, margin_db=x + 10)
    assert m.x_db[0, 1] == 1.0 and m.x_db[1, 0] == 2.0 and m.x_db[1, 2] == 3.0 and m.x_db[2, 1] == 4.0
    assert np.isnan(m.x_db[0, 2]) and np.isnan(m.x_db[2, 0])
    lists = Lists(n, 2)
    lists.take(m, T0 - 1.0, 20.0)
    held = lists.heard(m.known(T0, 20.0), m.sent_s, 20.0)
    for u in range(n):
        k = held.which[0, u]
        if k < 0:
            continue
        for p in range(held.start[k, u], held.start[k, u + 1]):
            assert held.x_db[p] == m.x_db[u, held.other[p]]


def heard_over_steps(m: Memory, steps: int = 3):
    """What the robots hold after lists of the memory ``m`` taken at ``steps`` steps a second
    apart, the last at ``T0 - 1``: enough steps for the records rule 1 orders by under
    shadowing (netsim.mobility.local.Lists)."""
    lists = Lists(len(m.sent_s), steps)
    for k in range(steps):
        lists.take(m, T0 - steps + k, 20.0)
    return lists.heard(m.known(T0, 20.0), m.sent_s, 20.0)


def triangle(sent_ago_s: float, x_db: float | None) -> tuple[np.ndarray, Memory]:
    """Robots 0 and 1 80 m apart, 2 about 43 m from each (a detour 0-2-1 for the link 0-1),
    each having heard every other's Ack sent ``sent_ago_s`` before ``T0``, with the pair's
    shadowing ``x_db`` measured on it (None: not measured)."""
    pos = np.array([[0.0, 0.0], [80.0, 0.0], [40.0, 15.0]])
    n = 3
    m = Memory(n)
    m.xy[:] = pos[None, :, :]
    sent = np.full((n, n), T0 - sent_ago_s)
    np.fill_diagonal(sent, -np.inf)
    m.sent_s[:] = sent
    m.measured_s[:] = sent
    if x_db is not None:
        m.x_db[:] = x_db
        np.fill_diagonal(m.x_db, np.nan)
    return pos, m


def test_detour_through_a_measured_link_beyond_the_sure_distance():
    """Rule 1 under shadowing: a detour's link longer than the sure distance is certified
    when the shadowing measured on it (by its own ends, told in their Acks' lists) leaves it
    up at t0 after the plausible change over the pair's largest travel since; not without
    a measurement."""
    f = fade()
    pos, m = triangle(0.5, None)
    record_margins(m, pos, -2.0)  # the margins the Acks came with, the shadowing unknown
    held = heard_over_steps(m)
    v = f.speed_mps
    assert not let_go(pos, m, held, T0, v, 7.5, SURE, fade=f)[0, 1]
    m.x_db[:] = -2.0  # a favourable shadowing, measured on every Ack
    np.fill_diagonal(m.x_db, np.nan)
    record_margins(m, pos)
    held = heard_over_steps(m)
    assert let_go(pos, m, held, T0, v, 7.5, SURE, fade=f)[0, 1]
    # A shadowing that leaves the detour's links too short at t0 certifies nothing.
    m.x_db[:] = 14.0
    record_margins(m, pos)
    held = heard_over_steps(m)
    assert not let_go(pos, m, held, T0, v, 7.5, SURE, fade=f)[0, 1]


@pytest.mark.slow
def test_local_plan_under_shadowing_spreads_and_keeps_the_real_network():
    """Under 4 dB shadowing, from the dense start of ``netsim validate``'s coverage scenario,
    the local plan moves (it keeps links by their measured margin, not only within the sure
    distance, where no robot moved) and the real network (links.parquet) gains no component
    after control starts."""
    from netsim import config
    from netsim.run import execute
    from netsim.tools.validate import coverage_outcome, coverage_settings

    n, duration = 12, 120.0
    cfg = config.load(None, coverage_settings("shadowing 4 dB", "local", n, 0.0, 1, duration))
    r = execute(cfg)
    o = coverage_outcome(r.frames, r.summary, n, cfg.coverage.start_s, duration)
    assert o["components_max"] == o["components_at_start"] == 1
    assert r.summary["distance_mean_m"] > 5.0
    assert r.summary["covered_of_bound_all_final"] > 1.1 * r.summary["covered_of_bound_all_start"]


def test_travel_since_a_measurement_is_bounded_by_the_velocity_the_acks_carried():
    """A robot bounds a neighbour's travel since an Ack by the velocity that Ack carried (its
    sender's leg, which holds from the leg's start until the next control step) and its own
    by its own leg; only where no velocity is known, or before the leg started, by the
    speed cap. Memory.hear takes the velocity with the Ack; the rule, plain and compiled,
    and numpy's reading of it agree."""
    from netsim.mobility import _local_kernels as kernels

    from netsim.compiled import compiled_copy
    from tests.oracles.local import largest_travel_m

    n = 3
    m = Memory(n)
    robot, other = np.array([0, 0]), np.array([1, 2])
    vel = np.array([[0.1, 0.0], [0.0, 0.0], [0.3, 0.4]])  # robot 1 holds, robot 2 at 0.5 m/s
    leg_start = np.array([T0 - 1.0, T0 - 3.0, T0 - 1.0])
    heard = np.array([T0 - 0.5, T0 - 2.0])  # robot 2's Ack left before its leg started
    m.hear(robot, other, np.zeros((2, 2)), heard, 0.0, vel, leg_start, T0)
    cap = 0.36
    since = np.full((n, n), T0 - 2.5)
    travel = m.travel_m(since, T0, cap)
    assert travel[0, 1] == 0.0  # its Ack: it has held since T0 - 3
    assert travel[0, 0] == pytest.approx(cap * 1.5 + 0.1 * 1.0)  # its own leg from T0 - 1
    assert travel[0, 2] == pytest.approx(cap * 2.5)  # no velocity known: the cap all along
    since[0, 1] = T0 - 4.0  # before the leg robot 1's Ack told of: the cap
    assert m.travel_m(since, T0, cap)[0, 1] == pytest.approx(cap * 1.0)
    want = largest_travel_m(m.leg_speed_mps, m.leg_from_s, m.leg_until_s, since, T0, cap)
    for k in (kernels, compiled_copy("netsim.mobility._local_kernels")):
        got = k.largest_travels_m(m.leg_speed_mps, m.leg_from_s, m.leg_until_s, since, T0, cap)
        assert got.tolist() == want.tolist()


def test_fade_step_counts_the_travel_the_acks_tell_not_the_cap():
    """The travel limit with velocities: a robot whose neighbour's Ack says it held, and which
    held itself, has the whole travel B allows less the neighbour's next step at the cap
    (fade_travel_m(B, X) - v period), more than the cap's worst case gives; the pair's
    travel still stays within the travel B allows."""
    f = fade()
    x, sent = 0.0, T0 - 0.8
    m = measured_pair(45.0, x, sent)
    budget = min(FADE_DB, float(m.margin_db[0, 1]))
    allowed = float(fade_travel_m(np.array([budget]), np.array([x]), SIGMA, DCORR)[0])
    _, blind = f.limits(m, T0, T0 + PERIOD, f.speed_mps)
    assert blind[0, 1] == pytest.approx(allowed - f.speed_mps * ((T0 - sent) + (T0 + PERIOD - sent)))
    # Both held on legs that started before the Ack (what Memory.hear records).
    m.leg_velocity_mps[:] = 0.0
    m.leg_from_s[:] = T0 - 5.0
    _, told = f.limits(m, T0, T0 + PERIOD, f.speed_mps)
    assert told[0, 1] == pytest.approx(allowed - f.speed_mps * PERIOD)
    assert told[0, 1] > blind[0, 1]


def test_detour_certified_over_the_travel_the_acks_tell():
    """Rule 1 with velocities: a detour's link measured beyond the sure distance counts as up
    at t0 over the pair's travel since the measurement as the robot knows it (both ends
    held, by their Acks: no change of the shadowing), where the speed cap's worst case
    (both ends at the cap since) would leave it too short."""
    f = fade()
    pos, m = triangle(1.5, 6.0)  # an adverse shadowing: the 43 m links are up out to 63 m
    record_margins(m, pos)
    held = heard_over_steps(m)
    v = f.speed_mps
    assert not let_go(pos, m, held, T0, v, 7.5, SURE, fade=f)[0, 1]
    m.leg_velocity_mps[:] = 0.0  # every Ack said its sender held, since before it was sent
    m.leg_from_s[:] = T0 - 5.0
    assert let_go(pos, m, held, T0, v, 7.5, SURE, fade=f)[0, 1]


def test_detour_certified_within_the_detour_sigmas():
    """Rule 1 with ``coverage.detour_sigmas``: a detour's measured link counts as up at t0 when
    its shadowing, plus that many standard deviations of its change over the pair's largest
    travel since, leaves it in range. At the kept links' four the 43 m links of an adverse
    shadowing measured 1.5 s ago with the cap's travel are too short for the detour; at two
    they carry it. The speed cap known to all does not change."""
    pos, m = triangle(1.5, 6.0)
    record_margins(m, pos)
    held = heard_over_steps(m)
    four, two = fade(), Fade(RADIO, SIGMA, DCORR, FADE_DB, SURE, 1.0, PERIOD, 3, detour_sigmas=2.0)
    assert two.speed_mps == four.speed_mps
    v = four.speed_mps
    assert not let_go(pos, m, held, T0, v, 7.5, SURE, fade=four)[0, 1]
    assert let_go(pos, m, held, T0, v, 7.5, SURE, fade=two)[0, 1]


def held_pair(distance_m: float, x_db: float, measured_s: float, exact: bool = True, x_larger_db: float | None = None):
    """Two robots 0 and 1 ``distance_m`` apart that have held since ``T0 - 5``, each having
    heard the other's Ack sent at ``measured_s`` (the pair's shadowing ``x_db``), which robot
    0, the smaller id, listed at the step before ``T0`` (the link's record). ``exact``: each
    knows where the other is at ``T0`` (the Ack was sent on its current leg); robot 1 measured
    ``x_larger_db`` (default the same). Returns the
    positions, what the robots know at ``T0`` (:meth:`Memory.at`'s form) and what they hold."""
    pos = np.array([[1000.0, 1000.0], [1000.0 + distance_m, 1000.0]])
    m = Memory(2)
    m.xy[0, 1], m.xy[1, 0] = pos[1], pos[0]
    m.sent_s[0, 1] = m.sent_s[1, 0] = measured_s
    m.measured_s[:] = m.sent_s
    m.x_db[0, 1] = x_db
    m.x_db[1, 0] = x_db if x_larger_db is None else x_larger_db
    record_margins(m, pos)
    m.leg_velocity_mps[:] = 0.0
    m.leg_from_s[:] = T0 - 5.0
    lists = Lists(2, 2)
    lists.take(m, T0 - 1.0, 20.0)
    held = lists.heard(m.known(T0, 20.0), m.sent_s, 20.0)
    knows = Memory(2)
    for name in ("xy", "x_db", "margin_db", "measured_s", "leg_velocity_mps", "leg_from_s"):
        setattr(knows, name, getattr(m, name).copy())
    knows.sent_s = np.where(np.isfinite(m.sent_s), T0 if exact else measured_s, -np.inf)
    return pos, knows, held


def test_halves_a_robot_answers_for_half_of_a_weak_link_it_cannot_answer_for_alone():
    """Rule 2 by halves: a weak link (margin below fade_margin_db) neither end can answer for
    alone (rule 3 holds both) is answered for by each end's half when each knows where the
    other is at t0 and reads the link's record: both compute one midpoint, one length L (where
    the margin with the recorded X is B = min(fade_margin_db, m0), m0 the margin at the
    length now) and each moves at most half of the travel B allows since the record."""
    f = fade()
    lim = limits(f)
    # Robot 1 measured a little less fade than robot 0: both read robot 0's, the record.
    pos, knows, held = held_pair(45.0, 6.0, T0 - 0.5, x_larger_db=5.0)
    assert knows.margin_db[0, 1] < FADE_DB and knows.margin_db[1, 0] < FADE_DB
    knows.keep_m, travel = f.limits(knows, T0, T0 + PERIOD, f.speed_mps)
    kept = np.array([[False, True], [True, False]])
    wish = np.array([[0.0, 5.0], [0.0, -5.0]])  # each sideways, away from the other's side
    alone = plan_local(pos, wish, knows, kept, T0, lim, Fade.reach(travel, kept))
    assert (alone.velocity_mps == 0).all() and alone.held.all()
    halves = f.halves(knows, held, pos, T0, f.speed_mps)
    assert halves.usable[0, 1] and halves.usable[1, 0]
    assert np.allclose(halves.centre_m[0, 1], halves.centre_m[1, 0], rtol=0, atol=1e-9)
    assert halves.radius_m[0, 1] == pytest.approx(halves.radius_m[1, 0], rel=1e-12)
    m0 = RADIO.tx_power_dbm - float(RADIO.path_loss_db(45.0)) - 6.0 - RADIO.sensitivity_dbm
    budget = min(FADE_DB, m0)
    length = max(float(RADIO.effective_range_m(6.0 + budget)), 45.0)
    assert 2 * halves.radius_m[0, 1] == pytest.approx(length, rel=1e-9)
    allowed = float(fade_travel_m(np.array([budget]), np.array([6.0]), SIGMA, DCORR)[0])
    assert halves.travel_m[0, 1] == pytest.approx(allowed / 2, rel=1e-9)
    used = answered_by_halves(pos, knows, kept, T0, lim, halves)
    halves = halves._replace(usable=used)
    reach = Fade.reach(np.where(used, halves.travel_m, travel), kept)
    plan = plan_local(pos, wish, knows, kept, T0, lim, reach, halves)
    step = plan.velocity_mps * PERIOD
    assert (np.hypot(*step.T) > 0).all()
    assert (np.hypot(*step.T) <= allowed / 2 * (1 + 1e-9)).all()
    assert np.hypot(*(pos[0] + step[0] - pos[1] - step[1])) <= length * (1 + 1e-9)


def test_halves_need_the_other_ends_position_at_t0_and_the_links_record():
    """A robot answers for half of a link only where both ends compute the same midpoint and
    length: it knows where the other end is at t0 (an Ack sent on the other's current leg),
    and it reads the link's record (the smaller id's list of the latest step)."""
    f = fade()
    pos, knows, held = held_pair(45.0, 6.0, T0 - 0.5, exact=False)
    assert not f.halves(knows, held, pos, T0, f.speed_mps).usable.any()
    pos, knows, held = held_pair(45.0, 6.0, T0 - 0.5)
    unread = held._replace(which=np.full_like(held.which, -1))
    usable = f.halves(knows, unread, pos, T0, f.speed_mps).usable
    assert usable[0, 1] and not usable[1, 0]  # robot 0 reads its own list, robot 1 none


@pytest.mark.parametrize("seed", range(10))
def test_halves_keep_the_link_within_its_length_and_the_pair_travel_within_its_budget(seed):
    """Whatever each end wishes, with both ends answering by their halves, or one by its half
    and the other alone (rule 3: it holds), the link is within L at the end of the step (so
    throughout: the distance is convex) and the pair's travel since the record within the
    travel B allows."""
    f = fade()
    lim = limits(f)
    rng = np.random.default_rng(seed)
    tried = 0
    for _ in range(20):
        d, x = rng.uniform(31.0, 70.0), rng.uniform(-4.0, 10.0)
        pos, knows, held = held_pair(d, x, T0 - rng.uniform(0.1, 1.0))
        knows.keep_m, travel = f.limits(knows, T0, T0 + PERIOD, f.speed_mps)
        kept = np.array([[False, True], [True, False]])
        halves = f.halves(knows, held, pos, T0, f.speed_mps)
        if not halves.usable[0, 1]:
            continue
        tried += 1
        used = answered_by_halves(pos, knows, kept, T0, lim, halves)
        if rng.random() < 0.3:
            used[1, 0] = False  # robot 1 answers alone
        h = halves._replace(usable=used)
        reach = Fade.reach(np.where(used, h.travel_m, travel), kept)
        wish = rng.normal(0.0, 3.0, (2, 2))
        plan = plan_local(pos, wish, knows, kept, T0, lim, reach, h)
        step = plan.velocity_mps * PERIOD
        # Both held since before the record: the pair's travel since is its steps.
        m0 = RADIO.tx_power_dbm - float(RADIO.path_loss_db(d)) - x - RADIO.sensitivity_dbm
        budget = min(FADE_DB, m0)
        length = max(float(RADIO.effective_range_m(x + budget)), d)
        allowed = float(fade_travel_m(np.array([budget]), np.array([x]), SIGMA, DCORR)[0])
        assert np.hypot(*(pos[0] + step[0] - pos[1] - step[1])) <= length * (1 + 1e-9)
        assert np.hypot(*step.T).sum() <= allowed * (1 + 1e-9)
    assert tried >= 10


def faded_triangle() -> tuple[np.ndarray, Memory]:
    """Robots 0 and 1 40 m apart in a deep fade (10 dB), robot 2 50 m from each on strong
    links (-6 dB); every robot heard the others' Acks sent at ``T0 - 0.5`` and measured it."""
    pos = np.array([[0.0, 0.0], [40.0, 0.0], [20.0, float(np.sqrt(50.0**2 - 20.0**2))]])
    m = Memory(3)
    m.xy[:] = pos[None, :, :]
    sent = np.full((3, 3), T0 - 0.5)
    np.fill_diagonal(sent, -np.inf)
    m.sent_s[:] = sent
    m.measured_s[:] = sent
    m.x_db[:] = -6.0
    m.x_db[0, 1] = m.x_db[1, 0] = 10.0
    np.fill_diagonal(m.x_db, np.nan)
    record_margins(m, pos)
    return pos, m


def test_detour_order_under_shadowing_is_the_length_at_zero_shadowing_under_the_records():
    """Rule 1's order under shadowing: a link's band is that of its length at zero shadowing
    under its record (40 m at 10 dB: 86 m; 50 m at -6 dB: 32 m), so robots 0 and 1 let go of
    their short link in a deep fade through 2 and its strong links, which by length alone
    come after it; 2 keeps both."""
    f = fade()
    pos, m = faded_triangle()
    out = let_go(pos, m, heard_over_steps(m), T0, f.speed_mps, 7.5, SURE, fade=f)
    assert out[0, 1] and out[1, 0]
    assert not out[0, 2] and not out[2, 0] and not out[1, 2] and not out[2, 1]
    # As strong as the others (-6 dB: 25 m at zero shadowing), the short link comes first.
    m.x_db[0, 1] = m.x_db[1, 0] = -6.0
    assert not let_go(pos, m, heard_over_steps(m), T0, f.speed_mps, 7.5, SURE, fade=f)[0, 1]


def test_detour_under_shadowing_needs_the_records_of_the_epoch():
    """A robot orders links by the records of the epoch only where it holds them: robot 2,
    whose latest Ack of 1 is older than that epoch's lists, as is 0's (so 0 held no list of
    1 of that epoch either), cannot read their short link's record (1's) and keeps 1,
    though a detour through 0 on strong links exists; robot 1 reads it (its own) and lets
    go of 2. Once 0 has heard 1 lately, 2 reads the record in the list 0 held of 1 and lets
    go of 1 too. From lists of a single step (no epoch's records yet) neither lets go."""
    f = fade()
    pos, m = faded_triangle()
    order = [1, 2, 0]  # robot 1 where 0 was, 2 where 1 was, 0 the strong corner
    pos, m = pos[np.argsort(order)], relabel(m, order)
    m.sent_s[2, 1] = m.measured_s[2, 1] = m.sent_s[0, 1] = m.measured_s[0, 1] = T0 - 5.5
    heard = heard_over_steps(m, steps=6)
    assert heard.steps[heard.which[2, 1]] < heard.records_from <= heard.steps[heard.which[2, 0]]
    out = let_go(pos, m, heard, T0, f.speed_mps, 7.5, SURE, fade=f)
    assert out[1, 2] and not out[2, 1]
    m.sent_s[0, 1] = m.measured_s[0, 1] = T0 - 0.5
    assert let_go(pos, m, heard_over_steps(m, steps=6), T0, f.speed_mps, 7.5, SURE, fade=f)[2, 1]
    assert not let_go(pos, m, heard_over_steps(m, steps=1), T0, f.speed_mps, 7.5, SURE, fade=f)[[1, 2], [2, 1]].any()


def relabel(m: Memory, order: list[int]) -> Memory:
    """The memory ``m`` with robot ``k`` renamed ``order[k]`` (every field of a pair)."""
    inverse = np.argsort(order)
    out = Memory(len(order))
    for name, value in vars(m).items():
        if isinstance(value, np.ndarray):
            setattr(out, name, value[np.ix_(inverse, inverse)].copy())
    return out


def test_lists_carry_the_records_of_an_epoch_read_a_delay_later():
    """Records are taken at every RECORD_EPOCH_STEPS-th list (the shadowing each robot had
    measured then on the robots it remembered); rule 1 reads those of the epoch of the list
    taken RECORD_DELAY_STEPS steps before the latest, from lists of that epoch or the next."""
    from netsim.mobility.local import RECORD_DELAY_STEPS, RECORD_EPOCH_STEPS

    _, m = faded_triangle()
    lists = Lists(3, 10)
    seen = []
    for k in range(2 * RECORD_EPOCH_STEPS + RECORD_DELAY_STEPS + 1):
        m.x_db[0, 1] = m.x_db[1, 0] = float(k)  # the shadowing measured at the k-th step
        lists.take(m, T0 - 10.0 + k, 20.0)
        heard = lists.heard(m.known(T0, 20.0), m.sent_s, 20.0)
        seen.append((heard.records_db[0, 1], heard.records_from, heard.records_to))
    for k, (record, lo, hi) in enumerate(seen):
        epoch = (k - RECORD_DELAY_STEPS) // RECORD_EPOCH_STEPS
        if epoch < 0:
            assert np.isnan(record) and lo < 0
        else:
            assert record == epoch * RECORD_EPOCH_STEPS  # measured at the epoch's first list
            assert (lo, hi) == (epoch * RECORD_EPOCH_STEPS, (epoch + 2) * RECORD_EPOCH_STEPS)


def test_travel_after_a_known_leg_ends_is_at_the_cap():
    """A neighbour's Ack tells the velocity of its leg only until its next step: from then
    on it may be on a leg no Ack told of yet, so its travel since a measurement counts the
    speed cap from that step on, as the plan's view of where it is does (Memory.at)."""
    m = Memory(2)
    held = np.zeros((2, 2))
    m.hear(np.array([0]), np.array([1]), np.zeros((1, 2)), np.array([T0 - 0.5]), 0.0, held, np.full(2, T0 - 3.0), T0)
    cap = 0.36
    since = np.full((2, 2), T0 - 0.5)
    assert m.travel_m(since, T0, cap)[0, 1] == 0.0  # within the leg it told of: it held
    assert m.travel_m(since, T0 + 1.0, cap)[0, 1] == pytest.approx(cap * 1.0)
    knows = m.at(T0 + 1.0, cap, 0.0)
    assert knows.travel_m(since, T0 + 1.0, cap)[0, 1] == pytest.approx(cap * 1.0)
    assert cap * (T0 + 1.0 - knows.sent_s[0, 1]) == pytest.approx(cap * 1.0)
