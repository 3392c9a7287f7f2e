"""Oracles of the protocols' loops (netsim.protocols._kernels), in numpy: the neighbour
table's update and announcement, the clustering's effects of an Ack, its rules 2 and 6 read
from a row, everyone's groups, who relays a flooded message, and the samples of beliefs
beside the truth. Each states its rule in array operations, independently of the loop."""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import numpy as np
from netsim.protocols import _kernels as K
from netsim.protocols.clustering import ELECTION_CODES, JOIN_CODES, Candidate, ElectionPolicy, JoinPolicy
from netsim.protocols.neighbours import NeighbourTable
from netsim.protocols.roles import LEADER as ALPHA
from netsim.protocols.roles import MEMBER, NO_LEADER, UNDECIDED

_NONE = np.empty(0, dtype=np.int64)
_JOIN_BY_CODE = {code: policy for policy, code in JOIN_CODES.items()}
_ELECTION_BY_CODE = {code: policy for policy, code in ELECTION_CODES.items()}


# Rules 2 and 6 as pure functions of the candidates: the policies as written in docs/model.md 4.2.
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


ELECTION: dict[ElectionPolicy, Callable[[Candidate, list[Candidate]], bool]] = {
    ElectionPolicy.LOWEST_ID: lambda me, rivals: all(me.id < r.id for r in rivals),
    ElectionPolicy.HIGHEST_DEGREE: lambda me, rivals: all((me.degree, -me.id) > (r.degree, -r.id) for r in rivals),
    ElectionPolicy.NONE: lambda me, rivals: False,
}


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


# -- neighbour tables ------------------------------------------------------------------
def ack_record(seq, role, leader, x_m, y_m, group_size, degree=0, heard=()) -> np.ndarray:
    """The packed record of an Ack's fields (time and link columns are filled on update),
    followed by the ids ``heard`` (ascending) it carries."""
    rec = np.empty(K.FIELDS + len(heard))
    rec[: K.FIELDS] = K.EMPTY_RECORD
    rec[K.SEQ], rec[K.ROLE], rec[K.LEADER], rec[K.X], rec[K.Y] = seq, role, leader, x_m, y_m
    rec[K.GROUP_SIZE], rec[K.DEGREE] = group_size, degree
    rec[K.FIELDS :] = heard
    return rec


def hears(heard: np.ndarray, receivers: np.ndarray) -> np.ndarray:
    """Per receiver, whether it is among the ids ``heard`` (ascending)."""
    if len(heard) == 0:
        return np.zeros(len(receivers), dtype=bool)
    at = np.minimum(heard.searchsorted(receivers), len(heard) - 1)
    return heard[at] == receivers


def deadline(last_heard_s, tau_s):
    """``tau`` after the last Ack, and the instants that round into it (``K.TIE_S``, or
    ``K.TIE_RELATIVE`` of the time past 10^6 s)."""
    due = last_heard_s + tau_s
    return np.where(due < K.TIE_RELATIVE_FROM_S, due + K.TIE_S, due + due * K.TIE_RELATIVE)


def two_way(records: np.ndarray, now: float, tau_s: float, symmetric: bool) -> np.ndarray:
    """Which ``records`` (any leading shape) are live neighbours over a two-way link."""
    live = now < deadline(records[..., K.LAST_HEARD], tau_s)  # against the deadline, as a timer
    if not symmetric:
        live &= records[..., K.HEARS_ME] != 0
    return live


class NumpyTable(NeighbourTable):
    """A neighbour table updated by gathers and scatters of records: the rules of
    :class:`netsim.protocols.neighbours.NeighbourTable`, stated in numpy. Its storage (the
    slots and their growth) is the production table's; only the rules are the oracle's."""

    def _free_slots(self, now: float, rows: np.ndarray) -> np.ndarray:
        # Strictly after tau: an Ack at the instant of expiry may still continue the entry.
        return (self.id[rows] == K.EMPTY) | (now > deadline(self.data[rows, :, K.LAST_HEARD], self.tau_s))

    def _place(self, now, sender, receivers, found):
        """Give ``sender`` a slot in the rows of the receivers that have none for it."""
        r_new = receivers[~found]
        free = self._free_slots(now, r_new)
        while not free.any(axis=1).all():
            self._grow()
            free = self._free_slots(now, r_new)
        self.id[r_new, free.argmax(axis=1)] = sender

    def update(self, now, sender, receivers, hears_me, record, power_dbm=None) -> np.ndarray:
        """Record an Ack from ``sender`` heard by ``receivers`` (``hears_me``: whether each
        was among the ids the Ack carried; ``power_dbm``: the power each got it at, None:
        the record's); returns per receiver whether it was taken."""
        found = (self.id[receivers] == sender).any(axis=1)
        if not found.all():
            self._place(now, sender, receivers, found)
        flat = receivers * self.slots + (self.id[receivers] == sender).argmax(axis=1)
        records = self.data.reshape(-1, K.FIELDS)
        old = records[flat]
        fresh = ~found | (old[:, K.SEQ] <= record[K.SEQ])
        flat, old, found, hears_me = flat[fresh], old[fresh], found[fresh], hears_me[fresh]
        rec = np.empty_like(old)
        rec[:] = record[: K.FIELDS]
        if power_dbm is not None:
            rec[:, K.RX_POWER] = np.asarray(power_dbm)[fresh]
        rec[:, K.LAST_HEARD] = now
        was_live = found & (now <= deadline(old[:, K.LAST_HEARD], self.tau_s))
        rec[:, K.LIVE_SINCE] = np.where(was_live, old[:, K.LIVE_SINCE], now)
        rec[:, K.HEARS_ME] = hears_me
        still_two_way = was_live & (old[:, K.HEARS_ME] != 0)
        rec[:, K.BIDIR_SINCE] = np.where(hears_me, np.where(still_two_way, old[:, K.BIDIR_SINCE], now), np.inf)
        same_role = was_live & (old[:, K.ROLE] == record[K.ROLE])
        rec[:, K.ROLE_SINCE] = np.where(same_role, old[:, K.ROLE_SINCE], now)
        said_member = record[K.ROLE] == MEMBER
        rec[:, K.MEMBER_OF] = record[K.LEADER] if said_member else np.where(was_live, old[:, K.MEMBER_OF], K.EMPTY)
        records[flat] = rec
        return fresh

    def receive(self, now, sender, receivers, record, power_dbm=None):
        """:meth:`update`, ``hears_me`` read from the record: ``(fresh, hears_me, stale)``."""
        hears_me = hears(record[K.FIELDS :], receivers)
        fresh = self.update(now, sender, receivers, hears_me, record, power_dbm)
        return fresh, hears_me, len(fresh) - int(fresh.sum())

    def live_mask(self, now: float, i: int) -> np.ndarray:
        return now < deadline(self.data[i, :, K.LAST_HEARD], self.tau_s)

    def announce(self, now, i, seq, role, leader, x_m, y_m, group_size) -> np.ndarray:
        """Robot ``i``'s Ack's packed record, with its two-way degree, then its live ids."""
        live = self.live_mask(now, i)
        degree = int((live & (self.data[i, :, K.HEARS_ME] != 0)).sum())
        return ack_record(seq, role, leader, x_m, y_m, group_size, degree, np.sort(self.id[i][live]))


# -- the clustering ----------------------------------------------------------------------
def ack_effects(now, told, hears_me, robots, table, rules, effects) -> tuple[int, int, int, int]:
    """What an Ack does to the clustering (netsim.protocols._kernels.ack_effects), by masks
    over its receivers."""
    sender, receivers, _, leads = told
    role, leader, role_sent, leader_since, deadline_s, armed_s = robots
    ids, records, _ = table
    c = rules[0]
    symmetric, merge_delay_s = bool(c["symmetric"]), float(c["merge_delay_s"])
    renewed_s = deadline(now, float(c["tau_s"]))
    r_role = role[receivers]
    mine = (r_role == MEMBER) & (leader[receivers] == sender)
    found = [np.flatnonzero(mine), _NONE, _NONE, _NONE, _NONE]
    if leads:
        both_ways = hears_me | symmetric
        renew = receivers[mine & both_ways]
        deadline_s[renew] = renewed_s
        leaders = receivers[(r_role == ALPHA) & both_ways]
        leaders = leaders[role_sent[leaders] == ALPHA]
        at = ids[leaders] == sender
        leaders, slots = leaders[at.any(axis=1)], np.argmax(at, axis=1)[at.any(axis=1)]
        rec = records[leaders, slots]
        linked = rec[:, K.LIVE_SINCE] if symmetric else rec[:, K.BIDIR_SINCE]
        since = np.maximum(np.maximum(linked, rec[:, K.ROLE_SINCE]), leader_since[leaders])
        ready = ~(now - since < merge_delay_s)
        found[1:] = [
            renew[renewed_s < armed_s[renew]],
            receivers[(r_role == UNDECIDED) & both_ways],
            leaders[ready],
            slots[ready],
        ]
    for row, found_ids in zip(effects, found):
        row[: len(found_ids)] = found_ids
    n_group, n_arm, n_join, n_merge = (len(found_ids) for found_ids in found[:4])
    return n_group, n_arm, n_join, n_merge


def mate_slots(records_row, now, tau_s, symmetric, leader) -> np.ndarray:
    """The slots of a row's live two-way neighbours whose last Ack said they were members
    of ``leader``."""
    mask = two_way(records_row, now, tau_s, symmetric)
    return np.flatnonzero(mask & (records_row[:, K.LEADER] == leader) & (records_row[:, K.ROLE] == MEMBER))


def group_size(records_row, now, tau_s, symmetric, i) -> int:
    """1 + the live two-way entries of a row whose last Ack named ``i`` as their leader."""
    return len(mate_slots(records_row, now, tau_s, symmetric, i)) + 1


def join_choice(table, i, now, rules, exclude, x_m, y_m, first_heard, side_m=None) -> tuple[int, int]:
    """Rule 2 from robot ``i``'s row: :func:`choose_leader` over
    its live two-way leaders but ``exclude``, and the chosen one's first slot; distances
    to the nearest image on a torus of side ``side_m`` (None: the plane)."""
    ids_all, records, tau_s = table
    ids_row, records_row = ids_all[i], records[i]
    c = rules[0]
    mask = two_way(records_row, now, tau_s, bool(c["symmetric"])) & (records_row[:, K.ROLE] == ALPHA)
    slots = np.flatnonzero(mask & (ids_row != exclude))
    if not len(slots):
        return NO_LEADER, -1
    dx, dy = records_row[slots, K.X] - x_m, records_row[slots, K.Y] - y_m
    if side_m is not None:
        dx, dy = dx - side_m * np.round(dx / side_m), dy - side_m * np.round(dy / side_m)
    dist = np.hypot(dx, dy)
    ids = ids_row[slots].tolist()
    candidates = [Candidate(int(j), float(d)) for j, d in zip(ids, dist.tolist())]
    policy = _JOIN_BY_CODE[int(c["join_policy"])]
    leader = choose_leader(policy, candidates, first_heard if first_heard >= 0 else None)
    return leader, int(slots[ids.index(leader)])


def elected_in_row(table, i, now, rules, old, degree) -> bool:
    """Rule 6 from robot ``i``'s row: :func:`elected` among the live two-way neighbours
    whose last Ack that said member named ``old``, each with the degree its last Ack
    announced."""
    ids_all, records, tau_s = table
    records_row = records[i]
    c = rules[0]
    had_old = two_way(records_row, now, tau_s, bool(c["symmetric"])) & (records_row[:, K.MEMBER_OF] == old)
    mates = np.flatnonzero(had_old)
    ids, degrees = ids_all[i][mates].tolist(), records_row[mates, K.DEGREE].tolist()
    rivals = [Candidate(int(j), degree=int(d)) for j, d in zip(ids, degrees)]
    return elected(_ELECTION_BY_CODE[int(c["election_policy"])], Candidate(i, degree=degree), rivals)


def membership(table, now, symmetric, roles) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Everyone's groups ``(robot, group, primary)``, ordered by robot and group."""
    ids, records, tau_s = table
    role, leader = roles
    linked = two_way(records, now, tau_s, symmetric)
    # A member is in a group only over a two-way link to its own leader.
    own_linked = (linked & (ids == leader[:, None])).any(axis=1)
    rows, slots = np.nonzero(linked & (records[:, :, K.ROLE] == ALPHA))
    other = ids[rows, slots]
    member = (role[rows] == MEMBER) & own_linked[rows]
    rows, other = rows[member], other[member]
    secondary = other != leader[rows]
    leaders = np.flatnonzero(role == ALPHA)
    members = np.flatnonzero((role == MEMBER) & own_linked)
    robot = np.concatenate([leaders, members, rows[secondary]])
    group = np.concatenate([leaders, leader[members], other[secondary]])
    primary = np.concatenate([np.ones(len(leaders) + len(members), bool), np.zeros(int(secondary.sum()), bool)])
    order = np.lexsort((~primary, group, robot))
    return robot[order], group[order], primary[order]


# -- relaying ----------------------------------------------------------------------------
def relays(table, now, symmetric, roles, receivers, distributed_gateways) -> np.ndarray:
    """The receivers of a flooded message that relay it: leaders, and members with a live
    two-way link to their own leader and a live two-way neighbour in another group."""
    ids, records, tau_s = table
    role, leader = roles
    rows = records[receivers]
    own = leader[receivers][:, None]
    if distributed_gateways:
        other = (rows[:, :, K.ROLE] != UNDECIDED) & (rows[:, :, K.LEADER] != own)
    else:
        other = (rows[:, :, K.ROLE] == ALPHA) & (ids[receivers] != own)
    r_role = role[receivers]
    linked = two_way(rows, now, tau_s, symmetric)
    own_linked = (linked & (ids[receivers] == own)).any(axis=1)
    gateway = own_linked & (linked & other).any(axis=1)
    return receivers[(r_role == ALPHA) | ((r_role == MEMBER) & gateway)]


def flood_step(seen, receivers, table, now, symmetric, roles, distributed_gateways):
    """Those ``receivers`` that had not ``seen`` the message (marked now), and which of
    them relay it."""
    fresh = receivers[~seen[receivers]]
    seen[fresh] = True
    return fresh, relays(table, now, symmetric, roles, fresh, distributed_gateways)


# -- samples of beliefs beside the truth ---------------------------------------------------
def in_sorted(values: np.ndarray, pool: np.ndarray) -> np.ndarray:
    """``np.isin(values, pool)`` for a sorted ``pool``, by binary search."""
    if len(pool) == 0:
        return np.zeros(len(values), dtype=bool)
    at = np.minimum(pool.searchsorted(values), len(pool) - 1)
    return pool[at] == values


def believed_keys(ids, records, now, tau_s) -> np.ndarray:
    """``robot * n + other`` for every live entry of the tables, ascending."""
    live = now < deadline(records[:, :, K.LAST_HEARD], tau_s)
    return np.sort(np.nonzero(live)[0] * len(ids) + ids[live])


def union_sorted(a, b):
    """The ascending union of two ascending arrays of distinct keys, and per key whether it
    is in ``a`` and whether in ``b``."""
    both = np.sort(np.concatenate([a, b]))
    both = both[np.r_[True, both[1:] != both[:-1]]] if len(both) else both
    return both, in_sorted(both, a), in_sorted(both, b)


class Beliefs(NamedTuple):
    """Who believes whom beside the truth, per pair (robot, neighbour), and where each
    robot's pairs start (``indptr``, ``n + 1``)."""

    robot: np.ndarray
    neighbour: np.ndarray
    believed: np.ndarray
    in_range: np.ndarray
    indptr: np.ndarray


def belief_rows(table, now, heard) -> Beliefs:
    """Who believes whom live beside who is in range (``heard``: ascending keys)."""
    ids, records, tau_s = table
    n = len(ids)
    keys, believed, in_range = union_sorted(believed_keys(ids, records, now, tau_s), heard)
    robot = keys // n if n else keys
    return Beliefs(robot, keys % n if n else keys, believed, in_range, robot.searchsorted(np.arange(n + 1)))


def belief_counts(neighbour, believed, in_range, indptr, role, leader):
    """Per robot: believed, true, stale and missing neighbours, and whether its leader is in
    two-way range."""
    n = len(indptr) - 1
    rows = np.repeat(np.arange(n), np.diff(indptr))
    believed_n = np.bincount(rows[believed], minlength=n)
    true_n = np.bincount(rows[in_range], minlength=n)
    stale_n = np.bincount(rows[believed & ~in_range], minlength=n)
    heard_keys = rows[in_range] * n + neighbour[in_range]
    has = np.flatnonzero((role == MEMBER) & (leader >= 0))
    in_reach = np.zeros(n, dtype=bool)
    in_reach[has] = in_sorted(has * n + leader[has], heard_keys) & in_sorted(leader[has] * n + has, heard_keys)
    return believed_n, true_n, stale_n, true_n - (believed_n - stale_n), in_reach | (role == ALPHA)


def sample_rows(table, now, symmetric, roles, heard):
    """A sample's groups and belief rows."""
    return membership(table, now, symmetric, roles), belief_rows(table, now, heard)


def hop_distances(state, now: float, node: int, towards: bool = False) -> np.ndarray:
    """Hops from ``node`` (or towards it) over every directed pair in reach, by a
    breadth-first search in numpy (:func:`netsim.topology.hop_distances`' oracle)."""
    from netsim.topology import geometric_pairs

    a, b, _ = geometric_pairs(state.positions_at(now), state.range_m, state.side_m if state.torus else None, True)
    return bfs_hops(b, a, state.n, node) if towards else bfs_hops(a, b, state.n, node)


def bfs_hops(tail: np.ndarray, head: np.ndarray, n: int, source: int) -> np.ndarray:
    """Hops from ``source`` to every node over the directed edges ``tail[k] -> head[k]``
    (``inf``: unreachable), a breadth-first search a frontier at a time. What scipy's
    ``shortest_path(..., unweighted=True)`` gives, without importing scipy.sparse's graph
    routines (0.1 s) for a handful of messages."""
    order = np.argsort(tail, kind="stable")
    heads = head[order]
    start = np.searchsorted(tail[order], np.arange(n + 1))
    hops = np.full(n, np.inf)
    hops[source] = 0.0
    frontier = np.array([source], dtype=np.int64)
    level = 0
    while len(frontier):
        level += 1
        first, count = start[frontier], start[frontier + 1] - start[frontier]
        # The out-edges of every frontier node, gathered in one index array.
        at = np.repeat(first - np.cumsum(count) + count, count) + np.arange(int(count.sum()))
        reached = heads[at]
        frontier = np.unique(reached[np.isinf(hops[reached])])
        hops[frontier] = level
    return hops
