"""The paper's plan (``coverage.members = "follow"``): leaders move, members follow
rigidly, and the bridges between groups are kept.

- the groups are the nodes of a graph whose edges are the links between groups: a
  *gateway* (a member in range of another leader, i.e. in the lens the two leaders' disks
  share) or a member-to-member link; a minimum spanning forest of that graph, preferring
  gateways, is the set of bridges to keep;
- a bridging gateway rides toward the centroid of the leaders it bridges (their planned
  positions), as far as it can while staying within ``r_c - margin`` of each; every other
  member translates with its leader, so it stays in its leader's range;
- each leader shortens its own step, and holds its position if it must, so that at the
  end of the step it is still within ``r_c - margin`` of the gateways it relies on
  (where they are now, which is where a gateway that cannot move stays), and the
  member-to-member bridges stay within range (each side keeps to its half); a group stays
  inside the area.

Every robot moves in a straight line, so kept links that hold at both ends of the step
hold throughout (:mod:`netsim.mobility.steps`).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from netsim.mobility.steps import SAFETY, Plan, StepLimits, box_limit, cap_length, step_limit

from netsim.compiled import load
from netsim.geometry import distances_m, in_motion
from netsim.groups import in_a_group, leads_itself
from netsim.topology import geometric_pairs

# Weights of the candidate bridges: any gateway is preferred to any member-to-member link.
_GATEWAY_WEIGHT, _LINK_WEIGHT = 1e-3, 1.0


class Groups(NamedTuple):
    group: np.ndarray  # each robot's group: its leader's id, or its own id if it follows no one
    is_leader: np.ndarray
    follows: np.ndarray  # members in range of a leader they can follow


class Bridges(NamedTuple):
    gw_robot: np.ndarray  # one row per bridging gateway and leader it must stay with
    gw_leader: np.ndarray
    bridging: np.ndarray  # (N,) robots that are bridging gateways
    link_u: np.ndarray  # kept member-to-member bridges
    link_v: np.ndarray
    count: int  # bridges kept


def groups_of(pos: np.ndarray, leader: np.ndarray, range_m: float) -> Groups:
    """Each robot's group, from each robot's leader (:mod:`netsim.groups`): a leader's own
    id; a member's leader if in range of it; anyone else (undecided, or a member cut off
    from its leader) a group of its own."""
    ids = np.arange(len(pos))
    is_leader = leads_itself(leader)
    member = in_a_group(leader)
    lead = np.where(member, leader, ids)
    near = load("netsim._kernels", len(pos)).in_range(pos, ids, lead, np.full(len(pos), float(range_m)), 0.0)
    follows = member & is_leader[lead] & near
    return Groups(np.where(follows, lead, ids), is_leader, follows)


def bridges_to_keep(pos: np.ndarray, g: Groups, range_m: float) -> Bridges:
    """A minimum spanning forest of the graph of groups, preferring gateways (nearest the
    middle of their leaders) to member-to-member links (shortest first)."""
    n = len(pos)
    group, follows, is_leader = g.group, g.follows, g.is_leader
    a, b, d = geometric_pairs(pos, range_m)
    cross = group[a] != group[b]
    a, b, d = a[cross], b[cross], d[cross]
    gw_a = follows[a] & is_leader[b]
    gw_b = follows[b] & is_leader[a]
    cand_u = np.concatenate([a[gw_a], b[gw_b], a])
    cand_v = np.concatenate([b[gw_a], a[gw_b], b])
    is_gw = np.concatenate([np.ones(int(gw_a.sum() + gw_b.sum()), bool), np.zeros(len(a), bool)])
    mid = 0.5 * (pos[group[cand_u]] + pos[group[cand_v]])
    weight = np.where(
        is_gw,
        _GATEWAY_WEIGHT * (1.0 + distances_m(pos[cand_u], mid, None, len(pos)) / range_m),
        _LINK_WEIGHT + np.concatenate([d[gw_a], d[gw_b], d]) / range_m,
    )
    ga, gb = group[cand_u], group[cand_v]
    key = np.minimum(ga, gb) * n + np.maximum(ga, gb)
    order = np.lexsort((weight, key))
    first = order[np.r_[True, key[order][1:] != key[order][:-1]]] if len(order) else order
    from scipy.sparse import coo_matrix  # imported when asked: a run without it does not load it
    from scipy.sparse.csgraph import minimum_spanning_tree

    tree = minimum_spanning_tree(
        coo_matrix((weight[first], (np.minimum(ga, gb)[first], np.maximum(ga, gb)[first])), shape=(n, n)).tocsr()
    ).tocoo()
    kept_key = np.minimum(tree.row, tree.col) * n + np.maximum(tree.row, tree.col)
    chosen = first[np.isin(key[first], kept_key)]
    gw_edges = chosen[is_gw[chosen]]
    link_edges = chosen[~is_gw[chosen]]
    gw_robot = cand_u[gw_edges]
    bridging = np.zeros(n, bool)
    bridging[gw_robot] = True
    # Each bridging gateway stays with the other group's leader and with its own.
    gw_pairs_robot = np.concatenate([gw_robot, np.unique(gw_robot)])
    gw_pairs_leader = np.concatenate([cand_v[gw_edges], group[np.unique(gw_robot)]])
    return Bridges(gw_pairs_robot, gw_pairs_leader, bridging, cand_u[link_edges], cand_v[link_edges], len(chosen))


def leader_step_factors(
    pos: np.ndarray, move: np.ndarray, g: Groups, br: Bridges, rigid: np.ndarray, limits: StepLimits
) -> np.ndarray:
    """How much of its wished step each leader may take (1: all of it): it must end
    within ``r_c - margin`` of the gateways it relies on, keep its half of each
    member-to-member bridge, and keep its rigid members inside the area."""
    n = len(pos)
    group, keep_m = g.group, limits.keep_m
    link_u, link_v = br.link_u, br.link_v
    rows_k, rows_off, rows_r = [], [], []
    off = pos[br.gw_leader] - pos[br.gw_robot]
    rows_k.append(br.gw_leader)
    rows_off.append(off)
    rows_r.append(np.maximum(keep_m, distances_m(pos[br.gw_leader], pos[br.gw_robot], None, n)))
    both = rigid[link_u] & rigid[link_v]
    m = 0.5 * (pos[link_u] + pos[link_v])
    for x, y in ((link_u, link_v), (link_v, link_u)):
        half = both
        alone = rigid[x] & ~rigid[y]
        centre = np.where(half[:, None], m, pos[y])
        sel = half | alone
        o = pos[x[sel]] - centre[sel]
        rows_k.append(group[x[sel]])
        rows_off.append(o)
        length = distances_m(pos[x[sel]], centre[sel], None, n)
        rows_r.append(np.maximum(np.where(half[sel], keep_m / 2, keep_m), length))
    k = np.concatenate(rows_k).astype(np.int64)
    s = np.ones(n)
    if len(k):
        np.minimum.at(s, k, step_limit(np.concatenate(rows_off), np.concatenate(rows_r), move[k], n))
    # Members translate with their leader: the whole group stays inside the area.
    r_idx = np.flatnonzero(rigid)
    np.minimum.at(s, group[r_idx], box_limit(pos[r_idx], move[group[r_idx]], limits.box))
    return s


def gateway_steps(pos: np.ndarray, move: np.ndarray, gw: np.ndarray, br: Bridges, limits: StepLimits) -> np.ndarray:
    """Steps of the bridging gateways ``gw``: toward the centroid of their leaders'
    planned positions, as far as they can while staying within ``r_c - margin`` of each
    and inside the area."""
    n = len(pos)
    cap = limits.reach_m * SAFETY  # a step at the reach, over the period, rounds past the speed cap
    planned = pos[br.gw_leader] + move[br.gw_leader]
    cnt = np.bincount(br.gw_robot, minlength=n)
    cx = np.bincount(br.gw_robot, weights=planned[:, 0], minlength=n)
    cy = np.bincount(br.gw_robot, weights=planned[:, 1], minlength=n)
    target = np.column_stack([cx[gw] / cnt[gw], cy[gw] / cnt[gw]])
    want = cap_length(target - pos[gw], cap)
    full = np.zeros((n, 2))
    full[gw] = want
    o = pos[br.gw_robot] - planned
    leash = np.maximum(limits.keep_m, distances_m(pos[br.gw_robot], planned, None, n))
    lim = step_limit(o, leash, full[br.gw_robot], n)
    sg = np.ones(n)
    np.minimum.at(sg, br.gw_robot, lim)
    sg[gw] = np.minimum(sg[gw], box_limit(pos[gw], want, limits.box))
    return want * sg[gw, None]


def plan_follow(pos: np.ndarray, leader: np.ndarray, desired_mps: np.ndarray, limits: StepLimits) -> Plan:
    """Velocities for one control step that keep every bridge between groups (module notes).

    ``desired_mps`` holds the leaders' wished velocities (other rows are ignored). The
    result moves leaders along their wish, shortened where a bridge or the area's border
    requires; members with their leader; bridging gateways toward the middle of the
    leaders they bridge; undecided robots not at all.
    """
    n = len(pos)
    g = groups_of(pos, leader, limits.range_m)
    br = bridges_to_keep(pos, g, limits.range_m)
    mobile = g.is_leader | g.follows
    pinned = ~mobile
    # A bridging gateway that is also the end of a member-to-member bridge stays put.
    pinned[br.link_u[br.bridging[br.link_u]]] = True
    pinned[br.link_v[br.bridging[br.link_v]]] = True
    rigid = mobile & ~br.bridging & ~pinned

    move = np.zeros((n, 2))
    move[g.is_leader] = desired_mps[g.is_leader] * limits.period_s
    cap_length(move, limits.reach_m * SAFETY)  # a step at the reach, over the period, rounds past the cap
    s = leader_step_factors(pos, move, g, br, rigid, limits)
    held = g.is_leader & in_motion(move) & (s < SAFETY)
    move *= s[:, None]

    step = np.zeros((n, 2))
    step[rigid] = move[g.group[rigid]]
    gw = np.flatnonzero(br.bridging & ~pinned)
    if len(gw):
        step[gw] = gateway_steps(pos, move, gw, br, limits)
    velocity = step / limits.period_s
    commander = np.where(in_motion(velocity) & ~g.is_leader, g.group, -1)
    return Plan(velocity, commander, held, br.count)
