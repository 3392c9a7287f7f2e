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
6. A robot whose leader timed out becomes ``alpha`` at once if it has the highest priority
   among the live neighbours that had the same leader (lowest id by default; vacuously
   when there are none, even if it hears another leader); otherwise it stays ``gamma``
   (and rule 2 or 4 follows). A robot whose leader resigned joins another known leader if
   it can, and only then holds the election (so does every robot with
   ``join_before_election``).

The decisions are small functions: the kernels' :func:`~netsim.protocols._kernels.join_choice`
(rule 2) and :func:`~netsim.protocols._kernels.elected_in_row` (rule 6) over a robot's row of
its neighbour table, and :func:`merge_loser` and :data:`TRANSITIONS`, pure functions of small
values; :class:`Clustering` is the runner that feeds them from Ack deliveries and timers.
Where each rule lives:

- rule 1: :meth:`Clustering.start`;
- rule 2: :func:`netsim.protocols._kernels.join_choice` (which leader),
  :meth:`Clustering._rule2_join`;
- rule 3: :func:`~netsim.protocols._kernels.ack_effects` renews a member's deadline on its leader's Ack
  (:meth:`Clustering._rule3_renew` schedules the event); the timeout is
  :meth:`Clustering._rule3_leader_lost`;
- rule 4: :meth:`Clustering._rule4_no_leader`;
- rule 5: :func:`~netsim.protocols._kernels.ack_effects` finds the leaders ready to merge with an Ack's sender,
  :func:`merge_loser` decides, :meth:`Clustering._rule5_merge` acts; a resignation and a
  mutual yield reach the members in :meth:`Clustering._rule5_leader_resigned` and
  :meth:`Clustering._rule5_mutual_yield`;
- rule 6: :func:`~netsim.protocols._kernels.elected_in_row` (who wins),
  :meth:`Clustering._rule6_reaffiliate`.

An Ack is taken in two steps: its effects first (:func:`~netsim.protocols._kernels.ack_effects`,
or :func:`~netsim.protocols._kernels.receive_effects` that also records it in the table: which
receivers are the sender's members, which timers to arm, who may join, who may merge, in an
:class:`~netsim.protocols._kernels.AckEffects`), then the rules they fire
(:meth:`Clustering._apply`). The loops (:mod:`netsim.protocols._kernels`) take the table's
``view``, the robots' state (:class:`~netsim.protocols._kernels.Robots`), the constants
(:data:`RULES`) and the effects' lists.

Timers are exact: a member's deadline is ``tau`` after the last two-way Ack from its
leader (and the instants that round into it: :data:`netsim.protocols._kernels.TIE_S`); an
undecided robot's is ``tau`` after it became undecided or last heard a leader
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
from netsim.protocols._kernels import DEGREE, LAST_HEARD, AckEffects, Robots, RoleArrays, Told
from netsim.protocols.ack import Ack, AckBeacon
from netsim.protocols.roles import (
    LEADER,
    LEADER_LOST,
    MEMBER,
    NO_LEADER,
    ROLE_NAMES,
    UNDECIDED,
    RoleChange,
    declare_roles,
)

from netsim.compiled import load
from netsim.plugins import Parts
from netsim.timers import DeadlineTimers

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


# The join policies' codes in the compiled join_choice (netsim.protocols._kernels).
JOIN_CODES = {JoinPolicy.NEAREST: 0, JoinPolicy.FIRST_HEARD: 1, JoinPolicy.LOWEST_ID: 2}


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


# The election policies' codes in the compiled elected_in_row (netsim.protocols._kernels).
ELECTION_CODES = {ElectionPolicy.LOWEST_ID: 0, ElectionPolicy.HIGHEST_DEGREE: 1, ElectionPolicy.NONE: 2}


# The clustering's constants, one record read by name in the compiled rules
# (netsim.protocols._kernels' ``rules``).
RULES = np.dtype(
    [
        ("tau_s", np.float64),  # rule 3: a renewed member's deadline is tau after the Ack
        ("merge_delay_s", np.float64),  # rule 5
        ("symmetric", np.bool_),  # equal ranges: every live link is two-way (docs/model.md 4.1)
        ("join_policy", np.int64),  # rule 2: JOIN_CODES
        ("election_policy", np.int64),  # rule 6: ELECTION_CODES
    ]
)


def rules_record(tau_s: float, merge_delay_s: float, symmetric: bool, join_policy: str, election_policy: str):
    """The clustering's constants as one :data:`RULES` record (an array of one row)."""
    # Records read by field name, in an array that is not a recarray: numba types a
    # recarray through its attribute lookups at every call.
    rules = np.zeros(1, dtype=np.dtype((np.record, RULES)))
    row = rules[0]
    row["tau_s"], row["merge_delay_s"], row["symmetric"] = tau_s, merge_delay_s, symmetric
    row["join_policy"] = JOIN_CODES[JoinPolicy(join_policy)]
    row["election_policy"] = ELECTION_CODES[ElectionPolicy(election_policy)]
    return rules


class Clustering:
    """Runs rules 1-6 for all robots on top of an :class:`AckBeacon`, writing their roles
    in ``roles`` (the beacon's, which its Acks announce).

    ``params`` holds ``tau_s``, ``merge_delay_s``, the three policies and
    ``join_before_election`` (the clustering protocol's parameters,
    :class:`netsim.protocols.stack.ClusteringParams`)."""

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
        self.join_before_election = bool(params.join_before_election)
        st = parts.state
        # With equal ranges hearing an Ack implies the link is two-way (docs/model.md 4.1).
        self.symmetric = bool(np.all(st.range_m == st.range_m[0])) if st.n else True
        self.timers = DeadlineTimers(parts.env, st.n, self._expire, parts.channel.agenda)
        self.rules = rules_record(
            self.tau_s, self.merge_delay_s, self.symmetric, self.join_policy, self.election_policy
        )
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
        # The rules' loops (netsim.protocols._kernels), loaded for the run's size.
        self.kernels = load("netsim.protocols._kernels", st.n)
        # What the rules read and write per Ack, and the lists an Ack's effects are written
        # in, each also as the plain tuple the compiled loops take.
        roles, timers = self.roles, self.timers
        self.robots = Robots(
            roles.role, roles.leader, beacon.role_sent, self.leader_since, timers.deadline_s, timers.armed_s
        )
        self.effects = AckEffects.empty(st.n)
        self._robots, self._effects_rows = tuple(self.robots), tuple(self.effects)
        self._roles = tuple(RoleArrays(roles.role, roles.leader))
        on_ack = self.on_ack  # one bound method: the beacon knows it by identity
        beacon.leader_listeners.append(on_ack)
        beacon.taker = (on_ack, self.take_told)
        beacon.sized, beacon.sized_symmetric = self._sized, self.symmetric

    # -- what a robot knows --------------------------------------------------------------
    def group_size(self, i: int, now: float) -> int:
        """1 + the live two-way neighbours whose last Ack named ``i`` as their leader."""
        return int(self.kernels.group_size(self.table.data[i], now, self.table.tau_s, self.symmetric, i))

    def membership(self, now: float):
        """Group membership of every robot now, as arrays ``(robot, group, primary)``.

        A leader is in its own group; a member with a live two-way link to its leader in
        its leader's (primary) and, if it is a gateway, in those of the other leaders it
        has a live two-way link with; an undecided robot, or a member its leader does not
        hear (a one-way link), in none. One pass over all neighbour tables
        (:func:`netsim.protocols._kernels.membership`).
        """
        return self.kernels.membership(self.table.view, now, self.symmetric, self._roles)

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

    def _run_timer(self, i: int, from_s: float) -> None:
        """Restart robot ``i``'s timer (rules 3 and 4) to run out ``tau`` after ``from_s``,
        as a leading Ack renews it (:func:`netsim.protocols._kernels.deadline_after`)."""
        self.timers.restart(i, self.kernels.deadline_after(from_s, self.tau_s))

    # -- the rules of docs/model.md 4.2, in its order ------------------------------------
    def start(self) -> None:
        """Rule 1: every robot starts undecided; its timer (rule 4) runs from its first Ack."""
        roles, now = self.roles, self.env.now
        roles.role[:] = UNDECIDED
        roles.leader[:] = NO_LEADER
        for i in range(self.state.n):
            self._record(now, i, ROLE_NAMES[UNDECIDED], NO_LEADER, START)
        # One deadline at a time: the kernel is then compiled for numbers alone.
        for i, phase_s in enumerate(self.beacon.phase_s.tolist()):
            self._run_timer(i, phase_s)

    def _rule2_join(self, i: int, now: float, first_heard: int = NO_LEADER, exclude: int = NO_LEADER) -> bool:
        """Rule 2 for robot ``i`` (undecided) from what its table knows: it joins a leader
        (the join policy's; ``first_heard``: the leader whose Ack triggered it), its timer
        running from that leader's last Ack; False if no leader but ``exclude`` is known."""
        table, motion = self.table, self.beacon.motion
        leader, slot = self.kernels.join_choice(table.view, i, now, self.rules, exclude, motion, first_heard)
        if leader < 0:
            return False
        self._set(i, "leader_heard", leader, now)
        self._run_timer(i, table.data[i, slot, LAST_HEARD])
        return True

    def _rule3_renew(self, to_arm: np.ndarray) -> None:
        """Rule 3, on a leading Ack: its members' deadlines were renewed (by
        :func:`netsim.protocols._kernels.ack_effects`, to ``now + tau``); the events of those
        timers ``to_arm`` are scheduled."""
        self.timers.arm(to_arm)

    def _rule3_leader_lost(self, i: int, now: float) -> None:
        """Rule 3: member ``i`` heard no Ack from its leader for ``tau``; rule 6 follows."""
        self._rule6_reaffiliate(i, now, "leader_timeout")

    def _rule4_no_leader(self, i: int, now: float) -> None:
        """Rule 4: undecided ``i`` heard no leader for ``tau``: it leads."""
        self._set(i, "no_leader_timeout", i, now)

    def _rule5_merge(self, r: int, slot: int, ack: Ack, now: float) -> None:
        """Rule 5 for leader ``r``, which has announced itself as a leader and been one beside
        the sender of ``ack`` (in ``slot`` of its row) for the merge delay
        (:func:`netsim.protocols._kernels.ack_effects`):
        by the merge policy, it yields (joins the sender, resigns in its next Ack) or not."""
        rows = self.table.data[r, slot]
        # What each announced in its last Ack: the same kind of information on both sides.
        me = Candidate(r, group_size=int(self.beacon.group_size[r]), degree=int(self.beacon.degree_sent[r]))
        other = Candidate(ack.sender, group_size=ack.group_size, degree=int(rows[DEGREE]))
        if merge_loser(self.merge_policy, me, other) == r:
            self._set(r, "merge_lost", ack.sender, now)
            self.beacon.resign_pending[r] = True
            self._run_timer(r, now)

    def _rule5_leader_resigned(self, r: int, now: float) -> None:
        """Rule 5: member ``r``'s leader resigned (or its Ack no longer says leader): ``r``
        re-affiliates at once (rule 6)."""
        self._rule6_reaffiliate(r, now, "leader_resigned")

    def _rule5_mutual_yield(self, r: int, other: int, now: float, two_way: bool) -> None:
        """Rule 5: ``r`` yielded to ``other``, which (on older news) yielded to ``r``: the lower
        id takes the lead back, the other stays its member."""
        if r < other:
            self._set(r, "mutual_yield", r, now)
            self.beacon.resign_pending[r] = False
            self.timers.cancel(r)
        elif two_way:
            # The other is about to lead again: its Ack shows the link alive meanwhile.
            self._run_timer(r, now)

    def _rule6_reaffiliate(self, i: int, now: float, event: str) -> None:
        """Rule 6: ``i`` lost its leader (``event``: timeout or resignation). A group whose
        leader timed out elects a new one among its members: ``i`` leads at once if it wins
        the election among the former members it knows, else stays undecided until a
        leader's Ack (rule 2) or rule 4's timer. A resigned leader's members re-affiliate
        at once (rule 5), and so does every member with ``join_before_election``: ``i``
        first joins another known leader (rule 2), then holds the election."""
        old = int(self.roles.leader[i])
        self._set(i, event, NO_LEADER, now)
        join_first = self.join_before_election or event == "leader_resigned"
        if join_first and self._rule2_join(i, now, exclude=old):
            return
        # Like with like: my degree as I announced it, beside theirs as they announced them
        # (a rival still naming the leader counted it before the loss; one that leads since,
        # after).
        degree = int(self.beacon.degree_sent[i])
        if self.kernels.elected_in_row(self.table.view, i, now, self.rules, old, degree):
            self._set(i, "elected", i, now)
            self.timers.cancel(i)
        else:
            self._run_timer(i, now)

    # -- the runner: timers and Acks to the rules ------------------------------------------
    def _expire(self, i: int, now: float) -> None:
        role = self.roles.role[i]
        if role == MEMBER:
            self._rule3_leader_lost(i, now)
        elif role == UNDECIDED:
            self._rule4_no_leader(i, now)

    def on_ack(self, now: float, ack: Ack, receivers: np.ndarray, hears_me: np.ndarray) -> None:
        leads = ack.role == LEADER and not ack.resign
        if not leads and not self._members_of[ack.sender]:
            return
        told = tuple(Told(ack.sender, receivers, ack.record, leads))
        counts = self.kernels.ack_effects(
            now, told, hears_me, self._robots, self.table.view, self.rules, self._effects_rows
        )
        self._apply(now, ack, leads, receivers, hears_me, *counts)

    def take_told(self, now: float, ack: Ack, receivers: np.ndarray, power_dbm: np.ndarray | None = None) -> int:
        """The beacon's table update (each receiver's power ``power_dbm``, None: not measured)
        and :meth:`on_ack` in one compiled call (:func:`netsim.protocols._kernels.receive_effects`;
        the beacon's ``taker``): returns how many receivers did not take the Ack (stale)."""
        leads = ack.role == LEADER and not ack.resign
        told = tuple(Told(ack.sender, receivers, ack.record, leads))
        stale, (kept, group, to_arm, may_join, may_merge) = self.table.take_by(
            self.kernels.receive_effects, now, told, power_dbm, self._robots, self.rules, self._effects_rows
        )
        if to_arm or may_join or may_merge or (group and not leads):  # else nothing left to do (most Acks)
            # Copies: the effects' lists are the next Ack's.
            effects = self.effects
            takers, hear_me = effects.takers[:kept].copy(), effects.takers_hear_me[:kept].copy()
            self._apply(now, ack, leads, takers, hear_me, group, to_arm, may_join, may_merge)
        return stale

    def _apply(
        self,
        now: float,
        ack: Ack,
        leads: bool,
        receivers: np.ndarray,
        hears_me: np.ndarray,
        group: int,
        to_arm: int,
        may_join: int,
        may_merge: int,
    ) -> None:
        """The rules an Ack fires, from the lists of its effects (:attr:`effects`, the
        first ``group``, ``to_arm``, ``may_join`` and ``may_merge`` of each) over its fresh
        ``receivers``. A leading Ack renews its members' timers (rule 3) before the joins
        (rule 2) and merges (rule 5) it brings: the timers' events are scheduled in that
        order, and events due at one instant run in the order they were scheduled."""
        effects = self.effects
        if not leads:
            # The sender's Ack no longer leads: its members learn it resigned (rule 5) or,
            # when it yielded to them, that both yielded.
            for k in effects.group[:group].tolist():
                r = int(receivers[k])
                if ack.role == MEMBER and ack.leader == r:
                    self._rule5_mutual_yield(r, ack.sender, now, bool(hears_me[k] | self.symmetric))
                else:
                    self._rule5_leader_resigned(r, now)
            return
        if to_arm:
            self._rule3_renew(effects.to_arm[:to_arm])
        if not (may_join or may_merge):
            return  # most leaders' Acks: their members' timers renewed, nothing else
        # The lists are reused: read them now.
        undecided = effects.may_join[:may_join].tolist()
        leaders, slots = effects.may_merge[:may_merge].tolist(), effects.merge_slot[:may_merge].tolist()
        for r in undecided:
            self._rule2_join(r, now, first_heard=ack.sender)
        for r, slot in zip(leaders, slots):
            self._rule5_merge(r, slot, ack, now)
