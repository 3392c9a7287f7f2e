"""One test per clustering rule (docs/model.md 4.2), on small scripted topologies.

Robots are static unless a test moves them; loss is off, jitter is off and beacon phases
are set by hand, so every event time is known. A phase above the Ack period is a robot
switched on later. A robot that becomes a leader at the instant of its own Ack sends that
Ack with its old role (deadlines come after every message of their instant), so its
first Ack as a leader comes one period later: a robot that is to join it must have
started more than a period after it.
"""

import numpy as np
import pytest
from netsim.protocols.clustering import TRANSITIONS, Candidate, merge_loser, rules_record, transition
from netsim.protocols.roles import LEADER, MEMBER, UNDECIDED

from tests.fixtures import clustering
from tests.oracles.protocols import deadline

TAU, PERIOD, LATENCY = 3.0, 1.0, 0.001


def scripted(positions, phases, range_m=10.0, latency_s=LATENCY, **protocol):
    core = {"range_m": range_m, "latency_s": latency_s, "side_m": 10_000.0}
    timing = {"ack_period_s": PERIOD, "ack_jitter_s": 0.0, "tau_s": TAU}
    sim, stack = clustering(positions, phases, core=core, **{**timing, **protocol})
    deliveries = []  # (t, sender, receivers) of every Ack
    stack.beacon.listeners.append(lambda now, ack, rec, hm: deliveries.append((now, ack.sender, set(rec.tolist()))))
    return sim, stack, deliveries


def roles(sim):
    return sim.trace.frame("roles")


def records(sim, robot):
    r = roles(sim)
    return r[(r.robot == robot) & (r.cause != "rule1_start")].reset_index(drop=True)


def move_away(sim, robot, at_s):
    def go():
        yield sim.env.timeout(at_s - sim.env.now)
        sim.state.set_leg(robot, sim.env.now, (0.0, 0.0), start_m=(9000.0, 9000.0))

    sim.env.process(go())


def last_delivery(deliveries, sender, receiver, before):
    return max(t for t, s, rec in deliveries if s == sender and receiver in rec and t <= before)


def test_rule1_every_robot_starts_undecided_and_beacons():
    sim, stack, _ = scripted([[0, 0], [50, 0], [100, 0]], [0.1, 0.2, 0.3])
    sim.run(until_s=2.5)
    start = roles(sim)
    assert (start.cause == "rule1_start").sum() == 3
    assert set(start[start.cause == "rule1_start"].role) == {"gamma"}
    assert (stack.role == UNDECIDED).all()
    assert sim.channel.counters_for("ack").sent.tolist() == [3, 3, 3]


def test_rule4_undecided_robot_that_hears_no_leader_becomes_leader_after_tau():
    """An isolated robot becomes alpha exactly tau after its protocol started."""
    sim, stack, _ = scripted([[0, 0], [50, 0]], [0.25, 0.6])
    sim.run(until_s=10)
    for i, phase in enumerate([0.25, 0.6]):
        rec = records(sim, i)
        assert rec.cause.tolist() == ["rule4_no_leader"]
        assert rec.t_s[0] == deadline(phase, TAU)
        assert rec.role[0] == "alpha" and rec.leader[0] == i


def test_rule2_undecided_robot_joins_the_leader_it_hears():
    """Robot 1, switched on 1.5 s after robot 0, hears robot 0's first Ack as alpha and
    joins before its own timeout."""
    sim, stack, deliveries = scripted([[0, 0], [5, 0]], [0.1, 1.6])
    sim.run(until_s=10)
    assert records(sim, 0).cause.tolist() == ["rule4_no_leader"]
    joined = records(sim, 1)
    assert joined.cause.tolist() == ["rule2_join"]
    assert (joined.role[0], joined.leader[0]) == ("beta", 0)
    # Robot 0 became alpha at 3.1, after its Ack of that instant; it joined on the first
    # Ack robot 0 sent as a leader (sent at 4.1, delivered 1 ms later).
    assert records(sim, 0).t_s[0] == deadline(0.1, TAU)
    assert joined.t_s[0] == pytest.approx(4.1 + LATENCY, abs=1e-12)
    assert (stack.role == [LEADER, MEMBER]).all()


@pytest.mark.parametrize("policy, expected", [("nearest", 1), ("lowest_id", 0)])
def test_rule2_join_policy_chooses_among_known_leaders(policy, expected):
    """Member 3 of leader 2 also hears leaders 0 (10 m away) and 1 (8 m away); when 2
    leaves, it joins the leader its policy picks, at once (rule 6 joining first)."""
    pos = [[18, 0], [0, 0], [8, -9], [8, 0]]  # ids: 0 = B (far), 1 = A (near), 2 = X, 3 = m
    sim, stack, deliveries = scripted(pos, [0.6, 0.3, 0.0, 1.9], join_policy=policy, join_before_election=True)
    move_away(sim, 2, 10.0)
    sim.run(until_s=20)
    rec = records(sim, 3)
    assert rec.cause.tolist() == ["rule2_join", "rule3_leader_lost", "rule2_join"]
    assert rec.leader.tolist() == [2, -1, expected]
    assert rec.t_s[1] == rec.t_s[2]


def test_rule3_member_whose_leader_leaves_becomes_undecided_exactly_tau_after_last_ack():
    sim, stack, deliveries = scripted([[0, 0], [5, 0]], [0.1, 1.6], election_policy="none")
    move_away(sim, 0, 10.0)
    sim.run(until_s=30)
    rec = records(sim, 1)
    assert rec.cause.tolist() == ["rule2_join", "rule3_leader_lost", "rule4_no_leader"]
    last = last_delivery(deliveries, 0, 1, before=10.0)
    assert rec.t_s[1] == deadline(last, TAU)  # exact to the instant
    assert rec.role[1] == "gamma"
    assert rec.t_s[2] == deadline(deadline(last, TAU), TAU)  # then rule 4, tau later


@pytest.mark.parametrize(
    "phases, causes, times",
    [
        ([0.5, 1.75], ["rule2_join"], [3.5]),
        # Robot 1's deadlines all fall at the instant of its own Ack as well.
        ([0.5, 1.5], ["rule2_join"], [3.5]),
        # Equal phases: neither hears a leader before its deadline; both become leaders at
        # 2.5, first hear each other as leaders at 3.5 (their first Acks as leaders), and
        # merge merge_delay (2 s) after that, not at once.
        ([0.5, 0.5], ["rule4_no_leader", "rule5_merge_yield"], [deadline(0.5, 2.0), 5.5]),
        # A phase no binary fraction holds: an Ack tau after the last reaches the member at
        # its timer's instant to the last bit, and the table, which read ``now - last <
        # tau``, must not end the entry there (it restarted it, from 8.1 on, then 16.1).
        ([0.1, 1.35], ["rule2_join"], [3.1]),
    ],
)
def test_ack_at_the_deadline_instant_counts(phases, causes, times):
    """With no latency and every other Ack of the leader lost, the member hears its leader
    at t and t + 2 = its deadline (tau = 2 periods): that Ack is processed first, counts,
    and the member never times out, even when its own Ack is due at the same instant."""
    sim, stack, deliveries = scripted([[0, 0], [5, 0]], phases, tau_s=2.0, latency_s=0.0)

    def every_other(sender, receivers, distances):
        odd = sim.env.now > 7 and int(round(sim.env.now - phases[0])) % 2 == 1
        return np.zeros(len(receivers), dtype=bool) if sender == 0 and odd else None

    sim.channel.survives = every_other
    sim.run(until_s=30)
    heard = sorted(t for t, s, rec in deliveries if s == 0 and 1 in rec and t > 8)
    assert np.diff(heard).min() == 2.0  # the gaps are exactly tau
    rec = records(sim, 1)
    assert rec.cause.tolist() == causes
    assert rec.t_s.tolist() == times
    # An Ack exactly tau after the previous one continues the entry: live without a break.
    assert stack.table.live_since_s[1, stack.table.entry(1, 0)] < 7.0
    assert records(sim, 0).cause.tolist() == ["rule4_no_leader"]
    assert stack.role.tolist() == [LEADER, MEMBER]


@pytest.mark.parametrize("latency_s", [0.001, 0.0123])
def test_an_ack_due_at_the_deadline_counts_however_its_instant_rounds(latency_s):
    """With latency, the deadline (the last Ack's arrival plus tau) and the arrival of the
    Ack sent tau later are sums rounded apart: the arrival may fall a few 1e-14 s past the
    deadline. It still counts (TIE_S): a member that hears its leader every third Ack, tau =
    3 periods, never times out, at any phase."""
    timeouts = []
    for phase in np.random.default_rng(0).uniform(0.0, 0.5, 12).tolist():
        sim, stack, _ = scripted([[0, 0], [5, 0]], [phase, phase + 1.2], latency_s=latency_s, election_policy="none")
        sent = [0]

        def every_third(sender, receivers, distances, sim=sim, sent=sent):
            if sender != 0 or sim.env.now < 20:
                return None
            sent[0] += 1
            return None if sent[0] % 3 == 0 else np.zeros(len(receivers), dtype=bool)

        sim.channel.survives = every_third
        sim.run(until_s=80.0)
        timeouts.append(int((records(sim, 1).cause == "rule3_leader_lost").sum()))
    assert timeouts == [0] * 12


def test_rule6_a_member_that_joins_another_leader_at_once_times_out_from_that_leaders_last_ack():
    """Member 2 of leader 1 also hears leader 0. Leader 1 leaves: at 2's deadline it
    joins leader 0 at once (rule 6 joining first, then rule 2), its timer running from
    leader 0's last Ack, not from the instant it joined: leader 0 leaves too, and 2 becomes
    undecided exactly tau after the last Ack it had from 0 (a timer from the join ran nearly
    a period longer)."""
    sim, stack, deliveries = scripted([[-9, 0], [6, 0], [0, 0]], [0.1, 0.05, 1.6], join_before_election=True)
    move_away(sim, 1, 10.5)
    move_away(sim, 0, 12.5)
    sim.run(until_s=30)
    rec = records(sim, 2)
    assert rec.cause.tolist()[:4] == ["rule2_join", "rule3_leader_lost", "rule2_join", "rule3_leader_lost"], rec
    assert rec.leader.tolist()[:3] == [1, -1, 0]
    assert rec.t_s[1] == deadline(last_delivery(deliveries, 1, 2, before=10.5), TAU)
    assert rec.t_s[2] == rec.t_s[1]  # joined at once
    assert rec.t_s[3] == deadline(last_delivery(deliveries, 0, 2, before=12.5), TAU) < deadline(rec.t_s[2], TAU)


def test_rule3_a_timer_and_the_table_agree_on_when_an_entry_ends():
    """Member 2 hears leaders 0 and 1 at one instant ``a``; both leave. At its timer's
    instant ``a + tau`` no entry of either may still be live: in floating point ``(a + tau)
    - a`` falls short of ``tau`` for this ``a``, and the table, read as ``now - a < tau``,
    held leader 1 live, so rule 6 joined it with its timer already due, which fired at
    once, and the member went from leader to leader at that instant for ever (the run hung)."""
    a_phase = 0.8958384524320082
    sim, stack, _ = scripted([[-8, 0], [8, 0], [0, 0]], [a_phase, a_phase, a_phase + 1.3])
    changes: list[float] = []

    def at_one_instant(event):
        changes.append(event.t_s)
        if changes.count(event.t_s) > 10:
            raise AssertionError(f"robot roles go round at t = {event.t_s!r}")

    sim.events.on("role_change", at_one_instant)
    for leader in (0, 1):
        move_away(sim, leader, 7.0 - a_phase / 2)
    sim.run(until_s=8.8)
    a = stack.table.last_heard_s[2, stack.table.entry(2, 1)]
    assert (a + TAU) - a < TAU  # the rounding this test is about
    sim.run(until_s=20)
    rec = records(sim, 2)
    assert rec.cause.tolist() == ["rule2_join", "rule3_leader_lost", "rule6_elected"], rec
    assert rec.t_s.iloc[-2] == deadline(stack.table.last_heard_s[2, stack.table.entry(2, 0)], TAU)


def test_rule3_only_two_way_acks_renew_a_member():
    """Rule 3: only the leader's Acks over a two-way link renew a member (docs/model.md
    4.1). Member 1 (range 5 m) joins leader 0 (range 15 m) at 4 m, then stands 10 m away at
    t = 10: it still hears every Ack of 0, but 0 no longer hears it, and once 0's entry of
    1 expires its Acks stop listing 1. Those one-way Acks must not renew 1: it becomes
    undecided exactly tau after the last Ack that listed it. A member renewed by any Ack of
    its leader stayed in a group its leader knew nothing of, for ever."""
    sim, stack, deliveries = scripted([[0, 0], [4, 0]], [0.1, 1.6], range_m=[15.0, 5.0])
    two_way = []  # when 0's Acks reached 1, and whether they listed it

    def listed(now, ack, receivers, hears_me):
        if ack.sender == 0 and 1 in receivers:
            two_way.append((now, bool(hears_me[receivers.tolist().index(1)])))

    stack.beacon.listeners.append(listed)

    def step_back():
        yield sim.env.timeout(10.0)
        sim.state.set_leg(1, sim.env.now, (0.0, 0.0), start_m=(10.0, 0.0))

    sim.env.process(step_back())
    sim.run(until_s=25)
    rec = records(sim, 1)
    assert rec.cause.tolist()[:2] == ["rule2_join", "rule3_leader_lost"], rec
    last = max(t for t, listed in two_way if listed)
    one_way = [t for t, listed in two_way if not listed and last < t < rec.t_s[1]]
    assert len(one_way) >= 2  # 1 heard 0's one-way Acks meanwhile
    assert rec.t_s[1] == deadline(last, TAU)


def test_rule5_neighbouring_leaders_merge_and_the_smaller_group_yields():
    """Group {0, 1, 2} (leader 0) and group {3, 4} (leader 3) come into range at t = 10;
    after merge_delay the smaller group's leader yields and its member re-affiliates at once."""
    pos = [[0, 0], [-5, 0], [0, 5], [100, 0], [105, 0]]
    sim, stack, deliveries = scripted(pos, [0.1, 0.5, 0.6, 0.2, 0.7])

    def bring():
        yield sim.env.timeout(10.0)
        sim.state.set_leg(3, 10.0, (0.0, 0.0), start_m=(8.0, 0.0))
        sim.state.set_leg(4, 10.0, (0.0, 0.0), start_m=(9.0, -3.0))

    sim.env.process(bring())
    sim.run(until_s=30)
    assert stack.role.tolist()[:3] == [LEADER, MEMBER, MEMBER]
    yield_rec = records(sim, 3)
    assert yield_rec.cause.tolist() == ["rule4_no_leader", "rule5_merge_yield"]
    assert yield_rec.leader[1] == 0
    # The link 0-3 came up with the first Ack heard across it after t = 10.
    first = min(t for t, s, rec in deliveries if t > 10 and {s} | rec >= {0, 3} and s in (0, 3))
    assert first + 2.0 <= yield_rec.t_s[1] < first + 2.0 + PERIOD + LATENCY
    member = records(sim, 4)
    assert member.cause.tolist()[-2:] == ["rule5_leader_resigned", "rule2_join"]
    resign_heard = member.t_s.iloc[-2]
    # Robot 4 heard 3's resign Ack: its first Ack after yielding.
    assert resign_heard == pytest.approx(min(t for t, s, r in deliveries if s == 3 and t > yield_rec.t_s[1]))
    assert member.leader.iloc[-1] == 0 and member.t_s.iloc[-1] == resign_heard
    assert stack.leader.tolist() == [0, 0, 0, 0, 0]


@pytest.mark.parametrize(
    "policy, winner", [("lowest_id_wins", 0), ("highest_degree_wins", 3), ("smaller_group_yields", 3)]
)
def test_rule5_merge_policies(policy, winner):
    """Leaders 0 (alone) and 3 (with two members) meet: the policy decides who stays; the
    loser yields once, merge_delay after both were leaders over the two-way link, and the
    winner never changes role."""
    pos = [[0, 0], [200, 0], [300, 0], [100, 0], [103, 0], [100, 3]]
    sim, stack, deliveries = scripted(pos, [0.1, 0.9, 0.95, 0.2, 1.5, 1.6], merge_policy=policy)

    def bring():
        yield sim.env.timeout(10.0)
        for k, p in zip((3, 4, 5), ((8.0, 0.0), (15.0, 0.0), (14.0, 4.0))):
            sim.state.set_leg(k, 10.0, (0.0, 0.0), start_m=p)

    sim.env.process(bring())
    sim.run(until_s=30)
    assert stack.role[winner] == LEADER
    loser = 3 if winner == 0 else 0
    assert records(sim, loser).cause.tolist() == ["rule4_no_leader", "rule5_merge_yield"]
    assert records(sim, winner).cause.tolist() == ["rule4_no_leader"]
    assert stack.leader[loser] == winner
    # Both leaders since t < 5; the two-way link exists from the second Ack across it.
    across = sorted(t for t, s, rec in deliveries if t > 10 and s in (0, 3) and ({0, 3} - {s}) <= rec)
    two_way = next(t for t in across if any(u < t for u in across if u > 10))
    t_yield = records(sim, loser).t_s.iloc[-1]
    assert two_way + 2.0 - PERIOD <= t_yield < two_way + 2.0 + PERIOD + LATENCY


def test_rule5_highest_degree_counts_two_way_links_on_both_sides():
    """Leader 1 hears three robots that cannot hear it (their range is 30 m, its 10 m):
    one-way links. Counted in its degree they would make it look busier than leader 0.
    Both leaders compare the same thing (two-way degrees, as each announced): 0 has 3
    (members 2, 3 and leader 1), 1 has 2 (member 4 and leader 0), so 1 yields, and only 1."""
    far = 100.0
    pos = [[0, 0], [far + 8, 0], [-5, 0], [-5, 3], [far + 12, 0], [far + 33, 0], [far + 33, 2], [far + 33, -2]]
    ranges = [10.0] * 5 + [30.0] * 3
    sim, stack, deliveries = scripted(
        pos, [0.1, 0.2, 1.5, 1.6, 1.7, 0.3, 1.8, 1.9], range_m=ranges, merge_policy="highest_degree_wins"
    )

    def bring():
        yield sim.env.timeout(10.0)
        for k in (1, 4, 5, 6, 7):
            p = sim.state.positions_at(10.0, [k])[0]
            sim.state.set_leg(k, 10.0, (0.0, 0.0), start_m=(p[0] - far, p[1]))

    sim.env.process(bring())
    sim.run(until_s=30)
    assert records(sim, 0).cause.tolist() == ["rule4_no_leader"]
    assert records(sim, 1).cause.tolist() == ["rule4_no_leader", "rule5_merge_yield"]
    assert stack.leader[[1, 2, 3]].tolist() == [0, 0, 0]


def test_rule5_leaders_that_yield_to_each_other_settle_on_the_lower_id(monkeypatch):
    """With latency 1.3 s each leader decides on news more than a period old; when that
    makes both yield (forced here: each believes it loses), the lower id takes the lead
    back on hearing the other's yield, the higher stays its member, and nothing changes
    after that."""
    import netsim.protocols.clustering as clustering

    monkeypatch.setattr(clustering, "merge_loser", lambda policy, me, other: me.id)
    sim, stack, deliveries = scripted([[0, 0], [5, 0]], [0.1, 0.2], latency_s=1.3)
    sim.run(until_s=60)
    r0, r1 = records(sim, 0), records(sim, 1)
    assert r0.cause.tolist() == ["rule4_no_leader", "rule5_merge_yield", "rule5_mutual_yield"]
    assert r1.cause.tolist() == ["rule4_no_leader", "rule5_merge_yield"]
    # Each yields before the other's yield reaches it; 0 resumes on hearing 1's.
    assert r1.t_s[1] < r0.t_s[1] < r1.t_s[1] + 1.3
    assert r0.t_s[2] == pytest.approx(min(t for t, s, rec in deliveries if s == 1 and t > r1.t_s[1] + 1.3))
    assert stack.role.tolist() == [LEADER, MEMBER] and stack.leader.tolist() == [0, 0]


def test_rule5_the_merge_delay_counts_from_the_robots_own_leadership():
    """Rule 5 counts merge_delay from the latest of the link known two-way, the other's
    Acks saying alpha and the robot's own becoming alpha. Member 2 of leader 1 has heard
    leader 0 over a two-way link since t = 4; leader 1 leaves and 2 is elected (rule 6) at
    its deadline. Link and 0's leadership are old news, so only 2's own leadership holds
    the merge back: 2 yields (equal groups: the higher id) on the first Ack of 0 it gets
    merge_delay after its election, not on the first it gets once it has announced itself
    (a period later), as a merge delay counted without it did."""
    sim, stack, deliveries = scripted([[9, 0], [-6, 0], [0, 0]], [0.2, 0.1, 1.6])
    move_away(sim, 1, 10.0)
    sim.run(until_s=20)
    rec = records(sim, 2)
    assert rec.cause.tolist() == ["rule2_join", "rule3_leader_lost", "rule6_elected", "rule5_merge_yield"], rec
    elected, yielded = rec.t_s[2], rec.t_s[3]
    assert rec.leader[3] == 0 and records(sim, 0).cause.tolist() == ["rule4_no_leader"]
    merge_delay = 2 * PERIOD
    assert min(t for t, s, r in deliveries if s == 0 and 2 in r) < elected - merge_delay  # an old link
    assert yielded >= elected + merge_delay
    assert yielded == min(t for t, s, r in deliveries if s == 0 and 2 in r and t >= elected + merge_delay)


def test_rule5_a_yielding_leader_resigns_in_its_next_ack():
    """Rule 5: the leader that yields sets the resign flag in its next Ack, which says beta
    and names the leader it joined; its later Acks do not (the flag is sent once). Leaders 0
    and 1 merge; 1 (the higher id, equal groups) yields. A yield that left the flag unset
    told nobody that it resigned."""
    sim, stack, deliveries = scripted([[0, 0], [5, 0]], [0.1, 0.2])
    acks = []  # (arrival, Ack) of robot 1
    stack.beacon.listeners.append(lambda now, ack, rec, hm: acks.append((now, ack)) if ack.sender == 1 else None)
    sim.run(until_s=10)
    rec = records(sim, 1)
    assert rec.cause.tolist() == ["rule4_no_leader", "rule5_merge_yield"], rec
    yielded = rec.t_s[1]
    before = [a for t, a in acks if t < yielded]
    (t_next, next_ack), *later = [(t, a) for t, a in acks if t > yielded]
    assert t_next < yielded + PERIOD + LATENCY
    assert (next_ack.role, next_ack.leader, next_ack.resign) == (MEMBER, 0, True)
    assert len(later) >= 2 and not any(a.resign for _, a in later) and not any(a.resign for a in before)


def test_an_overtaken_ack_does_not_undo_a_resignation():
    """Leader 0 yields to leader 2 and its member 1 (which hears no other leader, and
    holds no election) becomes undecided; an older Ack of 0, overtaken in flight, then
    arrives at 1: it is ignored, so 1 does not join the leader that resigned."""
    pos = [[0, 0], [-8, 0], [100, 0], [104, 3], [104, -3]]
    sim, stack, deliveries = scripted(pos, [0.1, 1.5, 0.2, 1.6, 1.7], election_policy="none")
    old = []
    stack.beacon.listeners.append(lambda now, ack, rec, hm: old.append(ack) if ack.sender == 0 and now < 10 else None)

    def bring():
        yield sim.env.timeout(10.0)
        for k, p in zip((2, 3, 4), ((8.0, 0.0), (12.0, 3.0), (12.0, -3.0))):
            sim.state.set_leg(k, 10.0, (0.0, 0.0), start_m=p)

    sim.env.process(bring())
    sim.run(until_s=15.0)
    assert records(sim, 0).cause.tolist() == ["rule4_no_leader", "rule5_merge_yield"]
    assert records(sim, 1).cause.tolist() == ["rule2_join", "rule5_leader_resigned"]
    assert old[-1].role == LEADER and not old[-1].resign
    stack.beacon.deliver(0, np.array([1]), old[-1])
    assert stack.role[1] == UNDECIDED
    assert stack.beacon.stale_acks == 1
    sim.run(until_s=16.0)
    assert records(sim, 1).cause.tolist() == ["rule2_join", "rule5_leader_resigned"]


@pytest.mark.parametrize("policy", ["lowest_id", "highest_degree"])
def test_rule6_group_that_lost_its_leader_elects_the_lowest_id(policy):
    """Leader 0 leaves; its members 1 and 2 time out together; 1 (lowest id; with
    highest_degree, a tie: both announced 2 neighbours) becomes alpha at once and 2 joins
    it on hearing it. Each compares what it announced itself with what the other announced,
    both counting the leader they had."""
    sim, stack, deliveries = scripted([[0, 0], [5, 0], [5, 4]], [0.1, 1.5, 1.7], election_policy=policy)
    move_away(sim, 0, 10.0)
    sim.run(until_s=30)
    r1, r2 = records(sim, 1), records(sim, 2)
    assert r1.cause.tolist() == ["rule2_join", "rule3_leader_lost", "rule6_elected"]
    deadline_s = deadline(last_delivery(deliveries, 0, 1, before=10.0), TAU)
    assert r1.t_s[1] == r1.t_s[2] == deadline_s
    assert r2.cause.tolist() == ["rule2_join", "rule3_leader_lost", "rule2_join"]
    assert r2.t_s[1] == deadline_s and r2.leader[2] == 1
    assert r2.t_s[2] == pytest.approx(min(t for t, s, r in deliveries if s == 1 and t > deadline_s))


def test_rule6_the_election_comes_before_joining_another_leader():
    """Leader 3 leads 0 and 1; 0 also hears leader 4, 1 does not. Leader 3 leaves: its group
    elects 0 (the lowest id) at once, though 0 knows another leader, and 1 joins 0 on
    hearing it. Joining leader 4 first would leave 1 without a leader until rule 4."""
    pos = [[4, 0], [-4, 0], [0, 100], [0, 0], [13, 0]]
    sim, stack, deliveries = scripted(pos, [1.5, 1.6, 0.9, 0.1, 0.2])
    move_away(sim, 3, 10.0)
    sim.run(until_s=14.0)
    r0, r1 = records(sim, 0), records(sim, 1)
    deadline_s = deadline(last_delivery(deliveries, 3, 0, before=10.0), TAU)
    assert r0.cause.tolist() == ["rule2_join", "rule3_leader_lost", "rule6_elected"], r0
    assert r0.leader.tolist() == [3, -1, 0] and r0.t_s[2] == deadline_s
    assert r1.cause.tolist() == ["rule2_join", "rule3_leader_lost", "rule2_join"], r1
    assert r1.leader[2] == 0
    assert r1.t_s[2] == min(t for t, s, r in deliveries if s == 0 and 1 in r and t > deadline_s)


def test_rule6_a_member_that_loses_the_election_joins_on_hearing_a_leader_not_at_once():
    """Leader 3 leads 0 and 1; 1 also hears leader 4. Leader 3 leaves: 1 loses the election
    to 0 and becomes undecided; it joins 4, the only leader it knows, when 4's next Ack
    arrives (rule 2), not at the instant it lost its leader."""
    pos = [[-4, 0], [4, 0], [0, 100], [0, 0], [13, 0]]
    sim, stack, deliveries = scripted(pos, [1.5, 1.6, 0.9, 0.1, 0.2])
    move_away(sim, 3, 10.0)
    sim.run(until_s=14.0)
    r1 = records(sim, 1)
    deadline_s = deadline(last_delivery(deliveries, 3, 1, before=10.0), TAU)
    assert r1.cause.tolist() == ["rule2_join", "rule3_leader_lost", "rule2_join"], r1
    assert r1.t_s[1] == deadline_s and r1.leader[2] == 4
    assert r1.t_s[2] == min(t for t, s, r in deliveries if s == 4 and 1 in r and t > deadline_s) > deadline_s
    assert records(sim, 0).cause.tolist()[-1] == "rule6_elected"


def test_rule6_a_former_member_that_already_leads_counts_in_the_election():
    """Leader 3 of 0 and 1 drives slowly away: 0 loses it first and is elected; 1 loses it
    8 s later, hearing 0 lead. 0 had the same leader and has the lower id, so 1 loses the
    election and joins 0 on hearing it, rather than leading beside it until a merge."""
    sim, stack, deliveries = scripted([[-4, 0], [4, 0], [0, 100], [0, 0]], [1.5, 1.6, 0.9, 0.1])

    def drive():
        yield sim.env.timeout(10.0)
        sim.state.set_leg(3, sim.env.now, (1.0, 0.0))

    sim.env.process(drive())
    sim.run(until_s=40)
    r0, r1 = records(sim, 0), records(sim, 1)
    assert r0.cause.tolist() == ["rule2_join", "rule3_leader_lost", "rule6_elected"], r0
    assert r1.cause.tolist() == ["rule2_join", "rule3_leader_lost", "rule2_join"], r1
    lost = r1.t_s[1]
    assert lost > r0.t_s[2] + PERIOD  # 1 heard 0's Acks as a leader before it lost 3
    assert r1.leader[2] == 0
    assert r1.t_s[2] == min(t for t, s, r in deliveries if s == 0 and 1 in r and t > lost)


def test_rule6_a_resigned_leaders_member_that_knows_no_other_leader_holds_the_election():
    """Leader 1 (member 2) merges into leader 0 and resigns (lowest id wins); 2 does not hear
    0. On hearing the resignation it knows no leader to join, so it holds the election and,
    with no rival, leads at once instead of waiting tau for rule 4."""
    sim, stack, deliveries = scripted([[100, 0], [8, 0], [16, 0]], [0.2, 0.1, 1.6], merge_policy="lowest_id_wins")

    def bring():
        yield sim.env.timeout(10.0)
        sim.state.set_leg(0, 10.0, (0.0, 0.0), start_m=(0.0, 0.0))

    sim.env.process(bring())
    sim.run(until_s=30)
    assert records(sim, 1).cause.tolist() == ["rule4_no_leader", "rule5_merge_yield"]
    r2 = records(sim, 2)
    assert r2.cause.tolist() == ["rule2_join", "rule5_leader_resigned", "rule6_elected"], r2
    assert r2.t_s[1] == r2.t_s[2] == min(t for t, s, r in deliveries if s == 1 and t > records(sim, 1).t_s[1])


def test_one_way_link_is_never_joined():
    """With unequal ranges robot 1 hears leader 0 but 0 cannot hear 1: 1 must not join."""
    sim, stack, deliveries = scripted([[0, 0], [10, 0]], [0.1, 0.6], range_m=[15.0, 5.0])
    sim.run(until_s=20)
    assert stack.role.tolist() == [LEADER, LEADER]
    assert records(sim, 1).cause.tolist() == ["rule4_no_leader"]


def test_group_size_counts_two_way_members_only():
    """A leader's Ack announces 1 + its live two-way neighbours whose last Ack named it
    their leader (docs/model.md 4). Member 1 (range 15 m) of leader 0 (range 5 m) stands 10 m
    away from t = 10: 0 still hears it, it no longer hears 0. Its Ack at its own deadline
    (tau after 0's last Ack it heard; Acks go before timers) still says beta of 0 but no
    longer lists 0: 0 hears a member over a one-way link. 0's next Ack must announce a
    group of 1, not 2 (counted once the member's Acks name the leader, whether or not they
    list it, the size takes in members the leader cannot reach)."""
    lost = float(deadline(9.5, TAU))  # 1's deadline: tau after 0's Ack at 9.5 (no latency)
    # 1's Acks are due at its deadline, to the last bit (dyadic instants: exact sums).
    sim, stack, _ = scripted([[0, 0], [4, 0]], [0.5, lost - 11.0], range_m=[5.0, 15.0], latency_s=0.0)
    heard = []  # 1's Acks as 0 got them
    stack.beacon.listeners.append(lambda now, ack, rec, hm: heard.append((now, ack)) if ack.sender == 1 else None)

    def step_back():
        yield sim.env.timeout(10.0)
        sim.state.set_leg(1, sim.env.now, (0.0, 0.0), start_m=(10.0, 0.0))

    sim.env.process(step_back())
    sim.run(until_s=13.0)
    assert stack.beacon.group_size[0] == 2  # 0's Ack at 12.5: 1 still lists it
    rec = records(sim, 1)
    assert rec.cause.tolist() == ["rule2_join", "rule3_leader_lost", "rule6_elected"], rec
    assert rec.t_s[1] == lost
    last = next(a for t, a in heard if t == lost)
    assert (last.role, last.leader) == (MEMBER, 0) and 0 not in last.heard.tolist()
    sim.run(until_s=13.75)  # 0's Ack at 13.5, before 1's next (as a leader)
    assert min(t for t, _ in heard if t > lost) > 13.5
    assert stack.beacon.group_size[0] == 1


def test_gateway_belongs_to_two_groups():
    """A member between two leaders out of each other's range is a gateway."""
    sim, stack, deliveries = scripted([[0, 0], [18, 0], [9, 0]], [0.1, 0.2, 0.9])
    sim.run(until_s=10)
    cl = stack.clustering
    assert stack.role.tolist() == [LEADER, LEADER, MEMBER]
    assert cl.groups(sim.now) == [{0}, {1}, {0, 1}]
    assert cl.gateways(sim.now).tolist() == [2]


# -- the pure decisions ------------------------------------------------------------------
def test_transition_table_names_a_rule_for_every_change():
    for (role, _event), (new, cause) in TRANSITIONS.items():
        assert new != role and cause.startswith("rule")
    with pytest.raises(KeyError):
        transition(LEADER, "leader_heard")


PROTOCOL_KERNELS = "netsim.protocols._kernels"


@pytest.fixture(params=["plain", "compiled"])
def rule_kernels(request):
    """The protocols' kernels as a small run calls them (plain Python) and compiled."""
    import importlib

    from netsim.compiled import compiled_copy

    return importlib.import_module(PROTOCOL_KERNELS) if request.param == "plain" else compiled_copy(PROTOCOL_KERNELS)


def _row(entries, n, row=0):
    """Robot ``row``'s neighbour table (the other rows empty): one live two-way entry per
    ``(id, role, leader, x, y, degree[, member_of])``, heard just now (``member_of``: the
    leader its last Ack that said member named; by default its leader if it is a member)."""
    from netsim.protocols._kernels import DEGREE, EMPTY_RECORD, HEARS_ME, LAST_HEARD, MEMBER_OF, ROLE, X, Y
    from netsim.protocols._kernels import LEADER as LEADER_FIELD

    ids = np.full((n, max(len(entries), 1)), -1, dtype=np.int64)
    records = np.broadcast_to(EMPTY_RECORD, (*ids.shape, len(EMPTY_RECORD))).copy()
    for s, (j, role, leader, x, y, degree, *had) in enumerate(entries):
        ids[row, s] = j
        member_of = had[0] if had else (leader if role == MEMBER else -1)
        fields = [LAST_HEARD, HEARS_ME, ROLE, LEADER_FIELD, X, Y, DEGREE, MEMBER_OF]
        records[row, s, fields] = [NOW_S, 1, role, leader, x, y, degree, member_of]
    return ids, records


NOW_S, TAU = 10.0, 3.0


def _joins(kernels, policy, leaders, first_heard=-1, side_m=None):
    """Rule 2 by the kernel: robot 0, still at the origin, hears each ``(id, x)`` as a leader
    at ``(x, 0)``; the leader it joins (on a torus of side ``side_m``; None: the plane)."""
    n = 1 + max(j for j, _ in leaders)
    ids, records = _row([(j, LEADER, j, x, 0.0, 0) for j, x in leaders], n)
    rules = rules_record(TAU, 1.0, False, policy, "lowest_id")
    motion = (np.zeros((n, 2)), np.zeros((n, 2)), np.zeros(n), side_m is not None, side_m or 0.0)
    leader, slot = kernels.join_choice((ids, records, TAU), 0, NOW_S, rules, -1, motion, first_heard)
    assert ids[0, slot] == leader
    return leader


def test_join_policies_choose_the_leader_the_model_names(rule_kernels):
    """Rule 2's policies: the nearest known leader (ties of distance to the lowest id), the
    lowest id, or the leader whose Ack triggered the join (the nearest when it is not known)."""
    leaders = [(4, 10.0), (2, -10.0), (7, 3.0)]
    assert _joins(rule_kernels, "nearest", leaders) == 7
    assert _joins(rule_kernels, "nearest", leaders[:2]) == 2  # tie: lowest id
    assert _joins(rule_kernels, "lowest_id", leaders) == 2
    assert _joins(rule_kernels, "first_heard", leaders, first_heard=4) == 4
    assert _joins(rule_kernels, "first_heard", leaders, first_heard=5) == 7


def test_join_nearest_leader_is_measured_across_the_torus_seam(rule_kernels):
    """Rule 2's nearest leader on a torus is the nearest image's: from the origin of a
    100 m torus a leader at x = 97 m is 3 m away, nearer than one at x = 10 m (on the plane
    it is the farther)."""
    leaders = [(4, 97.0), (2, 10.0)]
    assert _joins(rule_kernels, "nearest", leaders, side_m=100.0) == 4
    assert _joins(rule_kernels, "nearest", leaders) == 2


def test_merge_loser_is_the_same_seen_from_both_sides():
    a, b = Candidate(1, group_size=3, degree=5), Candidate(5, group_size=3, degree=9)
    for policy in ("smaller_group_yields", "lowest_id_wins", "highest_degree_wins"):
        assert merge_loser(policy, a, b) == merge_loser(policy, b, a)
    assert merge_loser("smaller_group_yields", a, b) == 5  # tie: higher id yields
    assert merge_loser("highest_degree_wins", a, b) == 1
    # Equal degrees: the higher id yields, as for equal groups.
    tied = Candidate(5, group_size=3, degree=5)
    assert merge_loser("highest_degree_wins", a, tied) == merge_loser("highest_degree_wins", tied, a) == 5


def _elected(kernels, policy, me, degree, rivals):
    """Rule 6 by the kernel: whether robot ``me`` (announcing ``degree``) takes over from
    leader 9 among its neighbours ``rivals``, ``(id, degree)`` members of 9, or ``(id,
    degree, role, member_of)``."""
    entries = []
    for j, d, *told in rivals:
        role, member_of = told or (MEMBER, 9)
        entries.append((j, role, 9 if role == MEMBER else j, 0.0, 0.0, d, member_of))
    ids, records = _row(entries, 10, row=me)
    rules = rules_record(TAU, 1.0, False, "nearest", policy)
    return bool(kernels.elected_in_row((ids, records, TAU), me, NOW_S, rules, 9, degree))


def test_election_policies(rule_kernels):
    """Rule 6's policies: the lowest id (vacuously with no rival), the highest degree (ties
    to the lowest id), or none."""
    assert _elected(rule_kernels, "lowest_id", 3, 0, []) is True
    assert _elected(rule_kernels, "lowest_id", 3, 0, [(5, 0), (8, 0)]) is True
    assert _elected(rule_kernels, "lowest_id", 3, 0, [(5, 0), (1, 0)]) is False
    assert _elected(rule_kernels, "none", 3, 0, []) is False
    assert _elected(rule_kernels, "highest_degree", 5, 4, [(1, 3)]) is True
    assert _elected(rule_kernels, "highest_degree", 5, 3, [(1, 4)]) is False
    assert _elected(rule_kernels, "highest_degree", 1, 3, [(5, 3)]) is True  # tie: lowest id
    assert _elected(rule_kernels, "highest_degree", 5, 3, [(1, 3)]) is False
    # A neighbour that had leader 9 counts when it leads or is undecided since; one that
    # leads and was last a member of another leader does not.
    assert _elected(rule_kernels, "lowest_id", 3, 0, [(1, 0, LEADER, 9)]) is False
    assert _elected(rule_kernels, "lowest_id", 3, 0, [(1, 0, UNDECIDED, 9)]) is False
    assert _elected(rule_kernels, "lowest_id", 3, 0, [(1, 0, LEADER, 4)]) is True
    assert _elected(rule_kernels, "lowest_id", 3, 0, [(1, 0, LEADER, -1)]) is True


def test_roles_table_is_the_frame_of_its_records():
    """The roles table kept as columns is the frame a trace makes of RoleChange records:
    the same values, dtypes and order; all-object columns when there is no change."""
    import pandas as pd
    from netsim.protocols.roles import RoleChange

    sim, stack, _ = scripted([[0, 0], [5, 0], [50, 0]], [0.1, 0.2, 0.3])
    # The records as the run announces them, one by one: a path apart from the table's columns.
    records: list = []
    sim.events.on("role_change", records.append)
    move_away(sim, 0, 7.0)
    sim.run(until_s=15.0)
    assert all(isinstance(r, RoleChange) for r in records)
    expected = pd.DataFrame(records, columns=list(RoleChange._fields))
    got = roles(sim)
    # The start records come before anyone can listen (the stack is built with them).
    start = got.cause == "rule1_start"
    assert start.sum() == 3 and got.t_s[start].eq(0.0).all()
    later = got[~start].reset_index(drop=True)
    assert len(later) > 5 and later.equals(expected) and got.dtypes.tolist() == expected.dtypes.tolist()
    stack.clustering._changes = ([], [], [], [], [])
    assert roles(sim).dtypes.tolist() == pd.DataFrame([], columns=list(RoleChange._fields)).dtypes.tolist()


def test_rule5_a_leader_compares_the_group_size_it_announced_not_the_one_it_counts_now():
    """Rule 5 compares what both leaders announced. Leaders 0 and 1 (alone each) stand in
    range; robot 2 walks into 1's range (only) at t = 5 and joins it, and its Ack naming 1
    reaches 1 before 1 checks the merge, but after 1's last Ack: both leaders announced a
    group of 1, so the higher id (1) yields, on 0's first Ack after the merge delay.
    Counting its members at that instant instead, 1 saw a larger group than it had
    announced and kept the lead, and 0 yielded on 1's next Ack, which said 2."""
    sim, stack, deliveries = scripted([[0, 0], [5, 0], [500, 0]], [0.1, 0.2, 2.5])

    def arrive():
        yield sim.env.timeout(5.0)
        sim.state.set_leg(2, 5.0, (0.0, 0.0), start_m=(12.0, 0.0))

    sim.env.process(arrive())
    sim.run(until_s=10)
    joined = records(sim, 2)
    assert joined.cause.tolist()[0] == "rule2_join" and joined.leader[0] == 1
    assert records(sim, 0).cause.tolist() == ["rule4_no_leader"]
    r1 = records(sim, 1)
    assert r1.cause.tolist() == ["rule4_no_leader", "rule5_merge_yield"], r1
    # 2's Ack naming 1 reached 1 before the merge, after 1's last Ack before it.
    named = min(t for t, s, r in deliveries if s == 2 and 1 in r)
    last_ack = max(t for t, s, r in deliveries if s == 1 and t < r1.t_s[1])
    assert last_ack < named < r1.t_s[1]


def test_rule5_a_leader_that_takes_the_lead_back_does_not_resign():
    """Rule 5: a leader that yielded owes a resign flag in its next Ack, but one that takes
    the lead back on hearing the other's yield (the lower id, after a mutual yield) before
    that Ack leads on: its next Ack says alpha without the flag. Leader 0 (alone) yields
    to leader 1 (with member 2); before 0's next Ack, an Ack of 1 saying it joined 0 (its
    yield on older news) arrives. Had the flag stayed set, 0's next Ack would say alpha
    and resign at once, and its members would leave a leader that leads."""
    from netsim.protocols._kernels import LEADER as LEADER_FIELD
    from netsim.protocols._kernels import ROLE, SEQ

    sim, stack, deliveries = scripted([[0, 0], [5, 0], [12, 0]], [0.1, 0.2, 1.7])
    acks = []  # (arrival, Ack) of 0's Acks
    stack.beacon.listeners.append(lambda now, ack, rec, hm: acks.append((now, ack)) if ack.sender == 0 else None)
    heard_from_1 = []
    stack.beacon.listeners.append(lambda now, ack, rec, hm: heard_from_1.append(ack) if ack.sender == 1 else None)
    sim.run(until_s=6.5)
    r0 = records(sim, 0)
    assert r0.cause.tolist() == ["rule4_no_leader", "rule5_merge_yield"] and r0.leader[1] == 1, r0
    yielded = r0.t_s[1]
    assert not any(t > yielded for t, _ in acks)  # 0 has sent no Ack since it yielded
    last = heard_from_1[-1]
    record = last.record.copy()
    record[SEQ], record[ROLE], record[LEADER_FIELD] = last.seq + 1, MEMBER, 0
    stack.beacon.deliver(1, np.array([0]), last._replace(seq=last.seq + 1, role=MEMBER, leader=0, record=record))
    r0 = records(sim, 0)
    assert r0.cause.tolist()[-1] == "rule5_mutual_yield" and stack.role[0] == LEADER
    sim.run(until_s=8.0)
    ack = next(a for t, a in acks if t > yielded)
    assert (ack.role, ack.resign) == (LEADER, False)


def test_rule2_with_equal_ranges_the_first_ack_heard_is_over_a_two_way_link():
    """With equal ranges hearing an Ack implies a two-way link (docs/model.md 4.1), even
    before the leader has heard the robot: undecided robot 1 walks into leader 0's range
    just after its own Ack and joins on 0's next Ack, which cannot list it yet. Asking
    that Ack to list it, 1 waited for 0's Ack after its own next one, and led by rule 4
    before it came."""
    sim, stack, deliveries = scripted([[0, 0], [500, 0]], [0.1, 2.05])

    def arrive():
        yield sim.env.timeout(4.06)
        sim.state.set_leg(1, sim.env.now, (0.0, 0.0), start_m=(5.0, 0.0))

    sim.env.process(arrive())
    acks = []  # 0's Acks as robot 1 hears them: (arrival, whether they list 1)
    stack.beacon.listeners.append(
        lambda now, ack, rec, hm: acks.append((now, 1 in ack.heard)) if ack.sender == 0 and 1 in rec else None
    )
    sim.run(until_s=8)
    (first, listed), *_ = acks
    assert not listed
    joined = records(sim, 1)
    assert joined.cause.tolist() == ["rule2_join"], joined
    assert joined.t_s[0] == first and joined.leader[0] == 0


def test_rule2_first_heard_joins_the_leader_whose_ack_came_first_of_those_it_knows():
    """join_policy = "first_heard": robot 1, member of leader 3, also hears leaders 4 (9.5
    m away) and 5 (7.3 m). Leader 3 leaves; 1 loses the election to 0 and joins the leader
    whose Ack it hears first, 4, though it knows the nearer 5 as a leader too."""
    pos = [[-6, 3], [0, 0], [0, 500], [-6, 0], [9.5, 0], [2, -7]]
    sim, stack, deliveries = scripted(pos, [1.5, 1.6, 0.9, 0.1, 0.2, 0.3], join_policy="first_heard")
    move_away(sim, 3, 10.0)
    sim.run(until_s=14.0)
    r1 = records(sim, 1)
    assert r1.cause.tolist() == ["rule2_join", "rule3_leader_lost", "rule2_join"], r1
    lost = r1.t_s[1]
    assert stack.role[[4, 5]].tolist() == [LEADER, LEADER]
    first = min((t, s) for t, s, r in deliveries if s in (4, 5) and 1 in r and t > lost)
    assert first[1] == 4
    assert (r1.t_s[2], r1.leader[2]) == first


def test_rule5_after_a_mutual_yield_the_higher_id_stays_a_member_from_the_others_yield(monkeypatch):
    """Both leaders yield on old news (forced, latency 1.7 s): 0 takes the lead back on
    hearing 1's yield, and 1 stays its member. 1's timer then runs from the Ack that told
    it of 0's yield (the link shown alive), not from 1's own yield: 0's first Ack leading
    again reaches 1 more than tau after 1 yielded. A timer left to run from the yield
    timed 1 out before it, and the two merged again."""
    import netsim.protocols.clustering as clustering

    monkeypatch.setattr(clustering, "merge_loser", lambda policy, me, other: me.id)
    sim, stack, deliveries = scripted([[0, 0], [5, 0]], [0.5, 0.1], latency_s=1.7)
    leading = []  # arrivals at 1 of 0's Acks that lead
    stack.beacon.listeners.append(
        lambda now, ack, rec, hm: leading.append(now) if ack.sender == 0 and ack.role == LEADER else None
    )
    sim.run(until_s=60)
    r0, r1 = records(sim, 0), records(sim, 1)
    assert r0.cause.tolist() == ["rule4_no_leader", "rule5_merge_yield", "rule5_mutual_yield"], r0
    assert r1.cause.tolist() == ["rule4_no_leader", "rule5_merge_yield"], r1
    assert min(t for t in leading if t > r0.t_s[2]) > deadline(r1.t_s[1], TAU)
    assert stack.role.tolist() == [LEADER, MEMBER] and stack.leader.tolist() == [0, 0]


def test_a_command_is_taken_by_its_leaders_members_only():
    """Leaders command their members, and only them (docs/model.md 4.3): member 2 of
    leader 0 also hears leader 1, whose command reaches it and 1's own member 3; 3 takes
    it, 2 does not."""
    sim, stack, deliveries = scripted([[0, 0], [15, 0], [7, 0], [20, 0]], [0.1, 0.2, 1.6, 1.7])
    sim.run(until_s=6.0)
    assert stack.leader.tolist() == [0, 1, 0, 1] and stack.role[[2, 3]].tolist() == [MEMBER, MEMBER]
    stack.send_command(1, "spread")
    sim.run(until_s=7.0)
    assert stack.command[3].payload == "spread"
    assert stack.command[2] is None


def test_a_member_takes_its_new_leaders_commands_whatever_their_numbers():
    """A command is newer than the one a member holds when it comes from another leader, or
    from the same one with a higher number: member 2 took leader 0's third command, then
    joined leader 1 (0 left); 1's first command is its new leader's, and is taken."""
    sim, stack, deliveries = scripted([[0, 0], [15, 0], [7, 0]], [0.1, 0.2, 1.6], join_before_election=True)
    sim.run(until_s=6.0)
    assert stack.leader[2] == 0
    for payload in ("a", "b", "c"):
        stack.send_command(0, payload)
    move_away(sim, 0, 6.5)
    sim.run(until_s=7.0)
    assert (stack.command[2].leader, stack.command[2].seq, stack.command[2].payload) == (0, 3, "c")
    sim.run(until_s=12.0)
    assert stack.role[2] == MEMBER and stack.leader[2] == 1
    stack.send_command(1, "spread")
    sim.run(until_s=13.0)
    assert (stack.command[2].leader, stack.command[2].seq, stack.command[2].payload) == (1, 1, "spread")


def _told(stack, t_s, sender, receiver, role, x_m, y_m, seq):
    """``receiver``'s table takes an Ack of ``sender`` at ``t_s`` saying ``role`` at (x, y)."""
    from tests.oracles.protocols import ack_record

    record = ack_record(seq, role, sender if role == LEADER else -1, x_m, y_m, 1)
    stack.table.receive(t_s, sender, np.array([receiver]), record)


def test_a_leader_knows_other_leaders_at_their_freshest_reported_position():
    """heard_leaders: the other leaders a leader hears and those its live neighbours hear,
    each at the position of the freshest report of it. Leader 0 heard leader 2 at 1 s (at
    (1, 1)); its neighbour 1 heard 2 at 2 s (at (2, 2)): 0 knows 2 at (2, 2)."""
    _, stack = clustering([[0, 0], [5, 0], [10, 0]], start=False)
    _told(stack, 0.5, 1, 0, MEMBER, 5.0, 0.0, 1)
    _told(stack, 1.0, 2, 0, LEADER, 1.0, 1.0, 1)
    _told(stack, 2.0, 2, 1, LEADER, 2.0, 2.0, 2)
    ids, xy = stack.heard_leaders(0, 2.5)
    assert ids.tolist() == [2] and xy.tolist() == [[2.0, 2.0]]


def test_a_robots_neighbourhood_reaches_two_hops_at_the_freshest_positions():
    """neighbourhood: each robot knows the robots it hears and those they hear, at the
    position of the latest Ack of each heard by anyone. 0 hears 1 and heard 2 at 1 s (at
    (1, 1)); 1 hears 2 (at 2 s, at (2, 2)) and 3: 0 knows 3 through 1, and 2 at (2, 2)."""
    _, stack = clustering([[0, 0], [5, 0], [10, 0], [15, 0]], start=False)
    _told(stack, 0.5, 1, 0, MEMBER, 5.0, 0.0, 1)
    _told(stack, 1.0, 2, 0, UNDECIDED, 1.0, 1.0, 1)
    _told(stack, 2.0, 2, 1, UNDECIDED, 2.0, 2.0, 2)
    _told(stack, 2.0, 3, 1, UNDECIDED, 15.0, 0.0, 1)
    robot, other, xy = stack.neighbourhood(2.5)
    known = {(r, o): tuple(p) for r, o, p in zip(robot.tolist(), other.tolist(), xy.tolist())}
    assert (0, 3) in known and known[(0, 2)] == known[(1, 2)] == (2.0, 2.0)
