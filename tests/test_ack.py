"""The Ack beacon and neighbour tables (docs/model.md section 4; docs/validation.md item 8)."""

import math

import numpy as np
import pytest
from netsim.protocols._kernels import TIE_S
from netsim.protocols.neighbours import NeighbourTable

from netsim.run import build
from tests.fixtures import make_config
from tests.oracles.protocols import ack_record


def _static(positions, duration=20.0, **protocol):
    n = len(positions)
    cfg = make_config(
        duration_s=duration,
        world={"n_robots": n, "side_m": 10_000.0},
        mobility={"model": "static"},
        channel={"range_m": 10.0},
        protocol={"model": "ack", **protocol},
    )
    sim = build(cfg)
    sim.state.place(np.asarray(positions, dtype=float))
    return sim


def test_every_robot_sends_one_ack_per_period():
    """Without jitter, Acks leave at phase + k t exactly: 50 in 50 s from phases in [0, 1)."""
    sim = _static([[0, 0], [5, 0], [100, 0]], duration=50.0, ack_jitter_s=0.0)
    sent_at = []
    sim.models["protocol"].listeners.append(lambda now, ack, rec, hm: sent_at.append((ack.sender, ack.seq, now)))
    sim.run()
    assert sim.channel.counters_for("ack").sent.tolist() == [50, 50, 50]
    phase = sim.models["protocol"].phase_s
    for sender, seq, now in sent_at:  # delivered 1 ms (the latency) after phase + (seq - 1) t
        assert now == pytest.approx(phase[sender] + (seq - 1) + 0.001, abs=1e-9)


def test_ack_carries_its_fields():
    sim = _static([[0, 0], [5, 0]], ack_jitter_s=0.0)
    beacon = sim.models["protocol"]
    seen = []
    beacon.listeners.append(
        lambda now, ack, receivers, hears_me: seen.append((ack, receivers.tolist(), hears_me.tolist()))
    )
    sim.run(until_s=5.0)
    from_0 = [s for s in seen if s[0].sender == 0]
    assert [a.seq for a, _, _ in from_0] == list(range(1, len(from_0) + 1))
    ack, receivers, _ = from_0[-1]
    assert (ack.x_m, ack.y_m) == (0.0, 0.0) and receivers == [1]
    assert (ack.role, ack.leader, ack.group_size) == (0, -1, 1)
    assert ack.heard.tolist() == [1]
    assert from_0[-1][2] == [True]


def test_leader_listeners_hear_leaders_and_watched_senders_first():
    """A leader listener is told of exactly the Acks that announce a leader and those of
    senders marked in ``watched`` (at delivery), before the other listeners."""
    sim = _static([[0, 0], [5, 0], [0, 5], [5, 5]], ack_jitter_s=0.0)
    beacon = sim.models["protocol"]
    beacon.roles.role[1] = 2  # alpha: every Ack of robot 1 announces a leader
    told, every = [], []
    beacon.leader_listeners.append(lambda now, ack, rec, hm: told.append((now, ack.sender, len(every))))
    beacon.listeners.append(lambda now, ack, rec, hm: every.append((now, ack.sender)))

    def mark():
        yield sim.env.timeout(5.0)
        beacon.watched[3] = 1

    sim.env.process(mark())
    sim.run(until_s=10.0)
    wanted = [(t, s) for t, s in every if s == 1 or (s == 3 and t > 5.0)]
    assert [(t, s) for t, s, _ in told] == wanted and len(wanted) > 10
    assert all(every[k] == (t, s) for t, s, k in told)  # told before the others: its record came next


def test_neighbour_entry_lives_for_tau_after_the_last_ack():
    sim = _static([[0, 0], [5, 0]], ack_jitter_s=0.0)
    sim.run(until_s=4.0)
    table = sim.models["protocol"].table
    slot = table.entry(1, 0)
    last = table.last_heard_s[1, slot]
    assert table.live_mask(last + 2.999, 1)[slot]
    assert table.live_mask(last + 3.0, 1)[slot]  # an Ack due now still counts (TIE_S)
    assert not table.live_mask(last + 3.0 + 2 * TIE_S, 1)[slot]


def test_one_way_link_is_not_reported_as_heard():
    """With unequal ranges, j's Ack lists only the ids j heard: i learns the link is one-way."""
    cfg = make_config(
        duration_s=10.0,
        world={"n_robots": 2, "side_m": 1000.0},
        mobility={"model": "static"},
        channel={"range_m": [15.0, 5.0]},
        protocol={"model": "ack"},
    )
    sim = build(cfg)
    sim.state.place(np.array([[0.0, 0.0], [10.0, 0.0]]))
    sim.run()
    table = sim.models["protocol"].table
    slot = table.entry(1, 0)
    assert slot is not None and not table.hears_me[1, slot]  # 1 hears 0, 0 does not hear 1
    assert table.entry(0, 1) is None


def test_two_way_link_is_reported_as_heard():
    sim = _static([[0, 0], [5, 0]], ack_jitter_s=0.0)
    sim.run(until_s=5.0)
    t = sim.models["protocol"].table
    assert t.hears_me[0, t.entry(0, 1)] and t.hears_me[1, t.entry(1, 0)]


@pytest.mark.slow
def test_table_grows_beyond_its_initial_slots():
    table = NeighbourTable(40, tau_s=3.0, slots=2)
    fields = ack_record(0, 0, -1, 0.0, 0.0, 1, heard=[0])  # it lists robot 0
    for s in range(1, 40):
        table.receive(1.0, s, np.array([0]), fields)
    assert table.slots >= 39
    assert table.live_ids(1.5, 0).tolist() == list(range(1, 40))


def test_live_ids_are_ascending_whatever_the_slots_order():
    """A row's live neighbours come ascending, not in the order their slots were taken:
    robot 0 hears 5, then 2, then 4 (whose slot is the one 5 left when it expired)."""
    table = NeighbourTable(6, tau_s=3.0, slots=2)
    fields = ack_record(0, 0, -1, 0.0, 0.0, 1, heard=[0])
    table.receive(0.0, 5, np.array([0]), fields)
    table.receive(1.0, 2, np.array([0]), fields)
    assert table.live_ids(1.5, 0).tolist() == [2, 5]
    table.receive(3.5, 4, np.array([0]), fields)  # 5 expired: its slot, before 2's, is 4's
    assert table.id[0].tolist() == [4, 2]
    assert table.live_ids(3.5, 0).tolist() == [2, 4]


def test_expired_slot_is_reused_and_live_since_restarts():
    table = NeighbourTable(3, tau_s=3.0, slots=1)
    fields = ack_record(0, 0, -1, 0.0, 0.0, 1, heard=[0])  # it lists robot 0
    table.receive(0.0, 1, np.array([0]), fields)
    table.receive(2.0, 1, np.array([0]), fields)
    assert table.live_since_s[0, 0] == 0.0
    table.receive(10.0, 2, np.array([0]), fields)  # 1 expired: slot reused
    assert table.slots == 1 and table.id[0, 0] == 2 and table.live_since_s[0, 0] == 10.0


@pytest.mark.parametrize("p", [0.0, 0.3])
@pytest.mark.slow
def test_discovery_delay_of_a_new_link(p):
    """Item 8: a link that appears at a random beacon phase is discovered after
    T_b / 2 + T_b p / (1 - p) on average."""
    pairs, period = 1500, 1.0
    n = 2 * pairs
    pos = np.zeros((n, 2))
    pos[:pairs, 0] = np.arange(pairs) * 100.0
    pos[pairs:, 0] = np.arange(pairs) * 100.0
    pos[pairs:, 1] = 5000.0  # far away until t0
    cfg = make_config(
        seed=8,
        duration_s=40.0,
        world={"n_robots": n, "side_m": 200_000.0},
        mobility={"model": "static"},
        channel={"range_m": 10.0, "loss_probability": p, "latency_s": 0.0},
        protocol={"model": "ack", "ack_period_s": period, "ack_jitter_s": 0.0, "tau_s": 3.0},
        output={"position_interval_s": 0.0},
    )
    sim = build(cfg)
    sim.state.place(pos)
    t0 = 10.0
    first = np.full(n, np.nan)

    def listen(now, ack, receivers, hears_me):
        if ack.sender < pairs:
            r = receivers[receivers == ack.sender + pairs]
            new = r[np.isnan(first[r])]
            first[new] = now

    def arrive():
        yield sim.env.timeout(t0)
        for k in range(pairs):
            sim.state.set_leg(pairs + k, t0, (0.0, 0.0), start_m=(k * 100.0, 5.0))

    sim.models["protocol"].listeners.append(listen)
    sim.env.process(arrive())
    sim.run()
    delay = first[pairs:] - t0
    assert not np.isnan(delay).any()
    theory = period / 2 + period * p / (1 - p)
    se = delay.std() / math.sqrt(pairs)
    assert abs(delay.mean() - theory) < 4 * se


def test_an_ack_exactly_tau_after_the_last_keeps_the_entry_live():
    """An Ack arriving at the instant the entry expires counts: the entry stays live
    (``live_since`` and the two-way start are kept), and the slot is not reused then."""
    table = NeighbourTable(3, tau_s=3.0, slots=1)
    fields = ack_record(1, 0, -1, 0.0, 0.0, 1, heard=[0])
    table.receive(0.0, 1, np.array([0]), fields)
    table.receive(3.0, 2, np.array([0]), fields)  # another sender, same instant
    table.receive(3.0, 1, np.array([0]), ack_record(2, 0, -1, 0.0, 0.0, 1, heard=[0]))
    slot = table.entry(0, 1)
    assert table.live_since_s[0, slot] == 0.0 and table.bidir_since_s[0, slot] == 0.0
    assert table.live_mask(5.9, 0)[slot]


def test_an_older_ack_does_not_roll_the_entry_back():
    """Acks overtaken by newer ones (latency jitter above the period) are ignored: the
    entry keeps the newest Ack's fields and time."""
    table = NeighbourTable(2, tau_s=3.0)
    fresh, _, _ = table.receive(1.0, 1, np.array([0]), ack_record(7, 2, 1, 5.0, 6.0, 4, heard=[0]))
    stale, _, _ = table.receive(1.5, 1, np.array([0]), ack_record(6, 0, -1, 1.0, 2.0, 1))
    assert fresh.tolist() == [True] and stale.tolist() == [False]
    slot = table.entry(0, 1)
    assert (table.seq[0, slot], table.role[0, slot], table.leader[0, slot], table.group_size[0, slot]) == (7, 2, 1, 4)
    assert table.last_heard_s[0, slot] == 1.0 and table.hears_me[0, slot]


def test_reordered_acks_never_roll_tables_back():
    """Latency jitter of 2.5 periods reorders Acks: what a table holds for a sender, and
    what the protocol above is told, only ever moves to newer sequence numbers."""
    cfg = make_config(
        seed=4,
        duration_s=40.0,
        world={"n_robots": 4, "side_m": 1000.0},
        mobility={"model": "static"},
        channel={"range_m": 10.0, "latency_jitter_s": 2.5},
        protocol={"model": "ack", "tau_s": 4.0},
    )
    sim = build(cfg)
    sim.state.place(np.array([[0.0, 0.0], [5.0, 0.0], [0.0, 5.0], [5.0, 5.0]]))
    beacon = sim.models["protocol"]
    told, held, arrivals = {}, {}, []
    rolled_back = []

    def listen(now, ack, receivers, hears_me):
        for r in receivers.tolist():
            if told.get((r, ack.sender), 0) > ack.seq:
                rolled_back.append(("told", now, r, ack.sender))
            told[(r, ack.sender)] = ack.seq
            slot = beacon.table.entry(r, ack.sender)
            if held.get((r, ack.sender), 0) > beacon.table.seq[r, slot]:
                rolled_back.append(("held", now, r, ack.sender))
            held[(r, ack.sender)] = beacon.table.seq[r, slot]

    deliver = beacon.deliver

    def counting(sender, receivers, ack):
        arrivals.append((ack.seq, sender, int(receivers[0])))
        deliver(sender, receivers, ack)

    beacon.deliver = counting
    beacon.listeners.append(listen)
    sim.run()
    newest, overtaken = {}, 0
    for seq, s, r in arrivals:
        overtaken += newest.get((r, s), 0) > seq
        newest[(r, s)] = max(newest.get((r, s), 0), seq)
    assert overtaken > 20  # the jitter did reorder Acks ...
    assert rolled_back == []  # ... and no table or listener went back
    assert beacon.stale_acks == overtaken
    assert beacon.summary({"acks": sim.channel.frame("ack")}, 40.0)["acks_overtaken"] == overtaken


def test_acks_overtaken_counts_every_overtaken_ack_with_nobody_listening():
    """The summary's acks_overtaken counts the receptions a table ignored as older than its
    entry, also on the path of Acks nobody above the tables listens to (the Ack model
    alone, where the table is all there is to update). Latency jitter of 2.5 periods
    reorders Acks; no listener is added."""
    cfg = make_config(
        seed=4,
        duration_s=20.0,
        world={"n_robots": 3, "side_m": 1000.0},
        mobility={"model": "static"},
        channel={"range_m": 10.0, "latency_jitter_s": 2.5},
        protocol={"model": "ack", "tau_s": 4.0},
    )
    sim = build(cfg)
    sim.state.place(np.array([[0.0, 0.0], [5.0, 0.0], [0.0, 5.0]]))
    beacon = sim.models["protocol"]
    assert not beacon.listeners and not beacon.leader_listeners
    arrivals = []
    deliver = beacon.deliver

    def counting(sender, receivers, ack, power_dbm=None):
        arrivals.extend((ack.seq, sender, r) for r in receivers.tolist())
        deliver(sender, receivers, ack, power_dbm)

    beacon.deliver = counting
    sim.run()
    newest, overtaken = {}, 0
    for seq, s, r in arrivals:
        overtaken += newest.get((r, s), 0) > seq
        newest[(r, s)] = max(newest.get((r, s), 0), seq)
    assert overtaken > 5
    assert beacon.summary({"acks": sim.channel.frame("ack")}, 20.0)["acks_overtaken"] == overtaken
