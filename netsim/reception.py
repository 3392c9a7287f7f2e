"""The radio's reception decision inside the channel, and the record of its decisions.

:class:`Reception` asks a :class:`~netsim.radio.propagation.Propagation` (compiled,
:class:`~netsim.radio.fast.CompiledChain`) which of a transmission's candidate receivers
(every robot within the radio's reach) can hear it: path loss or range, then shadowing,
then walls, each pair dropped as soon as it cannot make it. Shadowing is looked at then,
at the pair's travel (the sum of both robots' path lengths), from the channel's own
stream ``channel.shadowing``.

Under shadowing a link has no solvable up and down times (see docs/radio.md): the links
table is then the record of these decisions (:class:`LinkRecorder`): every decision is
symmetric (path loss, shadowing and walls are the same both ways, and every robot sends
with the same power), so each transmission tells the state of the sender's link with each
robot within reach.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from netsim.radio import compiled_kernels
from netsim.radio.fast import CompiledChain
from netsim.radio.propagation import Pairs, Propagation
from netsim.state import RobotState


def _link_changes():
    k = compiled_kernels()
    return None if k is None else k.link_changes


class LinkRecorder:
    """Links as the channel decides them: up from the first transmission between two robots
    (either way) that gets through, down at the first that does not, or when one of them
    sends while the other is beyond reach."""

    def __init__(self, n: int):
        self.n = n
        self.up = np.zeros((n, n), dtype=bool)
        self._since: dict[tuple[int, int], float] = {}
        self._rows: list[tuple[int, int, float, float]] = []
        self._scratch = np.zeros(n, dtype=bool)
        self._changed = np.empty(n, dtype=np.int64)
        self._kernel = _link_changes()
        # Called as fn(t, sender, robots, up) with every decision that changes links (lists:
        # the robots whose link with sender changed, and whether it is now up).
        self.listeners: list = []

    def observe(self, t: float, sender: int, receivers: np.ndarray, linked: np.ndarray) -> None:
        count = self._changes(sender, receivers, linked)
        if count == 0:
            return
        changed = self._changed[:count]
        now = ~self.up[sender, changed]
        robots, is_now_up = changed.tolist(), now.tolist()
        for fn in self.listeners:
            fn(t, sender, robots, is_now_up)
        for r, is_up in zip(robots, is_now_up):
            key = (sender, r) if sender < r else (r, sender)
            if is_up:
                self._since[key] = t
            else:
                self._rows.append((key[0], key[1], self._since.pop(key), t))
        self.up[sender, changed] = now
        self.up[changed, sender] = now

    def _changes(self, sender: int, receivers: np.ndarray, linked: np.ndarray) -> int:
        """How many robots' links with ``sender`` this decision changes (ids in ``_changed``)."""
        if self._kernel is not None:
            return int(self._kernel(self.up, sender, receivers, linked, self._scratch, self._changed))
        now = np.zeros(self.n, dtype=bool)
        now[receivers[linked]] = True
        changed = np.flatnonzero(self.up[sender] != now)
        self._changed[: len(changed)] = changed
        return len(changed)

    def intervals(self, duration_s: float) -> pd.DataFrame:
        """``a, b, t_up_s, t_down_s, open`` (still up at the end: ``t_down_s`` = duration)."""
        rows = self._rows + [(a, b, t, duration_s) for (a, b), t in self._since.items()]
        df = pd.DataFrame(rows, columns=["a", "b", "t_up_s", "t_down_s"])
        df["open"] = np.r_[np.zeros(len(self._rows), bool), np.ones(len(self._since), bool)]
        return df.astype({"a": np.int64, "b": np.int64, "t_up_s": float, "t_down_s": float})


class Reception:
    """Which candidate receivers hear a frame, for one run."""

    def __init__(self, propagation: Propagation, state: RobotState, record: bool = False):
        self.propagation = propagation
        self.compiled = CompiledChain(propagation)
        self.state = state
        self.reach_m = float(propagation.reach_m)
        self.map = self.compiled.occupancy
        self.shadowing = self.compiled.shadow
        self.recorder = LinkRecorder(state.n) if record else None
        # Every robot's speed, kept as legs change: the shadowing's clock is the pairs' travel.
        self.speed_mps = np.abs(state.velocity_c)
        if self.shadowing is not None:
            state.watchers.append(self._course_changed)

    def _course_changed(self, robot: int, t: float, jump: bool) -> None:
        # A one-item slice: numpy's array abs, the one state.travelled_m uses.
        self.speed_mps[robot] = np.abs(self.state.velocity_c[robot : robot + 1])[0]

    def decide(self, t: float, sender: int, receivers: np.ndarray, distances_m: np.ndarray) -> np.ndarray:
        """Mask of ``receivers`` (at ``distances_m`` from ``sender``) that hear ``sender`` at ``t``."""
        linked = self.compiled.transmission(self.state, t, sender, receivers, distances_m, self.speed_mps)
        if self.recorder is not None:
            self.recorder.observe(t, sender, receivers, linked)
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
        pairs = Pairs(np.full(k, sender, dtype=np.int64), receivers, None, None, distances_m, None)
        loss = c.log.loss_db(pairs)
        if c.shadow is not None and c.shadow.sigma_db > 0 and k:
            x, _ = c.shadow.state(pairs.a, receivers)
            loss = loss + np.clip(np.nan_to_num(x), -c.shadow.clip_db, c.shadow.clip_db)
        if c.walls is not None and k:
            loss = loss + c.walls.loss_db(c._pairs(self.state, t, sender, receivers, distances_m))
        return self.propagation.tx_power_dbm - loss
