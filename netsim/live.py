"""A networkx graph of the links, kept current during the run from the link events.

:class:`LiveTopology` (``sim.live_topology()``) subscribes to ``link_up`` and ``link_down``:
its :attr:`~LiveTopology.graph` has one node per robot and an edge for every link up now,
so a snapshot at any event costs nothing extra (``graph.copy()`` if it must be kept).
Node attributes are read when asked for: ``pos`` (the position now), and with the
protocol's groups ``role`` and ``leader`` (their current values); edges carry ``up_since``
(s). The graph equals :func:`netsim.topology.snapshot` at the same instant (edges and node
attributes; the snapshot's edges carry ``distance`` instead).

It also integrates, exactly, the time averages of three levels of the graph, which are
constant between events: the number of connected components, the size of the largest
one, and the mean degree ``2 E / N``. Components are kept incrementally: a link that comes
up merges two components (the smaller one is relabelled); a link that goes down is checked
by a breadth-first search from both ends at once, each step growing the smaller frontier,
which stops as soon as they meet or one side is exhausted (that side is then a component
of its own). The averages join the run's summary.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping, MutableMapping
from typing import Any

import networkx as nx
import simpy

from netsim.events import EventBus, LinkDown, LinkUp
from netsim.groups import GroupView
from netsim.state import RobotState

# The key through which a node's attribute mapping learns which robot it is.
_BIND = "__netsim_robot__"


class _NodeAttrs(MutableMapping):
    """A node's attributes: ``pos``, ``role`` and ``leader`` computed when read; any other
    key stored as in a plain dict."""

    __slots__ = ("_live", "_robot", "_own")

    def __init__(self) -> None:
        self._live: LiveTopology | None = None
        self._robot = -1
        self._own: dict = {}

    def _computed(self) -> tuple[str, ...]:
        live = self._live
        if live is None:
            return ()
        return ("pos", "role", "leader") if live.groups is not None else ("pos",)

    def __getitem__(self, key: str) -> Any:
        live = self._live
        if live is not None:
            if key == "pos":
                return live.state.position(self._robot, live.env.now)
            groups = live.groups
            if groups is not None:
                if key == "role":
                    return groups.role_names[int(groups.role[self._robot])]
                if key == "leader":
                    return int(groups.leader[self._robot])
        return self._own[key]

    def __setitem__(self, key: str, value: Any) -> None:
        if key == _BIND:
            self._live, self._robot = value
        elif key in self._computed():
            raise KeyError(f"node attribute {key!r} is computed from the run; it cannot be set")
        else:
            self._own[key] = value

    def __delitem__(self, key: str) -> None:
        del self._own[key]

    def __iter__(self) -> Iterator:
        yield from self._computed()
        yield from self._own

    def __len__(self) -> int:
        return len(self._computed()) + len(self._own)

    def __repr__(self) -> str:
        return repr(dict(self))


class _LiveGraph(nx.Graph):
    node_attr_dict_factory = _NodeAttrs


class LiveTopology:
    """The live graph and its time-averaged levels (module notes)."""

    def __init__(
        self,
        env: simpy.Environment,
        state: RobotState,
        events: EventBus,
        groups: GroupView | None = None,
    ):
        self.env, self.state, self.groups = env, state, groups
        n = state.n
        self.graph: nx.Graph = _LiveGraph()
        for i in range(n):
            self.graph.add_node(i, **{_BIND: (self, i)})
        # Components: a label per robot, the members of each label.
        self._label = list(range(n))
        self._members: dict[int, set[int]] = {i: {i} for i in range(n)}
        self._size_count: dict[int, int] = {1: n} if n else {}
        self._next_label = n
        self.components = n
        self.largest = 1 if n else 0
        self.edges = 0  # networkx counts edges in O(N)
        self._t_last = 0.0
        self._area = [0.0, 0.0, 0.0]  # integrals of components, largest, edges
        events.on("link_up", self._on_up)
        events.on("link_down", self._on_down)

    # -- levels --------------------------------------------------------------------------
    def _advance(self, t: float) -> None:
        dt = t - self._t_last
        if dt > 0:
            a = self._area
            a[0] += self.components * dt
            a[1] += self.largest * dt
            a[2] += self.edges * dt
            self._t_last = t

    def levels(self, t_end: float | None = None) -> dict:
        """Time averages over ``[0, t_end]`` (default: now) of the number of components, the
        size of the largest, and the mean degree."""
        t_end = self.env.now if t_end is None else float(t_end)
        self._advance(t_end)
        n = self.state.n
        if t_end <= 0 or n == 0:
            nan = float("nan")
            return {"time_mean_components": nan, "time_mean_largest_component": nan, "time_mean_degree": nan}
        a = self._area
        return {
            "time_mean_components": a[0] / t_end,
            "time_mean_largest_component": a[1] / t_end,
            "time_mean_degree": 2.0 * a[2] / (n * t_end),
        }

    def summary(self, frames: Mapping, duration_s: float) -> dict:
        return self.levels(duration_s)

    def _resize(self, size: int, delta: int) -> None:
        c = self._size_count.get(size, 0) + delta
        if c:
            self._size_count[size] = c
        else:
            del self._size_count[size]

    # -- events --------------------------------------------------------------------------
    def _on_up(self, ev: LinkUp) -> None:
        self._advance(ev.t_s)
        a, b = ev.a, ev.b
        self.graph.add_edge(a, b, up_since=ev.t_s)
        self.edges += 1
        la, lb = self._label[a], self._label[b]
        if la == lb:
            return
        big, small = (la, lb) if len(self._members[la]) >= len(self._members[lb]) else (lb, la)
        moved = self._members.pop(small)
        for r in moved:
            self._label[r] = big
        kept = self._members[big]
        self._resize(len(kept), -1)
        self._resize(len(moved), -1)
        kept |= moved
        self._resize(len(kept), 1)
        self.components -= 1
        self.largest = max(self.largest, len(kept))

    def _on_down(self, ev: LinkDown) -> None:
        self._advance(ev.t_s)
        a, b = ev.a, ev.b
        self.graph.remove_edge(a, b)
        self.edges -= 1
        side = self._split_side(a, b)
        if side is None:
            return
        old = self._label[a]
        members = self._members[old]
        self._resize(len(members), -1)
        members -= side
        new = self._next_label
        self._next_label += 1
        for r in side:
            self._label[r] = new
        self._members[new] = side
        self._resize(len(members), 1)
        self._resize(len(side), 1)
        self.components += 1
        if len(members) + len(side) == self.largest and self.largest not in self._size_count:
            self.largest = max(self._size_count)

    def _split_side(self, a: int, b: int) -> set[int] | None:
        """None if ``a`` and ``b`` are still connected; otherwise the nodes on the smaller
        side (found first)."""
        adj = self.graph.adj
        seen = ({a}, {b})
        frontier = ([a], [b])
        while True:
            k = 0 if len(frontier[0]) <= len(frontier[1]) else 1
            nxt = []
            mine, other = seen[k], seen[1 - k]
            for u in frontier[k]:
                for v in adj[u]:
                    if v in other:
                        return None
                    if v not in mine:
                        mine.add(v)
                        nxt.append(v)
            if not nxt:
                return mine
            frontier = (nxt, frontier[1]) if k == 0 else (frontier[0], nxt)
