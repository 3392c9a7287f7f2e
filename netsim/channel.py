"""The wireless channel: the only place that knows range, delay and loss.

A transmission from robot ``i`` at time ``t`` reaches the robots within ``i``'s range at
``t`` (so unequal ranges make some links one-way), minus the receptions the loss model
drops. Receivers are decided at send time, in one numpy operation, and handed to the
receiving protocol in bulk: with a fixed latency a broadcast costs one kernel event,
whatever the number of receivers; with jitter every reception has its own event.

Deliveries run at URGENT priority, ahead of timers due at the same instant.

Every transmission, reception and drop is counted per robot, per message kind, and per
drop cause:

- ``loss``: the loss model dropped it;
- ``not_alive``: the receiver was switched off;
- ``out_of_range``: a unicast whose destination was not in range at send time (under a
  radio other than the plain unit disk: could not hear it, for walls or shadowing too).

With a radio (:class:`~netsim.reception.Reception`: log-distance path loss, shadowing,
walls from a map) the receivers are decided by it among the robots within its reach, then
the loss model drops some: the reception is a chain, propagation, walls, shadowing, loss.
Without one (the plain unit disk) they are the robots within the sender's range.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pandas as pd
import simpy

from netsim.events import URGENT, scheduled_event
from netsim.spatial import RangeIndex
from netsim.state import RobotState

DROP_CAUSES = ("loss", "not_alive", "out_of_range")

# deliver(sender, receivers, payload): called at delivery time with the receiving ids.
Deliver = Callable[[int, np.ndarray, object], None]


class Counters:
    """Per-robot counts for one message kind."""

    def __init__(self, n: int):
        self.sent = np.zeros(n, dtype=np.int64)
        self.received = np.zeros(n, dtype=np.int64)
        self.dropped = np.zeros((len(DROP_CAUSES), n), dtype=np.int64)

    def frame(self) -> pd.DataFrame:
        df = pd.DataFrame({"robot": np.arange(len(self.sent)), "sent": self.sent, "received": self.received})
        for c, cause in enumerate(DROP_CAUSES):
            df[f"dropped_{cause}"] = self.dropped[c]
        return df


class Channel:
    def __init__(
        self,
        env: simpy.Environment,
        state: RobotState,
        survives: Callable[[int, np.ndarray, np.ndarray], np.ndarray],
        latency_s: float,
        latency_jitter_s: float = 0.0,
        latency_rng: np.random.Generator | None = None,
        reception=None,
    ):
        self.env = env
        self.state = state
        self.reception = reception
        self.index = RangeIndex(state, reach_m=None if reception is None else reception.reach_m)
        self.survives = survives
        self.latency_s = float(latency_s)
        self.latency_jitter_s = float(latency_jitter_s)
        self.latency_rng = latency_rng
        if self.latency_jitter_s > 0 and latency_rng is None:
            raise ValueError("latency jitter needs a random stream")
        self.counters: dict[str, Counters] = {}

    def counters_for(self, kind: str) -> Counters:
        c = self.counters.get(kind)
        if c is None:
            c = self.counters[kind] = Counters(self.state.n)
        return c

    def in_range(self, sender: int):
        """Robots that can hear ``sender`` now (ids ascending) and their distances (under a
        radio with shadowing this looks at the shadowing, as a transmission does)."""
        return self._hearers(sender)

    def _hearers(self, sender: int):
        now = self.env.now
        if self.reception is None:
            return self.index.within(now, sender)
        receivers, dist = self.index.within(now, sender, self.reception.reach_m)
        if len(receivers):
            keep = self.reception.decide(now, sender, receivers, dist)
            receivers, dist = receivers[keep], dist[keep]
        return receivers, dist

    def broadcast(self, sender: int, payload, deliver: Deliver, kind: str = "ack") -> np.ndarray:
        """Send ``payload`` from ``sender`` to everyone in range; returns the receivers."""
        c = self.counters_for(kind)
        c.sent[sender] += 1
        receivers, dist = self._hearers(sender)
        return self._transmit(sender, receivers, dist, payload, deliver, c)

    def unicast(self, sender: int, dest: int, payload, deliver: Deliver, kind: str = "data") -> bool:
        """Send ``payload`` to ``dest`` alone; returns whether it will be delivered."""
        c = self.counters_for(kind)
        c.sent[sender] += 1
        st = self.state
        now = self.env.now
        d = st.displacement(st.positions_at(now, [dest]), st.positions_at(now, [sender]))
        dist = np.hypot(d[:, 0], d[:, 1])
        if self.reception is None:
            heard = dest != sender and dist[0] <= st.range_m[sender]
        else:
            heard = self._hears(sender, dest, dist)
        if not heard:
            c.dropped[DROP_CAUSES.index("out_of_range"), dest] += 1
            return False
        got = self._transmit(sender, np.array([dest]), dist, payload, deliver, c)
        return len(got) == 1

    def _hears(self, sender: int, dest: int, dist: np.ndarray) -> bool:
        if dest == sender or dist[0] > self.reception.reach_m:
            return False
        return bool(self.reception.decide(self.env.now, sender, np.array([dest]), dist)[0])

    def _transmit(self, sender, receivers, dist, payload, deliver, c: Counters) -> np.ndarray:
        if len(receivers) == 0:
            return receivers
        alive = self.state.alive[receivers]
        if not alive.all():
            np.add.at(c.dropped[1], receivers[~alive], 1)
            receivers, dist = receivers[alive], dist[alive]
        keep = self.survives(sender, receivers, dist)
        if keep is not None and not keep.all():
            np.add.at(c.dropped[0], receivers[~keep], 1)
            receivers = receivers[keep]
        if len(receivers) == 0:
            return receivers
        if self.latency_jitter_s > 0:
            delays = self.latency_s + self.latency_rng.random(len(receivers)) * self.latency_jitter_s
            for r, delay in zip(receivers.tolist(), delays.tolist()):
                self._at(delay, deliver, sender, np.array([r]), payload, c)
        else:
            self._at(self.latency_s, deliver, sender, receivers, payload, c)
        return receivers

    def _at(self, delay, deliver: Deliver, sender, receivers, payload, c: Counters) -> None:
        def arrive(_event):
            c.received[receivers] += 1
            deliver(sender, receivers, payload)

        scheduled_event(self.env, delay, URGENT, arrive)

    def frame(self, kind: str) -> pd.DataFrame:
        return self.counters_for(kind).frame()
