"""The local plan (``coverage.plan = "local"``; docs/model.md section 5, "Local plan";
mobility/local.py): one test per rule, the argument's conclusion on random scenes, and
whole runs from dense starts that check the true network (``links.parquet``) at every
link event."""

from __future__ import annotations

import importlib
import math

import numpy as np
import pytest
from netsim.mobility.local import (
    NO_WALLS,
    Heard,
    Lists,
    Memory,
    carried,
    centre_estimates,
    clear_of_walls,
    cut_for_walls,
    latest_pulls,
    let_go,
    plan_local,
    pulls,
    sources_heard,
    step_clear_of_walls,
    walls_of,
)
from netsim.mobility.steps import StepLimits

from netsim import config
from netsim.errors import ConfigError
from netsim.metrics import components, components_at_link_events
from netsim.run import execute
from netsim.tools.cli import main
from netsim.tools.validate import coverage_settings
from tests.oracles import local as oracle

RC = 100.0
V = 2.0  # speed cap, m/s
LIMITS = StepLimits(period_s=1.0, range_m=RC, margin_m=1.0, speed_max_mps=V, side_m=2000.0)
T0 = 10.0


def memory_of(xy_heard, sent_s):
    """A Memory from ``xy_heard[i][j]`` and ``sent_s[i][j]`` (-inf: never heard)."""
    n = len(sent_s)
    m = Memory(n)
    m.xy[:] = np.asarray(xy_heard, dtype=float)
    m.sent_s[:] = np.asarray(sent_s, dtype=float)
    return m


def told(m, lists=None, release_s=20.0):
    """What the robots heard: their memory ``m`` and, from every robot they remember, its
    list as the memory ``lists`` (default ``m``) holds it, carried by every Ack they heard."""
    n = len(m.sent_s)
    kept = Lists(n, 1)
    kept.take(m if lists is None else lists, m.sent_s[np.isfinite(m.sent_s)].min(initial=T0) - 1.0, release_s)
    return kept.heard(m.known(T0, release_s), m.sent_s, release_s)


def all_heard(pos, sent):
    """Every robot heard every other at its true position, Acks sent at ``sent``."""
    n = len(pos)
    xy = np.broadcast_to(pos[None, :, :], (n, n, 2)).copy()
    s = np.full((n, n), float(sent))
    np.fill_diagonal(s, -np.inf)
    return memory_of(xy, s)


def random_scene(seed, n=30, side=300.0, staleness_s=3.0):
    """True positions at T0 and a memory consistent with the speed cap: a robot heard at
    ``q`` at ``s`` is within ``V (T0 - s)`` of ``q`` at T0. Robots in range hear each other
    (each Ack heard with probability 0.8)."""
    rng = np.random.default_rng(seed)
    pos = rng.uniform(0, side, (n, 2))
    d = np.hypot(*(pos[:, None] - pos[None]).transpose(2, 0, 1))
    heard = (d <= RC) & (rng.random((n, n)) < 0.8)
    np.fill_diagonal(heard, False)
    sent = np.where(heard, T0 - rng.uniform(0.0, staleness_s, (n, n)), -np.inf)
    # Each robot j was, at the time each Ack of it was sent, somewhere within V (T0 - s) of pos[j].
    angle = rng.uniform(0, 2 * np.pi, (n, n))
    radius = V * np.where(heard, T0 - sent, 0.0) * np.sqrt(rng.random((n, n)))
    xy = pos[None, :, :] + np.stack([radius * np.cos(angle), radius * np.sin(angle)], axis=2)
    return pos, memory_of(xy, sent)


# -- rule 1: detours -----------------------------------------------------------------


def test_detour_a_robot_lets_go_only_of_a_link_with_a_certified_detour():
    """Rule 1: robot 0 lets go of robot 1 (80 m) when robot 2 is 45 m from each and all three
    remember each other; not when robot 2 does not remember robot 1, and not when what it
    knows of robot 2 is so old that the detour may be longer than the link."""
    pos = np.array([[0.0, 0.0], [80.0, 0.0], [40.0, 20.0]])
    m = all_heard(pos, T0 - 0.5)
    out = let_go(pos, m, told(m), T0, V, 10.0, RC)
    assert out[0, 1] and out[1, 0]
    assert not out[0, 2] and not out[2, 0] and not out[1, 2] and not out[2, 1]

    one_sided = memory_of(m.xy, m.sent_s.copy())
    one_sided.sent_s[2, 1] = -np.inf
    assert not let_go(pos, m, told(m, one_sided), T0, V, 10.0, RC)[0, 1]

    m.sent_s[0, 2] = m.sent_s[1, 2] = T0 - 18.0  # 36 m of uncertainty on robot 2
    assert not let_go(pos, m, told(m), T0, V, 10.0, RC)[0, 1]


def heard_over_steps(pos, hears):
    """A memory and what each robot holds (:class:`Lists`) after control steps at 5, 6, ...,
    10 s (T0): at each, robot ``r`` hears the latest Ack of ``o`` (at its true position, sent
    half a second before the step) where ``hears(r, o, t)``."""
    n = len(pos)
    m, lists = Memory(n), Lists(n, 25)
    for t in np.arange(5.0, T0 + 0.5):
        pairs = [(r, o) for r in range(n) for o in range(n) if r != o and hears(r, o, t)]
        robot, other = np.array(pairs).T
        m.hear(robot, other, pos[other], np.full(len(pairs), t - 0.5), 0.0)
        heard = lists.heard(m.known(t, 20.0), m.sent_s, 20.0)
        lists.take(m, t, 20.0)
    return m, heard


@pytest.mark.parametrize("compiled", ["0", "1"])
def test_detour_a_robot_certifies_that_two_robots_remember_each_other_from_their_acks_alone(monkeypatch, compiled):
    """Rule 1 reads whether robot 2 remembers robot 1 from the list in the latest Ack of
    robot 2 that robot 0 heard, not from robot 2's memory. Robot 2 first hears robot 1 at
    the step of 9 s; robot 0's latest Ack of robot 2 was sent after that step (it lets go of
    robot 1 through robot 2), or, that Ack lost, before it (it keeps robot 1, though robots
    1 and 2 remember each other at T0)."""
    monkeypatch.setenv("NETSIM_COMPILED", compiled)
    pos = np.array([[0.0, 0.0], [80.0, 0.0], [40.0, 20.0]])

    def hears(lost):
        return lambda r, o, t: not (r == 2 and o == 1 and t < 9.0) and (r, o, t) != lost

    m, heard = heard_over_steps(pos, hears(None))
    assert let_go(pos, m, heard, T0, V, 10.0, RC)[0, 1]
    m, heard = heard_over_steps(pos, hears((0, 2, T0)))
    known = m.known(T0, 20.0)
    assert known[2, 1] and known[1, 2] and known[0, 2]
    assert not let_go(pos, m, heard, T0, V, 10.0, RC)[0, 1]


def test_forces_a_robot_knows_a_robot_two_links_out_from_the_lists_it_heard_alone():
    """The forces' sources: robot 0 knows robot 1 (out of its range, within twice it) only
    once the latest Ack of robot 2 it heard names it: not when that Ack was sent before
    robot 2 first heard robot 1 (at the step of 9 s), though robot 2 remembers it at T0."""
    pos = np.array([[0.0, 0.0], [180.0, 0.0], [90.0, 0.0]])

    def hears(lost):
        in_range = {(0, 2), (2, 0), (1, 2), (2, 1)}
        return lambda r, o, t: (r, o) in in_range and not (r == 2 and o == 1 and t < 9.0) and (r, o, t) != lost

    m, heard = heard_over_steps(pos, hears(None))
    robot, xy = sources_heard(m, heard, T0, 2 * RC, pos)
    assert sorted(map(tuple, xy[robot == 0].tolist())) == [(90.0, 0.0), (180.0, 0.0)]
    m, heard = heard_over_steps(pos, hears((0, 2, T0)))
    assert m.known(T0, 20.0)[2, 1]
    robot, xy = sources_heard(m, heard, T0, 2 * RC, pos)
    assert xy[robot == 0].tolist() == [[90.0, 0.0]]


def random_heard(seed, n=25, snapshots=3):
    """A memory and random lists (not made by hearing): robots listing themselves and robots
    the holder remembers, entries past the release, and sending times from a few values, so
    that two lists often report the same robot as fresh as each other."""
    rng = np.random.default_rng(seed)
    sent = np.where(rng.random((n, n)) < 0.4, T0 - rng.uniform(0.0, 5.0, (n, n)), -np.inf)
    np.fill_diagonal(sent, -np.inf)
    m = memory_of(rng.uniform(0.0, 300.0, (n, n, 2)), sent)
    known = m.known(T0, 20.0)
    # Lists of robots not remembered too, as Lists.heard gives them: they are not read.
    which = np.where(rng.random((n, n)) < 0.8, rng.integers(0, snapshots, (n, n)), -1)
    counts = rng.integers(0, 8, (snapshots, n))
    start = np.zeros((snapshots, n + 1), np.int64)
    start[:, 1:] = np.cumsum(counts, axis=1) + (np.arange(snapshots) * counts.sum(axis=1).max())[:, None]
    size = int(start[-1, -1])
    heard = Heard(
        known, which, start, rng.integers(0, n, size),
        T0 - rng.choice([0.5, 1.0, 3.0, 25.0], size), rng.uniform(0.0, 300.0, (size, 2)), 20.0,
    )  # fmt: skip
    return rng.uniform(0.0, 300.0, (n, 2)), m, heard


@pytest.mark.parametrize("compiled", ["0", "1"])
def test_forces_sources_heard_agree_with_their_oracle(monkeypatch, compiled):
    """The forces' sources (one kernel pass, keeping each robot's freshest report) are those
    of the oracle (sorting every robot's reports), to the last bit, on random lists where
    two lists often report a robot at the same time (the first list, by its holder's id,
    wins) and some reports are past the release."""
    monkeypatch.setenv("NETSIM_COMPILED", compiled)
    for seed in range(8):
        pos, m, heard = random_heard(seed)
        robot, xy = sources_heard(m, heard, T0, 150.0, pos)
        want_robot, want_xy = oracle.sources_heard(m, heard, T0, 150.0, pos)
        assert robot.tolist() == want_robot.tolist() and xy.tolist() == want_xy.tolist(), seed
        assert 0 < len(robot) < len(sources_heard(m, heard, T0, 1e9, pos)[0])


def test_forces_a_source_at_the_reach_is_in_reach_as_everywhere_in_the_engine():
    """A robot heard exactly ``reach_m`` away is a source, as the global plan's sources
    (the pairs in range, ``d <= r``) count it: one rule of "within reach"."""
    from netsim.mobility.coverage import sources_true

    pos = np.array([[0.0, 0.0], [180.0, 0.0], [90.0, 0.0]])
    everyone = {(r, o) for r in range(3) for o in range(3) if r != o}
    m, heard = heard_over_steps(pos, lambda r, o, t: (r, o) in everyone)
    robot, xy = sources_heard(m, heard, T0, 180.0, pos)
    assert [90.0, 0.0] in xy[robot == 0].tolist() and [180.0, 0.0] in xy[robot == 0].tolist()
    target, _ = sources_true(pos, 90.0)
    assert np.count_nonzero(target == 0) == 2


@pytest.mark.parametrize("seed", range(30))
def test_detour_links_nobody_lets_go_of_join_every_robot_the_known_links_join(seed):
    """The argument of rule 1: of the links in range that both ends remember (``K``), those
    neither end lets go of have the same components as ``K``, whatever the true positions
    within what the robots know (stale positions, speed capped)."""
    pos, m = random_scene(seed)
    known = m.known(T0, 20.0)
    gone = let_go(pos, m, told(m), T0, V, 10.0, RC)
    n = len(pos)
    d = np.hypot(*(pos[:, None] - pos[None]).transpose(2, 0, 1))
    k = (d <= RC) & known & known.T
    np.fill_diagonal(k, False)
    kept = k & ~gone & ~gone.T
    from scipy.sparse.csgraph import connected_components

    nk, lk = connected_components(k, directed=False)
    np_, lp = connected_components(kept, directed=False)
    assert nk == np_ and (lk[:, None] == lk[None, :]).__eq__(lp[:, None] == lp[None, :]).all()
    assert gone.sum() > n // 2  # the rule lets go of links at all


def agreed(monkeypatch, pos, m, heard, window_s=0.0, silent_of=None):
    """Rule 1's kernel, plain and compiled, and its oracle (tests/oracles/local.py) on one
    scene: asserts the three agree, returns what they let go of."""
    out = []
    for compiled in ("0", "1"):
        monkeypatch.setenv("NETSIM_COMPILED", compiled)
        out.append(let_go(pos, m, heard, T0, V, 10.0, RC, window_s=window_s, silent_of=silent_of))
    want = oracle.let_go(pos, m, heard, T0, V, 10.0, RC, NO_WALLS, window_s, silent_of)
    assert (out[0] == want).all() and (out[1] == want).all()
    return want


def test_detour_through_a_robot_two_hops_out_that_the_lists_show():
    """Rule 1 over two hops: robot 0 remembers 1 and 2, which do not remember each other;
    both remember 3, which 0 never heard. Their lists name 3 and carry the list of 3 they
    held, which names them: 0 lets go of 1 (90 m) through 2 and 3 (45, 40 and 54 m). Without
    the lists their senders held, 3's memory is unknown to 0 and 0 keeps 1."""
    pos = np.array([[0.0, 0.0], [90.0, 0.0], [20.0, 40.0], [60.0, 45.0]])
    sent = np.full((4, 4), -np.inf)
    for a, b in ((0, 1), (0, 2), (1, 3), (2, 3)):
        sent[a, b] = sent[b, a] = T0 - 0.5
    m = memory_of(np.broadcast_to(pos[None], (4, 4, 2)).copy(), sent)
    lists = Lists(4, 3)
    for taken in (T0 - 3.0, T0 - 2.0, T0 - 1.0):
        lists.take(m, taken, 20.0)
    heard = lists.heard(m.known(T0, 20.0), m.sent_s, 20.0)
    assert let_go(pos, m, heard, T0, V, 10.0, RC)[0, 1]
    assert not let_go(pos, m, heard._replace(held=None), T0, V, 10.0, RC)[0, 1]
    assert (let_go(pos, m, heard, T0, V, 10.0, RC) == oracle.let_go(pos, m, heard, T0, V, 10.0, RC, NO_WALLS)).all()


@pytest.mark.slow
def test_detour_over_two_hops_agrees_with_its_oracle(monkeypatch):
    """Rule 1's kernel over two hops, plain and compiled, lets go of exactly the links its
    oracle does, with lists taken at several steps that carry the lists their senders held
    (some robots two hops out known, some not); and the lists of two hops change what some
    robot lets go of."""
    rng = np.random.default_rng(11)
    changed = False
    for seed in range(8):
        pos, m = random_scene(seed, n=40)
        lists = Lists(len(pos), 4)
        for taken in (T0 - 4.5, T0 - 3.5, T0 - 2.5, T0 - 1.5):
            heard_then = np.where(rng.random(m.sent_s.shape) < 0.8, np.minimum(m.sent_s, taken - 0.2), -np.inf)
            lists.take(memory_of(m.xy, heard_then), taken, 20.0)
        heard = lists.heard(m.known(T0, 20.0), m.sent_s, 20.0)
        assert (heard.held >= 0).any()
        a = agreed(monkeypatch, pos, m, heard)
        assert a.any()
        changed |= bool((a != let_go(pos, m, heard._replace(held=None), T0, V, 10.0, RC)).any())
        # Over a window, with legs told (a robot two hops out has none i knows: the cap) and
        # silent robots.
        heading = rng.uniform(0.0, 2 * np.pi, m.sent_s.shape)
        speed = np.where(rng.random(m.sent_s.shape) < 0.7, 0.0, V)
        m.leg_velocity_mps[:] = (speed * np.stack([np.cos(heading), np.sin(heading)])).transpose(1, 2, 0)
        m.leg_from_s[:] = T0 - 20.0
        quiet = rng.random(m.sent_s.shape) < 0.1
        agreed(monkeypatch, pos, m, heard, window_s=3.0, silent_of=quiet)
    assert changed


@pytest.mark.slow
def test_detour_kernel_agrees_with_its_oracle(monkeypatch):
    """Rule 1's kernel, plain and compiled, lets go of exactly the links its numpy oracle
    (tests/oracles/local.py) does, the lists the robots hold taken at several steps, each
    naming some of what its sender remembers."""
    rng = np.random.default_rng(3)
    for seed in range(10):
        pos, m = random_scene(seed, n=40)
        lists = Lists(len(pos), 3)
        for taken in (T0 - 3.5, T0 - 2.5, T0 - 1.5):
            some = memory_of(m.xy, np.where(rng.random(m.sent_s.shape) < 0.8, m.sent_s - 18.5, -np.inf))
            lists.take(some, taken, 20.0)
        heard = lists.heard(m.known(T0, 20.0), m.sent_s, 20.0)
        assert len(np.unique(heard.which)) == 4  # every list, and none
        a = agreed(monkeypatch, pos, m, heard)
        assert a.any()
        assert (a != let_go(pos, m, told(m), T0, V, 10.0, RC)).any()


@pytest.mark.parametrize("compiled", [pytest.param("0", marks=pytest.mark.slow), "1"])
def test_detour_a_robot_decides_from_what_it_heard_alone(monkeypatch, compiled):
    """Rule 1 reads nothing of the robots i does not remember but what the lists of those it
    remembers carry: whatever they remember and wherever the others are, i lets go of the
    same robots (plain and compiled)."""
    monkeypatch.setenv("NETSIM_COMPILED", compiled)
    rng = np.random.default_rng(7)
    for seed in range(4):
        pos, m = random_scene(seed, n=30)
        known = m.known(T0, 20.0)
        gone = let_go(pos, m, told(m), T0, V, 10.0, RC)
        n = len(pos)
        for i in range(n):
            unheard = np.flatnonzero(~known[i])
            unheard = unheard[unheard != i]
            other = np.flatnonzero(np.arange(n) != i)
            p2, m2, k2 = pos.copy(), memory_of(m.xy.copy(), m.sent_s.copy()), known.copy()
            p2[other] = rng.uniform(0, 300.0, (len(other), 2))
            k2[unheard] = rng.random((len(unheard), n)) < 0.5
            m2.sent_s[unheard] = np.where(k2[unheard], T0 - rng.uniform(0, 3.0, (len(unheard), n)), -np.inf)
            m2.xy[unheard] = rng.uniform(0, 300.0, (len(unheard), n, 2))
            assert (let_go(p2, m2, told(m2), T0, V, 10.0, RC)[i] == gone[i]).all(), i


# -- rule 2: leashes -------------------------------------------------------------------


@pytest.mark.parametrize("seed", range(20))
def test_leash_keeps_every_kept_robot_in_range_over_the_step_whatever_it_does(seed):
    """Rule 2: for every link a robot keeps, at every instant of the step, its distance to
    the position it last heard plus the farthest that robot can have gone since is within
    the range: the link holds whatever the other end does."""
    pos, m = random_scene(seed)
    known = m.known(T0, 20.0)
    kept = known & ~let_go(pos, m, told(m), T0, V, 10.0, RC)
    rng = np.random.default_rng(seed)
    wish = rng.normal(0, 3.0, pos.shape)
    plan = plan_local(pos, wish, m, kept, T0, LIMITS)
    move = plan.velocity_mps * LIMITS.period_s
    assert (np.hypot(*move.T) <= LIMITS.reach_m + 1e-9).all()
    i, j = np.nonzero(kept)
    moving = np.hypot(*move[i].T) > 0
    i, j = i[moving], j[moving]
    assert len(i) > 10
    for tau in np.linspace(0.0, 1.0, 11):
        at = pos[i] + tau * move[i]
        worst = np.hypot(*(at - m.xy[i, j]).T) + V * (T0 + tau * LIMITS.period_s - m.sent_s[i, j])
        assert (worst <= RC + 1e-6).all()


def test_leash_lets_a_robot_slide_along_a_taut_link():
    """Rule 2 allows motion along a taut link: the step is projected into the leash, not
    cut to nothing."""
    pos = np.array([[0.0, 0.0], [96.5, 0.0]])
    m = all_heard(pos, T0 - 0.1)  # leash: 99 - 2 x 1.1 = 96.8 m
    kept = m.known(T0, 20.0)
    plan = plan_local(pos, np.array([[0.0, 0.0], [2.0, 2.0]]), m, kept, T0, LIMITS)
    assert plan.velocity_mps[1, 1] > 1.0


# -- rule 3: hold ---------------------------------------------------------------------


def test_hold_a_robot_that_cannot_answer_for_a_kept_link_holds():
    """Rule 3: a robot farther from a kept robot's last-heard position than it can answer
    for now (its knowledge is too old) holds, whatever it wishes; its step is marked held."""
    pos = np.array([[0.0, 0.0], [96.0, 0.0]])
    m = all_heard(pos, T0 - 0.1)
    m.sent_s[0, 1] = T0 - 3.0  # robot 0 answers for 99 - 6 = 93 m now
    kept = m.known(T0, 20.0)
    plan = plan_local(pos, np.array([[0.0, 2.0], [0.0, 0.0]]), m, kept, T0, LIMITS)
    assert (plan.velocity_mps[0] == 0).all() and plan.held[0]


def test_hold_a_robot_forgets_a_robot_not_heard_for_release_s():
    """A robot remembers the latest Ack of each robot it heard (a later one replaces it,
    an earlier one does not), for release_s after the Ack was sent."""
    m = Memory(2)
    m.hear(np.array([0]), np.array([1]), np.array([[5.0, 5.0]]), np.array([3.0]), 0.01)
    m.hear(np.array([0]), np.array([1]), np.array([[1.0, 1.0]]), np.array([2.0]), 0.01)
    assert m.xy[0, 1].tolist() == [5.0, 5.0] and m.sent_s[0, 1] == pytest.approx(2.99)
    assert m.known(22.98, 20.0)[0, 1] and not m.known(23.0, 20.0)[0, 1]
    assert not m.known(5.0, 20.0)[1, 0]


def test_knowledge_an_ack_carries_its_senders_leg_until_the_next_step():
    """An Ack sent during its sender's current leg carries the leg's velocity: the position
    is carried along it to the step's start (exact up to the velocity times the send time's
    uncertainty); after the leg's end, and for an Ack sent before the leg began, only the
    speed cap bounds where the sender is."""
    m = Memory(3)
    vel = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 2.0]])
    leg_start = np.array([0.0, 9.0, 9.6])
    m.hear(
        np.array([0, 0]),
        np.array([1, 2]),
        np.array([[10.0, 0.0], [0.0, 10.0]]),
        np.array([9.5, 9.5]),
        0.1,
        vel,
        leg_start,
        10.1,
    )
    now = m.at(10.1, V, 0.05)
    assert now.xy[0, 1].tolist() == pytest.approx([10.7, 0.0])  # sent at 9.4 (at the earliest), carried 0.7 s
    assert V * (10.1 - now.sent_s[0, 1]) == pytest.approx(0.05)  # |v| x jitter
    assert now.xy[0, 2].tolist() == [0.0, 10.0]  # sent before its leg began
    assert V * (10.1 - now.sent_s[0, 2]) == pytest.approx(V * 0.7)
    later = m.at(11.1, V, 0.05)  # the leg may have changed at 10.1
    assert later.xy[0, 1].tolist() == pytest.approx([10.7, 0.0])
    assert V * (11.1 - later.sent_s[0, 1]) == pytest.approx(0.05 + V * 1.0)


# -- rule 4: pulls ----------------------------------------------------------------------


def test_pull_a_robot_follows_a_kept_robot_that_announced_it_moves_away():
    """Rule 4: robot 1, 95 m out, announced 2 m/s away from robot 0; robot 0's leash leaves
    1 m/s of slack, so robot 0 is pulled after it at the excess, 1 m/s. A wish heard before
    it was announced pulls nobody."""
    pos = np.array([[0.0, 0.0], [95.0, 0.0]])
    m = all_heard(pos, T0 - 0.5)  # leash: 99 - 2 (T0 + 1 - (T0 - 0.5)) = 96 m
    kept = m.known(T0, 20.0)
    announced = np.array([[0.0, 0.0], [2.0, 0.0]])
    out = pulls(pos, m, kept, announced, T0 - 1.0, T0, LIMITS)
    assert out[0].tolist() == pytest.approx([1.0, 0.0])
    assert out[1].tolist() == [0.0, 0.0]
    assert (pulls(pos, m, kept, announced, T0 - 0.1, T0, LIMITS) == 0).all()


def test_pull_a_robot_that_missed_the_latest_ack_uses_the_wish_of_the_one_before():
    """Rule 4 under loss: robot 0's latest Ack of robot 1 was sent after the step before
    last and before the last step, so it carried the wish announced at the step before
    last: robot 0 is pulled by that wish. An Ack sent before both announcements pulls
    nobody; one sent after the last uses the last wish."""
    pos = np.array([[0.0, 0.0], [92.0, 0.0]])
    m = all_heard(pos, T0 - 0.5)
    kept = m.known(T0, 20.0)
    last = (np.array([[0.0, 0.0], [0.0, 0.0]]), T0 - 1.0)
    before = (np.array([[0.0, 0.0], [3.0, 0.0]]), T0 - 2.0)
    m.sent_s[0, 1] = T0 - 1.5  # leash: 99 - 2 x 2.5 = 94 m, 2 m/s of slack
    out = latest_pulls(pos, m, kept, last, before, T0, LIMITS, m.sent_s)
    assert out[0].tolist() == pytest.approx([1.0, 0.0])
    m.sent_s[0, 1] = T0 - 2.5
    assert (latest_pulls(pos, m, kept, last, before, T0, LIMITS, m.sent_s) == 0).all()
    m.sent_s[0, 1] = T0 - 0.5
    assert (latest_pulls(pos, m, kept, last, before, T0, LIMITS, m.sent_s) == 0).all()


# -- rule 6: expansion --------------------------------------------------------------------


def test_expansion_a_robot_averages_its_centre_with_those_announced_in_the_acks_it_heard():
    """Rule 6: robot 0 heard robot 1 after robot 1's last announcement and robot 4 at its
    very instant (their latest centres count), robot 2 between the two announcements and
    robot 5 at the earlier one's instant (their earlier centres count), robot 3 before both
    (neither counts); robot 6 it never heard."""
    known = np.zeros((7, 7), bool)
    known[0, 1:6] = True
    sent = np.full((7, 7), -np.inf)
    sent[0, 1:6] = [T0 - 0.5, T0 - 1.5, T0 - 2.5, T0 - 1.0, T0 - 2.0]
    last = np.array([[0, 0], [10, 0], [100, 0], [1e3, 0], [30, 0], [1e3, 0], [1e4, 0]], dtype=float)
    earlier = np.array([[0, 0], [100, 0], [20, 0], [1e3, 0], [1e3, 0], [40, 0], [1e4, 0]], dtype=float)
    own = np.zeros((7, 2))
    own[0], own[1] = [0.0, 5.0], [7.0, 7.0]
    c = centre_estimates(own, known, sent, (last, T0 - 1.0), (earlier, T0 - 2.0))
    assert c[0].tolist() == pytest.approx([20.0, 1.0])  # (0 + 10 + 20 + 30 + 40) / 5, (5 + 0 + 0 + 0 + 0) / 5
    assert c[1:].tolist() == own[1:].tolist()  # who heard nobody keeps its own


def test_expansion_the_centres_of_a_connected_team_meet_inside_it():
    """Rule 6 as a consensus: on a star (one robot hearing four, each of them hearing it),
    Acks sent before the last announcement every other step (so the earlier announcement
    is used too), the estimates, started at the robots' own positions, meet at one point
    inside the team, nearer the robot that hears most than the plain mean is."""
    pos = np.array([[1000.0, 1000.0], [1090.0, 1000.0], [1000.0, 1090.0], [910.0, 1000.0], [1000.0, 950.0]])
    known = np.zeros((5, 5), bool)
    known[0, 1:] = known[1:, 0] = True
    centre, said, earlier = pos.copy(), (pos.copy(), -np.inf), (pos.copy(), -np.inf)
    for k in range(400):
        sent = np.where(known, k - (0.5 if k % 2 else 1.5), -np.inf)
        centre = centre_estimates(centre, known, sent, said, earlier)
        said, earlier = (centre.copy(), float(k)), said
    assert np.ptp(centre, axis=0).max() < 1e-9
    point = centre[0]
    assert (pos.min(axis=0) < point).all() and (point < pos.max(axis=0)).all()
    assert np.hypot(*(point - pos[0])) < np.hypot(*(pos.mean(axis=0) - pos[0]))


def test_expansion_a_robot_starts_from_its_own_position_and_goes_on_from_its_estimate():
    """Rule 6 in the controller: at the first control step each robot's estimate is its own
    position; at the next its previous estimate averaged with those announced at the first
    step, as the Acks it heard since carried them; and each step's estimate is what its
    Acks announce next, as of the step's instant."""
    from netsim.run import build

    sim = build(config.load(None, coverage_settings("unit disk", "local", 5, 0.0, 1, 13.0)))
    cov = sim.models["coverage"]
    start = sim.config.coverage.start_s
    sim.run(until_s=start + 0.5)
    first = cov.centre_m.copy()
    np.testing.assert_array_equal(first, sim.state.positions_at(start + cov.loop.lead_s))  # where the step starts
    assert cov.centre_announced[1] == start and np.isinf(cov.centre_earlier[1])
    sim.run(until_s=start + 1.5)
    known, sent = cov.heard.known, cov.memory.sent_s
    latest, older = carried(known, sent, start, math.inf)
    assert latest.any() and not older.any()
    expected = (first + latest.astype(float) @ first) / (1.0 + latest.sum(axis=1))[:, None]
    np.testing.assert_allclose(cov.centre_m, expected, rtol=1e-12)
    assert cov.centre_announced[1] == start + 1.0 and cov.centre_earlier[1] == start


@pytest.mark.slow
def test_expansion_unfolds_the_local_plans_team_past_its_even_disk():
    """From the dense start of ``netsim validate`` (100 robots, no loss): with rule 6 the
    local plan covers more of min(1, U(N) / A) than without it (``coverage.expansion = 0``),
    and its network never splits."""
    n = 100
    r = local_run(n, 1, 0.0)
    times, counts = true_components(r, n)
    assert counts[times > r.sim.config.coverage.start_s].max() == 1
    off = local_run(n, 1, 0.0, **{"coverage.expansion": 0.0})
    # Any change in a run's last digits moves where it ends (docs/model.md 5.2, "How far
    # single runs scatter"), so this asks that rule 6 covers more, not by how much.
    assert r.summary["covered_of_bound_all_final"] > off.summary["covered_of_bound_all_final"]


# -- rule 5: walls -------------------------------------------------------------------------

RES = 0.5
ORIGIN = (-10.0, -10.0)


def blocks_map(blocks, width_m=320.0, height_m=320.0):
    """An occupancy grid (0.5 m cells from ``ORIGIN``) with the rectangles ``blocks``
    (``x0, y0, x1, y1``, metres) occupied."""
    occ = np.zeros((int(height_m / RES), int(width_m / RES)), dtype=bool)
    for x0, y0, x1, y1 in blocks:
        c0, c1 = int((x0 - ORIGIN[0]) / RES), int(np.ceil((x1 - ORIGIN[0]) / RES))
        r0, r1 = int((y0 - ORIGIN[1]) / RES), int(np.ceil((y1 - ORIGIN[1]) / RES))
        occ[r0:r1, c0:c1] = True
    return occ


def wall_shapes(occ):
    """The occupied cells as one shapely geometry (closed squares)."""
    from shapely import box, unary_union

    rows, cols = np.nonzero(occ)
    x0, y0 = ORIGIN[0] + cols * RES, ORIGIN[1] + rows * RES
    return unary_union([box(a, b, a + RES, b + RES) for a, b in zip(x0, y0)])


def disks_hull(a, ea, b, eb, outer=True):
    """The convex hull of two disks, as a shapely polygon a hair larger than the true one
    (``outer``) or a hair smaller."""
    from shapely import GeometryCollection, Point

    grow = 1.0 / math.cos(math.pi / 256) + 1e-9 if outer else 1.0  # 64 segments a quarter
    return GeometryCollection([Point(a).buffer(ea * grow, 64), Point(b).buffer(eb * grow, 64)]).convex_hull


@pytest.mark.slow
def test_walls_a_pair_of_disks_is_clear_exactly_when_its_hull_keeps_off_every_wall():
    """The walls' test is exact: it says clear exactly when the convex hull of the two disks
    keeps more than ``clearance_m`` from every occupied cell (closed squares, shapely, its
    polygons a hair outside and inside the true hull). Disks of equal and unequal radii,
    and segments grazing a wall's side and corner within a cell of their radius."""
    rng = np.random.default_rng(5)
    occ = blocks_map([(40, 40, 42, 120), (100, 0, 160, 3), (200, 200, 201, 201), (60, 150, 150, 151)], 250.0, 250.0)
    walls, shapes = walls_of(occ, ORIGIN, RES), wall_shapes(occ)
    a = rng.uniform(0, 220, (400, 2))
    b = a + rng.normal(0, 30, (400, 2))
    ea = rng.uniform(0, 5, 400)
    eb = np.where(rng.random(400) < 0.5, ea, rng.uniform(0, 5, 400))
    graze = rng.uniform(0, 5, 200)
    x = 42.0 + graze + rng.uniform(-0.5, 0.5, 200)
    a = np.r_[a, np.c_[x, rng.uniform(20, 60, 200)]]
    b = np.r_[b, np.c_[x, rng.uniform(80, 140, 200)]]
    ea, eb = np.r_[ea, graze], np.r_[eb, graze]
    said = clear_of_walls(walls, a, b, ea, eb)
    gap = np.array([disks_hull(p, u, q, w).distance(shapes) for p, u, q, w in zip(a, ea, b, eb)])
    inner = np.array([disks_hull(p, u, q, w, outer=False).distance(shapes) for p, u, q, w in zip(a, ea, b, eb)])
    assert (gap[said] > 0).all()
    assert said[inner > walls.clearance_m + 1e-6].all()
    assert ((inner > walls.clearance_m + 1e-6) & (inner < RES)).sum() > 50
    assert said.sum() > 100 and (~said).sum() > 20


def test_walls_a_step_and_a_disk_are_clear_exactly_when_their_hull_keeps_off_every_wall(monkeypatch):
    """Rule 5's walls' test of a step is exact: it says clear exactly when the convex hull of
    the step (a segment) and the disk where the other end can be keeps more than
    ``clearance_m`` from every occupied cell
    (shapely, the disk's polygon a hair outside and inside the true disk), plain and
    compiled; steps grazing a wall's side within a cell."""
    from shapely import GeometryCollection, LineString, Point

    rng = np.random.default_rng(8)
    occ = blocks_map([(40, 40, 42, 120), (100, 0, 160, 3), (60, 150, 150, 151)], 250.0, 250.0)
    walls, shapes = walls_of(occ, ORIGIN, RES), wall_shapes(occ)
    n = 150
    p = np.r_[rng.uniform(0, 220, (n, 2)), np.c_[42.0 + rng.uniform(0, 1.0, n), rng.uniform(20, 140, n)]]
    move = rng.normal(0, 2.0, (2 * n, 2))
    move[::5, 1] = 0.0
    q = p + rng.normal(0, 20, (2 * n, 2))
    e = rng.uniform(0, 3, 2 * n)
    e[::7] = 0.0
    grow = 1.0 / math.cos(math.pi / 256) + 1e-9

    def gap(k, scale):
        disk = Point(q[k]).buffer(e[k] * scale, 64) if e[k] > 0 else Point(q[k])
        step = LineString([p[k], p[k] + move[k]])
        return GeometryCollection([step, disk]).convex_hull.distance(shapes)

    outer = np.array([gap(k, grow) for k in range(2 * n)])
    inner = np.array([gap(k, 1.0) for k in range(2 * n)])
    for flag in ("0", "1"):
        monkeypatch.setenv("NETSIM_COMPILED", flag)
        said = step_clear_of_walls(walls, p, move, q, e)
        assert (outer[said] > 0).all()
        assert said[inner > walls.clearance_m + 1e-6].all()
    assert ((inner > walls.clearance_m + 1e-6) & (inner < RES)).sum() > 10
    assert said.sum() > 50 and (~said).sum() > 20


def test_walls_a_hull_of_unknown_extent_is_not_clear():
    """The walls' test proves nothing of a disk of infinite radius or a point not a number
    (and ends: its walk steps by the clearance less the reach)."""
    walls = walls_of(blocks_map([(40, 40, 42, 120)], 100.0, 100.0), ORIGIN, RES)
    a = np.array([[0.0, 0.0], [0.0, 0.0], [0.0, 0.0]])
    b = np.array([[10.0, 0.0], [np.nan, 0.0], [10.0, 0.0]])
    assert clear_of_walls(walls, a, b, np.array([np.inf, 0.1, 0.1])).tolist() == [False, False, True]
    said = step_clear_of_walls(
        walls, a, np.array([[np.inf, 0.0], [1.0, 0.0], [1.0, 0.0]]), b, np.array([0.1, 0.1, np.inf])
    )
    assert said.tolist() == [False, False, False]
    # Plain, as NETSIM_COMPILED=0 runs it: the same answers, and no warning (infinite radii
    # taken apart, inf - inf, warned).
    plain = importlib.import_module("netsim.mobility._local_kernels")
    out = np.empty(3, dtype=bool)
    e = np.array([np.inf, 0.1, 0.1])
    plain.clear_many(walls, np.ascontiguousarray(a), np.ascontiguousarray(b), e, e.copy(), out)
    assert out.tolist() == [False, False, True]


def test_walls_kernel_agrees_with_its_oracle(monkeypatch):
    """The walls' test, plain and compiled, says exactly what its oracle (the least distance
    over the hull's disks, by ternary search) says: on random hulls, and on hulls whose
    straight side passes a wall's corner within 30 nm to 0.3 m."""
    rng = np.random.default_rng(6)
    occ = blocks_map([(40, 40, 42, 120), (100, 0, 160, 3), (60, 150, 150, 151)], 250.0, 250.0)
    walls = walls_of(occ, ORIGIN, RES)
    a = rng.uniform(0, 220, (300, 2))
    b = a + rng.normal(0, 30, (300, 2))
    ea, eb = rng.uniform(0, 5, (2, 300))
    corners = np.array([[40, 40], [42, 40], [42, 120], [40, 120], [100, 3], [160, 3], [60, 151], [150, 150]], float)
    n = 300
    corner = corners[rng.integers(len(corners), size=n)]
    angle = rng.uniform(0, 2 * np.pi, n)
    along = np.c_[np.cos(angle), np.sin(angle)]
    side = rng.choice([-1.0, 1.0], n)[:, None] * np.c_[-along[:, 1], along[:, 0]]
    graze_ea = np.where(rng.random(n) < 0.4, 0.0, rng.uniform(0, 2, n))
    graze_eb = np.where(rng.random(n) < 0.5, graze_ea, rng.uniform(0, 2, n))
    centre = corner + side * (10 ** rng.uniform(-7.5, -0.5, n) + 0.5 * (graze_ea + graze_eb))[:, None]
    a = np.r_[a, centre - along * rng.uniform(0.5, 15, n)[:, None]]
    b = np.r_[b, centre + along * rng.uniform(0.5, 15, n)[:, None]]
    ea, eb = np.r_[ea, graze_ea], np.r_[eb, graze_eb]
    want = oracle.clear_of_walls(walls, a, b, ea, eb)
    assert 0 < want[:300].sum() < 300 and 0 < want[300:].sum() < n
    assert (want == clear_of_walls(walls, a, b, ea, eb)).all()
    plain = importlib.import_module("netsim.mobility._local_kernels")
    out = np.empty(len(a), dtype=bool)
    plain.clear_many(walls, np.ascontiguousarray(a), np.ascontiguousarray(b), ea, eb, out)
    assert (want == out).all()


def test_walls_a_robot_stopped_at_a_wall_keeps_its_links_along_it():
    """The control loop stops a robot a hair short of a wall (netsim.world.free_space); a
    link from there along the wall, to a robot known exactly, is clear (its hull keeps more
    than ``clearance_m`` from the wall), and the robot may step away along it."""
    from netsim.world.free_space import short_of_walls
    from netsim.world.maps import OccupancyMap

    occ = blocks_map([(0, 20, 100, 21)], 100.0, 60.0)
    walls = walls_of(occ, ORIGIN, RES)
    grid = OccupancyMap(occ, ~occ, RES, ORIGIN)
    start = np.array([[30.0, 19.0]])
    stopped = start + short_of_walls(grid, start, np.array([[0.0, 5.0]]), 1.0)
    assert 19.999 < stopped[0, 1] < 20.0
    other = stopped + [[15.0, 0.0]]
    assert clear_of_walls(walls, stopped, other, np.zeros(1))[0]
    assert step_clear_of_walls(walls, stopped, np.array([[2.0, -1.0]]), other, np.zeros(1))[0]
    assert not clear_of_walls(walls, stopped, other + [[0.0, 0.01]], np.zeros(1))[0]


def test_walls_a_robot_that_keeps_no_link_moves_as_it_wished():
    """Rule 5 asks nothing of a robot that keeps no link, even when no robot keeps one."""
    pos = np.array([[0.0, 0.0], [50.0, 0.0]])
    m = all_heard(pos, T0 - 0.1)
    kept = np.zeros((2, 2), dtype=bool)
    move = np.array([[0.0, -2.0], [1.0, 0.0]])
    walls = walls_of(blocks_map([(10.0, -5.0, 10.5, 5.0)], 80.0, 40.0), ORIGIN, RES)
    assert (cut_for_walls(pos, move, m, kept, T0 + LIMITS.period_s, LIMITS, walls) == move).all()


@pytest.mark.slow
def test_detour_on_a_map_needs_links_surely_clear_of_walls(monkeypatch):
    """Rule 1 on a map: robot 0 lets go of robot 1 through robot 2 (as in open space) only
    when the detour's links are surely clear of walls: a pillar on the link from robot 2 to
    robot 1 (and none on the link from 0 to 1) keeps the link (0, 1); plain and compiled
    kernels agree with the oracle."""
    pos = np.array([[0.0, 0.0], [80.0, 0.0], [40.0, 20.0]])
    m = all_heard(pos, T0 - 0.5)
    pillar = walls_of(blocks_map([(59.5, 9.5, 60.5, 10.5)], 120.0, 60.0), ORIGIN, RES)
    far = walls_of(blocks_map([(59.5, 29.5, 60.5, 30.5)], 120.0, 60.0), ORIGIN, RES)
    assert let_go(pos, m, told(m), T0, V, 10.0, RC, far)[0, 1]
    assert not let_go(pos, m, told(m), T0, V, 10.0, RC, pillar)[0, 1]
    for seed in range(5):
        pos, m = random_scene(seed, n=40)
        walls = walls_of(blocks_map([(100, 50, 102, 250), (150, 100, 300, 101)]), ORIGIN, RES)
        out = []
        for flag in ("0", "1"):
            monkeypatch.setenv("NETSIM_COMPILED", flag)
            out.append(let_go(pos, m, told(m), T0, V, 10.0, RC, walls))
        want = oracle.let_go(pos, m, told(m), T0, V, 10.0, RC, walls)
        assert (out[0] == want).all() and (out[1] == want).all()


def test_walls_a_robot_moves_only_while_its_kept_links_stay_clear_of_walls():
    """Rule 5: robot 0 keeps robot 1, 20 m east, heard 0.1 s ago, so standing within 0.2 m of
    where it was heard (it holds, rule 7), and steps 2 m south. The hull of its step and of
    that disk spans, where a pillar stands 10 m east, from 0.1 m north of the link to 1.1 m
    south of it. With no wall near, or a pillar 0.3 m north of the link (which the hull with
    the disk of 2.2 m where robot 1 could be by the step's end, were it moving, would meet),
    it makes its whole step; with a pillar 1 m south, half of it; with a pillar touching the
    link from the south, it holds."""
    pos = np.array([[0.0, 0.0], [20.0, 0.0]])
    m = all_heard(pos, T0 - 0.1)
    kept = m.known(T0, 20.0)
    move = np.array([[0.0, -2.0], [0.0, 0.0]])
    t1 = T0 + LIMITS.period_s

    def scale(y0, y1):
        walls = walls_of(blocks_map([(10.0, y0, 10.5, y1)], 60.0, 40.0), ORIGIN, RES)
        return cut_for_walls(pos, move, m, kept, t1, LIMITS, walls)[0, 1] / move[0, 1]

    assert scale(15.0, 15.5) == 1.0
    assert scale(0.5, 1.0) == 1.0
    walls = walls_of(blocks_map([(10.0, 0.5, 10.5, 1.0)], 60.0, 40.0), ORIGIN, RES)
    assert not step_clear_of_walls(walls, pos[:1], move[:1], pos[1:], np.array([2.2]))[0]
    assert scale(-1.5, -1.0) == 0.5
    assert scale(-0.5, 0.0) == 0.0
    assert (cut_for_walls(pos, move, m, kept, t1, LIMITS, NO_WALLS) == move).all()


@pytest.mark.parametrize("seed", range(8))
def test_walls_every_kept_link_stays_clear_of_walls_over_the_step_while_the_other_holds(seed):
    """Rule 5, the argument: for every link a moving robot keeps, the convex hull of its step
    and of the disk where the other end stands (it holds: rule 7; every segment between
    them at every instant) meets no wall (shapely, exact), and the leash of rule 2 still
    holds at the step's end (both ends moving in turns: tests/test_coverage_local_map.py)."""
    from shapely import GeometryCollection, LineString, Point

    pos, m = random_scene(seed, n=30)
    occ = blocks_map([(100, 50, 102, 250), (150, 100, 300, 101), (40, 200, 80, 204)])
    walls, shapes = walls_of(occ, ORIGIN, RES), wall_shapes(occ)
    known = m.known(T0, 20.0)
    kept = known & ~let_go(pos, m, told(m), T0, V, 10.0, RC, walls)
    wish = np.random.default_rng(seed).normal(0, 3.0, pos.shape)
    move = plan_local(pos, wish, m, kept, T0, LIMITS).velocity_mps * LIMITS.period_s
    t1 = T0 + LIMITS.period_s
    move = cut_for_walls(pos, move, m, kept, t1, LIMITS, walls)
    i, j = np.nonzero(kept & (np.hypot(*move.T) > 0)[:, None])
    assert len(i) > 10
    for a, b in zip(i.tolist(), j.tolist()):
        e = V * (T0 - m.sent_s[a, b])
        step = LineString([pos[a], pos[a] + move[a]]) if (move[a] != 0).any() else Point(pos[a])
        hull = GeometryCollection([step, Point(m.xy[a, b]).buffer(e * 1.001 + 1e-9, 64)]).convex_hull
        assert not hull.intersects(shapes)
        assert np.hypot(*(pos[a] + move[a] - m.xy[a, b])) + e <= RC - LIMITS.margin_m + 1e-6


# -- whole runs --------------------------------------------------------------------------


def local_run(n, seed, loss=0.0, duration=600, **extra):
    overrides = coverage_settings("unit disk", "local", n, loss, seed, duration)
    if "channel.propagation" in extra:
        # Another radio in place of the unit disk, whose range its law would ignore.
        overrides = [o for o in overrides if not o.startswith("channel.range_m=")]
    return execute(config.load(None, overrides + [f"{k}={v!r}".replace("'", '"') for k, v in extra.items()]))


def true_components(r, n):
    links = r.frames["links"]
    return components_at_link_events(
        *(links[c].to_numpy() for c in ("a", "b", "t_up_s", "t_down_s", "censored_end")), n
    )


@pytest.mark.slow
@pytest.mark.parametrize(
    "n,loss,floor",
    [(20, 0.0, 0.6), (20, 0.3, 0.6), (60, 0.0, 0.6), (60, 0.3, 0.6), (200, 0.0, 0.6), (200, 0.3, 0.6)],
)
def test_local_plan_never_splits_the_network_and_covers_the_bound(n, loss, floor):
    """From a dense start, with 0 or 30 % of receptions lost: the true network (the links of
    links.parquet) has one component when control starts and at every link event after;
    the disks end covering at least ``floor`` of min(1, U(N) / A)."""
    r = local_run(n, 1, loss)
    times, counts = true_components(r, n)
    start = r.sim.config.coverage.start_s
    assert counts[times <= start][-1] == 1
    assert counts[times > start].max() == 1
    assert (times > start).sum() > 10  # links do go up and down under control
    assert r.summary["covered_of_bound_all_final"] >= floor


@pytest.mark.slow
def test_local_plan_keeps_a_log_distance_network_without_shadowing():
    """Under log-distance path loss without shadowing a link is a disk of the implied range:
    the local plan keeps the true network in one component."""
    n = 20
    r = local_run(n, 2, duration=120, **{"channel.propagation": "log_distance", "channel.tx_power_dbm": 23.0})
    rc = float(r.sim.state.range_m[0])
    assert rc == pytest.approx(10 ** (63 / 30))  # the implied range, not channel.range_m
    times, counts = true_components(r, n)
    assert counts.max() == 1 and (times > 10.0).sum() > 10
    assert r.summary["covered_fraction_all_final"] > 1.5 * r.summary["covered_fraction_all_start"]
    assert components(r.sim.state.positions_at(r.sim.now), rc).max() == 0


@pytest.mark.slow
@pytest.mark.parametrize(
    "radio, n", [("shadowing 4 dB", 60), ("office, line of sight", 40), ("office, 5 dB a wall", 40)]
)
def test_local_plan_never_splits_the_real_network_on_every_radio(radio, n):
    """Under shadowing (links kept by the shadowing each robot measured on them) and on
    the office map (links kept clear of walls over each step, or at 5 dB a wall within the
    range through the walls they can cross; line of sight, and 5 dB a wall), from a dense
    start (the scenario of ``netsim validate`` item 30): the real
    network (links.parquet) never has more components after control starts than at its
    start, and the coverage table reports it truly."""
    from netsim.tools.validate import coverage_run

    o = coverage_run(radio, "local", n, 0.0, 1, 600.0)
    assert o["components_max"] == o["components_at_start"]
    assert o["table_true"]
    assert o["of_bound"] > 0.1


def test_shadowing_the_local_plans_range_is_the_sure_distance():
    """Under shadowing the local plan's range (rules 1 to 3) is the sure distance: where a
    link with the worst shadowing the channel uses (clipped at +4 sigma) has a margin of
    exactly 0, well inside the implied range; without shadowing it is the implied range."""
    from netsim.radio.propagation import path_loss_db

    log = {"channel.propagation": "log_distance", "channel.tx_power_dbm": 23.0}
    log["coverage.start_s"] = 0.0  # a control step inside the short run
    plain = local_run(6, 1, duration=1, **log).sim.models["coverage"]
    shadowed = local_run(6, 1, duration=1, **log, **{"channel.shadowing_sigma_db": 4.0}).sim.models["coverage"]
    r = shadowed.local_limits.range_m
    p = shadowed.rules.log
    assert p.budget_db + p.reference_loss_db - path_loss_db(np.array([r]), p)[0] - 16.0 == pytest.approx(0.0, abs=1e-9)
    assert plain.local_limits.range_m == pytest.approx(plain.range_m) and r < 0.5 * plain.range_m


@pytest.mark.slow
def test_local_plan_every_robot_decides_its_own_step_no_command_is_sent():
    """With the local plan no leader sends commands: every robot moves by its own decision
    (members included), and the moves are the same whatever the roles."""
    r = local_run(20, 3, duration=60)
    assert r.sim.channel.counters_for("command").sent.sum() == 0
    legs = r.sim.state.legs()
    assert legs["robot"].nunique() == 20


# -- bad input -------------------------------------------------------------------------


@pytest.mark.parametrize(
    "overrides, key",
    [
        (['coverage.plan="central"'], "coverage.plan"),
        (['coverage.plan="local"', 'coverage.knowledge="global"'], "coverage.plan"),
        (['coverage.plan="local"', 'coverage.members="follow"'], "coverage.plan"),
        (
            ["coverage.enabled=true", 'mobility.model="static"', 'coverage.plan="local"', 'channel.mac="aloha"'],
            "coverage.plan",
        ),
        (["coverage.release_s=0"], "coverage.release_s"),
        (["coverage.band_m=-1"], "coverage.band_m"),
    ],
)
def test_bad_plan_is_one_line_exit_2_nothing_written(tmp_path, capsys, overrides, key):
    with pytest.raises(ConfigError) as err:
        config.load(None, overrides)
    assert err.value.key == key
    out = tmp_path / "out"
    argv = ["run", "--quiet", "--out", str(out)]
    for o in overrides:
        argv += ["--set", o]
    assert main(argv) == 2
    msg = capsys.readouterr().err.strip()
    assert msg.startswith(f"netsim: error: {key} = "), msg
    assert "\n" not in msg
    assert not out.exists()


@pytest.mark.parametrize("compiled", ["0", "1"])
def test_a_robot_remembers_another_while_its_latest_ack_is_younger_than_release_s(monkeypatch, compiled):
    """Rule of memory: an Ack sent exactly ``release_s`` ago is forgotten, one a hair younger
    remembered, one never heard (sent at minus infinity) never; the same for a number, a
    row and the robots' (n, n) memory, whose shape it keeps."""
    from netsim.mobility.local import Memory, remembered

    monkeypatch.setenv("NETSIM_COMPILED", compiled)
    release_s, now = 20.0, 50.0
    sent = np.array([now - release_s, np.nextafter(now - release_s, now), now, -np.inf])
    assert remembered(sent, now, release_s).tolist() == [False, True, True, False]
    m = Memory(2)
    m.sent_s[:] = [[-np.inf, now - release_s], [np.nextafter(now - release_s, now), -np.inf]]
    assert m.known(now, release_s).tolist() == [[False, False], [True, False]]
