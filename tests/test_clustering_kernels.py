"""The clustering's loops (protocols/_kernels.py), as plain Python and compiled, compute
exactly what the numpy oracles compute (compared with ``==``, tests/oracles/protocols.py):
the effects of an Ack, a leader's group size and the Ack announcing it (make_sized_ack),
rule 2's choice and rule 6's verdict from a row, everyone's groups, who relays a flooded
message and the samples of beliefs beside the truth; and the relaying rule holds."""

import importlib

import numpy as np
import pandas as pd
import pytest
from netsim.protocols._kernels import (
    EMPTY_RECORD,
    GROUP_SIZE,
    HEARS_ME,
    LAST_HEARD,
    LEADER,
    ROLE,
    TIE_S,
    AckEffects,
    X,
    Y,
)
from netsim.protocols.clustering import ElectionPolicy, JoinPolicy, rules_record
from netsim.protocols.roles import LEADER as ALPHA
from netsim.protocols.roles import MEMBER, UNDECIDED

from tests.fixtures import clustering, make_config
from tests.oracles.protocols import (
    ack_effects,
    belief_counts,
    believed_keys,
    deadline,
    elected_in_row,
    flood_step,
    group_size,
    join_choice,
    membership,
    relays,
    sample_rows,
)

pytest.importorskip("numba")

KERNELS = "netsim.protocols._kernels"
TAU_S = 3.0


@pytest.fixture(params=["plain", "compiled"])
def kernels(request):
    """The protocols' kernel module as a small run calls it (plain Python) and compiled."""
    from netsim.compiled import compiled_copy

    return importlib.import_module(KERNELS) if request.param == "plain" else compiled_copy(KERNELS)


def random_tables(rng, n, slots, now):
    """Neighbour tables ``(ids, records)`` with random entries: live, expired, exactly tau
    old (live: its deadline takes the instants that round into it), at their deadline to
    the last bit (expired), empty; one-way and two-way; any role and leader."""
    ids = np.where(rng.random((n, slots)) < 0.8, rng.integers(0, n, (n, slots)), -1).astype(np.int64)
    records = np.broadcast_to(EMPTY_RECORD, (n, slots, len(EMPTY_RECORD))).copy()
    used = ids >= 0
    at_deadline = now - TAU_S - TIE_S
    while deadline(at_deadline, TAU_S) < now:
        at_deadline = np.nextafter(at_deadline, np.inf)
    assert deadline(at_deadline, TAU_S) == now
    heard_s = np.array([now - age for age in (0.0, 0.5, 2.9, TAU_S, 4.0)] + [at_deadline])
    records[:, :, LAST_HEARD] = np.where(used, heard_s[rng.integers(0, len(heard_s), (n, slots))], -np.inf)
    records[:, :, HEARS_ME] = used & (rng.random((n, slots)) < 0.7)
    records[:, :, ROLE] = np.where(used, rng.integers(0, 3, (n, slots)), 0)
    records[:, :, LEADER] = np.where(used, rng.integers(-1, 6, (n, slots)), -1)
    return ids, records


def leaders_in_rows(rng, ids):
    """A leader for each robot: most often one its own row holds (so that its link to its
    leader is in the table, as a member's is), else any id, -1 included."""
    n = len(ids)
    picked = ids[np.arange(n), rng.integers(0, ids.shape[1], n)]
    anyone = rng.integers(-1, 6, n)
    return np.where((picked >= 0) & (rng.random(n) < 0.8), picked, anyone).astype(np.int64)


@pytest.mark.parametrize("symmetric", [False, True])
def test_ack_effects_loop_equals_the_oracle(symmetric, kernels):
    """An Ack's effects (its group's members; for a leading Ack the timers it renews, which
    of them to arm, the undecided robots it reaches over two-way links and the leaders that
    may merge with its sender now, with the sender's slot in their rows) and the deadlines it
    writes are the oracle's."""
    from netsim.protocols.neighbours import BIDIR_SINCE, LIVE_SINCE, ROLE_SINCE

    rng = np.random.default_rng(5)
    n, now = 60, 10.0
    found = np.zeros(5, dtype=int)
    for _ in range(400):
        role = rng.integers(0, 3, n).astype(np.int8)
        leader = rng.integers(-1, 8, n).astype(np.int64)
        sender = int(rng.integers(8))
        receivers = np.sort(rng.choice(np.delete(np.arange(n), sender), int(rng.integers(0, 15)), replace=False))
        hears_me = rng.random(len(receivers)) < 0.6
        leads = bool(rng.random() < 0.7)
        armed_s = rng.choice([np.inf, 10.0, 13.0, 14.0, 18.0], n)  # renewed: now + tau = 13
        deadline_a = rng.uniform(0.0, 10.0, n)
        deadline_b = deadline_a.copy()
        ids, records = random_tables(rng, n, 6, now)
        # The sender has an entry in most receivers' rows (the Ack was just recorded there).
        has = receivers[rng.random(len(receivers)) < 0.9]
        ids[has, rng.integers(0, 6, len(has))] = sender
        for col in (LIVE_SINCE, BIDIR_SINCE, ROLE_SINCE):
            records[:, :, col] = rng.choice([-np.inf, 2.0, 6.5, 8.0, 9.0, np.inf], (n, 6))
        role_sent = rng.integers(0, 3, n)
        leader_since = rng.choice([np.inf, 0.0, 7.0, 8.5], n)
        told = (sender, receivers, np.zeros(12), leads)
        rules = rules_record(TAU_S, 1.0, symmetric, "nearest", "lowest_id")
        out_a, out_b = AckEffects.empty(n), AckEffects.empty(n)
        for out in (out_a, out_b):
            for row in out[:5]:
                row[:] = -7
        robots_a = (role, leader, role_sent, leader_since, deadline_a, armed_s)
        robots_b = (role, leader, role_sent, leader_since, deadline_b, armed_s)
        a = kernels.ack_effects(now, told, hears_me, robots_a, (ids, records, TAU_S), rules, tuple(out_a))
        b = ack_effects(now, told, hears_me, robots_b, (ids, records, TAU_S), rules, tuple(out_b))
        assert a == b
        counts = [*a, a[3]]
        assert [row[:k].tolist() for row, k in zip(out_a[:5], counts)] == [
            row[:k].tolist() for row, k in zip(out_b[:5], counts)
        ]
        assert deadline_a.tobytes() == deadline_b.tobytes()
        found += [k > 0 for k in counts]
    assert found.min() > 20


@pytest.mark.parametrize("symmetric", [False, True])
def test_receive_effects_is_receive_then_ack_effects(symmetric, kernels):
    """An Ack told to the clustering, recorded in the table and acted on in one call
    (receive_effects), leaves the table, the deadlines and ack_effects' lists (over the
    receivers that took it) as the two calls do, one after the other; overtaken Acks
    (stale) and rows that must grow midway included."""
    from netsim.protocols.neighbours import NeighbourTable

    from tests.test_neighbour_kernels import _ack_stream

    rng = np.random.default_rng(23)
    n = 12
    one, two = NeighbourTable(n, TAU_S, slots=2), NeighbourTable(n, TAU_S, slots=2)
    one.kernels = two.kernels = kernels
    deadline_one, deadline_two = np.full(n, np.inf), np.full(n, np.inf)
    out_one, out_two = AckEffects.empty(n), AckEffects.empty(n)
    stale_seen = acted = 0
    for now, sender, receivers, _, record in _ack_stream(rng, n, 300):
        role = rng.integers(0, 3, n).astype(np.int8)
        leader = rng.integers(-1, 4, n).astype(np.int64)
        leads = bool(rng.random() < 0.7)
        armed_s = rng.choice([np.inf, now + 1.0, now + 5.0], n)
        role_sent, leader_since = rng.integers(0, 3, n), rng.choice([np.inf, 0.0, now - 0.5], n)
        rules = rules_record(TAU_S, 1.0, symmetric, "nearest", "lowest_id")
        power = rng.uniform(-95.0, -40.0, len(receivers)) if rng.random() < 0.7 else None
        fresh, hears_me, stale = one.receive(now, sender, receivers, record, power)
        kept = receivers[fresh]
        counts = kernels.ack_effects(
            now,
            (sender, kept, record, leads),
            hears_me[fresh],
            (role, leader, role_sent, leader_since, deadline_one, armed_s),
            one.view,
            rules,
            tuple(out_one),
        )
        told = (sender, receivers, record, leads)
        robots = (role, leader, role_sent, leader_since, deadline_two, armed_s)
        stale_two, (kept_two, *counts_two) = two.take_by(
            kernels.receive_effects, now, told, power, robots, rules, tuple(out_two)
        )
        assert (stale_two, kept_two, tuple(counts_two)) == (stale, len(kept), counts)
        assert out_two.takers[:kept_two].tolist() == kept.tolist()
        assert out_two.takers_hear_me[:kept_two].tolist() == hears_me[fresh].tolist()
        for row, k in zip(range(5), [*counts, counts[3]]):
            assert out_two[row][:k].tolist() == out_one[row][:k].tolist()
        assert deadline_two.tobytes() == deadline_one.tobytes()
        assert two.id.tobytes() == one.id.tobytes() and two.data.tobytes() == one.data.tobytes()
        stale_seen += stale
        acted += sum(counts) > 0
    assert stale_seen > 5 and acted > 50 and one.slots > 2


def test_clustering_taking_told_acks_in_one_call_runs_as_in_two():
    """A run where the clustering takes the Acks it is told of into the table and acts on
    them in one call (the beacon's taker) has the same roles, groups and tables as one where
    the table takes them and the clustering is told after (the taker unset)."""
    from tests.fixtures import clustering

    rng = np.random.default_rng(8)
    positions = rng.uniform(0, 60, (30, 2))
    runs = []
    calls = []
    for taker in (True, False):
        sim, stack = clustering(positions, start=False, core={"range_m": 25.0})
        listener, take = stack.beacon.taker
        stack.beacon.taker = (listener, lambda *args, take=take, run=taker: calls.append(run) or take(*args))
        if taker is False:
            stack.beacon.taker = None
        stack.start(np.random.default_rng(3).uniform(0, 1, 30))
        sim.run(until_s=20.0)
        runs.append(stack)
    assert calls.count(True) > 100 and set(calls) == {True}
    a = runs[0]
    assert len(a.clustering.roles_frame()) > 30
    for b in runs[1:]:
        assert a.clustering.roles_frame().equals(b.clustering.roles_frame())
        assert a.groups_frame().equals(b.groups_frame())
        assert a.beacon.table.data.tobytes() == b.beacon.table.data.tobytes()


@pytest.mark.parametrize("symmetric", [False, True])
def test_group_size_loop_equals_the_oracle(symmetric, kernels):
    """A leader's group size from its row of the neighbour table is the oracle's count."""
    rng = np.random.default_rng(7)
    sizes = []
    for _ in range(50):
        now = 10.0
        ids, records = random_tables(rng, 6, 8, now)
        for i in range(6):
            a = kernels.group_size(records[i], now, TAU_S, symmetric, i)
            b = group_size(records[i], now, TAU_S, symmetric, i)
            assert a == b
            sizes.append(b)
    assert min(sizes) == 1 and max(sizes) > 2


@pytest.mark.parametrize("symmetric", [False, True])
def test_sized_ack_announces_the_oracles_group_size(symmetric, kernels):
    """The group size an Ack built in one call announces (make_sized_ack counts a leader's
    members in the pass that makes the Ack) is the oracle's group_size of its row for
    a leader, 1 for anyone else, whatever it announced before; and it is kept in sizes."""
    rng = np.random.default_rng(17)
    n, now, announced = 6, 10.0, []
    origin, velocity, t0 = rng.uniform(0, 50, (n, 2)), np.zeros((n, 2)), np.zeros(n)
    sent, resign = np.zeros((n, 3), dtype=np.int64), np.zeros(n, dtype=bool)
    sizes, sized = np.ones(n, dtype=np.int64), np.zeros(n, dtype=bool)
    for _ in range(60):
        ids, records = random_tables(rng, n, 8, now)
        role = rng.integers(0, 3, n).astype(np.int8)
        leader = rng.integers(-1, n, n).astype(np.int64)
        for i in range(n):
            motion, beacon = (origin, velocity, t0, False, 0.0), (sent, resign, sizes)
            ack = kernels.make_sized_ack(
                i, now, motion, beacon, (role, leader), (ids, records, TAU_S), sized, symmetric
            )
            want = group_size(records[i], now, TAU_S, symmetric, i) if role[i] == ALPHA else 1
            assert ack[6] == ack[8][GROUP_SIZE] == sizes[i] == want and sized[i] == (role[i] == ALPHA)
            announced.append((int(role[i]), want))
    assert sum(size > 1 for role, size in announced if role == ALPHA) > 10
    assert any(role != ALPHA and size == 1 for role, size in announced)


@pytest.mark.parametrize("symmetric", [False, True])
@pytest.mark.parametrize("distributed_gateways", [False, True])
def test_relays_loop_equals_the_oracle(symmetric, distributed_gateways, kernels):
    """The receivers of a flooded message that relay it are the oracle's."""
    rng = np.random.default_rng(9)
    relayed = 0
    for _ in range(100):
        n, now = 12, 10.0
        ids, records = random_tables(rng, n, 6, now)
        role = rng.integers(0, 3, n).astype(np.int8)
        leader = leaders_in_rows(rng, ids)
        receivers = np.sort(rng.choice(n, int(rng.integers(0, n)), replace=False)).astype(np.int64)
        args = ((ids, records, TAU_S), now, symmetric, (role, leader), receivers, distributed_gateways)
        a, b = kernels.relays(*args), relays(*args)
        assert a.tolist() == b.tolist()
        relayed += len(a)
    assert relayed > 50


def test_flood_step_loop_equals_the_oracle(kernels):
    """A flood's step (who had not seen the message, marked now; which of them relay it) is
    the oracle's, the flags left alike."""
    rng = np.random.default_rng(4)
    fresh_seen = relayed = 0
    for _ in range(100):
        n, now = 12, 10.0
        ids, records = random_tables(rng, n, 6, now)
        role = rng.integers(0, 3, n).astype(np.int8)
        leader = leaders_in_rows(rng, ids)
        seen = rng.random(n) < 0.4
        receivers = np.sort(rng.choice(n, int(rng.integers(0, n)), replace=False)).astype(np.int64)
        seen_a, seen_b = seen.copy(), seen.copy()
        rest = ((ids, records, TAU_S), now, bool(rng.random() < 0.5), (role, leader), bool(rng.random() < 0.5))
        fresh_a, relay_a = kernels.flood_step(seen_a, receivers, *rest)
        fresh_b, relay_b = flood_step(seen_b, receivers, *rest)
        assert fresh_a.tolist() == fresh_b.tolist() == [r for r in receivers.tolist() if not seen[r]]
        assert relay_a.tolist() == relay_b.tolist() and seen_a.tolist() == seen_b.tolist()
        assert seen_a[receivers].all()
        fresh_seen += len(fresh_a)
        relayed += len(relay_a)
    assert fresh_seen > 100 and relayed > 30


def test_relays_are_leaders_and_members_next_to_another_group(kernels):
    """Leaders relay; a member relays when its link to its own leader is two-way and a live
    two-way neighbour is in another group: a member of another leader (distributed
    gateways) or another leader (strict backbone); undecided robots, one-way and expired
    neighbours do not count, and a member whose own leader does not hear it is no gateway
    (MODEL 4.1: it belongs to no group; it relayed all the same)."""
    now = 10.0
    # Robot 0: leader. 1: member of 0 hearing a member of leader 5 over a two-way link.
    # 2: member of 0 hearing leader 5 one way only. 3: member of 0 hearing leader 5 two-way.
    # 4: member of 0 hearing undecided 7, and 5's member 6 too long ago. 7: undecided.
    # 8: member of 0 that 0 no longer hears (one way), hearing leader 5 two-way.
    # Every member but 8 has a two-way link to its leader.
    role = np.array([ALPHA, MEMBER, MEMBER, MEMBER, MEMBER, ALPHA, MEMBER, UNDECIDED, MEMBER], dtype=np.int8)
    leader = np.array([0, 0, 0, 0, 0, 5, 5, -1, 0], dtype=np.int64)
    ids = np.full((9, 3), -1, dtype=np.int64)
    records = np.broadcast_to(EMPTY_RECORD, (9, 3, len(EMPTY_RECORD))).copy()

    def entry(i, slot, j, heard_s, hears_me):
        ids[i, slot] = j
        records[i, slot, [LAST_HEARD, HEARS_ME, ROLE, LEADER]] = [now - heard_s, hears_me, role[j], leader[j]]

    for member in (1, 2, 3, 4, 6):
        entry(member, 2, leader[member], 1.0, 1)
    entry(8, 2, 0, 1.0, 0)
    entry(1, 0, 6, 1.0, 1)
    entry(2, 0, 5, 1.0, 0)
    entry(3, 0, 5, 1.0, 1)
    entry(4, 0, 7, 1.0, 1)
    entry(4, 1, 6, TAU_S + 2 * TIE_S, 1)  # just past its deadline
    entry(8, 0, 5, 1.0, 1)
    everyone = np.arange(9)
    table, roles = (ids, records, TAU_S), (role, leader)
    for fn in (relays, kernels.relays):
        assert fn(table, now, False, roles, everyone, True).tolist() == [0, 1, 3, 5]
        assert fn(table, now, True, roles, everyone, True).tolist() == [0, 1, 2, 3, 5, 8]
        assert fn(table, now, False, roles, everyone, False).tolist() == [0, 3, 5]
    robot, group, _ = kernels.membership(table, now, False, roles)
    assert 8 not in robot.tolist() and group[robot == 3].tolist() == [0, 5]


def test_members_counted_as_roles_change():
    """The count of each robot's members, which lets the clustering skip the Acks that do
    not lead when their sender has none, follows every role change: at every second of a
    run with merges, timeouts and resignations it is the count from the roles."""
    from tests.fixtures import clustering

    rng = np.random.default_rng(2)
    sim, stack = clustering(rng.uniform(0, 40, (25, 2)), core={"duration_s": 40.0, "range_m": 12.0})
    cl = stack.clustering
    changes = 0
    for t in range(1, 41):
        sim.run(until_s=float(t))
        members = stack.role == MEMBER
        assert cl._members_of == np.bincount(stack.leader[members], minlength=25).tolist()
        changes = int(cl.role_changes.sum())
    assert changes > 25


@pytest.mark.parametrize("symmetric", [False, True])
def test_membership_loop_equals_the_oracle(symmetric, kernels):
    """Everyone's groups (leaders in their own, members in their leader's and those of the
    other leaders they know), ordered by robot and group, are the oracle's."""
    rng = np.random.default_rng(17)
    secondary = 0
    for _ in range(40):
        n, now = 12, 10.0
        ids, records = random_tables(rng, n, 6, now)
        role = rng.integers(0, 3, n).astype(np.int8)
        leader = np.where(role == MEMBER, leaders_in_rows(rng, ids), np.where(role == ALPHA, np.arange(n), -1))
        args = ((ids, records, TAU_S), now, symmetric, (role, leader))
        a, b = kernels.membership(*args), membership(*args)
        assert [x.tolist() for x in a] == [x.tolist() for x in b]
        assert [x.dtype for x in a] == [x.dtype for x in b]
        secondary += int((~a[2]).sum())
    assert secondary > 20


def belief_inputs(rng, n, slots, now):
    """Random tables (ids distinct in a row) and random ascending ``heard`` keys, some of
    them pairs both ways, some on the tables' live entries."""
    ids, records = random_tables(rng, n, slots, now)
    if n:
        distinct = np.argsort(rng.random((n, max(slots, n))), axis=1)[:, :slots]
        ids = np.where((ids >= 0) & (distinct < n), distinct, -1)
        records[ids < 0] = EMPTY_RECORD  # an EMPTY slot holds the empty record (never live)
    a = rng.integers(0, max(n, 1), int(rng.integers(0, 4 * n + 1)))
    b = rng.integers(0, max(n, 1), len(a))
    believed = believed_keys(ids, records, now, TAU_S)
    keys = np.concatenate([a * n + b, b * n + a, rng.choice(believed, len(believed) // 2) if len(believed) else a])
    return ids, records, np.unique(keys).astype(np.int64) if n else np.empty(0, np.int64)


def reach_tables(rng, n, slots, now, heard):
    """Neighbour tables whose rows hold (distinct) ids of robots that reach their robot
    (``heard``: ascending keys), and other ids: entries true and stale, live and expired."""
    ids, records = random_tables(rng, n, slots, now)
    senders = np.split(heard % n, np.searchsorted(heard, np.arange(1, n) * n))
    for r in range(n):
        near = rng.permutation(senders[r])[: int(rng.integers(0, slots + 1))]
        row = np.unique(np.concatenate([near, rng.integers(0, n, int(rng.integers(0, 4)))]))[:slots]
        ids[r] = -1
        ids[r, rng.permutation(slots)[: len(row)]] = row
    records[ids < 0] = EMPTY_RECORD
    return ids, records, senders


@pytest.mark.parametrize("kernels", [pytest.param("plain", marks=pytest.mark.slow), "compiled"], indirect=True)
@pytest.mark.parametrize("torus", [False, True])
@pytest.mark.parametrize("symmetric", [False, True])
def test_sample_into_loop_equals_the_oracle(torus, symmetric, kernels):
    """A sample written in one pass, the truth from the range index's neighbour
    lists, is the oracle's (membership and belief rows of the keys in reach, then the
    counts): the groups, who believes whom and the per-robot columns, row for row;
    distances a hair either side of the range, unequal ranges, members whose leader reaches
    them both ways, one way, not at all. Nothing is written past the rows it reports."""
    from netsim.radio.spatial import RangeIndex
    from netsim.state import RobotState
    from tests.oracles.near_pairs import reach_keys as reach_keys_of_pairs
    from tests.test_kernels import reach_layouts

    rng = np.random.default_rng(37)
    side, now, slots = 1000.0, 10.0, 8
    lir = 0
    for pos, ranges in reach_layouts(rng, side):
        n = len(pos)
        st = RobotState(n, side, ranges, torus=torus)
        st.place(pos % side if torus else pos)
        at = st.positions_at(0.0)
        near_ptr, near = RangeIndex(st).lists(0.0)
        heard = reach_keys_of_pairs(at, st.range_m, side if torus else None)
        ids, records, senders = reach_tables(rng, n, slots, now, heard)
        role = rng.integers(0, 3, n).astype(np.int8)
        reaching = [int(rng.choice(s)) if len(s) and rng.random() < 0.8 else int(rng.integers(-1, n)) for s in senders]
        leader = np.where(role == MEMBER, reaching, np.where(role == ALPHA, np.arange(n), -1)).astype(np.int64)
        groups = tuple(np.full(n * (slots + 1) + 3, fill, dtype) for fill, dtype in [(-7, np.int64)] * 2 + [(1, bool)])
        pairs = tuple(
            np.full(n * slots + len(near) + 3, fill, dtype) for fill, dtype in [(-7, np.int64)] * 2 + [(1, bool)] * 2
        )
        counts = tuple(np.full(n, -7, dtype) for dtype in [np.int64, np.int8, np.int64, bool, *[np.int64] * 4])
        box = side if torus else 0.0
        table, roles, truth = (ids, records, TAU_S), (role, leader), (at, st.range_m, box, near_ptr, near)
        m, k = kernels.sample_into(table, now, symmetric, roles, truth, groups, pairs, counts, 0, n)
        (g_robot, g_group, g_primary), rows = sample_rows(table, now, symmetric, roles, heard)
        want = belief_counts(rows.neighbour, rows.believed, rows.in_range, rows.indptr, role, leader)
        assert [x[:m].tolist() for x in groups] == [g_robot.tolist(), g_group.tolist(), g_primary.tolist()]
        assert [x[:k].tolist() for x in pairs] == [x.tolist() for x in rows[:4]]
        believed_n, true_n, stale_n, missing_n, leader_in_range = want
        expected = [np.arange(n), role, leader, leader_in_range, believed_n, true_n, stale_n, missing_n]
        assert [x.tolist() for x in counts] == [x.tolist() for x in expected]
        assert all((x[m:] == x[-1]).all() for x in groups) and all((x[k:] == x[-1]).all() for x in pairs)
        lir += int((leader_in_range & (role == MEMBER)).sum())
    assert lir > 50


@pytest.mark.parametrize("radio", [False, True], ids=["unit disk", "log-distance"])
@pytest.mark.parametrize("compiled", [pytest.param(False, marks=pytest.mark.slow), True])
def test_sampler_tables_written_in_place_equal_those_made_of_rows(monkeypatch, compiled, radio):
    """A run's sampled tables (groups, beliefs, neighbour_beliefs), written in place by one
    pass (sample_into) over neighbour lists, the channel's range index's or (under a radio)
    built for the sample, are the oracle's made of a sample's rows and counts (membership
    and belief rows of the keys in reach, then the counts), plain and compiled."""
    (_, a), (_, b) = (_clustering_after(monkeypatch, 12.0, compiled, rows, radio) for rows in (False, True))
    for x, y in [(a.groups_frame(), b.groups_frame()), (a.beliefs_frame(), b.beliefs_frame())]:
        assert x.equals(y) and len(x) > 300
    x, y = a.neighbour_beliefs_frame(), b.neighbour_beliefs_frame()
    assert x.equals(y) and x["believed"].sum() > 300 and x["in_range"].sum() > 300


@pytest.mark.parametrize("radio", [False, True], ids=["unit disk", "log-distance"])
def test_sample_in_two_halves_equals_one_pass(monkeypatch, radio):
    """A run's sampled tables taken in two halves at once (two threads, the second's rows
    moved up after the first's) are those of one pass (the threshold lowered to this small
    run, two cores assumed whatever the machine has), on the range index's lists and on
    lists built for the sample."""
    import netsim.protocols.stack

    (_, whole) = _clustering_after(monkeypatch, 12.0, True, radio=radio)
    monkeypatch.setattr(netsim.protocols.stack, "SAMPLE_IN_TWO_ROBOTS", 1)
    monkeypatch.setattr(netsim.protocols.stack, "cores", lambda: 2)
    calls = []
    both = netsim.protocols.stack.side_by_side
    monkeypatch.setattr(netsim.protocols.stack, "side_by_side", lambda *fns: calls.append(1) or both(*fns))
    (_, halves) = _clustering_after(monkeypatch, 12.0, True, radio=radio)
    assert len(calls) == 12  # a sample a second, from 0 s, before 12 s
    for frame in ("groups_frame", "beliefs_frame", "neighbour_beliefs_frame"):
        a, b = getattr(whole, frame)(), getattr(halves, frame)()
        assert a.equals(b) and len(a) > 300, frame


def test_gateways_mean_counts_robots_in_two_groups_per_sample():
    """``gateways_mean`` (the summary figure) is the mean over the sampled instants of the
    robots with two rows or more in the ``groups`` table, as a groupby counts them; a
    sample without rows (no group yet) counts 0."""
    from netsim.protocols.stack import gateways_mean

    rng = np.random.default_rng(23)
    times = np.arange(10.0)
    for _ in range(30):
        rows = []
        for t in np.sort(rng.choice(times, int(rng.integers(1, 6)), replace=False)).tolist():
            for r in np.sort(rng.choice(20, int(rng.integers(1, 8)), replace=False)).tolist():
                rows += [(t, r)] * int(rng.choice([1, 1, 2, 3]))
        groups = pd.DataFrame(rows, columns=["t_s", "robot"])
        per_robot = groups.groupby(["t_s", "robot"]).size()
        expected = float((per_robot > 1).groupby(level="t_s").sum().reindex(times, fill_value=0).mean())
        assert gateways_mean(groups["t_s"].to_numpy(), groups["robot"].to_numpy(), len(times)) == expected


def test_leader_statistics_are_the_role_changes_levels_and_tenures():
    """The summary's leader figures from the roles table over a 60 s run: robot 0 leads
    from 3 s to the end, robot 1 joins it, loses it, leads from 33 s and yields at 50 s.
    The mean number of leaders weights each level by its time, (57 + 17) / 60; the role
    changes leave out the rule1_start rows (5 changes of 2 robots in a minute); a tenure
    still running at the end counts up to it (mean (57 + 17) / 2), one tenure complete.
    A robot's first row is never read as the end of the previous robot's tenure."""
    from netsim.protocols.stack import leader_statistics

    rows = [
        (0.0, 0, "gamma", -1, "rule1_start"),
        (0.0, 1, "gamma", -1, "rule1_start"),
        (3.0, 0, "alpha", 0, "rule4_no_leader"),
        (4.0, 1, "beta", 0, "rule2_join"),
        (30.0, 1, "gamma", -1, "rule3_leader_lost"),
        (33.0, 1, "alpha", 1, "rule4_no_leader"),
        (50.0, 1, "beta", 0, "rule5_merge_yield"),
    ]
    roles = pd.DataFrame(rows, columns=["t_s", "robot", "role", "leader", "cause"])
    assert leader_statistics(roles, 2, 60.0) == {
        "leaders_time_mean": pytest.approx(74.0 / 60.0, abs=1e-12),
        "role_changes_per_robot_per_min": 2.5,
        "mean_leader_tenure_s": 37.0,
        "leader_tenures_complete": 1,
    }


def test_gateways_mean_of_a_run_counts_the_samples_before_the_groups_formed(tmp_path):
    """The first samples of a run come before any group: each counts 0 gateways."""
    from netsim.run import execute

    result = execute(make_config(world={"n_robots": 30}, duration_s=5.0, output={"position_interval_s": 1.0}))
    groups, beliefs = result.frames["groups"], result.frames["beliefs"]
    instants = np.unique(beliefs["t_s"])
    assert len(instants) == 6 and groups["t_s"].min() > 0  # no group at t = 0
    per = groups.groupby(["t_s", "robot"]).size().gt(1).groupby(level="t_s").sum()
    assert result.summary["gateways_mean"] == pytest.approx(per.reindex(instants, fill_value=0).mean(), abs=1e-12)


def _clustering_after(monkeypatch, seconds: float, compiled: bool, rows: bool = False, radio: bool = False):
    """The clustering on 30 robots within a few ranges of each other, run for ``seconds``:
    groups formed, tables filled; compiled loops or plain Python; ``rows``: sampled by the
    oracles (tests/oracles/protocols.py), not by the production pass; ``radio``: under
    log-distance with 4 dB shadowing (no range index's lists), the truth of the oracle's
    sample from the KD-tree's pairs."""
    from tests.fixtures import clustering
    from tests.oracles.near_pairs import reach_keys

    monkeypatch.setenv("NETSIM_COMPILED", "1" if compiled else "0")
    rng = np.random.default_rng(8)
    core: dict = {"range_m": 25.0}
    if radio:
        # About 32 m without shadowing; the channel has no range index's lists.
        core = {"range_m": None, "propagation": "log_distance", "path_loss_exponent": 4.0, "shadowing_sigma_db": 4.0}
    sim, stack = clustering(rng.uniform(0, 60, (30, 2)), start=False, core=core)
    assert (sim.channel.reach_lists is None) == radio
    if rows:

        def by_rows(now, groups_out, pairs_out, counts_out):
            st = stack.state
            heard = reach_keys(st.positions_at(now), st.range_m, st.side_m if st.torus else None)
            roles = (stack.roles.role, stack.roles.leader)
            (robot, group, primary), b = sample_rows(stack.table.view, now, stack.clustering.symmetric, roles, heard)
            groups_out.add(now, {"robot": robot, "group": group, "primary": primary})
            pairs_out.add(
                now, {"robot": b.robot, "neighbour": b.neighbour, "believed": b.believed, "in_range": b.in_range}
            )
            counts = belief_counts(b.neighbour, b.believed, b.in_range, b.indptr, *roles)
            names = ["believed_neighbours", "true_neighbours", "stale_neighbours", "missing_neighbours"]
            columns = {"robot": np.arange(st.n), "role": roles[0], "leader": roles[1], "leader_in_range": counts[4]}
            counts_out.add(now, columns | dict(zip(names, counts[:4])))

        stack._sample_into = by_rows
    stack.start()
    sim.run(until_s=seconds)
    return sim, stack


def test_sized_acks_plain_and_compiled_are_the_same(monkeypatch):
    """An Ack built in one call with the group size its sender announces (a leader's: 1 +
    its live two-way members; anyone else's 1; make_sized_ack) is the same built by the
    plain-Python loop as by the compiled one, and leaves the same sizes and marks of who is
    sized."""
    (sim_a, a), (sim_b, b) = _clustering_after(monkeypatch, 8.0, True), _clustering_after(monkeypatch, 8.0, False)
    assert a.beacon.table.kernels is not b.beacon.table.kernels
    rng = np.random.default_rng(9)
    now = sim_a.env.now
    sizes = []
    for k in range(300):
        if k == 150:  # the rest as if ranges differed: one-way links do not count
            a.clustering.symmetric = a.beacon.sized_symmetric = b.clustering.symmetric = False
        i = int(rng.integers(30))
        role, leader = rng.choice([UNDECIDED, MEMBER, ALPHA, ALPHA]), rng.integers(-1, 30)
        for stack in (a, b):
            stack.roles.role[i], stack.roles.leader[i] = role, leader
        ack_a, ack_b = a.beacon.make_ack(i), b.beacon.make_ack(i)
        assert ack_a._replace(record=None) == ack_b._replace(record=None)
        assert ack_a.heard.tolist() == ack_b.heard.tolist() and ack_a.record.tobytes() == ack_b.record.tobytes()
        sizes.append(ack_a.group_size)
        now += 0.01
        sim_a.env._now = sim_b.env._now = now
    for name in ("group_size", "seq", "role_sent", "degree_sent"):
        assert np.array_equal(getattr(a.beacon, name), getattr(b.beacon, name)), name
    assert np.array_equal(a.clustering._sized, b.clustering._sized)
    assert max(sizes) > 3 and sizes.count(1) > 50


@pytest.mark.parametrize("torus", [False, True])
@pytest.mark.parametrize("policy", list(JoinPolicy))
@pytest.mark.parametrize("symmetric", [False, True])
def test_join_choice_loop_equals_the_oracle(policy, symmetric, torus, kernels):
    """Rule 2 from a row of the table (the leader joined among the known ones but the one
    excluded, by each join policy, and its slot) is the oracle's choice; ties of distance go
    to the lowest id as there. On a torus (of side 4 m, the grid's) distances are to the
    nearest image."""
    rng = np.random.default_rng(11)
    now, joined = 10.0, 0
    for _ in range(60):
        ids, records = random_tables(rng, 6, 10, now)
        # Positions on a coarse grid: equal distances (ties) happen.
        records[:, :, X] = rng.integers(0, 4, (6, 10)).astype(float)
        records[:, :, Y] = rng.integers(0, 4, (6, 10)).astype(float)
        for i in range(6):
            x, y = float(rng.integers(0, 4)), float(rng.integers(0, 4))
            exclude = int(rng.choice([-1, *ids[i][:3].tolist()]))
            first = int(rng.choice([-1, *ids[i][:4].tolist()]))  # -1: no Ack triggered it
            rules = rules_record(TAU_S, 1.0, symmetric, policy, "lowest_id")
            table = (ids, records, TAU_S)
            # Robot i stands still at (x, y) (the kernel places it from the robots' motion).
            origin = np.zeros((6, 2))
            origin[i] = x, y
            motion = (origin, np.zeros((6, 2)), np.zeros(6), torus, 4.0 if torus else 0.0)
            a = kernels.join_choice(table, i, now, rules, exclude, motion, first)
            b = join_choice(table, i, now, rules, exclude, x, y, first, 4.0 if torus else None)
            assert a == b
            joined += a[0] >= 0
    assert joined > 50


@pytest.mark.parametrize("policy", list(ElectionPolicy))
@pytest.mark.parametrize("symmetric", [False, True])
def test_elected_in_row_loop_equals_the_oracle(policy, symmetric, kernels):
    """Rule 6 from a row of the table (whether a robot takes over among the former members
    of its lost leader it knows, by each election policy; ties of degree to the lowest id)
    is the oracle's verdict."""
    from netsim.protocols.neighbours import DEGREE, MEMBER_OF

    rng = np.random.default_rng(12)
    now, verdicts = 10.0, []
    for _ in range(80):
        ids, records = random_tables(rng, 8, 6, now)
        records[:, :, DEGREE] = rng.integers(0, 4, (8, 6))
        records[:, :, MEMBER_OF] = rng.integers(-1, 3, (8, 6))  # former mates of a few leaders
        for i in range(8):
            old, degree = int(rng.integers(0, 3)), int(rng.integers(0, 4))
            rules = rules_record(TAU_S, 1.0, symmetric, "nearest", policy)
            table = (ids, records, TAU_S)
            a = kernels.elected_in_row(table, i, now, rules, old, degree)
            b = elected_in_row(table, i, now, rules, old, degree)
            assert a == b
            verdicts.append(a)
    assert policy == ElectionPolicy.NONE or 50 < sum(verdicts) < len(verdicts) - 50


@pytest.mark.parametrize("compiled", ["0", "1"])
def test_leaders_announce_their_group_size(monkeypatch, compiled):
    """A leader's Ack carries its group's size (1 + its live two-way members), built by the
    plain-Python loop or the compiled one."""
    monkeypatch.setenv("NETSIM_COMPILED", compiled)
    rng = np.random.default_rng(8)
    sim, stack = clustering(rng.uniform(0, 60, (30, 2)), core={"range_m": 25.0})
    sim.run(until_s=20.0)
    leaders = np.flatnonzero(stack.roles.role == ALPHA)
    sizes = [stack.clustering.group_size(int(i), sim.env.now) for i in leaders]
    assert max(sizes) > 1
    assert stack.beacon.group_size[leaders].tolist() == sizes


def test_side_by_side_returns_both_and_raises_either_error():
    """Two calls side by side (the second in a thread of its own) give both results in
    order; an error in either is raised in the caller's thread, after both have ended."""
    from netsim.compiled import side_by_side

    assert side_by_side(lambda: 1, lambda: "two") == (1, "two")
    ended = []

    def fails():
        raise ValueError("second")

    with pytest.raises(ValueError, match="second"):
        side_by_side(lambda: ended.append("first"), fails)
    with pytest.raises(KeyError):
        side_by_side(lambda: {}["x"], lambda: ended.append("second"))
    assert ended == ["first", "second"]


def test_side_by_side_one_after_the_other_without_a_thread(monkeypatch):
    """Where no thread can be started (a limit on threads), the two calls run one after the
    other, in the caller's thread: the same results, the same errors."""
    import threading

    from netsim.compiled import side_by_side

    def refuse(self):
        raise RuntimeError("can't start new thread")

    monkeypatch.setattr(threading.Thread, "start", refuse)
    me = threading.get_ident()
    assert side_by_side(lambda: threading.get_ident(), lambda: threading.get_ident()) == (me, me)
    with pytest.raises(ValueError):
        side_by_side(lambda: 1, lambda: int("x"))


@pytest.mark.parametrize("until_s", [17.3, 30.0])
def test_gateways_mean_mid_run_is_the_mean_over_the_samples_handed_out(until_s):
    """Asked for mid-run, the summary's ``gateways_mean`` is the mean over every sample of
    the ``groups`` table handed out with it, the one at ``now`` included, and equals the
    figure of a run that ends there. (It divided the gateways of the samples and the one
    at ``now`` by the kept samples alone.)"""
    from netsim.run import build, collect, execute, summarize

    def config(duration_s):
        return make_config(
            seed=3, duration_s=duration_s, world={"n_robots": 15, "side_m": 400.0}, channel={"loss_probability": 0.05}
        )

    sim = build(config(60.0))
    sim.run(until_s=until_s)
    frames = collect(sim)
    groups, beliefs = frames["groups"], frames["beliefs"]
    instants = np.unique(beliefs["t_s"])
    assert instants[-1] == until_s
    per = groups.groupby(["t_s", "robot"]).size().gt(1).groupby(level="t_s").sum()
    expected = per.reindex(instants, fill_value=0).mean()
    assert expected > 0
    assert summarize(sim, frames, 0.0)["gateways_mean"] == pytest.approx(expected, abs=1e-12)
    assert execute(config(until_s)).summary["gateways_mean"] == pytest.approx(expected, abs=1e-12)
