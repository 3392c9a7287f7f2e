"""Robots' own traffic through the simulated channel.

A message robot ``i`` publishes on ``/robot_i/tx/<name>`` is one broadcast frame of the
run's channel, sent at the simulated instant the bridge takes it: the channel decides
who receives it (range, walls, shadowing, the loss model), delivers it after its latency
and, on a shared medium (``channel.mac``), makes it take the airtime of its serialized
size (CDR, as DDS sends it) and contend and collide with the protocol's frames. Each
reception is a row of ``relay.parquet``; the bridge publishes it on ``/robot_j/rx/<name>``.

A topic's frames are of the channel's kind ``relay/<name>``, so they are counted as the
other kinds are (sent, received, dropped by cause).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

RELAY_COLUMNS = {
    "msg_id": "int64",
    "topic": "object",
    "src": "int64",
    "dst": "int64",
    "nbytes": "int64",
    "t_sent_s": "float64",
    "t_received_s": "float64",
}


class ChannelRelay:
    """Sends relayed messages on the run's channel; keeps what arrived until taken."""

    def __init__(self, sim: Any, names: list[str]):
        self.sim, self.channel = sim, sim.channel
        for name in names:
            # The medium needs a size per kind before anything is sent; each send sets its own.
            self.channel.frame_bytes.setdefault(self.kind(name), 1)
        self.sent = 0
        self._rows: list[tuple] = []
        self._arrived: list[tuple[int, str, Any]] = []

    @staticmethod
    def kind(name: str) -> str:
        return f"relay/{name}"

    def send(self, src: int, name: str, message: Any, nbytes: int) -> int:
        """Broadcast ``message`` (``nbytes`` on the air) from robot ``src`` now; its id."""
        msg_id = self.sent
        self.sent += 1
        kind = self.kind(name)
        # The medium reads the size when the frame is queued, which is now.
        self.channel.frame_bytes[kind] = int(nbytes)
        payload = (msg_id, name, message, int(nbytes), self.sim.now)
        self.channel.broadcast(src, payload, self._deliver, kind=kind)
        return msg_id

    def _deliver(self, sender: int, receivers: np.ndarray, payload: tuple, *_power: Any) -> None:
        msg_id, name, message, nbytes, t_sent = payload
        now = self.sim.now
        for j in receivers.tolist():
            self._rows.append((msg_id, name, sender, j, nbytes, t_sent, now))
            self._arrived.append((j, name, message))

    def take(self) -> list[tuple[int, str, Any]]:
        """The receptions since the last call: ``(robot, topic name, message)``."""
        out, self._arrived = self._arrived, []
        return out

    def frame(self) -> pd.DataFrame:
        """Every reception so far, one row each, in order of arrival."""
        df = pd.DataFrame(self._rows, columns=list(RELAY_COLUMNS))
        return df.astype(RELAY_COLUMNS)
