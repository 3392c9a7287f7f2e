"""Compiled (numba) loops of the protocols' hot paths: the neighbour tables and the Ack
(:mod:`netsim.protocols.neighbours`, :mod:`netsim.protocols.ack`), the clustering's per-Ack rules, relaying
and once-a-second samples (:mod:`netsim.protocols.clustering`, :mod:`netsim.protocols.relay`,
:mod:`netsim.protocols.stack`).

Each rule is written once, here, receiver by receiver: for the ten or so receivers of one
Ack, a loop costs less than numpy's array operations, whose cost per operation, not the
arithmetic, is what a call costs. :func:`netsim.compiled.load` gives a run this module as it
is (plain Python, for a few robots) or its compiled copy; the tests check both against
reference oracles (``tests/oracles/protocols.py``).

The loops take a few records, each a :class:`~typing.NamedTuple` defined here and read by
field name (and the robots' :class:`netsim._kernels.Motion`): :class:`Table`,
:class:`RoleArrays`, :class:`Robots`, :class:`Told`, :class:`AckEffects`, :class:`Beacon`,
:class:`Truth` and the sample's columns (:class:`Groups`, :class:`Pairs`, :class:`Counts`).
numba types a named tuple passed from Python by a slower path than a plain one, on every
call: so the callers pass each as a plain tuple of its fields (``tuple(Table(...))``, built
once where it can be), and a loop called from Python names it on entry (``Table(*table)``,
free in compiled code). The clustering's constants are a one-row record
(:data:`netsim.protocols.clustering.RULES`: ``tau_s``, ``merge_delay_s``, ``symmetric``, the
join and election policies' codes).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from netsim._kernels import (
    Motion,
    length_m,
    longest_list,
    lower_bound,
    position,
    reaches_robot,
    restarted,
    senders_in_list,
    sort_range,
)
from netsim.compiled import jit

# Columns of a neighbour table's packed record (netsim.protocols.neighbours). BIDIR_SINCE:
# since when the neighbour has continuously listed us in its Acks (the link is known
# two-way); inf while it does not. ROLE_SINCE: since when the live entry's Acks have
# continuously told the role they tell now. RX_POWER: the power (dBm) at which the receiver
# got the Ack the entry holds, NaN when the channel measures none (no log-distance law): the
# receiver's own measurement, written on receipt, never carried by an Ack (its record holds
# NaN there). MEMBER_OF: the leader the neighbour named in the latest of the Acks of its
# live entry that said member (EMPTY before any): the group it had, once it leads or is
# undecided (rule 6's election); like the other histories, it starts afresh with the
# entry, so a slot kept or reused after an expiry reads the same; the receiver's own
# reading, never carried by an Ack.
LAST_HEARD, LIVE_SINCE, HEARS_ME, BIDIR_SINCE, SEQ, ROLE, LEADER, X, Y, GROUP_SIZE, DEGREE, ROLE_SINCE = range(12)
RX_POWER, MEMBER_OF = 12, 13
EMPTY = -1  # the id of an empty slot
# An empty slot's record (never live), a constant of the compiled code (not an argument per Ack).
EMPTY_RECORD = np.array([-np.inf, np.inf, 0, np.inf, 0, 0, EMPTY, 0, 0, 0, 0, np.inf, np.nan, EMPTY], dtype=float)
FIELDS = len(EMPTY_RECORD)  # an Ack's record: these fields, then the ids it heard
# Columns of the Ack beacon's per-robot (n, 3) array of what each robot sent last
# (netsim.protocols.ack.AckBeacon.sent): its sequence number, role and two-way degree.
SEQ_SENT, ROLE_SENT, DEGREE_SENT = 0, 1, 2
# Roles (netsim.protocols.roles).
UNDECIDED, MEMBER, LEADER_ROLE = 0, 1, 2


class Table(NamedTuple):
    """A neighbour table (:attr:`netsim.protocols.neighbours.NeighbourTable.view`)."""

    ids: np.ndarray  # (n, slots): the neighbour in each slot, EMPTY for none
    records: np.ndarray  # (n, slots, FIELDS): the packed records
    tau_s: float  # the liveness timeout


class RoleArrays(NamedTuple):
    """Every robot's role and leader (:class:`netsim.protocols.roles.Roles`)."""

    role: np.ndarray
    leader: np.ndarray


class Robots(NamedTuple):
    """The per-robot state the clustering's rules read and write on an Ack."""

    role: np.ndarray  # Roles.role
    leader: np.ndarray  # Roles.leader
    role_sent: np.ndarray  # the role each announced in its last Ack (AckBeacon.role_sent)
    leader_since: np.ndarray  # when each last became a leader (inf: it is not one)
    deadline_s: np.ndarray  # the timers' deadlines (rules 3 and 4; DeadlineTimers)
    armed_s: np.ndarray  # when each timer's event is armed


class Told(NamedTuple):
    """An Ack told to the clustering."""

    sender: int
    receivers: np.ndarray
    record: np.ndarray  # the Ack's packed record
    leads: bool  # a leader's Ack, not resigning


class AckEffects(NamedTuple):
    """What an Ack does to the clustering (docs/model.md 4.2), as lists filled per Ack by
    :func:`ack_effects` (and :func:`receive_effects`), each as long as the robots and reused
    from Ack to Ack: the counts returned say how much of each is the Ack's."""

    group: np.ndarray  # rules 3, 5, 6: where (in the receivers) the sender's group's members are
    to_arm: np.ndarray  # rule 3: members whose renewed timer needs its event armed
    may_join: np.ndarray  # rule 2: undecided robots over a two-way link (a leader's Ack)
    may_merge: np.ndarray  # rule 5: leaders over a two-way link ready to merge with the sender
    merge_slot: np.ndarray  # rule 5: the sender's slot in each of their rows of the table
    takers: np.ndarray  # the receivers that took the Ack (not overtaken)
    fresh: np.ndarray  # per receiver: whether it took the Ack
    hears_me: np.ndarray  # per receiver: whether the Ack lists it
    takers_hear_me: np.ndarray  # per taker: whether the Ack lists it

    @classmethod
    def empty(cls, n: int) -> AckEffects:
        """Room for an Ack to all of ``n`` robots."""
        rows, flags = np.empty((6, n), dtype=np.int64), np.empty((3, n), dtype=bool)
        return cls(*rows, *flags)


class Beacon(NamedTuple):
    """The Ack beacon's per-robot state (:class:`netsim.protocols.ack.AckBeacon`)."""

    sent: np.ndarray  # (n, 3): the sequence number, role and degree each sent last
    resign_pending: np.ndarray  # whose next Ack resigns
    group_size: np.ndarray  # the group size each announces


class Truth(NamedTuple):
    """Who reaches whom now, from neighbour lists (ascending, holding every robot within
    reach: :func:`netsim.topology.reach_lists`), decided as
    :func:`netsim._kernels.reach_keys_in_lists` decides it."""

    pos: np.ndarray  # positions
    ranges: np.ndarray  # ranges
    box: float  # the torus' side, or 0
    near_ptr: np.ndarray
    near: np.ndarray


class Groups(NamedTuple):
    """Group membership, a row per robot and group (the ``groups`` table's columns)."""

    robot: np.ndarray
    group: np.ndarray
    primary: np.ndarray


class Pairs(NamedTuple):
    """Who believes whom beside the truth (the ``neighbour_beliefs`` table's columns)."""

    robot: np.ndarray
    neighbour: np.ndarray
    believed: np.ndarray
    in_range: np.ndarray


class Counts(NamedTuple):
    """Per robot, its beliefs beside the truth (the ``beliefs`` table's columns)."""

    robot: np.ndarray
    role: np.ndarray
    leader: np.ndarray
    leader_in_range: np.ndarray
    believed_neighbours: np.ndarray
    true_neighbours: np.ndarray
    stale_neighbours: np.ndarray
    missing_neighbours: np.ndarray


@jit(nogil=True)
def receive(table, now, sender, receivers, record, power_dbm, fresh, hears_me, start):
    """Record an Ack of ``sender`` (its packed ``record``: the fields, then the sorted ids it
    heard) in the rows of ``receivers[start:]`` of the ``table``
    (:meth:`netsim.protocols.neighbours.NeighbourTable.receive`), with the power each
    receiver got it at (``power_dbm``, per receiver; None: none measured, NaN kept).

    Fills, per receiver, ``fresh``: whether the Ack was taken (not older than the entry's),
    and ``hears_me``: whether the receiver is among ``heard``. Returns ``(-1, stale)`` when done,
    ``stale`` the number of receivers from ``start`` on that did not take the Ack, or
    ``(k, stale)`` where ``receivers[k]``'s row has no free slot (the table must grow first;
    the receivers before it are done, ``stale`` counting those of them from ``start``).
    """
    return _receive(Table(*table), now, sender, receivers, record, power_dbm, fresh, hears_me, start)


@jit(nogil=True)
def take(table, now, sender, receivers, record, power_dbm, start):
    """:func:`receive` without the flags (:meth:`netsim.protocols.neighbours.NeighbourTable.take`):
    two arrays fewer to pass per Ack."""
    return _receive(Table(*table), now, sender, receivers, record, power_dbm, None, None, start)


@jit(nogil=True)
def _receive(table, now, sender, receivers, record, power_dbm, fresh, hears_me, start):
    # fresh and hears_me are both arrays or both None (take): the compiler drops the
    # branches on them in each version, as on power_dbm (None: the record's NaN stays).
    ids, records, tau_s = table.ids, table.records, table.tau_s
    slots = ids.shape[1]
    heard = record[FIELDS:]
    n_heard = len(heard)
    stale = 0
    for k in range(start, len(receivers)):
        r = receivers[k]
        at = lower_bound(heard, 0, n_heard, r)
        hm = at < n_heard and heard[at] == r
        if hears_me is not None:
            hears_me[k] = hm
        slot = -1
        for s in range(slots):
            if ids[r, s] == sender:
                slot = s
                break
        found = slot >= 0
        if not found:
            # A slot that no Ack can continue any more (an Ack at the instant of expiry may).
            for s in range(slots):
                if ids[r, s] == EMPTY or not continues(records[r, s, LAST_HEARD], now, tau_s):
                    slot = s
                    break
            if slot < 0:
                return k, stale
            ids[r, slot] = sender
        old = records[r, slot]
        if found and not old[SEQ] <= record[SEQ]:
            if fresh is not None:
                fresh[k] = False
            stale += 1
            continue
        if fresh is not None:
            fresh[k] = True
        was_live = found and continues(old[LAST_HEARD], now, tau_s)
        live_since = old[LIVE_SINCE] if was_live else now
        if hm:
            bidir_since = old[BIDIR_SINCE] if was_live and old[HEARS_ME] != 0 else now
        else:
            bidir_since = np.inf
        role_since = old[ROLE_SINCE] if was_live and old[ROLE] == record[ROLE] else now
        member_of = record[LEADER] if record[ROLE] == MEMBER else (old[MEMBER_OF] if was_live else EMPTY)
        for c in range(FIELDS):
            old[c] = record[c]
        old[MEMBER_OF] = member_of
        old[LAST_HEARD] = now
        old[LIVE_SINCE] = live_since
        old[HEARS_ME] = 1.0 if hm else 0.0
        old[BIDIR_SINCE] = bidir_since
        old[ROLE_SINCE] = role_since
        if power_dbm is not None:
            old[RX_POWER] = power_dbm[k]
    return -1, stale


@jit(nogil=True)
def announce(table, i, now, seq, role, leader, x_m, y_m, group_size):
    """What robot ``i``'s Ack carries, from its row of the ``table``: the Ack's packed record
    (these fields, the others the empty record's, with the two-way degree: live entries
    that hear the robot), then the ids of the live entries, ascending. One array: the Ack
    costs one array, not two."""
    return _announce(Table(*table), i, now, seq, role, leader, x_m, y_m, group_size, None, True)


@jit(nogil=True)
def _announce(table, i, now, seq, role, leader, x_m, y_m, group_size, mates_of, symmetric):
    # mates_of: None, or the robot sending the Ack (the clustering's), whose members are
    # counted in the same pass over the live entries: a leader announces 1 + those over a
    # two-way link that named it their leader (group_size), read where the row's lines are
    # already in cache. The compiler drops the counting where it is None.
    ids_row, records_row, tau_s = table.ids[i], table.records[i], table.tau_s
    record = np.empty(FIELDS + len(ids_row))
    for f in range(FIELDS):  # not a copy into a slice (docs/architecture.md, the compiled cache)
        record[f] = EMPTY_RECORD[f]
    k = 0
    degree = 0
    size = 1
    for s in range(len(ids_row)):
        # An EMPTY slot holds the empty record, never live: its record is not read (a row's
        # ids are a few cache lines, its records many).
        if ids_row[s] != EMPTY and is_live(records_row[s, LAST_HEARD], now, tau_s):
            record[FIELDS + k] = ids_row[s]
            k += 1
            hears_me = records_row[s, HEARS_ME] != 0
            if hears_me:
                degree += 1
            if mates_of is not None:
                if (symmetric or hears_me) and records_row[s, ROLE] == MEMBER and records_row[s, LEADER] == mates_of:
                    size += 1
    sort_range(record, int(FIELDS), FIELDS + k)  # int(): no literal argument (netsim._kernels.sort_range)
    record[SEQ], record[ROLE], record[LEADER], record[X], record[Y] = seq, role, leader, x_m, y_m
    record[GROUP_SIZE] = size if mates_of is not None and role == LEADER_ROLE else group_size
    record[DEGREE] = degree
    return record[: FIELDS + k]


@jit(nogil=True)
def make_ack(i, now, motion, beacon, roles, table):
    """Robot ``i``'s Ack at ``now``, once its hooks have run, as
    :meth:`netsim.protocols.ack.AckBeacon.make_ack` builds it: its position (``motion``), its next
    sequence number, the resignation it owes, its role, leader and group size (``beacon``,
    ``roles``), and what its row of the ``table`` announces (:func:`announce`). Counts the
    sequence number, clears the resignation and records the role and degree sent (the
    beacon's ``sent``, an (n, 3) array). Returns the Ack's fields in
    the order of :class:`netsim.protocols.ack.Ack`: ``(i, role, leader, seq, x, y, group_size,
    resign, record)``."""
    return _make_ack(i, now, Motion(*motion), Beacon(*beacon), RoleArrays(*roles), Table(*table), None, True)


@jit(nogil=True)
def _make_ack(i, now, motion, beacon, roles, table, mates_of, symmetric):
    # mates_of: as in _announce; the size announced is also written in group_size.
    sent, resign_pending, group_size = beacon.sent, beacon.resign_pending, beacon.group_size
    x, y = position(motion.origin_m, motion.velocity_mps, motion.t0_s, i, now, motion.torus, motion.side_m)
    s = sent[i, SEQ_SENT] + 1
    sent[i, SEQ_SENT] = s
    resign = resign_pending[i]
    if resign:
        resign_pending[i] = False
    ro, le, size = np.int64(roles.role[i]), roles.leader[i], group_size[i]
    record = _announce(table, i, now, s, ro, le, x, y, size, mates_of, symmetric)
    if mates_of is not None:
        size = np.int64(record[GROUP_SIZE])
        group_size[i] = size
    sent[i, ROLE_SENT] = ro
    sent[i, DEGREE_SENT] = np.int64(record[DEGREE])
    # Python's scalars, as the compiled copy returns them, in plain Python too.
    return i, int(ro), int(le), int(s), float(x), float(y), int(size), bool(resign), record


@jit(nogil=True)
def make_sized_ack(i, now, motion, beacon, roles, table, sized, symmetric):
    """:func:`make_ack` with the group size the Ack announces: a leader's is 1 + its live
    two-way members in its row (:func:`group_size`, counted in the pass that makes the
    Ack), anyone else's 1 (the beacon's ``group_size``, written back; ``sized``: whose is
    other than 1). One call per Ack."""
    # The members counted for every Ack, used for a leader's: one call for both cases (a
    # call for each would cost every Ack a second compiled call).
    beacon, roles = Beacon(*beacon), RoleArrays(*roles)
    sizes = beacon.group_size
    if roles.role[i] == LEADER_ROLE:
        sized[i] = True
    elif sized[i]:
        sizes[i] = 1
        sized[i] = False
    return _make_ack(i, now, Motion(*motion), beacon, roles, Table(*table), i, symmetric)


# Rule 2's join policies (netsim.protocols.clustering.JOIN_CODES).
JOIN_NEAREST, JOIN_FIRST_HEARD, JOIN_LOWEST_ID = 0, 1, 2


@jit(nogil=True)
def join_choice(table, i, now, rules, exclude, motion, first_heard):
    """Rule 2 from robot ``i``'s row of the ``table``
    (:meth:`netsim.protocols.clustering.Clustering._rule2_join`): the leader that ``i``, where
    ``motion`` places it at ``now``, joins among its live two-way neighbours whose last Ack said they were
    leaders, but ``exclude``, by the join policy of the ``rules`` (its code,
    :data:`netsim.protocols.clustering.JOIN_CODES`; ``first_heard``: the leader
    whose Ack triggered the join, or negative), and the first slot of that leader in the
    row; ``(-1, -1)`` when it knows no leader."""
    table, m = Table(*table), Motion(*motion)
    ids_row, records_row, tau_s = table.ids[i], table.records[i], table.tau_s
    c = rules[0]
    symmetric, policy = c.symmetric, c.join_policy
    x_m, y_m = position(m.origin_m, m.velocity_mps, m.t0_s, i, now, m.torus, m.side_m)
    best, best_d = -1, np.inf
    for s in range(len(ids_row)):
        rec = records_row[s]
        if not (_two_way(rec, now, tau_s, symmetric) and rec[ROLE] == LEADER_ROLE and ids_row[s] != exclude):
            continue
        j = ids_row[s]
        if policy == JOIN_LOWEST_ID:
            if best < 0 or j < best:
                best = j
            continue
        if policy == JOIN_FIRST_HEARD and j == first_heard:
            best = j
            break
        # On a torus the leader's nearest image: a leader across the seam is as near as the
        # link to it is short.
        d = length_m(rec[X] - x_m, rec[Y] - y_m, m.side_m if m.torus else 0.0)
        if best < 0 or d < best_d or (d == best_d and j < best):
            best, best_d = j, d
    if best < 0:
        return -1, -1
    for s in range(len(ids_row)):
        rec = records_row[s]
        if ids_row[s] == best and _two_way(rec, now, tau_s, symmetric) and rec[ROLE] == LEADER_ROLE:
            return best, s
    return -1, -1  # not reached: best is one of those slots


# Rule 6's election policies (netsim.protocols.clustering.ELECTION_CODES).
ELECT_LOWEST_ID, ELECT_HIGHEST_DEGREE, ELECT_NONE = 0, 1, 2


@jit(nogil=True)
def elected_in_row(table, i, now, rules, old, degree):
    """Rule 6 from robot ``i``'s row of the ``table``
    (:meth:`netsim.protocols.clustering.Clustering._rule6_reaffiliate`): whether ``i``, of
    announced ``degree``, takes over from its lost leader ``old`` among the live two-way
    neighbours that had ``old`` as their leader (the last of their Acks that said member
    named ``old``: members of ``old``, and former members that lead or are undecided since),
    by the election policy of the ``rules`` (its code,
    :data:`netsim.protocols.clustering.ELECTION_CODES`)."""
    table = Table(*table)
    ids_row, records_row, tau_s = table.ids[i], table.records[i], table.tau_s
    c = rules[0]
    symmetric, policy = c.symmetric, c.election_policy
    if policy == ELECT_NONE:
        return False
    for s in range(len(ids_row)):
        rec = records_row[s]
        if not (_two_way(rec, now, tau_s, symmetric) and rec[MEMBER_OF] == old):
            continue
        j = ids_row[s]
        if policy == ELECT_LOWEST_ID:
            if not i < j:
                return False
        else:
            d = int(rec[DEGREE])
            if not (degree > d or (degree == d and i < j)):
                return False
    return True


# The clustering's loops (netsim.protocols.clustering, relay and stack): per Ack, per flooded
# message and per sample.


@jit(nogil=True)
def ack_effects(now, told, hears_me, robots, table, rules, effects):
    """What an Ack ``told`` (:class:`Told`) does, from the roles before it acts (the
    ``robots``, :class:`Robots`), in the lists of ``effects`` (:class:`AckEffects`;
    returned: how many of ``group``, ``to_arm``, ``may_join`` and ``may_merge``):

    - ``group``: positions (in the receivers) of the members of the sender's group;
    - if the Ack leads (a leader's, not resigning), those members' timers over a two-way
      link restart ``tau_s`` from ``now`` (rule 3: written in the robots' ``deadline_s``;
      ``to_arm``: those of them whose timer's event must be armed, the deadline before
      the event in ``armed_s``);
    - ``may_join``: the undecided robots over a two-way link (rule 2);
    - ``may_merge``: the leaders over a two-way link that may merge with the sender now
      (rule 5; ``merge_slot``: the sender's slot in their rows of the ``table``): those that
      announced themselves as leaders (``role_sent``) and have been leaders beside the
      sender for ``merge_delay_s`` at ``now``, counted from the latest of the link known
      (two-way, or live when links are symmetric), the sender's Acks saying leader, and
      their own leadership (``leader_since``).

    ``hears_me``: per receiver, whether the Ack lists it; ``rules``:
    :data:`netsim.protocols.clustering.RULES`. Counts and reused lists, not new arrays:
    cheaper to hand back, once per Ack."""
    told, robots, table, effects = Told(*told), Robots(*robots), Table(*table), AckEffects(*effects)
    sender, receivers, leads = told.sender, told.receivers, told.leads
    role, leader, deadline_s, armed_s = robots.role, robots.leader, robots.deadline_s, robots.armed_s
    ids, records = table.ids, table.records
    group, to_arm, may_join, may_merge = effects.group, effects.to_arm, effects.may_join, effects.may_merge
    c = rules[0]
    symmetric, merge_delay_s = c.symmetric, c.merge_delay_s
    renewed_s = deadline_after(now, c.tau_s)
    n_group = n_arm = n_join = n_merge = 0
    for k in range(len(receivers)):
        r = receivers[k]
        ro = role[r]
        two_way = symmetric or hears_me[k]
        if ro == MEMBER and leader[r] == sender:
            # Rules 3, 5 and 6: a member of the sender's group.
            group[n_group] = k
            n_group += 1
            if leads and two_way and restarted(deadline_s, armed_s, r, renewed_s):
                to_arm[n_arm] = r
                n_arm += 1
        elif leads and two_way and ro == UNDECIDED:
            may_join[n_join] = r  # rule 2
            n_join += 1
        elif leads and two_way and ro == LEADER_ROLE and robots.role_sent[r] == LEADER_ROLE:
            # Rule 5: leaders that have announced themselves as such, beside the sender
            # for the merge delay.
            slot = -1
            for s in range(ids.shape[1]):
                if ids[r, s] == sender:
                    slot = s
                    break
            if slot < 0:
                continue
            rec = records[r, slot]
            linked = rec[LIVE_SINCE] if symmetric else rec[BIDIR_SINCE]
            since = max(max(linked, rec[ROLE_SINCE]), robots.leader_since[r])
            if not now - since < merge_delay_s:
                may_merge[n_merge] = r
                effects.merge_slot[n_merge] = slot
                n_merge += 1
    return n_group, n_arm, n_join, n_merge


@jit(nogil=True)
def receive_effects(table, now, told, power_dbm, robots, rules, effects, start):
    """:func:`receive` then :func:`ack_effects` in one call: an Ack ``told`` to the clustering
    (:meth:`netsim.protocols.clustering.Clustering.take_told`), recorded in the ``table`` with
    the power each receiver got it at (``power_dbm``, as :func:`receive` takes it; the
    ``effects``' ``fresh`` and ``hears_me`` per receiver, as :func:`receive` fills its
    flags) and then acted on by the receivers that took it (the ``effects``' ``takers``,
    with their ``takers_hear_me``). Returns ``(k, stale, kept, group, to_arm, may_join,
    may_merge)``: ``k`` and ``stale`` as :func:`receive` returns them (``k >= 0``: the table
    must grow, then the call be made again from ``k``; nothing acted on yet), ``kept`` the
    receivers that took the Ack, and :func:`ack_effects`' counts."""
    table, told, effects = Table(*table), Told(*told), AckEffects(*effects)
    receivers, fresh, hears_me = told.receivers, effects.fresh, effects.hears_me
    k, stale = _receive(table, now, told.sender, receivers, told.record, power_dbm, fresh, hears_me, start)
    if k >= 0:
        return k, stale, 0, 0, 0, 0, 0
    takers, takers_hear_me = effects.takers, effects.takers_hear_me
    kept = 0
    for j in range(len(receivers)):
        if fresh[j]:
            takers[kept] = receivers[j]
            takers_hear_me[kept] = hears_me[j]
            kept += 1
    taken = Told(told.sender, takers[:kept], told.record, told.leads)
    n_group, n_arm, n_join, n_merge = ack_effects(now, taken, takers_hear_me[:kept], robots, table, rules, effects)
    return k, stale, kept, n_group, n_arm, n_join, n_merge


@jit(nogil=True)
def group_size(records_row, now, tau_s, symmetric, i):
    """1 + the live two-way entries of robot ``i``'s row whose Ack named ``i`` as their
    leader (:meth:`netsim.protocols.clustering.Clustering.group_size`)."""
    size = 1
    for s in range(len(records_row)):
        rec = records_row[s]
        if _two_way(rec, now, tau_s, symmetric) and rec[ROLE] == MEMBER and rec[LEADER] == i:
            size += 1
    return size


# A run's instants are floats: periods and a latency that add up to exactly ``tau`` in the
# model can add up to a few units in the last place more (each sum rounds on its own),
# which would make an Ack due at its deadline miss it by rounding alone. Instants this
# close count as one: within a nanosecond (ns-3's time resolution), or, past 10^6 s, where
# a nanosecond is below the times' own rounding, within a few units in the last place.
TIE_S = 1e-9
TIE_RELATIVE = 2.0**-50
# Where the relative slack overtakes the nanosecond.
TIE_RELATIVE_FROM_S = TIE_S / TIE_RELATIVE


@jit(nogil=True)
def deadline_after(from_s, tau_s):
    """When a timer of rules 3 and 4 runs out: ``tau_s`` after the instant it runs from (the
    leader's Ack a member last heard, a robot's first Ack, the event that restarted it),
    and the instants that round into it (:data:`TIE_S`), so that an Ack at the deadline
    counts however it rounds."""
    due = from_s + tau_s
    if due < TIE_RELATIVE_FROM_S:  # an empty entry's -inf too, which stays -inf
        return due + TIE_S
    return due + due * TIE_RELATIVE


@jit(nogil=True)
def is_live(last_heard_s, now, tau_s):
    """An entry is live while the last Ack that told it arrived less than ``tau_s`` ago: the
    timeout rule, read by every use of the table. Read against the deadline a timer of the
    same entry runs out at (:func:`deadline_after`, the same rounding), not as ``now -
    last_heard_s < tau_s``: in floating point ``(a + tau) - a`` may fall short of ``tau``,
    and an entry would be live at its own timer's instant, where the timer has ended it (a
    member could join a leader whose timer is already due, and time out again at once)."""
    return now < deadline_after(last_heard_s, tau_s)


@jit(nogil=True, inline="always")
def continues(last_heard_s, now, tau_s):
    """Whether an Ack arriving ``now`` continues an entry last told at ``last_heard_s``: up to
    ``tau_s`` after it, the instant of expiry included (an Ack at exactly ``tau`` keeps the
    entry's history, docs/model.md section 4), where :func:`is_live` has already ended; the
    same deadline as :func:`is_live`'s."""
    return now <= deadline_after(last_heard_s, tau_s)


@jit(nogil=True)
def live_entries(last_heard_s, now, tau_s):
    """:func:`is_live` of every entry of ``last_heard_s`` (one dimension: flatten a table)."""
    out = np.empty(last_heard_s.shape[0], np.bool_)
    for k in range(last_heard_s.shape[0]):
        out[k] = is_live(last_heard_s[k], now, tau_s)
    return out


@jit(nogil=True)
def _two_way(rec, now, tau_s, symmetric):
    """Whether an entry (its record) is a live neighbour over a two-way link."""
    return is_live(rec[LAST_HEARD], now, tau_s) and (symmetric or rec[HEARS_ME] != 0)


@jit(nogil=True)
def membership(table, now, symmetric, roles):
    """Group membership of every robot, as arrays ``(robot, group, primary)`` ordered by
    robot and group (:meth:`netsim.protocols.clustering.Clustering.membership`): a leader in
    its own group, a member with a live two-way link to its leader in its leader's
    (primary) and in those of the other leaders it knows over a live two-way link, a member
    whose link to its leader is one-way in none."""
    table, roles = Table(*table), RoleArrays(*roles)
    n, slots = table.ids.shape
    groups = _group_arrays(n, slots)
    m = 0
    for r in range(n):
        m = _membership_row(table, r, now, symmetric, roles, groups, m)
    return groups.robot[:m], groups.group[:m], groups.primary[:m]


@jit(nogil=True)
def _group_arrays(n, slots):
    """The :class:`Groups` :func:`_membership_row` fills, for at most every slot and the
    robot's own group."""
    size = n * (slots + 1)
    return Groups(np.empty(size, dtype=np.int64), np.empty(size, dtype=np.int64), np.empty(size, dtype=np.bool_))


@jit(nogil=True, inline="always")
def _linked_to_leader(ids_row, records_row, own, now, tau_s, symmetric):
    """Whether a member's row holds a live two-way link to its leader ``own``: what puts it
    in its leader's group (MODEL 4.1), and so what a gateway and a relaying member need."""
    for s in range(len(ids_row)):
        if ids_row[s] == own and _two_way(records_row[s], now, tau_s, symmetric):
            return True
    return False


@jit(nogil=True, inline="always")
def _membership_row(table, r, now, symmetric, roles, groups, m):
    """Robot ``r``'s rows of :func:`membership`, written in ``groups`` (:class:`Groups`)
    from ``m`` on; returns the next free row. A slot's record is read only when
    its id is not EMPTY (an EMPTY slot's record is EMPTY_RECORD, never live): the records
    are tens of MB at 10,000 robots, a scan costs the memory it reads."""
    ids_row, records_row, tau_s = table.ids[r], table.records[r], table.tau_s
    role, own = roles.role[r], roles.leader[r]
    robot, group, primary = groups.robot, groups.group, groups.primary
    if role == LEADER_ROLE:
        robot[m], group[m], primary[m] = r, r, True
        return m + 1
    if role != MEMBER:
        return m
    # The robot's groups, ascending, inserted in place (a gateway has two or three). A
    # group holds the members its leader has a two-way link with: a member whose link to
    # its own leader is one-way now (unequal ranges) is in no group, and no gateway.
    if not _linked_to_leader(ids_row, records_row, own, now, tau_s, symmetric):
        return m
    m0 = m
    group[m] = own
    m += 1
    for s in range(len(ids_row)):
        j = ids_row[s]
        if j != EMPTY and j != own and records_row[s, ROLE] == LEADER_ROLE:
            if _two_way(records_row[s], now, tau_s, symmetric):
                at = m
                while at > m0 and group[at - 1] > j:
                    group[at] = group[at - 1]
                    at -= 1
                group[at] = j
                m += 1
    for q in range(m0, m):
        robot[q], primary[q] = r, group[q] == own
    return m


@jit(nogil=True)
def relays(table, now, symmetric, roles, receivers, distributed_gateways):
    """The ``receivers`` of a flooded message that relay it (:mod:`netsim.protocols.relay`):
    leaders, and gateways, the members with a live two-way link to their own leader and a
    live two-way neighbour in another group (a leader other than their own or, with
    ``distributed_gateways``, a member of another leader)."""
    table, roles = Table(*table), RoleArrays(*roles)
    ids, records, tau_s = table.ids, table.records, table.tau_s
    role, leader = roles.role, roles.leader
    out = np.empty(len(receivers), dtype=np.int64)
    m = 0
    for r in receivers:
        ro = role[r]
        relay = ro == LEADER_ROLE
        if ro == MEMBER and _linked_to_leader(ids[r], records[r], leader[r], now, tau_s, symmetric):
            own = leader[r]
            row = records[r]
            for s in range(len(row)):
                if ids[r, s] == EMPTY:
                    continue  # the empty record, never live: not read
                rec = row[s]
                if not _two_way(rec, now, tau_s, symmetric):
                    continue
                if distributed_gateways:
                    other = rec[ROLE] != UNDECIDED and rec[LEADER] != own
                else:
                    other = rec[ROLE] == LEADER_ROLE and ids[r, s] != own
                if other:
                    relay = True
                    break
        if relay:
            out[m] = r
            m += 1
    return out[:m]


@jit(nogil=True)
def flood_step(seen, receivers, table, now, symmetric, roles, distributed_gateways):
    """A flooded message's copy reaching ``receivers`` (:meth:`netsim.protocols.relay.Relay._on_flood`):
    those that had not ``seen`` it (a flag per robot, set for them now), and which of them
    relay it (:func:`relays`)."""
    fresh = np.empty(len(receivers), dtype=np.int64)
    m = 0
    for r in receivers:
        if not seen[r]:
            seen[r] = True
            fresh[m] = r
            m += 1
    fresh = fresh[:m]
    return fresh, relays(table, now, symmetric, roles, fresh, distributed_gateways)


# The once-a-second samples of beliefs beside the truth (netsim.protocols.stack): one pass over the
# neighbour tables, rows as they are laid out, each slot's record read only when its id is
# not EMPTY (an EMPTY slot's record is EMPTY_RECORD, never live): the (n, slots, fields)
# records are tens of MB at 10,000 robots, so a scan's cost is the memory it reads.


@jit(nogil=True, inline="always")
def _live_row(ids_row, records_row, now, tau_s, live):
    """The ids of the live entries of a robot's row, ascending, in ``live``; how many. A
    slot's record is read only when its id is not EMPTY (never live)."""
    m = int(0)  # not a literal (netsim._kernels.sort_range)
    for s in range(len(ids_row)):
        j = ids_row[s]
        if j != EMPTY and is_live(records_row[s, LAST_HEARD], now, tau_s):
            live[m] = j
            m += 1
    sort_range(live, int(0), m)
    return m


# Above every robot id: where one of two merged lists has ended.
_PAST_IDS = np.iinfo(np.int64).max


@jit(nogil=True, inline="always")
def _pair_rows(live, m, heard, h, r, out, k):
    """Robot ``r``'s pairs: the union of the ids it believes live (``live[:m]``) and of those
    whose transmissions reach it (``heard[:h]``), both ascending, written in ``out``
    (:class:`Pairs`) from row ``k`` on with the flags; returns the next row and how many of
    the pairs are believed, in range, and believed but not in range (stale)."""
    robot, neighbour, believed, in_range = out.robot, out.neighbour, out.believed, out.in_range
    q = u = b_n = t_n = s_n = 0
    while q < m or u < h:
        b = live[q] if q < m else _PAST_IDS
        c = heard[u] if u < h else _PAST_IDS
        robot[k] = r
        neighbour[k] = min(b, c)
        believed[k] = b <= c
        in_range[k] = c <= b
        b_n += b <= c
        t_n += c <= b
        s_n += b < c
        q += b <= c
        u += c <= b
        k += 1
    return k, b_n, t_n, s_n


@jit(nogil=True)
def sample_into(table, now, symmetric, roles, truth, groups, pairs, counts, lo, hi):
    """A sample of robots ``lo`` to ``hi - 1`` (all: a whole sample) in one pass over their
    rows of the tables, written where the caller says (the sampled tables' buffers, from
    their next free row): their groups (:func:`membership`) in ``groups``
    (:class:`Groups`), room for ``(hi - lo) * (slots + 1)`` rows; who believes whom beside
    the truth in ``pairs`` (:class:`Pairs`: per robot, by neighbour, the union of the ids
    it believes live and of those whose transmissions reach it, flagged), room for ``(hi -
    lo) * slots`` rows plus the length of their neighbour lists; and per robot its row of
    ``counts`` (:class:`Counts`: how many it believes, how many truly reach it, how many
    beliefs are stale and how many missing, and whether its leader is in two-way range).
    Returns the rows written in ``groups`` and in ``pairs``.

    The ``truth`` (:class:`Truth`) is neighbour lists holding every robot within reach
    (:func:`netsim.topology.reach_lists`). Nothing is allocated but two rows of scratch:
    each row is written once, where the table keeps it. Two calls, on two parts of the
    robots, can run in two threads at once (the loop holds no lock)."""
    table, roles, truth = Table(*table), RoleArrays(*roles), Truth(*truth)
    groups, pairs, counts = Groups(*groups), Pairs(*pairs), Counts(*counts)
    ids, records, tau_s = table.ids, table.records, table.tau_s
    role, leader = roles.role, roles.leader
    pos, ranges, box, near_ptr, near = truth.pos, truth.ranges, truth.box, truth.near_ptr, truth.near
    live = np.empty(ids.shape[1], np.int64)
    heard = np.empty(longest_list(near_ptr), np.int64)
    m = k = 0
    for r in range(lo, hi):
        m = _membership_row(table, r, now, symmetric, roles, groups, m)
        lv = _live_row(ids[r], records[r], now, tau_s, live)
        h = senders_in_list(pos, ranges, box, near_ptr, near, r, heard)
        k, b, t, s = _pair_rows(live, lv, heard, h, r, pairs, k)
        own = leader[r]
        counts.robot[r], counts.role[r], counts.leader[r] = r, role[r], own
        counts.believed_neighbours[r], counts.true_neighbours[r] = b, t
        counts.stale_neighbours[r], counts.missing_neighbours[r] = s, t - (b - s)
        in_range = role[r] == LEADER_ROLE
        if role[r] == MEMBER and own >= 0:
            # Two-way: the leader among the robots that reach r, r reaching the leader.
            at = lower_bound(heard, int(0), h, own)
            if at < h and heard[at] == own:
                first, end = near_ptr[own], near_ptr[own + 1]
                at = lower_bound(near, first, end, r)
                in_range = at < end and near[at] == r and reaches_robot(pos, ranges, box, own, r)
        counts.leader_in_range[r] = in_range
    return m, k
