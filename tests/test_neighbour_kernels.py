"""The neighbour tables' and the Ack's loops (protocols/_kernels.py), as plain Python and
compiled, compute exactly what the numpy oracle computes (compared with ``==``,
tests/oracles/protocols.py), and build the same Acks either way."""

import importlib

import numpy as np
import pytest
from netsim.protocols.neighbours import DEGREE, NeighbourTable, heard_in

from netsim.simpy_internals import set_now
from tests.oracles.protocols import NumpyTable, ack_record, deadline

pytest.importorskip("numba")

KERNELS = "netsim.protocols._kernels"


@pytest.fixture(params=["plain", "compiled"])
def kernels(request):
    """The protocols' kernel module as a small run calls it (plain Python) and compiled."""
    from netsim.compiled import compiled_copy

    return importlib.import_module(KERNELS) if request.param == "plain" else compiled_copy(KERNELS)


def _table(kernels, n, tau_s, slots):
    table = NeighbourTable(n, tau_s=tau_s, slots=slots)
    table.kernels = kernels
    return table


def test_overtaken_ack_counted_when_a_later_receivers_row_grows(kernels):
    """An Ack older than a receiver's entry (overtaken in flight) is counted stale, also when
    a later receiver of the same delivery has no free slot and the table grows midway
    (receive and take)."""
    out = []
    for how in ("receive", "take"):
        t = _table(kernels, 3, 10.0, 1)
        t.receive(0.0, 2, np.array([0]), ack_record(5, 0, -1, 0.0, 0.0, 1))  # 0 holds 2's seq 5
        t.receive(0.0, 0, np.array([1]), ack_record(1, 0, -1, 0.0, 0.0, 1))  # 1's only slot: 0
        older = ack_record(4, 0, -1, 0.0, 0.0, 1)
        if how == "receive":
            fresh, _, stale = t.receive(1.0, 2, np.array([0, 1]), older)
            assert fresh.tolist() == [False, True]
        else:
            stale = t.take(1.0, 2, np.array([0, 1]), older)
        out.append((stale, t.slots))
    assert out == [(1, 2)] * 2


def _ack_stream(rng, n, calls):
    """Random Acks: senders, receivers (distinct, ascending), heard lists, records (some
    sequence numbers going back: Acks overtaken in flight), at times with gaps past tau."""
    t = 0.0
    seq = np.zeros(n, dtype=np.int64)
    for _ in range(calls):
        t += float(rng.choice([0.0, 0.25, 0.5, 1.0, 3.0]))  # on a grid: Acks exactly tau apart
        s = int(rng.integers(n))
        seq[s] += 1
        others = np.delete(np.arange(n), s)
        receivers = np.sort(rng.choice(others, int(rng.integers(0, n - 1)), replace=False)).astype(np.int64)
        heard = np.sort(rng.choice(others, int(rng.integers(0, 8)), replace=False)).astype(np.int64)
        back = int(rng.integers(0, 3)) if rng.random() < 0.1 else 0
        fields = (seq[s] - back, int(rng.integers(0, 3)), int(rng.integers(-1, n)), *rng.random(2), 3, 2)
        yield t, s, receivers, heard, ack_record(*fields, heard=heard)


@pytest.mark.slow
def test_neighbour_table_loops_equal_the_oracle(kernels):
    """Recording Acks (new entries, renewals, expiry and reuse of slots, overtaken Acks,
    growth of the table, each receiver's power or none measured) leaves the same table and
    flags as the numpy oracle's update, and what an Ack announces (heard ids, packed record
    with the degree) is the oracle's."""
    rng = np.random.default_rng(11)
    n = 12
    table, oracle = _table(kernels, n, 3.0, 2), NumpyTable(n, tau_s=3.0, slots=2)
    # take(): receive() without the flags kept (the Ack model's deliveries).
    taken = _table(kernels, n, 3.0, 2)
    stale = 0
    for t, s, receivers, heard, record in _ack_stream(rng, n, 1500):
        power = rng.uniform(-95.0, -40.0, len(receivers)) if rng.random() < 0.7 else None
        a_fresh, a_hm, a_stale = table.receive(t, s, receivers, record, power)
        b_fresh, b_hm, b_stale = oracle.receive(t, s, receivers, record, power)
        assert a_fresh.tolist() == b_fresh.tolist() and a_hm.tolist() == b_hm.tolist()
        assert a_hm.tolist() == np.isin(receivers, heard).tolist()
        assert a_stale == b_stale == int((~a_fresh).sum())
        assert taken.take(t, s, receivers, record, power) == a_stale
        stale += a_stale
        i = int(rng.integers(n))
        fields = (int(rng.integers(100)), int(rng.integers(3)), int(rng.integers(-1, n)), *rng.random(2), 4)
        a_record = table.announce(t, i, *fields)
        assert a_record.tobytes() == oracle.announce(t, i, *fields).tobytes()
        assert heard_in(a_record).tolist() == sorted(oracle.id[i][oracle.live_mask(t, i)].tolist())
    assert table.slots == oracle.slots > 2
    for tb in (table, taken):
        assert np.array_equal(tb.id, oracle.id) and tb.data.tobytes() == oracle.data.tobytes()
    assert stale > 10


def _beacon_after(monkeypatch, seconds: float, compiled: bool):
    """An Ack beacon on 30 robots, some moving, run for ``seconds``: its tables filled."""
    from netsim.protocols.ack import AckBeacon, AckParams

    from tests.fixtures import static_core

    monkeypatch.setenv("NETSIM_COMPILED", "1" if compiled else "0")
    rng = np.random.default_rng(8)
    sim = static_core(rng.uniform(0, 60, (30, 2)), range_m=25.0)
    for i in range(0, 30, 3):
        sim.state.set_leg(i, 0.0, rng.uniform(-2, 2, 2), cause="command")
    beacon = AckBeacon(AckParams(), sim.parts)
    beacon.start()
    sim.run(until_s=seconds)
    return sim, beacon


def test_acks_built_plain_and_compiled_are_the_same(monkeypatch):
    """An Ack built in one call (position, sequence number, resignation, role, leader,
    group size, what the table announces; the sequence number counted, the resignation
    cleared, the role and degree sent recorded) is the same built by the plain-Python loop
    as by the compiled one, and announces what the oracle's table announces."""
    (sim_a, a), (sim_b, b) = _beacon_after(monkeypatch, 6.0, True), _beacon_after(monkeypatch, 6.0, False)
    assert a.table.kernels is not b.table.kernels
    rng = np.random.default_rng(9)
    now = sim_a.env.now
    degrees = []
    for _ in range(200):
        i = int(rng.integers(30))
        role, leader, size, resign = rng.integers(0, 3), rng.integers(-1, 30), rng.integers(1, 9), rng.random() < 0.3
        for beacon in (a, b):
            beacon.roles.role[i], beacon.roles.leader[i] = role, leader
            beacon.group_size[i], beacon.resign_pending[i] = size, resign
        ack_a, ack_b = a.make_ack(i), b.make_ack(i)
        assert ack_a._replace(record=None) == ack_b._replace(record=None)
        assert [type(x) for x in ack_a] == [type(x) for x in ack_b]
        assert ack_a.heard.tolist() == ack_b.heard.tolist() and ack_a.record.tobytes() == ack_b.record.tobytes()
        oracle = NumpyTable(30, a.table.tau_s)
        oracle.id, oracle.data = a.table.id, a.table.data
        fields = (ack_a.seq, ack_a.role, ack_a.leader, ack_a.x_m, ack_a.y_m, ack_a.group_size)
        assert ack_a.record.tobytes() == oracle.announce(now, i, *fields).tobytes()
        degrees.append(ack_a.record[DEGREE])
        now += 0.01
        set_now(sim_a.env, now)
        set_now(sim_b.env, now)
    for name in ("seq", "resign_pending", "role_sent", "degree_sent"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    assert max(degrees) > 3 and a.resign_pending.sum() < 30


def _first_after(now, tau_s, last, step):
    """The float nearest ``last`` on the side of ``step`` whose deadline (``tau_s`` later, as
    a timer computes it: :func:`tests.oracles.protocols.deadline`) is past ``now`` (step
    +inf) or before it (step -inf)."""
    while not (deadline(last, tau_s) > now if step > 0 else deadline(last, tau_s) < now):
        last = np.nextafter(last, step)
    return last


def _at(now, tau_s):
    """A last Ack's instant whose deadline is ``now`` to the last bit."""
    # The least float whose deadline is not before ``now``, by bisection over the floats'
    # bit patterns (ordered as the positive floats are): a tie's nanosecond is a million of
    # them, too many to step through one at a time.
    lo, hi = np.float64(now - tau_s - 2e-9), np.float64(now - tau_s)
    assert deadline(lo, tau_s) < now <= deadline(hi, tau_s)
    lo_bits, hi_bits = int(lo.view(np.int64)), int(hi.view(np.int64))
    while hi_bits - lo_bits > 1:
        mid = (lo_bits + hi_bits) // 2
        if deadline(np.int64(mid).view(np.float64), tau_s) < now:
            lo_bits = mid
        else:
            hi_bits = mid
    last = np.int64(hi_bits).view(np.float64)
    assert deadline(last, tau_s) == now
    return last


def test_member_of_is_the_group_a_live_entry_last_named_and_starts_afresh_with_it(kernels):
    """Rule 6's rivals: an entry keeps the leader its latest member Ack named once the
    neighbour leads, while the entry lives; a neighbour back after its entry expired starts
    with none, whether its slot was kept or another sender took it meanwhile."""
    member, leader = 1, 2
    for taken_meanwhile in (False, True):
        table = _table(kernels, 4, 3.0, 1)
        r = np.array([0])
        table.receive(0.0, 1, r, ack_record(1, member, 2, 0.0, 0.0, 1))
        table.receive(1.0, 1, r, ack_record(2, leader, 1, 0.0, 0.0, 1))
        assert table.member_of[0, table.entry(0, 1)] == 2
        if taken_meanwhile:
            table.receive(5.0, 3, r, ack_record(1, leader, 3, 0.0, 0.0, 1))
        table.receive(100.0, 1, r, ack_record(3, leader, 1, 0.0, 0.0, 1))
        assert table.member_of[0, table.entry(0, 1)] == -1


def test_timeout_an_entry_is_live_while_its_last_ack_is_younger_than_tau(kernels):
    """The timeout rule, one kernel for every reader of the table: an entry is live while
    its deadline, its last Ack's instant plus ``tau_s`` as a timer computes it, is still to
    come: not at its deadline or past it, but one a hair younger is; an empty slot (last
    heard at minus infinity) never is. Read as ``now - last < tau_s`` instead, an entry could
    still be live at its own timer's instant (``(a + tau) - a`` may fall short of ``tau``)."""
    tau_s, now = 2.5, 10.0
    younger = _first_after(now, tau_s, _at(now, tau_s), np.inf)
    last = np.array([_at(now, tau_s), younger, now, -np.inf, 0.0, 9.0])
    assert kernels.live_entries(last, now, tau_s).tolist() == [False, True, True, False, False, True]
    rng = np.random.default_rng(3)
    last = rng.uniform(0.0, now, 500)
    assert kernels.live_entries(last, now, tau_s).tolist() == (now < deadline(last, tau_s)).tolist()
    # An instant whose rounding puts the two readings apart: only the deadline's agrees
    # with the timer of the same entry.
    a = 5.896838452432008
    assert bool(kernels.is_live(a, deadline(a, 3.0), 3.0)) is False and (a + 3.0) - a < 3.0


def test_an_ack_at_the_instant_of_expiry_continues_the_entry(kernels):
    """An Ack up to tau after the entry's last one continues it (its history kept), the
    instant of expiry included, where the entry is no longer live; a hair later it starts
    afresh."""
    tau_s, now = 2.5, 10.0
    for last, live, continued in (
        (_at(now, tau_s), False, True),
        (_first_after(now, tau_s, _at(now, tau_s), -np.inf), False, False),
        (_first_after(now, tau_s, _at(now, tau_s), np.inf), True, True),
        (now, True, True),
    ):
        assert bool(kernels.is_live(float(last), now, tau_s)) is live
        assert bool(kernels.continues(float(last), now, tau_s)) is continued


def test_a_deadline_takes_the_instants_that_round_into_it_at_any_time_of_a_run(kernels):
    """A deadline is tau and a nanosecond after its start; past 10^6 s, where a nanosecond is
    below the times' own rounding (at 10^8 s, t + 1e-9 == t), a few units in the last
    place. An empty entry's -inf stays -inf."""
    for t in (10.0, 1e6, 1e8, 1e12):
        due = t + 3.0
        d = kernels.deadline_after(t, 3.0)
        assert due < d <= due + max(1e-9, 2**-49 * due)
    assert kernels.deadline_after(-np.inf, 3.0) == -np.inf


def test_a_slot_an_ack_may_still_continue_is_not_given_to_another_sender(kernels):
    """At the instant of its expiry an entry is no longer live, but an Ack of its sender
    arriving then still continues it (its history kept), so another sender's Ack of that
    instant takes a free slot, not that one. Robot 0 heard 1 at ``last``; at ``last``'s
    deadline, 2's Ack then 1's arrive: 1's entry keeps its live-since. Giving the expired
    slot away made 1's Ack start a new entry, as if the link had broken."""
    tau_s, now = 2.5, 10.0
    last = _at(now, tau_s)
    t = _table(kernels, 3, tau_s, 4)
    t.receive(float(last), 1, np.array([0]), ack_record(1, 0, -1, 0.0, 0.0, 1))
    t.receive(now, 2, np.array([0]), ack_record(1, 0, -1, 0.0, 0.0, 1))
    t.receive(now, 1, np.array([0]), ack_record(2, 0, -1, 0.0, 0.0, 1))
    assert sorted(t.id[0][t.id[0] >= 0].tolist()) == [1, 2]
    assert t.live_since_s[0, t.entry(0, 1)] == last
    assert t.live_since_s[0, t.entry(0, 2)] == now
