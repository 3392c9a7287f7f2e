"""The wireless channel: the only place that knows range, delay and loss.

A transmission from robot ``i`` at time ``t`` reaches the robots within ``i``'s range at
``t`` (so unequal ranges make some links one-way), minus the receptions the loss model
drops. Receivers are decided at send time, in one numpy operation, and handed to the
receiving protocol in bulk: with a fixed latency a broadcast costs one delivery event,
whatever the number of receivers; with jitter every reception has its own event.

Deliveries run at URGENT priority, ahead of timers due at the same instant. They are
entries of the channel's :class:`~netsim.agenda.Agenda` (which the Ack beacons share for
their ticks): run in exactly the order of one kernel event each, without the cost of one.

Every transmission, reception and drop is counted per robot, per message kind, and per
drop cause:

- ``loss``: the loss model dropped it;
- ``not_alive``: the receiver was switched off;
- ``out_of_range``: a unicast whose destination was not in range at send time (under a
  radio other than the plain unit disk: could not hear it, for walls or shadowing too).

With a radio (:class:`~netsim.radio.reception.Reception`: log-distance path loss, shadowing,
walls from a map) the receivers are decided by it among the robots within its reach, then
the loss model drops some: the reception is a chain, propagation, walls, shadowing, loss.
Without one (the plain unit disk) they are the robots within the sender's range.

With a shared medium (``channel.mac`` other than ``"none"``: :mod:`netsim.radio.mac`)
``broadcast`` and ``unicast`` hand the frame to it at once: it decides the receivers when
the frame goes on the air, the collisions at its end, and adds its own drop causes. Without
one, the code below runs as it always has.

A kind's deliveries can carry the power each receiver got the frame at
(:meth:`Channel.measure_power`: the Acks', for the neighbour tables), under a radio with a
log-distance law: computed once per frame, for its receivers, right after the radio decided
them (the power the decision saw). Under the unit disk there is none and no such work.

A kind's counts can also be kept over time (:meth:`Channel.bin_by_send_time`): per
interval of *send* time, so that each bin tells the fate of the transmissions sent in it
(a reception is counted, on arrival, in the bin its transmission was sent in).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
import pandas as pd
import simpy

from netsim.agenda import Agenda
from netsim.events import Delivery, Drop, EventBus, notify, read_only
from netsim.radio.loss import Survives
from netsim.radio.spatial import RangeIndex
from netsim.rng import KindStreams
from netsim.scheduling import URGENT
from netsim.state import RobotState

DROP_CAUSES = ("loss", "not_alive", "out_of_range")

# deliver(sender, receivers, payload): called at delivery time with the receiving ids; for a
# kind whose power is measured (Channel.measure_power), deliver(sender, receivers, payload,
# power_dbm), with the power each receiver got the frame at.
Deliver = Callable[..., None]


class Counters:
    """Per-robot counts for one message kind (``causes``: the channel's drop causes)."""

    def __init__(self, n: int, causes: tuple[str, ...] = DROP_CAUSES):
        self.causes = causes
        self.sent = np.zeros(n, dtype=np.int64)
        self.received = np.zeros(n, dtype=np.int64)
        self.dropped = np.zeros((len(causes), n), dtype=np.int64)

    def frame(self) -> pd.DataFrame:
        df = pd.DataFrame({"robot": np.arange(len(self.sent)), "sent": self.sent, "received": self.received})
        for c, cause in enumerate(self.causes):
            df[f"dropped_{cause}"] = self.dropped[c]
        return df


class SendTimeBins:
    """Counts of one message kind per interval ``[k dt, (k+1) dt)`` of send time:
    transmissions sent, receptions attempted (robots alive and in range at send time),
    received (counted on arrival, in the bin of the send), and dropped by cause."""

    COLUMNS = ("sent", "in_range", "received") + tuple(f"dropped_{c}" for c in DROP_CAUSES)
    SENT, IN_RANGE, RECEIVED, DROPPED = 0, 1, 2, 3

    def __init__(self, interval_s: float, causes: tuple[str, ...] = DROP_CAUSES):
        if not interval_s > 0:
            raise ValueError(f"a bin interval must be positive, got {interval_s}")
        self.interval_s = float(interval_s)
        self.columns = self.COLUMNS[: self.DROPPED] + tuple(f"dropped_{c}" for c in causes)
        # One list of Python ints per bin, up to the last bin asked for: adding to a count
        # (a few times per message) costs less than adding to a numpy element.
        self.rows: list[list[int]] = []
        # The bin last asked for by at(), and its edges: most sends fall in the same bin.
        self._lo, self._hi = 0.0, 0.0
        self._last: _Bin | None = None

    @property
    def counts(self) -> np.ndarray:
        """The counts so far, one row per bin (k = 0 up to the last bin asked for)."""
        out = np.zeros((len(self.rows), len(self.columns)), dtype=np.int64)
        if self.rows:
            out[:] = self.rows
        return out

    def at(self, t: float) -> _Bin:
        """The bin of time ``t`` (:meth:`bin`), as a :class:`_Bin` (the same object for every
        ``t`` within one bin: its edges are the same products as :meth:`bin` compares)."""
        last = self._last
        if last is not None and self._lo <= t < self._hi:
            return last
        k = self.bin(t)
        last = _Bin(self, k)
        self._lo, self._hi, self._last = k * self.interval_s, (k + 1) * self.interval_s, last
        return last

    def bin(self, t: float) -> int:
        """The bin of time ``t``: the ``k`` with ``k dt <= t < (k+1) dt``, the edges being
        the products ``k * dt`` (the same floats as the table's ``t_s``)."""
        dt = self.interval_s
        k = int(t // dt)
        if (k + 1) * dt <= t:
            k += 1
        elif k * dt > t:
            k -= 1
        while len(self.rows) <= k:
            self.rows.append([0] * len(self.columns))
        return k

    def frame(self, duration_s: float) -> pd.DataFrame:
        """One row per bin from 0 to ``duration_s`` (bins with nothing sent included)."""
        counted = self.counts
        used = np.flatnonzero(counted.any(axis=1))
        bins = max(int(math.ceil(duration_s / self.interval_s - 1e-9)), int(used[-1]) + 1 if len(used) else 0)
        counts = np.zeros((bins, len(self.columns)), dtype=np.int64)
        counts[: min(bins, len(counted))] = counted[:bins]
        df = pd.DataFrame({"t_s": np.arange(bins) * self.interval_s})
        for c, name in enumerate(self.columns):
            df[name] = counts[:, c]
        return df


class _Bin:
    """One bin of a kind's counts: its index ``k`` and its ``row`` of counts (the list
    itself, which stays the bin's as later bins are added)."""

    __slots__ = ("bins", "k", "row")

    def __init__(self, bins: SendTimeBins, k: int):
        self.bins = bins
        self.k = k
        self.row = bins.rows[k]

    def add(self, column: int, count: int) -> None:
        self.row[column] += count


class Channel:
    def __init__(
        self,
        env: simpy.Environment,
        state: RobotState,
        survives: Survives,
        latency_s: float,
        latency_jitter_s: float = 0.0,
        latency_rng: KindStreams | None = None,
        reception: Any = None,
        events: EventBus | None = None,
        loss_rng: KindStreams | None = None,
    ):
        self.env = env
        self.state = state
        # Deliveries, and the callbacks of whoever shares it (the Ack beacons' ticks).
        self.agenda = Agenda(env)
        # The radio (netsim.radio.reception.Reception), None for the plain unit disk.
        self.reception = reception
        self.index = RangeIndex(state, reach_m=None if reception is None else reception.reach_m)
        # The engine's loops (netsim._kernels), compiled or plain as the run has them.
        self.kernels = self.index.kernels
        self.survives = survives
        self.latency_s = float(latency_s)
        self.latency_jitter_s = float(latency_jitter_s)
        # Per kind of frame (netsim.rng.KindStreams): one kind's traffic leaves another's draws.
        self.latency_rng = latency_rng
        self.loss_rng = loss_rng
        if self.latency_jitter_s > 0 and latency_rng is None:
            raise ValueError("latency jitter needs a random stream")
        self.counters: dict[str, Counters] = {}
        self.bins: dict[str, SendTimeBins] = {}
        # The run's bus: "delivery" and "drop" events for whoever subscribes.
        self.events = events
        # Its subscribers to "delivery" (the bus's own list: it follows later subscriptions).
        self.on_delivery: list[Callable] = events.subscribers("delivery") if events is not None else []
        # The shared medium (netsim.radio.mac.Medium), None: infinite capacity, every
        # transmission decided at send time (the code below, unchanged by a MAC).
        self.mac: Any = None
        self.causes = DROP_CAUSES
        # Bytes of a frame of each kind (set by the protocols; the medium's airtime).
        self.frame_bytes: dict[str, int] = {}
        # Kinds whose senders want a delivery with no receivers when nobody got a frame
        # (under a medium only: receivers are known at the frame's end, not at send time).
        self.notify_empty: set[str] = set()
        # Per kind, called as (payload, cause, receptions) for what a medium loses of a
        # frame (cause "collision", "half_duplex"; "queue_full", "retry_limit" with 1).
        self.medium_losses: dict[str, Callable[[object, str, int], None]] = {}
        # The record of every reception (netsim.radio.receptions.ReceptionLog), None: none
        # kept, and no per-reception work. The frame being decided fills ``_rows``.
        self.receptions: Any = None
        self._rows: Any = None
        # Kinds whose deliveries carry each receiver's power (measure_power); empty without a
        # log-distance law.
        self.measured: set[str] = set()

    def measure_power(self, kind: str) -> bool:
        """Hand ``kind``'s deliveries the power (dBm) each receiver got the frame at, as a
        fourth argument of ``deliver``, when the radio has a power law (log-distance);
        returns whether it has (else deliveries stay as they are, and nothing is measured)."""
        rec = self.reception
        if rec is None or rec.compiled.log is None:
            return False
        self.measured.add(kind)
        return True

    def power_dbm(self, sender: int, kind: str, receivers: np.ndarray, dist: np.ndarray | None) -> np.ndarray | None:
        """The power at ``receivers`` (at ``dist``) of ``sender``'s frame of ``kind`` now, as
        the radio just decided them; None where ``kind`` is not measured."""
        if kind not in self.measured or dist is None:
            return None
        return self.reception.received_dbm(self.env.now, sender, receivers, dist)

    @property
    def survives(self) -> Survives:
        """The loss model (netsim.radio.loss): which receptions survive."""
        return self._survives

    @survives.setter
    def survives(self, survives: Survives) -> None:
        self._survives = survives
        # Whether a transmission needs its receivers' distances (else the range query skips
        # them): for the loss model (a callable without the flag is taken to read them).
        self._distances = getattr(survives, "uses_distances", True)

    @property
    def reach_lists(self) -> RangeIndex | None:
        """The range index, where its neighbour lists hold every robot a sender reaches:
        None under a radio (which decides its links otherwise)."""
        return self.index if self.reception is None else None

    def attach_mac(self, mac: Any) -> None:
        """Put every transmission from now on through the shared medium ``mac``."""
        if self.counters or self.bins:
            raise RuntimeError("attach the medium before anything is sent or counted")
        self.mac = mac
        self.causes = mac.causes

    @property
    def medium_causes(self) -> tuple[str, ...]:
        """The drop causes the medium adds to the channel's own (none without a medium)."""
        return self.causes[len(DROP_CAUSES) :]

    def on_air(self, sender: int, dest: int, payload: object, deliver: Deliver, kind: str) -> np.ndarray:
        """A medium's frame from ``sender`` going on the air now, with nothing to collide
        with (a slot of its own): counted as sent, received by the robots that hear it
        (``dest`` alone for a unicast, -1: a broadcast) and that the loss model spares,
        delivered once after the latency (one jitter draw per frame), to nobody if none
        got it and ``kind`` asks for that (:attr:`notify_empty`), as a medium delivers.
        Returns the receivers."""
        c = self.counters_for(kind)
        c.sent[sender] += 1
        binned = self._bin(kind)
        if dest < 0:
            receivers, dist = self._hearers(sender, kind, math.inf)
        else:
            heard, dist = self._unicast_hears(sender, dest, kind, math.inf)
            receivers = np.array([dest])
            if not heard:
                self._out_of_range(kind, sender, dest, c, binned)
                receivers = receivers[:0]
        power = None
        if len(receivers):
            receivers, kept = self._decide(sender, receivers, dist, c, kind, binned)
            if self.measured:
                power = self.power_dbm(sender, kind, receivers, kept)
        if self._rows is not None:
            self._close()
        delay = self.latency_s
        if self.latency_jitter_s > 0:
            assert self.latency_rng is not None  # checked when built
            delay += self.latency_rng.use(kind).random() * self.latency_jitter_s
        if len(receivers):
            self._at(delay, deliver, sender, receivers, payload, c, kind, binned, power)
        elif kind in self.notify_empty:
            self.agenda.at(delay, URGENT, deliver, sender, receivers, payload)
        return receivers

    @property
    def deferred(self) -> bool:
        """Whether receivers are decided at a frame's end (a medium), not at send time:
        ``broadcast`` then returns no receivers and ``unicast`` whether the frame was queued."""
        return self.mac is not None

    def counters_for(self, kind: str) -> Counters:
        c = self.counters.get(kind)
        if c is None:
            c = self.counters[kind] = Counters(self.state.n, self.causes)
        return c

    def bin_by_send_time(self, kind: str, interval_s: float) -> SendTimeBins:
        """Keep the counts of ``kind`` also per ``interval_s`` of send time, from now on."""
        bins = self.bins.get(kind)
        if bins is None:
            bins = self.bins[kind] = SendTimeBins(interval_s, self.causes)
        elif bins.interval_s != interval_s:
            raise ValueError(f"{kind!r} is already binned every {bins.interval_s} s")
        return bins

    def in_range(self, sender: int) -> tuple[np.ndarray, np.ndarray]:
        """Robots that can hear ``sender`` now (ids ascending) and their distances (under a
        radio with shadowing this looks at the shadowing, as a transmission does)."""
        return self._hearers(sender)

    def _hearers(
        self, sender: int, kind: str | None = None, sinr_db: float = math.nan
    ) -> tuple[np.ndarray, np.ndarray]:
        """The robots that hear ``sender`` now, and their distances; ``kind``: of a frame
        (its rows opened when receptions are recorded, their SINR ``sinr_db`` until the
        medium finds it), None: a query (:meth:`in_range`)."""
        now = self.env.now
        log = self.receptions if kind is not None else None
        if self.reception is None:
            receivers, dist = self.index.within(now, sender)
            if log is not None:
                self._rows = log.open(now, sender, kind, receivers, dist, None, sinr_db)
            return receivers, dist
        candidates, near = self.index.within(now, sender, self.reception.reach_m)
        receivers, dist, keep = candidates, near, None
        if len(candidates):
            keep = self.reception.decide(now, sender, candidates, near)
            receivers, dist = candidates[keep], near[keep]
        if log is not None:
            self._rows = log.open(now, sender, kind, candidates, near, keep, sinr_db)
        return receivers, dist

    def broadcast(self, sender: int, payload: object, deliver: Deliver, kind: str = "ack") -> np.ndarray:
        """Send ``payload`` from ``sender`` to everyone in range; returns the receivers."""
        if self.mac is not None:
            return self.mac.send(sender, -1, payload, deliver, kind)
        c = self.counters.get(kind) or self.counters_for(kind)
        c.sent[sender] += 1
        binned = self._bin(kind) if self.bins else None
        if self.receptions is not None:
            receivers, dist = self._hearers(sender, kind, math.inf)
            receivers = self._transmit(sender, receivers, dist, payload, deliver, c, kind, binned)
            self._close()
            return receivers
        if self.reception is not None:
            receivers, dist = self._hearers(sender)
        elif self._distances:
            receivers, dist = self.index.within(self.env.now, sender)
        else:
            # The common case (no radio, a loss model blind to distance): the range query
            # tells at once whether every receiver is alive, and measures no distance.
            receivers, all_alive = self.index.within_alive(self.env.now, sender)
            return self._transmit(sender, receivers, None, payload, deliver, c, kind, binned, all_alive)
        return self._transmit(sender, receivers, dist, payload, deliver, c, kind, binned)

    def unicast(self, sender: int, dest: int, payload: object, deliver: Deliver, kind: str = "data") -> bool:
        """Send ``payload`` to ``dest`` alone; returns whether it will be delivered."""
        if self.mac is not None:
            return bool(len(self.mac.send(sender, dest, payload, deliver, kind)))
        c = self.counters_for(kind)
        c.sent[sender] += 1
        binned = self._bin(kind)
        heard, dist = self._unicast_hears(sender, dest, kind, math.inf)
        if not heard:
            self._out_of_range(kind, sender, dest, c, binned)
            if self._rows is not None:
                self._close()
            return False
        got = self._transmit(sender, np.array([dest]), dist, payload, deliver, c, kind, binned)
        if self._rows is not None:
            self._close()
        return len(got) == 1

    def _close(self) -> None:
        """The frame whose rows are open is decided: keep them."""
        self.receptions.close(self._rows)
        self._rows = None

    def _unicast_hears(
        self, sender: int, dest: int, kind: str | None = None, sinr_db: float = math.nan
    ) -> tuple[bool, np.ndarray]:
        """Whether ``dest`` hears ``sender`` now (range, or the radio deciding this pair
        alone), and their distance (an array of one); ``kind``: of a frame (its row opened
        when receptions are recorded, as :meth:`_hearers`)."""
        st, now = self.state, self.env.now
        r = st.range_m[sender] if self.reception is None else self.reception.reach_m
        in_reach, d = self.index.pair_within(now, sender, dest, r)
        dist = np.array([d])
        if dest == sender or not in_reach:
            heard = False
        elif self.reception is None:
            heard = True
        else:
            heard = bool(self.reception.decide(now, sender, np.array([dest]), dist, every_pair=False)[0])
        if kind is not None and self.receptions is not None:
            self._rows = self.receptions.open(now, sender, kind, np.array([dest]), dist, np.array([heard]), sinr_db)
        return heard, dist

    def _out_of_range(self, kind: str, sender: int, dest: int, c: Counters, binned: _Bin | None) -> None:
        """Count a unicast whose destination could not hear it."""
        k = self.causes.index("out_of_range")
        c.dropped[k, dest] += 1
        if binned is not None:
            binned.add(SendTimeBins.DROPPED + k, 1)
        self._dropped(kind, sender, np.array([dest]), "out_of_range")

    def _bin(self, kind: str) -> _Bin | None:
        """``kind``'s bin of now, with one more transmission sent (None: not binned)."""
        bins = self.bins.get(kind)
        if bins is None:
            return None
        binned = bins.at(self.env.now)
        binned.row[SendTimeBins.SENT] += 1
        return binned

    def _dropped(self, kind: str, sender: int, receivers: np.ndarray, cause: str) -> None:
        ev = self.events
        if ev is not None and ev.wants("drop"):
            ev.emit("drop", Drop(self.env.now, kind, sender, read_only(receivers), cause))

    def _transmit(
        self,
        sender: int,
        receivers: np.ndarray,
        dist: np.ndarray | None,
        payload: object,
        deliver: Deliver,
        c: Counters,
        kind: str,
        binned: _Bin | None = None,
        all_alive: bool | None = None,
    ) -> np.ndarray:
        if len(receivers) == 0:
            return receivers
        receivers, dist = self._decide(sender, receivers, dist, c, kind, binned, all_alive)
        if len(receivers) == 0:
            return receivers
        power = self.power_dbm(sender, kind, receivers, dist) if self.measured else None
        if self.latency_jitter_s > 0:
            assert self.latency_rng is not None  # checked when built
            delays = self.latency_s + self.latency_rng.use(kind).random(len(receivers)) * self.latency_jitter_s
            for k, (r, delay) in enumerate(zip(receivers.tolist(), delays.tolist())):
                one = None if power is None else power[k : k + 1]
                self._at(delay, deliver, sender, np.array([r]), payload, c, kind, binned, one)
        else:
            self._at(self.latency_s, deliver, sender, receivers, payload, c, kind, binned, power)
        return receivers

    def _decide(
        self,
        sender: int,
        receivers: np.ndarray,
        dist: np.ndarray | None,
        c: Counters,
        kind: str,
        binned: _Bin | None,
        all_alive: bool | None = None,
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """The receivers (and distances: None when not measured) alive and spared by the loss
        model; the others counted. ``all_alive``: whether all are alive, if known already."""
        if all_alive is None:
            # Everyone alive is the common case: the loop's check makes no temporary array.
            all_alive = self.kernels.all_set(self.state.alive, receivers)
        if not all_alive:
            alive = self.state.alive[receivers]
            receivers, dist = self._drop_all_but(alive, "not_alive", sender, receivers, dist, c, kind, binned)
        if binned is not None:
            binned.row[SendTimeBins.IN_RANGE] += len(receivers)
        if self.loss_rng is not None:
            self.loss_rng.use(kind)
        keep = self._survives(sender, receivers, dist)
        if keep is not None and not keep.all():
            receivers, dist = self._drop_all_but(keep, "loss", sender, receivers, dist, c, kind, binned)
        return receivers, dist

    def _drop_all_but(
        self,
        keep: np.ndarray,
        cause: str,
        sender: int,
        receivers: np.ndarray,
        dist: np.ndarray | None,
        c: Counters,
        kind: str,
        binned: _Bin | None,
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """The receivers (and distances) where ``keep``; the others counted and told as
        dropped for ``cause``."""
        k = DROP_CAUSES.index(cause)
        lost = receivers[~keep]
        self.kernels.count_each(c.dropped[k], lost)
        if binned is not None:
            binned.add(SendTimeBins.DROPPED + k, len(lost))
        if self._rows is not None:
            self._rows.mark(lost, k)
        self._dropped(kind, sender, lost, cause)
        return receivers[keep], (dist[keep] if dist is not None else None)

    def _at(
        self,
        delay: float,
        deliver: Deliver,
        sender: int,
        receivers: np.ndarray,
        payload: object,
        c: Counters,
        kind: str,
        binned: _Bin | None = None,
        power_dbm: np.ndarray | None = None,
    ) -> None:
        # At URGENT priority, on the agenda: where a kernel event scheduled now would run.
        # Deliveries at the channel's latency come in the order they are due: queued.
        arrive: Callable[..., None]
        if power_dbm is not None:
            # The receivers' power handed on as deliver's fourth argument.
            payload = (payload, power_dbm)
            arrive = self._arrive_measured
        else:
            arrive = self._arrive
        if delay == self.latency_s:
            self.agenda.at_in_order(delay, URGENT, arrive, deliver, sender, receivers, payload, c, kind, binned)
        else:
            self.agenda.at(delay, URGENT, arrive, deliver, sender, receivers, payload, c, kind, binned)

    def _arrive(
        self,
        deliver: Deliver,
        sender: int,
        receivers: np.ndarray,
        payload: object,
        counters: Counters,
        kind: str,
        binned: _Bin | None,
    ) -> None:
        """A delivery's arrival: count the receptions, tell the bus, hand them to the protocol."""
        self.kernels.count_each(counters.received, receivers)
        if binned is not None:
            binned.row[SendTimeBins.RECEIVED] += len(receivers)
        on_delivery = self.on_delivery
        if on_delivery:
            delivery = Delivery(self.env.now, kind, sender, read_only(receivers), payload)
            notify(on_delivery, delivery)
        deliver(sender, receivers, payload)

    def _arrive_measured(
        self,
        deliver: Deliver,
        sender: int,
        receivers: np.ndarray,
        measured: tuple[object, np.ndarray],
        counters: Counters,
        kind: str,
        binned: _Bin | None,
    ) -> None:
        """:meth:`_arrive` of a measured kind: ``measured`` the payload and the receivers' power."""
        payload, power_dbm = measured
        self._arrive(lambda s, r, p: deliver(s, r, p, power_dbm), sender, receivers, payload, counters, kind, binned)

    def frame(self, kind: str) -> pd.DataFrame:
        return self.counters_for(kind).frame()
