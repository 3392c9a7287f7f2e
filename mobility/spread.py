"""The spreading plan (``coverage.members = "spread"``): every robot that can move goes as
near as it can to where its forces push it, while a spanning forest of the network keeps
the team connected.

- The kept links are a minimum spanning forest of the links up now (the caller's
  :class:`~netsim.mobility.steps.Candidates`, :mod:`netsim.mobility.keep`; by default the disk of range
  ``r_c``): it has as many components as the network, and its links are the strongest
  (the shortest on a disk), so the stretched links are the ones let go. It is chosen
  afresh every step.
- Each kept link ``(i, j)`` of length ``d`` may end the step at most ``R = max(keep, d)``
  long (on a disk ``keep = r_c - margin``). If both ends move, each keeps to its half: it
  ends within ``R / 2`` of the link's midpoint now. If only ``i`` moves, ``i`` ends within
  ``R`` of ``j``. A link whose pair travel is bounded (shadowing) bounds each moving end's
  step to its share of it (half when both move).
- So each moving robot has a few disks to end in (one per kept link, and its reach,
  ``speed_max x period``, around where it is) and the area. Where it is now lies in all
  of them, so standing still is always allowed. Its wished end point is brought into
  their intersection by cyclic projection (a few rounds; this keeps the sliding motion
  along a taut link that scaling the step down would forbid), and the step is then cut
  exactly where the segment from its position first leaves a disk or the area.
- A taut link would only block: the outer robot of a chain wants out while the inner
  ones, pushed evenly from all sides, stay. So a robot that wants to move away from a
  neighbour along a kept link by more than the link's slack allows passes the excess on
  to it as a pull (:func:`pass_on_pulls`), and the chain follows.
- Every robot moves in a straight line over the step, so a link within range at both
  ends of the step is within range throughout (:mod:`netsim.mobility.steps`): the number of
  components never grows above its value at the step's start (walls: the caller's
  exact cut, :meth:`netsim.mobility.keep.LinkRules.cut_for_walls`).

Who may move is the caller's: leaders, and members that can hear their leader's command.
Everyone else (undecided robots, members out of their leader's range) holds, and the
links to them are kept from the moving end alone.
"""

from __future__ import annotations

import numpy as np
from netsim.mobility.steps import Candidates, Plan, StepLimits, box_limit, cap_length, fell_short, step_limit

from netsim.area import Bounds, as_bounds
from netsim.compiled import load
from netsim.geometry import distances_m, in_motion
from netsim.topology import geometric_pairs

# Rounds of cyclic projection onto a robot's disks; the exact cut after them makes any
# number safe, more only bring the end point nearer the best one.
PROJECTION_ROUNDS = 8
# How many links a pull travels along taut links in one step: a branch of the spanning
# tree is seldom longer, and a pull stopped short of the branch's root leaves the branch
# folded.
TENSION_HOPS = 30


def link_disks(pos: np.ndarray, mobile: np.ndarray, i: np.ndarray, j: np.ndarray, d: np.ndarray, keep_m):
    """The disk each moving end of each kept link must end the step in: arrays
    ``(robot, centre (k, 2), radius)`` (module notes); ``keep_m`` one for all links or one
    per link."""
    limit = np.maximum(keep_m, d)
    mid = 0.5 * (pos[i] + pos[j])
    robots, centres, radii = [], [], []
    for x, y in ((i, j), (j, i)):
        sel = mobile[x]
        both = mobile[y[sel]]
        centre = np.where(both[:, None], mid[sel], pos[y[sel]])
        radius = np.where(both, limit[sel] / 2, limit[sel])
        # Never smaller than the distance now (rounding): standing still stays allowed.
        radius = np.maximum(radius, distances_m(pos[x[sel]], centre, None, len(pos)))
        robots.append(x[sel])
        centres.append(centre)
        radii.append(radius)
    return np.concatenate(robots), np.concatenate(centres).reshape(-1, 2), np.concatenate(radii)


def pass_on_pulls(
    pos: np.ndarray,
    wish_mps: np.ndarray,
    mobile: np.ndarray,
    link: tuple[np.ndarray, np.ndarray, np.ndarray],
    limit_m: np.ndarray,
    period_s: float,
) -> np.ndarray:
    """Wishes with the pulls along kept links added. A robot that wants to move away from
    a neighbour along a kept link ``(i, j, length)`` by more than its half of the link's
    slack (``(limit - length) / 2``) pulls the neighbour after it with the excess, which
    that neighbour passes on likewise, for :data:`TENSION_HOPS` links.

    Without this a taut link only blocks: the outer robot of a chain wants out, the inner
    ones are pushed evenly from all sides and stay, and the team stops growing long before
    its forces are spent.

    >>> pos = np.array([[0.0, 0.0], [98.0, 0.0]])
    >>> link = (np.array([0]), np.array([1]), np.array([98.0]))
    >>> pass_on_pulls(pos, np.array([[0.0, 0.0], [2.0, 1.0]]), np.array([True, True]), link, np.array([99.0]), 1.0)
    array([[1.5, 0. ],
           [2. , 1. ]])
    """
    i, j, d = link
    both = mobile[i] & mobile[j]
    i, j, d, slack = i[both], j[both], d[both], ((limit_m - d) / (2 * period_s))[both]
    along = (pos[j] - pos[i]) / np.maximum(d, 1e-12)[:, None]  # unit vectors from i to j
    total = np.where(mobile[:, None], wish_mps, 0.0)
    pull = total.copy()
    for _ in range(TENSION_HOPS):
        nxt = np.zeros_like(pull)
        add_pulls(nxt, i, along, pull[j], slack)
        add_pulls(nxt, j, -along, pull[i], slack)
        total += nxt
        pull = nxt
    return total


def add_pulls(out: np.ndarray, robot: np.ndarray, along: np.ndarray, wish_mps: np.ndarray, slack_mps) -> np.ndarray:
    """The pull (rule of the leash's tension): to row ``robot[k]`` of ``out`` add, along the
    unit vector ``along[k]`` toward the robot it is linked to, the excess of that robot's
    wish ``wish_mps[k]`` along it over the slack ``slack_mps[k]`` (m/s), if any. Returns
    ``out``."""
    excess = np.maximum(np.einsum("ij,ij->i", wish_mps, along) - slack_mps, 0.0)
    np.add.at(out, robot, excess[:, None] * along)
    return out


def project_into(target: np.ndarray, robot: np.ndarray, centre: np.ndarray, radius: np.ndarray, area: float | Bounds):
    """Cyclic projection of each robot's ``target`` onto its disks and the area (Bounds, or
    the side of the square ``[0, side]^2``), in
    place, :data:`PROJECTION_ROUNDS` rounds. A robot's disks are the rows of ``robot``
    naming it; each round projects onto them one at a time, then onto the square."""
    box = as_bounds(area)
    order = np.argsort(robot, kind="stable")
    robot, centre, radius = robot[order], centre[order], radius[order]
    first = np.r_[0, np.flatnonzero(robot[1:] != robot[:-1]) + 1] if len(robot) else np.empty(0, np.int64)
    rank = np.arange(len(robot)) - np.repeat(first, np.diff(np.r_[first, len(robot)]))
    layers = [np.flatnonzero(rank == k) for k in range(int(rank.max()) + 1 if len(rank) else 0)]
    # Each layer's disks, and where the rule of in range keeps its answers.
    disks = [
        (robot[rows], centre[rows], np.ascontiguousarray(radius[rows], float), np.empty(len(rows), bool))
        for rows in layers
    ]
    beyond_disks = load("netsim._kernels", len(target)).beyond_disks
    for _ in range(PROJECTION_ROUNDS):
        for x, c, r, out in disks:
            points = target[x]
            beyond_disks(points, c, r, out)
            if not out.any():
                continue
            at, centre_at = points[out], c[out]
            dist = distances_m(at, centre_at, None, len(target))
            target[x[out]] = centre_at + (at - centre_at) * (r[out] / dist)[:, None]
        np.clip(target, box.lo, box.hi, out=target)
    return target


def forest_rows(n: int, links: Candidates) -> np.ndarray:
    """The rows of ``links`` in a minimum spanning forest of the network they make (by
    ``links.weight``, positive), in the order ``(i, j)``."""
    if len(links.i) == 0:
        return np.empty(0, np.int64)
    from scipy.sparse import coo_matrix  # imported when asked: a run without it does not load it
    from scipy.sparse.csgraph import minimum_spanning_tree

    tree = minimum_spanning_tree(coo_matrix((links.weight, (links.i, links.j)), shape=(n, n)).tocsr()).tocoo()
    i, j = np.minimum(tree.row, tree.col).astype(np.int64), np.maximum(tree.row, tree.col).astype(np.int64)
    keys = links.i * n + links.j
    order = np.argsort(keys, kind="stable")
    want = np.sort(i * n + j)
    return order[np.searchsorted(keys, want, sorter=order)]


def disk_links(pos: np.ndarray, limits: StepLimits) -> Candidates:
    """The links of the disk of ``limits.range_m`` (every robot's), kept at ``limits.keep_m``."""
    i, j, d = geometric_pairs(pos, limits.range_m)
    k = len(i)
    r = np.full(k, limits.range_m)
    return Candidates(i, j, d, d + limits.range_m, np.full(k, limits.keep_m), np.full(k, np.inf), r)


def plan_spread(
    pos: np.ndarray,
    mobile: np.ndarray,
    commander_of: np.ndarray,
    desired_mps: np.ndarray,
    limits: StepLimits,
    links: Candidates | None = None,
) -> Plan:
    """Velocities for one control step (module notes).

    ``mobile``: who may move; ``commander_of``: for each robot, whose command it needs to
    move (-1: its own decision, as a leader); ``desired_mps``: the wished velocities (rows
    of robots that may not move are ignored); ``links``: the links up now, with what keeps
    each up and their lengths at ``pos`` (:mod:`netsim.mobility.keep`; default: the disk of
    ``limits.range_m``).
    """
    n = len(pos)
    movers = np.flatnonzero(mobile)
    if links is None:
        links = disk_links(pos, limits)
    kept = forest_rows(n, links)
    i, j, d = links.i[kept], links.j[kept], links.d[kept]
    keep = links.keep_m[kept]
    robot, centre, radius = link_disks(pos, mobile, i, j, d, keep)
    reach = np.full(n, limits.reach_m)
    travel = links.travel_m[kept]
    bounded = np.isfinite(travel)
    if bounded.any():
        # Each mobile end's share of the pair's allowed travel: half when both may move.
        share = np.where(mobile[i] & mobile[j], travel / 2, travel)
        for x in (i, j):
            sel = bounded & mobile[x]
            np.minimum.at(reach, x[sel], share[sel])
    robot = np.concatenate([robot, movers])
    centre = np.concatenate([centre, pos[movers]])
    radius = np.concatenate([radius, reach[movers]])

    # A wish to move farther than the range in one step says only "away": a law that grows
    # without bound at short range (inverse_square) would otherwise pull the whole team
    # after one close pair, step after step.
    bounded_mps = cap_length(desired_mps.copy(), limits.range_m / limits.period_s)
    wanted = pass_on_pulls(pos, bounded_mps, mobile, (i, j, d), np.maximum(keep, d), limits.period_s)
    wish = np.zeros((n, 2))
    wish[movers] = cap_length(wanted[movers] * limits.period_s, reach[movers])
    end = project_into(pos + wish, robot, centre, radius, limits.box)
    move = end - pos
    move[~mobile] = 0.0
    s = np.ones(n)
    if len(robot):
        np.minimum.at(s, robot, step_limit(pos[robot] - centre, radius, move[robot], n))
    s = np.minimum(s, box_limit(pos, move, limits.box))
    move *= s[:, None]

    held = mobile & fell_short(wish, move, limits.range_m)
    velocity = move / limits.period_s
    commander = np.where(in_motion(velocity), commander_of, -1)
    return Plan(velocity, commander, held, len(i), kept)
