"""The clustering protocol of Cai, Ren and Zou (2009), docs/model.md section 4.2.

Roles: leader ``alpha``, member ``beta``, undecided ``gamma``. From their Acks alone the
robots build a two-level network:

1. Every robot starts ``gamma`` and beacons (its clock starts at its first Ack).
2. A ``gamma`` robot that hears an ``alpha`` over a two-way link joins a leader and
   becomes ``beta`` (join policy: nearest known leader, ties to the lowest id).
3. A ``beta`` robot that hears no Ack from its leader for ``tau`` becomes ``gamma``.
4. A ``gamma`` robot that hears no ``alpha`` for ``tau`` becomes ``alpha``.
5. Two ``alpha`` robots merge once each has been ``alpha`` over their two-way link for
   ``merge_delay`` (counted from the latest of: the link known two-way, the other's Acks
   saying ``alpha``, and its own leadership): by the merge policy one yields and joins the
   other; its next Ack carries a resign flag and its members re-affiliate at once. The
   policy compares what both leaders announced in their Acks (group size, two-way
   degree), so both reach the same verdict from the same information once it has
   travelled; if stale information still makes each yield to the other, the lower id
   takes the lead back on hearing it and the other stays its member.
6. A robot whose leader timed out (or resigned) joins another known leader if it can;
   otherwise, if it has the highest priority among the live neighbours that had the same
   leader (lowest id by default; vacuously when there are none), it becomes ``alpha`` at
   once; otherwise it stays ``gamma`` (and rule 2 or 4 follows).

The decisions are pure functions of small values (:func:`choose_leader`,
:func:`merge_loser`, :func:`elected`, :data:`TRANSITIONS`), testable without the kernel;
:class:`Clustering` is the runner that feeds them from Ack deliveries and timers.

Timers are exact: a member's deadline is ``tau`` after the last two-way Ack from its
leader; an undecided robot's is ``tau`` after it became undecided or last heard a leader
over a two-way link (one-way links are not links). Deliveries precede timers due at the
same instant, so an Ack arriving exactly at a deadline counts, and so do Acks sent at
that instant (sends too run ahead of timers), always.
"""

from __future__ import annotations

from collections.abc import Callable
from enum import StrEnum
from typing import NamedTuple

import numpy as np
import pandas as pd

from netsim.compiled import load
from netsim.plugins import Parts
from netsim.timers import DeadlineTimers
from protocols.ack import Ack, AckBeacon
from protocols.neighbours import BIDIR_SINCE, DEGREE, LAST_HEARD, LIVE_SINCE, ROLE, ROLE_SINCE, X, Y, two_way
from protocols.neighbours import LEADER as LEADER_FIELD
from protocols.roles import LEADER, LEADER_LOST, MEMBER, NO_LEADER, ROLE_NAMES, UNDECIDED, RoleChange, declare_roles

# Causes recorded in roles.parquet, named after the rule that fired.
START = "rule1_start"
JOIN = "rule2_join"
NO_LEADER_HEARD = "rule4_no_leader"
MERGE_YIELD = "rule5_merge_yield"
LEADER_RESIGNED = "rule5_leader_resigned"
ELECTED = "rule6_elected"
MUTUAL_YIELD = "rule5_mutual_yield"

# The state machine: (role, event) -> (new role, cause).
TRANSITIONS = {
    (UNDECIDED, "leader_heard"): (MEMBER, JOIN),
    (MEMBER, "leader_timeout"): (UNDECIDED, LEADER_LOST),
    (MEMBER, "leader_resigned"): (UNDECIDED, LEADER_RESIGNED),
    (UNDECIDED, "no_leader_timeout"): (LEADER, NO_LEADER_HEARD),
    (LEADER, "merge_lost"): (MEMBER, MERGE_YIELD),
    (UNDECIDED, "elected"): (LEADER, ELECTED),
    (MEMBER, "mutual_yield"): (LEADER, MUTUAL_YIELD),
}


def transition(role: int, event: str) -> tuple[int, str]:
    """The role after ``event`` and the rule that fired; KeyError if the event does not
    apply to the role."""
    return TRANSITIONS[(role, event)]


class Candidate(NamedTuple):
    """A robot as another sees it in its neighbour table."""

    id: int
    distance_m: float = 0.0
    group_size: int = 1
    degree: int = 0


class JoinPolicy(StrEnum):
    """Rule 2: which known leader an undecided robot joins."""

    NEAREST = "nearest"
    FIRST_HEARD = "first_heard"
    LOWEST_ID = "lowest_id"


class MergePolicy(StrEnum):
    """Rule 5: which of two neighbouring leaders yields."""

    SMALLER_GROUP_YIELDS = "smaller_group_yields"
    LOWEST_ID_WINS = "lowest_id_wins"
    HIGHEST_DEGREE_WINS = "highest_degree_wins"


class ElectionPolicy(StrEnum):
    """Rule 6: who replaces a lost leader among its former members."""

    LOWEST_ID = "lowest_id"
    HIGHEST_DEGREE = "highest_degree"
    NONE = "none"


def _nearest(candidates: list[Candidate], first_heard: int | None) -> int:
    return min(candidates, key=lambda c: (c.distance_m, c.id)).id


def _first_heard(candidates: list[Candidate], first_heard: int | None) -> int:
    if first_heard is not None and any(c.id == first_heard for c in candidates):
        return first_heard
    return _nearest(candidates, first_heard)


JOIN: dict[JoinPolicy, Callable[[list[Candidate], int | None], int]] = {
    JoinPolicy.NEAREST: _nearest,
    JoinPolicy.FIRST_HEARD: _first_heard,
    JoinPolicy.LOWEST_ID: lambda candidates, first_heard: min(c.id for c in candidates),
}


# The join policies' codes in the compiled join_choice (protocols._kernels).
JOIN_CODES = {JoinPolicy.NEAREST: 0, JoinPolicy.FIRST_HEARD: 1, JoinPolicy.LOWEST_ID: 2}


def choose_leader(policy: str, candidates: list[Candidate], first_heard: int | None = None) -> int:
    """Rule 2: which of the candidate leaders to join.

    ``nearest`` (ties to the lowest id), ``lowest_id``, or ``first_heard`` (the leader
    whose Ack triggered the join; the nearest when there is none). An unknown policy is
    a ValueError.

    >>> choose_leader("nearest", [Candidate(4, 10.0), Candidate(2, 10.0), Candidate(7, 3.0)])
    7
    >>> choose_leader("lowest_id", [Candidate(4, 10.0), Candidate(2, 12.0)])
    2
    """
    rule = JOIN[JoinPolicy(policy)]
    if not candidates:
        raise ValueError("no candidate leader")
    return rule(candidates, first_heard)


# Rule 5: the order in which leaders win (the larger key wins; on equal keys, the higher
# id yields).
MERGE_KEY: dict[MergePolicy, Callable[[Candidate], tuple]] = {
    MergePolicy.SMALLER_GROUP_YIELDS: lambda c: (c.group_size, -c.id),
    MergePolicy.LOWEST_ID_WINS: lambda c: (-c.id,),
    MergePolicy.HIGHEST_DEGREE_WINS: lambda c: (c.degree, -c.id),
}


def merge_loser(policy: str, a: Candidate, b: Candidate) -> int:
    """Rule 5: the id of the leader that yields when leaders ``a`` and ``b`` merge.

    ``smaller_group_yields`` (ties: the higher id yields), ``lowest_id_wins``,
    ``highest_degree_wins`` (ties: the higher id yields). An unknown policy is a ValueError.

    >>> merge_loser("smaller_group_yields", Candidate(1, group_size=2), Candidate(5, group_size=4))
    1
    >>> merge_loser("smaller_group_yields", Candidate(1, group_size=3), Candidate(5, group_size=3))
    5
    """
    key = MERGE_KEY[MergePolicy(policy)]
    return a.id if key(a) < key(b) else b.id


ELECTION: dict[ElectionPolicy, Callable[[Candidate, list[Candidate]], bool]] = {
    ElectionPolicy.LOWEST_ID: lambda me, rivals: all(me.id < r.id for r in rivals),
    ElectionPolicy.HIGHEST_DEGREE: lambda me, rivals: all((me.degree, -me.id) > (r.degree, -r.id) for r in rivals),
    ElectionPolicy.NONE: lambda me, rivals: False,
}


# The election policies' codes in the compiled elected_in_row (protocols._kernels).
ELECTION_CODES = {ElectionPolicy.LOWEST_ID: 0, ElectionPolicy.HIGHEST_DEGREE: 1, ElectionPolicy.NONE: 2}


def elected(policy: str, me: Candidate, rivals: list[Candidate]) -> bool:
    """Rule 6: whether ``me`` takes over among the former members ``rivals`` it can hear.

    ``lowest_id`` (the default priority), ``highest_degree`` (ties to the lowest id), or
    ``none`` (no election: wait for rule 2 or 4). An unknown policy is a ValueError.

    >>> elected("lowest_id", Candidate(3), [Candidate(5), Candidate(8)])
    True
    >>> elected("lowest_id", Candidate(3), [Candidate(2)])
    False
    """
    return ELECTION[ElectionPolicy(policy)](me, rivals)


_NONE = np.empty(0, dtype=np.int64)


def ack_effects(
    role: np.ndarray,
    leader: np.ndarray,
    receivers: np.ndarray,
    hears_me: np.ndarray,
    symmetric: bool,
    sender: int,
    leads: bool,
    deadline_s: np.ndarray,
    armed_s: np.ndarray,
    renewed_s: float,
    out: np.ndarray,
    ids: np.ndarray,
    records: np.ndarray,
    now: float,
    role_sent: np.ndarray,
    leader_since: np.ndarray,
    merge_delay_s: float,
) -> tuple[int, int, int, int]:
    """What an Ack of ``sender`` does, from the roles before it acts, in the rows of ``out``
    (each at least as long as ``receivers``; returned: how many of the first four): positions
    (in ``receivers``) of the members of ``sender``'s group; and if the Ack ``leads`` (a
    leader's, not resigning), those members' timers over a two-way link restart at
    ``renewed_s`` (written in the timers' ``deadline_s``; listed: those of them whose timers
    must be armed, ``renewed_s`` before the event in ``armed_s``), the undecided robots over
    a two-way link (they may join), and the leaders over a two-way link that may merge with
    ``sender`` now (row 4: the slot of ``sender`` in their rows of the table, ``ids`` and
    ``records``): those that announced themselves as leaders (``role_sent``) and have been
    leaders beside ``sender`` for ``merge_delay_s`` at ``now``, counted from the latest of
    the link known (two-way, or live when links are ``symmetric``), ``sender``'s Acks saying
    leader, and their own leadership (``leader_since``). Counts and a reused ``out``, not new
    arrays: cheaper to hand back from the compiled twin, once per Ack."""
    r_role = role[receivers]
    mine = (r_role == MEMBER) & (leader[receivers] == sender)
    found = [np.flatnonzero(mine), _NONE, _NONE, _NONE, _NONE]
    if leads:
        both_ways = hears_me | symmetric
        renew = receivers[mine & both_ways]
        deadline_s[renew] = renewed_s
        leaders = receivers[(r_role == LEADER) & both_ways]
        leaders = leaders[role_sent[leaders] == LEADER]
        at = ids[leaders] == sender
        leaders, slots = leaders[at.any(axis=1)], np.argmax(at, axis=1)[at.any(axis=1)]
        rec = records[leaders, slots]
        linked = rec[:, LIVE_SINCE] if symmetric else rec[:, BIDIR_SINCE]
        since = np.maximum(np.maximum(linked, rec[:, ROLE_SINCE]), leader_since[leaders])
        ready = ~(now - since < merge_delay_s)
        found[1:] = [
            renew[renewed_s < armed_s[renew]],
            receivers[(r_role == UNDECIDED) & both_ways],
            leaders[ready],
            slots[ready],
        ]
    for row, found_ids in zip(out, found):
        row[: len(found_ids)] = found_ids
    a, b, c, d = (len(found_ids) for found_ids in found[:4])
    return a, b, c, d


def group_size(records_row: np.ndarray, now: float, tau_s: float, symmetric: bool, i: int) -> int:
    """1 + the live two-way entries of robot ``i``'s neighbour table row (its records, as
    :class:`protocols.neighbours.NeighbourTable` holds them) whose last Ack named ``i`` as
    their leader."""
    return len(mate_slots(records_row, now, tau_s, symmetric, i)) + 1


def announced_size(
    role: np.ndarray,
    sizes: np.ndarray,
    sized: np.ndarray,
    records_row: np.ndarray,
    now: float,
    tau_s: float,
    symmetric: bool,
    i: int,
) -> None:
    """Before robot ``i``'s Ack: the group size it announces, in ``sizes``: a leader its
    :func:`group_size`, anyone else 1 (written only when it was not: ``sized`` marks whose
    size is other than 1)."""
    if role[i] == LEADER:
        sizes[i] = group_size(records_row, now, tau_s, symmetric, i)
        sized[i] = True
    elif sized[i]:
        sizes[i] = 1
        sized[i] = False


def leader_slots(
    ids_row: np.ndarray, records_row: np.ndarray, now: float, tau_s: float, symmetric: bool, exclude: int
) -> np.ndarray:
    """The slots of a row's live two-way neighbours whose last Ack said they were leaders,
    but ``exclude``."""
    mask = two_way(records_row, now, tau_s, symmetric) & (records_row[:, ROLE] == LEADER) & (ids_row != exclude)
    return np.flatnonzero(mask)


def join_choice(
    ids_row: np.ndarray,
    records_row: np.ndarray,
    now: float,
    tau_s: float,
    symmetric: bool,
    exclude: int,
    x_m: float,
    y_m: float,
    policy: str,
    first_heard: int | None,
) -> tuple[int, int]:
    """Rule 2 from a row of the table: the leader that a robot at ``(x_m, y_m)`` joins
    (:func:`choose_leader`) among the live two-way neighbours whose last Ack said they were
    leaders, but ``exclude`` (:func:`leader_slots`; their distances from the positions their
    Acks carried), and its first slot in the row; ``(NO_LEADER, -1)`` when there is none."""
    slots = leader_slots(ids_row, records_row, now, tau_s, symmetric, exclude)
    if not len(slots):
        return NO_LEADER, -1
    dist = np.hypot(records_row[slots, X] - x_m, records_row[slots, Y] - y_m)
    ids = ids_row[slots].tolist()
    leader = choose_leader(policy, [Candidate(int(j), float(d)) for j, d in zip(ids, dist.tolist())], first_heard)
    return leader, int(slots[ids.index(leader)])


def mate_slots(records_row: np.ndarray, now: float, tau_s: float, symmetric: bool, leader: int) -> np.ndarray:
    """The slots of a row's live two-way neighbours whose last Ack said they were members
    of ``leader``."""
    mask = two_way(records_row, now, tau_s, symmetric)
    return np.flatnonzero(mask & (records_row[:, LEADER_FIELD] == leader) & (records_row[:, ROLE] == MEMBER))


def elected_in_row(
    ids_row: np.ndarray,
    records_row: np.ndarray,
    now: float,
    tau_s: float,
    symmetric: bool,
    old: int,
    i: int,
    degree: int,
    policy: str,
) -> bool:
    """Rule 6 from robot ``i``'s row of the table: whether ``i``, of announced ``degree``,
    takes over from its lost leader ``old`` (:func:`elected`) among the former members it
    knows (:func:`mate_slots`), each with the degree its last Ack announced."""
    mates = mate_slots(records_row, now, tau_s, symmetric, old)
    ids, degrees = ids_row[mates].tolist(), records_row[mates, DEGREE].tolist()
    rivals = [Candidate(int(j), degree=int(d)) for j, d in zip(ids, degrees)]
    return elected(policy, Candidate(i, degree=degree), rivals)


def membership(
    ids: np.ndarray,
    records: np.ndarray,
    now: float,
    tau_s: float,
    symmetric: bool,
    role: np.ndarray,
    leader: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Group membership of every robot, as arrays ``(robot, group, primary)`` ordered by
    robot and group, from the roles and the neighbour tables (``ids``, ``records``):
    a leader in its own group, a member in its leader's (primary) and in those of the other
    leaders it knows over a live two-way link."""
    rows, slots = np.nonzero(two_way(records, now, tau_s, symmetric) & (records[:, :, ROLE] == LEADER))
    other = ids[rows, slots]
    member = role[rows] == MEMBER
    rows, other = rows[member], other[member]
    secondary = other != leader[rows]
    leaders = np.flatnonzero(role == LEADER)
    members = np.flatnonzero(role == MEMBER)
    robot = np.concatenate([leaders, members, rows[secondary]])
    group = np.concatenate([leaders, leader[members], other[secondary]])
    primary = np.concatenate([np.ones(len(leaders) + len(members), bool), np.zeros(int(secondary.sum()), bool)])
    order = np.lexsort((~primary, group, robot))
    return robot[order], group[order], primary[order]


class Clustering:
    """Runs rules 1-6 for all robots on top of an :class:`AckBeacon`, writing their roles
    in ``roles`` (the beacon's, which its Acks announce).

    ``params`` holds ``tau_s``, ``merge_delay_s`` and the three policies (the clustering
    protocol's parameters, :class:`protocols.stack.ClusteringParams`)."""

    def __init__(self, params, parts: Parts, beacon: AckBeacon):
        self.env, self.state, self.trace = parts.env, parts.state, parts.trace
        self.events = parts.events
        self.beacon = beacon
        self.roles = beacon.roles
        self.table = beacon.table
        self.tau_s = params.tau_s
        self.merge_delay_s = params.merge_delay_s
        self.join_policy = JoinPolicy(params.join_policy)
        self.merge_policy = MergePolicy(params.merge_policy)
        self.election_policy = ElectionPolicy(params.election_policy)
        st = parts.state
        # With equal ranges hearing an Ack implies the link is two-way (docs/model.md 4.1).
        self.symmetric = bool(np.all(st.range_m == st.range_m[0])) if st.n else True
        self.timers = DeadlineTimers(parts.env, st.n, self._expire, parts.channel.agenda)
        self.role_changes = np.zeros(st.n, dtype=np.int64)
        # When each robot last became a leader (inf: it is not one).
        self.leader_since = np.full(st.n, np.inf)
        # How many members each robot has now: an Ack that does not lead (a member's, an
        # undecided robot's, a resignation) does something only to its sender's members.
        # The beacon's list: it tells on_ack of no other Ack but a leader's.
        self._members_of = beacon.watched
        # Whose announced group size may be other than 1 (it last sent an Ack as a leader).
        self._sized = np.zeros(st.n, dtype=bool)
        declare_roles(parts.trace)
        # The role changes (the roles table), a list per field of RoleChange: a record per
        # change (10^5 in a 10,000-robot run) would be one more object for the garbage
        # collector to walk, again and again, until the end.
        self._changes: tuple[list, list, list, list, list] = ([], [], [], [], [])
        parts.trace.add_frame("roles", self.roles_frame)
        # The compiled twins of ack_effects, group_size and membership (and of join_choice and
        # elected_in_row, used by name), past netsim.compiled.SMALL_RUN_ROBOTS
        # robots.
        self.kernels = k = load("protocols._kernels", st.n)
        self._effects = k.ack_effects if k is not None else ack_effects
        # ack_effects' lists, per Ack (row 5: the receivers that took it, for take_told).
        self._effects_out = np.empty((6, st.n), dtype=np.int64)
        self._flags = np.empty((3, st.n), dtype=bool)  # take_told's flags, per Ack
        self._group_size = k.group_size if k is not None else group_size
        self._membership = k.membership if k is not None else membership
        on_ack = self.on_ack  # one bound method: the beacon knows it by identity
        beacon.leader_listeners.append(on_ack)
        if k is not None:
            beacon.taker = (on_ack, self.take_told)
        beacon.sized, beacon.sized_symmetric, beacon.size_rule = self._sized, self.symmetric, self._before_ack

    def start(self) -> None:
        roles, now = self.roles, self.env.now
        roles.role[:] = UNDECIDED
        roles.leader[:] = NO_LEADER
        for i in range(self.state.n):
            self._record(now, i, ROLE_NAMES[UNDECIDED], NO_LEADER, START)
        self.timers.restart(np.arange(self.state.n), self.beacon.phase_s + self.tau_s)

    # -- what a robot knows --------------------------------------------------------------
    def group_size(self, i: int, now: float) -> int:
        """1 + the live two-way neighbours whose last Ack named ``i`` as their leader."""
        return int(self._group_size(self.table.data[i], now, self.table.tau_s, self.symmetric, i))

    def membership(self, now: float):
        """Group membership of every robot now, as arrays ``(robot, group, primary)``.

        A leader is in its own group; a member in its leader's (primary) and, if it is a
        gateway, in those of the other leaders it has a live two-way link with; an
        undecided robot in none. One pass over all neighbour tables.
        """
        table, st = self.table, self.roles
        return self._membership(table.id, table.data, now, table.tau_s, self.symmetric, st.role, st.leader)

    def groups(self, now: float) -> list[set[int]]:
        """The groups (leader ids) each robot belongs to now (see :meth:`membership`)."""
        out: list[set[int]] = [set() for _ in range(self.state.n)]
        for r, g, _ in zip(*(a.tolist() for a in self.membership(now))):
            out[r].add(g)
        return out

    def gateways(self, now: float) -> np.ndarray:
        """Ids of the members that belong to two groups or more."""
        robot, _, _ = self.membership(now)
        return np.flatnonzero(np.bincount(robot, minlength=self.state.n) > 1)

    def _before_ack(self, i: int, now: float) -> None:
        table = self.table
        announced_size(
            self.roles.role, self.beacon.group_size, self._sized, table.data[i], now, table.tau_s, self.symmetric, i
        )

    # -- transitions ---------------------------------------------------------------------
    def _set(self, i: int, event: str, leader: int, now: float) -> None:
        st = self.roles
        old = int(st.role[i])
        role, cause = transition(old, event)
        if old == MEMBER:
            self._members_of[int(st.leader[i])] -= 1
        if role == MEMBER:
            self._members_of[leader] += 1
        st.role[i] = role
        st.leader[i] = leader
        self.leader_since[i] = now if role == LEADER else np.inf
        self.role_changes[i] += 1
        self._record(now, i, ROLE_NAMES[role], leader, cause)

    def _record(self, t_s: float, robot: int, role: str, leader: int, cause: str) -> None:
        for column, value in zip(self._changes, (t_s, robot, role, leader, cause)):
            column.append(value)
        if self.events is not None and self.events.wants("role_change"):
            self.events.emit("role_change", RoleChange(t_s, robot, role, leader, cause))

    def roles_frame(self) -> pd.DataFrame:
        """The ``roles`` table: every role change, in order (the frame the trace makes of its
        records: columns typed from their values, all ``object`` when there are none)."""
        if not self._changes[0]:
            return pd.DataFrame([], columns=list(RoleChange._fields))
        return pd.DataFrame(dict(zip(RoleChange._fields, self._changes)))

    def _join(self, i: int, now: float, first_heard: int | None = None, exclude: int = NO_LEADER) -> bool:
        """Rule 2 for robot ``i`` (undecided) from what its table knows; False if no leader is known."""
        table = self.table
        k = self.kernels
        if k is not None:
            x, y = self.state.position(i, now)
            leader, slot = k.join_choice(
                table.id[i], table.data[i], now, table.tau_s, self.symmetric, exclude, x, y,
                JOIN_CODES[self.join_policy], -2 if first_heard is None else first_heard,
            )  # fmt: skip
            if leader < 0:
                return False
        else:
            x, y = self.state.position(i, now)
            leader, slot = join_choice(
                table.id[i], table.data[i], now, table.tau_s, self.symmetric, exclude, x, y, self.join_policy,
                first_heard,
            )  # fmt: skip
            if leader == NO_LEADER:
                return False
        self._set(i, "leader_heard", leader, now)
        self.timers.restart(i, table.data[i, slot, LAST_HEARD] + self.tau_s)
        return True

    def _leader_gone(self, i: int, now: float, event: str) -> None:
        """Rules 3 and 6: ``i`` lost its leader (timeout or resignation)."""
        old = int(self.roles.leader[i])
        self._set(i, event, NO_LEADER, now)
        if self._join(i, now, exclude=old):
            return
        # Like with like: my degree as I announced it, beside theirs as they announced them
        # (all counted before the leader was lost).
        table, degree = self.table, int(self.beacon.degree_sent[i])
        k = self.kernels
        if k is not None:
            code = ELECTION_CODES[self.election_policy]
            won = k.elected_in_row(table.id[i], table.data[i], now, table.tau_s, self.symmetric, old, i, degree, code)
        else:
            won = elected_in_row(
                table.id[i], table.data[i], now, table.tau_s, self.symmetric, old, i, degree, self.election_policy
            )
        if won:
            self._set(i, "elected", i, now)
            self.timers.cancel(i)
        else:
            self.timers.restart(i, now + self.tau_s)

    def _expire(self, i: int, now: float) -> None:
        role = self.roles.role[i]
        if role == MEMBER:
            self._leader_gone(i, now, "leader_timeout")
        elif role == UNDECIDED:
            self._set(i, "no_leader_timeout", i, now)

    def on_ack(self, now: float, ack: Ack, receivers: np.ndarray, hears_me: np.ndarray) -> None:
        leads = ack.role == LEADER and not ack.resign
        if not leads and not self._members_of[ack.sender]:
            return
        st, timers, out = self.roles, self.timers, self._effects_out
        renewed_s = now + self.tau_s
        table = self.table
        a, b, c, d = self._effects(
            st.role, st.leader, receivers, hears_me, self.symmetric, ack.sender, leads,
            timers.deadline_s, timers.armed_s, renewed_s, out,
            table.id, table.data, now, self.beacon.role_sent, self.leader_since, self.merge_delay_s,
        )  # fmt: skip
        self._act(now, ack, leads, receivers, hears_me, renewed_s, a, b, c, d)

    def take_told(self, now: float, ack: Ack, receivers: np.ndarray) -> int:
        """The beacon's table update and :meth:`on_ack` in one compiled call
        (:func:`protocols._kernels.receive_effects`; the beacon's ``taker``): returns how
        many receivers did not take the Ack (stale)."""
        st, timers, out, flags = self.roles, self.timers, self._effects_out, self._flags
        leads = ack.role == LEADER and not ack.resign
        renewed_s = now + self.tau_s
        stale, (kept, a, b, c, d) = self.table.take_by(
            self.kernels.receive_effects, now, ack.sender, receivers, ack.record, flags, st.role, st.leader,
            self.symmetric, leads, timers.deadline_s, timers.armed_s, renewed_s, out, self.beacon.role_sent,
            self.leader_since, self.merge_delay_s,
        )  # fmt: skip
        if b or c or d or (a and not leads):  # else nothing left to do (most Acks)
            # Copies: out and flags are the next Ack's.
            self._act(now, ack, leads, out[5, :kept].copy(), flags[2, :kept].copy(), renewed_s, a, b, c, d)
        return stale

    def _act(
        self, now: float, ack: Ack, leads: bool, receivers: np.ndarray, hears_me: np.ndarray, renewed_s: float,
        a: int, b: int, c: int, d: int,
    ) -> None:  # fmt: skip
        """What an Ack does, from :func:`ack_effects`' lists (in ``_effects_out``, counts
        ``a`` to ``d``) of its fresh ``receivers``."""
        out = self._effects_out
        if not leads:
            for k in out[0, :a].tolist():
                r = int(receivers[k])
                if ack.role == MEMBER and ack.leader == r:
                    self._mutual_yield(r, ack.sender, now, bool(hears_me[k] | self.symmetric))
                else:
                    self._leader_gone(r, now, "leader_resigned")
            return
        if b:
            self.timers.arm(out[1, :b], renewed_s)
        if not (c or d):
            return  # most leaders' Acks: their members' timers renewed, nothing else
        # out is reused: read it now.
        undecided, leaders, slots = out[2, :c].tolist(), out[3, :d].tolist(), out[4, :d].tolist()
        for r in undecided:
            self._join(r, now, first_heard=ack.sender)
        for r, slot in zip(leaders, slots):
            self._merge(r, slot, ack, now)

    def _mutual_yield(self, r: int, other: int, now: float, two_way: bool) -> None:
        """``r`` yielded to ``other``, which (on older news) yielded to ``r``: the lower id
        takes the lead back, the other stays its member."""
        if r < other:
            self._set(r, "mutual_yield", r, now)
            self.beacon.resign_pending[r] = False
            self.timers.cancel(r)
        elif two_way:
            # The other is about to lead again: its Ack shows the link alive meanwhile.
            self.timers.restart(r, now + self.tau_s)

    def _merge(self, r: int, slot: int, ack: Ack, now: float) -> None:
        """Rule 5 for leader ``r``, which has announced itself as a leader and been one beside
        the sender of ``ack`` (in ``slot`` of its row) for the merge delay (ack_effects)."""
        rows = self.table.data[r, slot]
        # What each announced in its last Ack: the same kind of information on both sides.
        me = Candidate(r, group_size=int(self.beacon.group_size[r]), degree=int(self.beacon.degree_sent[r]))
        other = Candidate(ack.sender, group_size=ack.group_size, degree=int(rows[DEGREE]))
        if merge_loser(self.merge_policy, me, other) == r:
            self._set(r, "merge_lost", ack.sender, now)
            self.beacon.resign_pending[r] = True
            self.timers.restart(r, now + self.tau_s)
