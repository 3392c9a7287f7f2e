"""Topology snapshots as networkx graphs, for analysis (never for the inner loop), and the
pairs of robots within range."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from netsim.compiled import filled, load
from netsim.geometry import distances_m, near_pairs
from netsim.groups import GroupView
from netsim.state import RobotState

if TYPE_CHECKING:  # networkx is imported by the snapshots alone, when asked for
    import networkx as nx

    from netsim.plugins import LinkState


def reach_lists(state: RobotState, now: float, index: Any = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every robot's position at ``now`` and neighbour lists ``(indptr, indices)``, each
    list ascending and holding every robot within the largest range: those of the channel's
    range index (``index``, :meth:`netsim.radio.spatial.RangeIndex.lists`) or, without
    one, of the pairs within the largest range, built for the call. Who reaches whom is
    then decided in the lists (:func:`netsim._kernels.senders_in_list`)."""
    pos = state.positions_at(now)
    if index is not None:
        indptr, indices = index.lists(now)
        return pos, indptr, indices
    pairs = near_pairs(pos, float(state.range_m.max()), state.torus_side_m)
    indptr, indices = load("netsim._kernels", state.n).neighbour_lists(pairs, state.n)
    return pos, indptr, indices


def hop_distances(
    state: RobotState,
    now: float,
    node: int,
    towards: bool = False,
    index: Any = None,
    links: tuple[np.ndarray, np.ndarray] | None = None,
    target: int = -1,
) -> np.ndarray:
    """Hops from ``node`` to every robot over the true directed unit-disk links now
    (``towards=True``: from every robot to ``node``, a search on the reversed links), as
    floats, ``inf`` where there is no path: one compiled search
    (:func:`netsim._kernels.hops_in_lists`) over the channel's range index's neighbour lists
    (``index``: a unit disk), or, without one, over lists of the pairs within the largest
    range built for the search. ``links``: the links up now, arrays ``(a, b)``, as a radio
    decides them (shadowing, walls: no range circle gives them), searched instead, each both
    ways. ``target``: the one robot whose hops are wanted: the search ends there, so every
    finite entry is exact but an ``inf`` may be a robot it did not reach."""
    kernels = load("netsim._kernels", state.n)
    if links is not None:
        indptr, indices = kernels.neighbour_lists(np.column_stack(links).astype(np.int64), state.n)
        # Every listed pair is a link: no range to test it by.
        everywhere = np.full(state.n, np.inf)
        return kernels.hops_in_lists(np.zeros((state.n, 2)), everywhere, 0.0, indptr, indices, node, towards, target)
    pos, indptr, indices = reach_lists(state, now, index)
    side = state.side_m if state.torus else 0.0
    return kernels.hops_in_lists(pos, state.range_m, side, indptr, indices, node, towards, target)


def geometric_pairs(
    positions_m: np.ndarray, range_m: float | np.ndarray, side_m: float | None = None, directed: bool = False
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pairs of robots in range as arrays ``(i, j, distance_m)``, sorted by ``(i, j)``.

    Undirected (default): ``i < j`` and ``d <= min(r_i, r_j)``, the links on which both
    robots hear each other. Directed: every ordered pair with ``d <= r_i`` (i reaches j).
    ``side_m`` set: distances on a torus. In range as everywhere in the engine
    (:func:`netsim._kernels.reaches`).

    Notes
    -----
    A grid of cells finds the candidate pairs within the largest range: ``O(N + E)``.
    """
    positions_m = np.ascontiguousarray(positions_m, dtype=float)
    n = len(positions_m)
    ranges = filled(range_m, (n,))
    if n < 2:
        return np.empty(0, np.int64), np.empty(0, np.int64), np.empty(0)
    pairs = near_pairs(positions_m, float(ranges.max()), side_m)
    i, j, dist = load("netsim._kernels", n).pairs_in_range(
        positions_m, pairs[:, 0], pairs[:, 1], ranges, float(side_m or 0.0), directed
    )
    # Each pair once: one key per pair orders them as lexsort((j, i)) would, five times faster.
    order = np.argsort(i * n + j)
    return i[order], j[order], dist[order]


def reach_keys(positions_m: np.ndarray, range_m: float | np.ndarray, side_m: float | None = None) -> np.ndarray:
    """``receiver * n + sender`` for every ordered pair where the sender reaches the
    receiver (``d <= r_sender``), ascending: :func:`geometric_pairs`'s directed pairs as
    one sorted key each, decided in neighbour lists of the pairs within the largest range
    as a run decides them (:func:`netsim._kernels.reach_keys_in_lists`).

    >>> reach_keys(np.array([[0., 0.], [3., 4.], [20., 0.]]), np.array([5.0, 4.0, 30.0])).tolist()
    [2, 3, 5]
    """
    positions_m = np.ascontiguousarray(positions_m, dtype=float)
    n = len(positions_m)
    if n < 2:
        return np.empty(0, np.int64)
    ranges = filled(range_m, (n,))
    kernels = load("netsim._kernels", n)
    indptr, indices = kernels.neighbour_lists(near_pairs(positions_m, float(ranges.max()), side_m), n)
    return kernels.reach_keys_in_lists(positions_m, ranges, float(side_m or 0.0), indptr, indices)


def geometric_edges(
    positions_m: np.ndarray, range_m: float | np.ndarray, side_m: float | None = None, directed: bool = False
) -> list[tuple[int, int, float]]:
    """:func:`geometric_pairs` as a list of ``(i, j, distance_m)`` tuples.

    >>> geometric_edges(np.array([[0., 0.], [3., 4.], [20., 0.]]), 5.0)
    [(0, 1, 5.0)]
    """
    i, j, d = geometric_pairs(positions_m, range_m, side_m, directed)
    return list(zip(i.tolist(), j.tolist(), d.tolist()))


def snapshot(
    state: RobotState,
    t: float,
    directed: bool = False,
    groups: GroupView | None = None,
    links: LinkState | None = None,
) -> nx.Graph:
    """The true network at time ``t``.

    Nodes carry ``pos`` (x, y) and, only when given the protocol's ``groups``
    (``snapshot(sim.state, sim.now, groups=sim.groups)``), ``role`` (its label, as
    "alpha", "beta", "gamma") and ``leader``; edges carry ``distance``. Positions are
    those of the robots' current legs at ``t``; roles and leaders are the current ones, so
    take the snapshot while the run is at ``t`` (``sim.now``) for a consistent picture. A
    ``t`` before some robot's current leg began is refused (ValueError): the state no
    longer holds where that robot was (a past instant: :func:`netsim.tools.figures.snapshot`
    reads a run's tables). A later ``t`` carries every current leg on unchanged.

    The edges are the links as the channel makes them: with ``links`` (the run's runtime
    link solver, ``sim.link_events()``), the links up now, whatever the radio (shadowing,
    walls: the same links as ``links.parquet``), so ``t`` must be the run's present
    (another is refused, ValueError);
    without it, the unit disk of the robots' ranges at ``t``, which are the channel's links
    only under the unit disk (or log-distance path loss alone) in open space. With
    ``directed=True`` the graph is a DiGraph with an edge i -> j when j is within i's
    range (one-way links appear once; the links of a solver, always two-way, appear both
    ways).
    """
    began = float(state.t0_s.max(initial=-math.inf))
    if t < began:
        raise ValueError(
            f"snapshot at t = {t:g} s: a robot's current leg began at {began:g} s, so its position then is not "
            "held; take the snapshot while the run is at t"
        )
    if links is not None and t != links.now_s:
        raise ValueError(
            f"snapshot at t = {t:g} s with links: they are the links up now, at t = {links.now_s:g} s; take the "
            "snapshot at the run's present (sim.now), or leave links out for the unit disk at t"
        )
    pos = state.positions_at(t)
    import networkx as nx

    g = nx.DiGraph() if directed else nx.Graph()
    for i in range(state.n):
        g.add_node(i, pos=(float(pos[i, 0]), float(pos[i, 1])))
    if groups is not None:
        for i, (code, leader) in enumerate(zip(groups.role.tolist(), groups.leader.tolist())):
            g.nodes[i].update(role=groups.role_names[code], leader=int(leader))
    side = state.torus_side_m
    if links is not None:
        a, b = links.up_pairs()
        dist = distances_m(pos[a], pos[b], side, state.n)
        if directed:
            a, b, dist = np.r_[a, b], np.r_[b, a], np.r_[dist, dist]
    else:
        a, b, dist = geometric_pairs(pos, state.range_m, side, directed)
    g.add_weighted_edges_from(zip(a.tolist(), b.tolist(), dist.tolist()), weight="distance")  # type: ignore[attr-defined]
    return g
