"""A user's own medium access control: TDMA, the example of docs/plugins.md, tested end to
end by tests/test_channel_plugins.py.

Time is cut into cycles of ``tdma_slots`` slots of ``tdma_slot_s`` each (0 slots: one per
robot); robot ``i`` owns slot ``i mod tdma_slots`` of every cycle and sends the first frame
of its queue when its slot starts, one frame per slot. With a slot per robot nothing
collides, so a frame on the air is the channel's own decision
(:meth:`netsim.radio.channel.Channel.on_air`).
"""

import math
from collections import deque
from dataclasses import dataclass

import numpy as np
import pandas as pd

from netsim.errors import ConfigError
from netsim.params import Params, finite, non_negative, param, positive
from netsim.radio.channel import DROP_CAUSES
from netsim.radio.models import MacModel


@dataclass(frozen=True)
class TdmaParams(Params):
    section = "channel"
    tdma_slot_s: float = param(0.002, finite(positive), "tdma: length of a slot (one frame), s")
    tdma_slots: int = param(0, non_negative, "tdma: slots per cycle (0: one per robot)")


class Tdma:
    """The medium: a queue per robot, emptied one frame per own slot."""

    causes = DROP_CAUSES  # nothing collides: the channel's own causes

    def __init__(self, params: TdmaParams, channel):
        self.channel = channel
        self.env = channel.env
        n = channel.state.n
        self.slot_s = params.tdma_slot_s
        self.slots = params.tdma_slots or max(n, 1)
        self.queue = [deque() for _ in range(n)]
        self.frames_sent = np.zeros(n, dtype=np.int64)

    def slot_start(self, robot: int, after_s: float) -> float:
        """The first start of ``robot``'s slot at or after ``after_s``."""
        cycle_s = self.slot_s * self.slots
        offset_s = (robot % self.slots) * self.slot_s
        k = math.ceil((after_s - offset_s) / cycle_s - 1e-9)
        return k * cycle_s + offset_s

    def send(self, sender: int, dest: int, payload, deliver, kind: str) -> np.ndarray:
        q = self.queue[sender]
        q.append((dest, payload, deliver, kind))
        if len(q) == 1:
            self._wait(sender, self.env.now)
        return np.array([sender])

    def _wait(self, robot: int, after_s: float) -> None:
        at = self.slot_start(robot, after_s)
        self.env.timeout(at - self.env.now).callbacks.append(lambda _ev: self._slot(robot))

    def _slot(self, robot: int) -> None:
        dest, payload, deliver, kind = self.queue[robot].popleft()
        self.channel.on_air(robot, dest, payload, deliver, kind)
        self.frames_sent[robot] += 1
        if self.queue[robot]:
            self._wait(robot, self.env.now + self.slot_s)

    def summary(self, now: float) -> dict:
        return {"mac": "tdma", "tdma_frames": int(self.frames_sent.sum())}

    def frame(self) -> pd.DataFrame:
        return pd.DataFrame({"robot": np.arange(len(self.frames_sent)), "frames_sent": self.frames_sent})


def check(params: TdmaParams, channel) -> None:
    if params.tdma_slots and params.tdma_slot_s * params.tdma_slots > 10.0:
        raise ConfigError("channel.tdma_slots", params.tdma_slots, "a cycle must last at most 10 s")


PLUGIN = MacModel(
    TdmaParams,
    build=lambda params, channel, rng, power: Tdma(params, channel),
    airtime_s=lambda params, nbytes: params.tdma_slot_s,
    tables=lambda tables: {**tables, "medium": {"robot": "int64", "frames_sent": "int64"}},
    check=check,
)
