"""The radio's reception decision inside the channel, and the record of its decisions.

:class:`Reception` asks a :class:`~netsim.radio.propagation.Propagation` (in one pass,
:class:`~netsim.radio.fast.CompiledChain`) which of a transmission's candidate receivers
(every robot within the radio's reach) can hear it: path loss or range, then shadowing,
then walls, each pair dropped as soon as it cannot make it. Shadowing is looked at then,
at the pair's travel (the sum of both robots' path lengths), from the channel's own
stream ``channel.shadowing``.

Under shadowing a link has no solvable up and down times (see docs/radio.md): the links
table is then the record of these decisions (:class:`LinkRecorder`): every decision is
symmetric (path loss, shadowing and walls are the same both ways, and every robot sends
with the same power), so each broadcast tells the state of the sender's link with each
robot within reach, and a unicast that of its own pair alone.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from netsim._kernels import Motion
from netsim.compiled import load
from netsim.radio.fast import GenericChain, one_pass
from netsim.radio.propagation import Propagation
from netsim.state import RobotState

# What a pass reads where a run has no shadowing or no walls.
_NONE = np.zeros(1)
_NO_CELLS = np.zeros(1, dtype=bool)


class LinkRecorder:
    """Links as the channel decides them: up from the first transmission between two robots
    (either way) that gets through, down at the first that does not, or when one of them
    sends while the other is beyond reach.

    Besides these changes it keeps *touches*: transmissions that get through on a link
    already up, where the pair may have left the reach since its last decision (one of the
    two robots started a leg, or jumped, at or after that decision; on a torus, every one).
    A link is also cut where the pair leaves the reach, which this record does not know; the
    first transmission to get through after such a cut opens a new lifetime, and it is
    always a touch: between two decisions with no course change the distance of the pair
    is convex in time, so a pair within reach at both cannot have left it in between.
    :func:`netsim.links.radio_links.recorded_lifetimes` and
    :class:`netsim.links.shadowed_links.ShadowedLinks` apply the cut.

    Parameters
    ----------
    n : robots.
    t0_s : each robot's current leg's start (:attr:`~netsim.state.RobotState.t0_s`, kept
        current by the state); None: unknown, every success on a link up is a touch.
    torus : distances on a torus (not convex in time: every success on a link up is a touch).
    """

    def __init__(self, n: int, t0_s: np.ndarray | None = None, torus: bool = False):
        self.n = n
        self.up = np.zeros((n, n), dtype=bool)
        # Key -> (since when, the raw interval's id).
        self._since: dict[tuple[int, int], tuple[float, int]] = {}
        self._rows: list[tuple[int, int, float, float, int]] = []
        self._opened = 0
        self._touches: list[tuple[int, int, float, int]] = []
        self._scratch = np.zeros(n, dtype=bool)
        self._changed = np.empty(n, dtype=np.int64)
        self._touched = np.empty(n, dtype=np.int64)
        self._t0 = t0_s if t0_s is not None else np.full(n, np.inf)
        self._every = bool(torus)
        # Each robot's last send (a decision on all its pairs).
        self._last_t = np.full(n, -np.inf)
        kernels = load("netsim.radio._kernels", n)
        self._kernel, self._touch_kernel = kernels.link_changes, kernels.link_touches
        # Called as fn(t, sender, robots, up, touched) with every decision that changes links
        # or touches one (lists: the robots whose link with sender changed, whether it is now
        # up, and the robots touched).
        self.listeners: list = []

    def observe(self, t: float, sender: int, receivers: np.ndarray, linked: np.ndarray) -> None:
        touched_n = self._touches_of(sender, receivers, linked)
        self._last_t[sender] = t
        count = self._changes(sender, receivers, linked)
        if count == 0 and touched_n == 0:
            return
        changed = self._changed[:count]
        now = ~self.up[sender, changed]
        self._record(t, sender, changed.tolist(), now.tolist(), self._touched[:touched_n].tolist())

    def observe_pair(self, t: float, sender: int, dest: int, linked: bool) -> None:
        """A decision on one pair alone (a unicast): it tells nothing of ``sender``'s other
        pairs, so only this link may change, and ``sender``'s last decision on all its pairs
        stays where it was (a touch is then judged from that earlier instant: a touch too
        many is harmless, it only matters after a cut at the reach)."""
        up = bool(self.up[sender, dest])
        touched = self._touched[: self._touches_of(sender, np.array([dest]), np.array([linked]))].tolist()
        changed = [dest] if linked != up else []
        if changed or touched:
            self._record(t, sender, changed, [linked] * len(changed), touched)

    def _record(self, t: float, sender: int, robots: list, is_now_up: list, touched: list) -> None:
        """Tell the listeners, then keep the touches and the links that changed."""
        for fn in self.listeners:
            fn(t, sender, robots, is_now_up, touched)
        for r in touched:
            key = (sender, r) if sender < r else (r, sender)
            self._touches.append((key[0], key[1], t, self._since[key][1]))
        for r, is_up in zip(robots, is_now_up):
            key = (sender, r) if sender < r else (r, sender)
            if is_up:
                self._since[key] = (t, self._opened)
                self._opened += 1
            else:
                since, ident = self._since.pop(key)
                self._rows.append((key[0], key[1], since, t, ident))
        self.up[sender, robots] = is_now_up
        self.up[robots, sender] = is_now_up

    def _changes(self, sender: int, receivers: np.ndarray, linked: np.ndarray) -> int:
        """How many robots' links with ``sender`` this decision changes (ids in ``_changed``)."""
        return int(self._kernel(self.up, sender, receivers, linked, self._scratch, self._changed))

    def _touches_of(self, sender: int, receivers: np.ndarray, linked: np.ndarray) -> int:
        """How many robots this decision touches (ids in ``_touched``, class notes); before
        ``_last_t[sender]`` is set to now."""
        args = (self.up, sender, receivers, linked, self._t0, self._last_t, self._every, self._touched)
        return int(self._touch_kernel(*args))

    def intervals(self, duration_s: float) -> pd.DataFrame:
        """``a, b, t_up_s, t_down_s, open, id`` (still up at the end: ``t_down_s`` =
        duration): the changes' intervals, before any cut at the reach."""
        rows = self._rows + [(a, b, t, duration_s, i) for (a, b), (t, i) in self._since.items()]
        df = pd.DataFrame(rows, columns=["a", "b", "t_up_s", "t_down_s", "id"])
        df["open"] = np.r_[np.zeros(len(self._rows), bool), np.ones(len(self._since), bool)]
        types = {"a": np.int64, "b": np.int64, "t_up_s": float, "t_down_s": float, "id": np.int64}
        return df[["a", "b", "t_up_s", "t_down_s", "open", "id"]].astype(types)

    def touches(self) -> pd.DataFrame:
        """``a, b, t_s, id``: the touches (class notes), ``id`` the interval they fell in."""
        df = pd.DataFrame(self._touches, columns=["a", "b", "t_s", "id"])
        return df.astype({"a": np.int64, "b": np.int64, "t_s": float, "id": np.int64})


class Reception:
    """Which candidate receivers hear a frame, for one run."""

    def __init__(self, propagation: Propagation, state: RobotState, record: bool = False):
        self.propagation = propagation
        fast = one_pass(propagation)
        # The model's compiled path (CompiledChain for the built-in chains), or the generic one.
        self.compiled: Any = fast(propagation, state.n) if fast is not None else GenericChain(propagation)
        self.state = state
        self.reach_m = float(propagation.reach_m)
        self.map = self.compiled.occupancy
        self.shadowing = self.compiled.shadow
        self.recorder = LinkRecorder(state.n, state.t0_s, state.torus) if record else None

    def within_reach(self, distances_m: np.ndarray) -> np.ndarray:
        """Whether each distance is within the radio's reach (:attr:`reach_m`), by the one
        rule of in range (:func:`netsim.radio._kernels.in_disk`)."""
        d = np.ascontiguousarray(distances_m, float)
        out = np.empty(d.shape[0], bool)
        load("netsim.radio._kernels", self.state.n).in_disks(d, self.reach_m, out)
        return out

    def decide(
        self, t: float, sender: int, receivers: np.ndarray, distances_m: np.ndarray, every_pair: bool = True
    ) -> np.ndarray:
        """Mask of ``receivers`` (at ``distances_m`` from ``sender``) that hear ``sender`` at
        ``t``. ``every_pair``: ``receivers`` are all the robots within reach (a broadcast),
        so the decision tells the state of every link of ``sender``; False: of these pairs
        alone (a unicast's destination)."""
        linked = self.compiled.transmission(self.state, t, sender, receivers, distances_m)
        if self.recorder is not None:
            if every_pair:
                self.recorder.observe(t, sender, receivers, linked)
            else:
                for r, ok in zip(receivers.tolist(), linked.tolist()):
                    self.recorder.observe_pair(t, sender, r, bool(ok))
        return linked

    def received_dbm(self, t: float, sender: int, receivers: np.ndarray, distances_m: np.ndarray) -> np.ndarray:
        """Power (dBm) at ``receivers`` of ``sender``'s frame at ``t``, as the decision just
        made for these pairs saw it: path loss, each pair's shadowing as it stands (no new
        draw: call it right after :meth:`decide` on the same pairs) and walls. A medium's
        signal: a frame the radio kept is then at or above the sensitivity."""
        c = self.compiled
        if c.log is None:
            raise ValueError("received power needs a log-distance radio")
        k = len(receivers)
        x = _NONE
        if c.shadow is not None and c.shadow.sigma_db > 0 and k:
            x, _ = c.shadow.state(np.full(k, sender, dtype=np.int64), receivers)
        st = self.state
        motion = tuple(Motion(st.origin_m, st.velocity_mps, st.t0_s, st.torus, st.side_m))
        flat = c.occupancy.occupied.ravel() if c.occupancy is not None else _NO_CELLS
        out = np.empty(k)
        c.k.received_pass(c.frame, t, sender, receivers, np.asarray(distances_m, dtype=float), x, motion, flat, out)
        return out
