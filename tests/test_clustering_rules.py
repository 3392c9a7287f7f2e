"""One test per clustering rule (docs/model.md 4.2), on small scripted topologies.

Robots are static unless a test moves them; loss is off, jitter is off and beacon phases
are set by hand, so every event time is known.
"""

import numpy as np
import pytest

from netsim.config import from_dict
from netsim.sim import Simulation
from netsim.state import LEADER, MEMBER, UNDECIDED
from protocols.clustering import TRANSITIONS, Candidate, choose_leader, elected, merge_loser, transition
from protocols.stack import Stack

TAU, PERIOD, LATENCY = 3.0, 1.0, 0.001


def scripted(positions, phases, range_m=10.0, latency_s=LATENCY, **protocol):
    n = len(positions)
    cfg = from_dict(
        {
            "duration_s": 100.0,
            "world": {"n_robots": n, "side_m": 10_000.0},
            "mobility": {"model": "static"},
            "channel": {"range_m": range_m, "latency_s": latency_s},
            "protocol": {
                "model": "clustering",
                "ack_period_s": PERIOD,
                "ack_jitter_s": 0.0,
                "tau_s": TAU,
                "message_rate_hz": 0.0,
                **protocol,
            },
            "output": {"position_interval_s": 0.0},
        }
    )
    sim = Simulation(cfg)
    sim.state.place(np.asarray(positions, dtype=float))
    stack = Stack(sim)
    stack.start(phase_s=phases)
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
    assert (sim.state.role == UNDECIDED).all()
    assert sim.channel.counters_for("ack").sent.tolist() == [3, 3, 3]


def test_rule4_undecided_robot_that_hears_no_leader_becomes_leader_after_tau():
    """An isolated robot becomes alpha exactly tau after its protocol started."""
    sim, stack, _ = scripted([[0, 0], [50, 0]], [0.25, 0.6])
    sim.run(until_s=10)
    for i, phase in enumerate([0.25, 0.6]):
        rec = records(sim, i)
        assert rec.cause.tolist() == ["rule4_no_leader"]
        assert rec.t_s[0] == pytest.approx(phase + TAU, abs=1e-12)
        assert rec.role[0] == "alpha" and rec.leader[0] == i


def test_rule2_undecided_robot_joins_the_leader_it_hears():
    """Robot 1 hears robot 0's first Ack as alpha and joins before its own timeout."""
    sim, stack, deliveries = scripted([[0, 0], [5, 0]], [0.1, 0.6])
    sim.run(until_s=10)
    assert records(sim, 0).cause.tolist() == ["rule4_no_leader"]
    joined = records(sim, 1)
    assert joined.cause.tolist() == ["rule2_join"]
    assert (joined.role[0], joined.leader[0]) == ("beta", 0)
    # It joined on the first Ack robot 0 sent as a leader (sent at 3.1, delivered 1 ms later).
    assert joined.t_s[0] == pytest.approx(3.1 + LATENCY, abs=1e-12)
    assert (sim.state.role == [LEADER, MEMBER]).all()


@pytest.mark.parametrize("policy, expected", [("nearest", 1), ("lowest_id", 0)])
def test_rule2_join_policy_chooses_among_known_leaders(policy, expected):
    """Member 3 of leader 2 also hears leaders 0 (10 m away) and 1 (8 m away); when 2
    leaves, it joins the leader its policy picks, at once."""
    pos = [[18, 0], [0, 0], [8, -9], [8, 0]]  # ids: 0 = B (far), 1 = A (near), 2 = X, 3 = m
    sim, stack, deliveries = scripted(pos, [0.6, 0.3, 0.0, 0.9], join_policy=policy)
    move_away(sim, 2, 10.0)
    sim.run(until_s=20)
    rec = records(sim, 3)
    assert rec.cause.tolist() == ["rule2_join", "rule3_leader_lost", "rule2_join"]
    assert rec.leader.tolist() == [2, -1, expected]
    assert rec.t_s[1] == rec.t_s[2]


def test_rule3_member_whose_leader_leaves_becomes_undecided_exactly_tau_after_last_ack():
    sim, stack, deliveries = scripted([[0, 0], [5, 0]], [0.1, 0.6], election_policy="none")
    move_away(sim, 0, 10.0)
    sim.run(until_s=30)
    rec = records(sim, 1)
    assert rec.cause.tolist() == ["rule2_join", "rule3_leader_lost", "rule4_no_leader"]
    last = last_delivery(deliveries, 0, 1, before=10.0)
    assert rec.t_s[1] == last + TAU  # exact to the instant
    assert rec.role[1] == "gamma"
    assert rec.t_s[2] == last + 2 * TAU  # then rule 4, tau later


def test_ack_at_the_deadline_instant_counts():
    """With no latency and every other Ack of the leader lost, the member hears its leader
    at t and t + 2 = its deadline (tau = 2 periods): that Ack is processed first, counts,
    and the member never times out."""
    sim, stack, deliveries = scripted([[0, 0], [5, 0]], [0.5, 0.75], tau_s=2.0, latency_s=0.0)

    def every_other(sender, receivers, distances):
        odd = sim.env.now > 5 and int(round(sim.env.now - 0.5)) % 2 == 1
        return np.zeros(len(receivers), dtype=bool) if sender == 0 and odd else None

    sim.channel.survives = every_other
    sim.run(until_s=30)
    heard = sorted(t for t, s, rec in deliveries if s == 0 and 1 in rec and t > 6)
    assert np.diff(heard).min() == 2.0  # the gaps are exactly tau
    assert records(sim, 1).cause.tolist() == ["rule2_join"]


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
    assert sim.state.role.tolist()[:3] == [LEADER, MEMBER, MEMBER]
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
    assert sim.state.leader.tolist() == [0, 0, 0, 0, 0]


@pytest.mark.parametrize("policy, winner", [("lowest_id_wins", 0), ("highest_degree_wins", 3)])
def test_rule5_merge_policies(policy, winner):
    """Leaders 0 (alone) and 3 (with two members) meet: the policy decides who stays."""
    pos = [[0, 0], [200, 0], [300, 0], [100, 0], [103, 0], [100, 3]]
    sim, stack, deliveries = scripted(pos, [0.1, 0.9, 0.95, 0.2, 0.5, 0.6], merge_policy=policy)

    def bring():
        yield sim.env.timeout(10.0)
        for k, p in zip((3, 4, 5), ((8.0, 0.0), (15.0, 0.0), (14.0, 4.0))):
            sim.state.set_leg(k, 10.0, (0.0, 0.0), start_m=p)

    sim.env.process(bring())
    sim.run(until_s=30)
    assert sim.state.role[winner] == LEADER
    loser = 3 if winner == 0 else 0
    assert records(sim, loser).cause.iloc[-1] in ("rule5_merge_yield", "rule2_join")
    assert sim.state.leader[loser] == winner


def test_rule6_group_that_lost_its_leader_elects_the_lowest_id():
    """Leader 0 leaves; its members 1 and 2 time out together; 1 (lowest id) becomes
    alpha at once and 2 joins it on hearing it."""
    sim, stack, deliveries = scripted([[0, 0], [5, 0], [5, 4]], [0.1, 0.5, 0.7])
    move_away(sim, 0, 10.0)
    sim.run(until_s=30)
    r1, r2 = records(sim, 1), records(sim, 2)
    assert r1.cause.tolist() == ["rule2_join", "rule3_leader_lost", "rule6_elected"]
    deadline = last_delivery(deliveries, 0, 1, before=10.0) + TAU
    assert r1.t_s[1] == r1.t_s[2] == deadline
    assert r2.cause.tolist() == ["rule2_join", "rule3_leader_lost", "rule2_join"]
    assert r2.t_s[1] == deadline and r2.leader[2] == 1
    assert r2.t_s[2] == pytest.approx(min(t for t, s, r in deliveries if s == 1 and t > deadline))


def test_one_way_link_is_never_joined():
    """With unequal ranges robot 1 hears leader 0 but 0 cannot hear 1: 1 must not join."""
    sim, stack, deliveries = scripted([[0, 0], [10, 0]], [0.1, 0.6], range_m=[15.0, 5.0])
    sim.run(until_s=20)
    assert sim.state.role.tolist() == [LEADER, LEADER]
    assert records(sim, 1).cause.tolist() == ["rule4_no_leader"]


def test_gateway_belongs_to_two_groups():
    """A member between two leaders out of each other's range is a gateway."""
    sim, stack, deliveries = scripted([[0, 0], [18, 0], [9, 0]], [0.1, 0.2, 0.9])
    sim.run(until_s=10)
    cl = stack.clustering
    assert sim.state.role.tolist() == [LEADER, LEADER, MEMBER]
    assert cl.groups(sim.now) == [{0}, {1}, {0, 1}]
    assert cl.gateways(sim.now).tolist() == [2]


# -- the pure decisions ------------------------------------------------------------------
def test_transition_table_names_a_rule_for_every_change():
    for (role, _event), (new, cause) in TRANSITIONS.items():
        assert new != role and cause.startswith("rule")
    with pytest.raises(KeyError):
        transition(LEADER, "leader_heard")


def test_choose_leader_policies():
    c = [Candidate(4, 10.0), Candidate(2, 10.0), Candidate(7, 3.0)]
    assert choose_leader("nearest", c) == 7
    assert choose_leader("nearest", c[:2]) == 2  # tie: lowest id
    assert choose_leader("lowest_id", c) == 2
    assert choose_leader("first_heard", c, first_heard=4) == 4


def test_merge_loser_is_the_same_seen_from_both_sides():
    a, b = Candidate(1, group_size=3, degree=5), Candidate(5, group_size=3, degree=9)
    for policy in ("smaller_group_yields", "lowest_id_wins", "highest_degree_wins"):
        assert merge_loser(policy, a, b) == merge_loser(policy, b, a)
    assert merge_loser("smaller_group_yields", a, b) == 5  # tie: higher id yields
    assert merge_loser("highest_degree_wins", a, b) == 1


def test_election_policies():
    assert elected("lowest_id", Candidate(2), []) is True
    assert elected("none", Candidate(2), []) is False
    assert elected("highest_degree", Candidate(5, degree=4), [Candidate(1, degree=3)]) is True
