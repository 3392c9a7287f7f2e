"""The shared medium: frames take airtime, overlapping frames collide, CSMA senses and defers.

Under ``channel.mac = "aloha"`` or ``"csma"`` the channel hands every frame to a
:class:`Medium` (docs/radio.md, "Shared medium"): the airtime, the collisions and a frame's
end, common to both, with an access policy (:class:`Aloha`, :class:`Csma`) deciding when a
robot's head frame goes on the air and whether a failed unicast is sent again. A frame of
``b`` bytes occupies the medium for ``preamble_s + 8 b / data_rate_bps`` from the instant its
sender puts it on the air:

- ``aloha``: at once (after the sender's own earlier frames: a radio sends one frame at a time);
- ``csma``: 802.11 DCF. The robot draws a backoff of ``U{0..cw}`` slots, counts it down
  while the medium has been idle for ``difs_s``, freezes it while the medium is busy and
  resumes after ``difs_s`` of idle medium; a failed unicast doubles ``cw`` (up to
  ``cw_max``) and is sent again, at most ``retry_limit`` times.

The receivers are the robots that hear the sender when the frame starts (range or radio,
then the loss model), as without a medium; the frame's end decides which of them got it:

- ``half_duplex``: the receiver transmitted during the frame;
- ``collision``: under the unit disk, another frame whose sender is within
  ``interference_range_m`` of the receiver overlapped it; under ``log_distance``, the
  signal-to-interference-plus-noise ratio fell below ``capture_threshold_db`` at some
  instant of the frame (the stronger frame may survive).

Deliveries happen at the frame's end plus the channel latency, all receivers of a frame
together (one jitter draw per frame). A robot senses the medium busy while it transmits or
while a frame whose sender is within ``interference_range_m`` is on the air.

Events are O(1) per frame: its start (CSMA: one kernel event for the earliest pending
transmission of all robots, recomputed as counters freeze and resume, never one per slot)
and its end. Each decision is a handful of numpy operations over the robots within
interference range of the sender.
"""

from __future__ import annotations

import heapq
import math
from collections import deque
from typing import Any

import numpy as np
import pandas as pd
import simpy

from netsim.compiled import load
from netsim.radio._mac_kernels import Ends, Leaving, MediumArrays
from netsim.radio.chain import Radio, in_db, linear, path_loss_db
from netsim.radio.channel import DROP_CAUSES, Channel, SendTimeBins
from netsim.radio.spatial import RangeIndex
from netsim.scheduling import URGENT, scheduled_event

# Causes a medium adds: per reception (collision, half_duplex), per frame at its sender's row
# (queue_full: the queue was full when it was handed over; retry_limit: a unicast that
# failed every attempt).
MAC_CAUSES = ("collision", "half_duplex", "queue_full", "retry_limit")
MAC_DROP_CAUSES = DROP_CAUSES + MAC_CAUSES
RECEPTION_CAUSES = ("loss", "collision", "half_duplex")

_EMPTY = np.empty(0, dtype=np.int64)
_NO_SINR = np.empty(0)  # what a frame's end reads as SINR without a power model
# Transmit instants computed from the same idle instant and slot count are equal floats;
# this absorbs the kernel's now + (t - now) rounding.
_EPS_S = 1e-12


def airtime_s(nbytes: int, data_rate_bps: float, preamble_s: float) -> float:
    """How long a frame of ``nbytes`` occupies the medium, s.

    >>> airtime_s(64, 1e6, 192e-6)
    0.000704
    """
    return preamble_s + nbytes * 8.0 / data_rate_bps


class Frame:
    """One frame handed to the medium, with what its end needs to decide it."""

    __slots__ = (
        "sender",
        "dest",
        "kind",
        "payload",
        "deliver",
        "counters",
        "binned",
        "airtime_s",
        "seq",
        "receivers",
        "hd_start",
        "col_start",
        "interferers",
        "power_mw",
        "signal_mw",
        "rx_mw",
        "peak_mw",
        "power_dbm",
        "rows",
    )

    def __init__(self, sender, dest, kind, payload, deliver, counters, binned, airtime):
        self.sender, self.dest, self.kind, self.payload = sender, dest, kind, payload
        self.deliver, self.counters, self.binned, self.airtime_s = deliver, counters, binned, airtime
        self.seq = 0
        self.receivers = _EMPTY
        self.hd_start = self.col_start = np.empty(0, dtype=bool)
        self.interferers = _EMPTY
        self.power_mw = self.signal_mw = self.rx_mw = self.peak_mw = np.empty(0)
        # Its receivers' power (dBm) when its kind's is measured (Channel.measure_power).
        self.power_dbm = None
        # Its receptions' rows while it is decided (netsim.radio.receptions), None: not recorded.
        self.rows = None


class PowerModel:
    """Mean received power for SINR sums: the radio's ``P_t`` less the path loss
    (:func:`netsim.radio.chain.path_loss_db`, the chain's own law), no shadowing or walls.
    ``params``: the log-distance keys (:class:`~netsim.radio.propagation.LogDistanceParams`)."""

    def __init__(self, params: Any, noise_floor_dbm: float, capture_threshold_db: float):
        self.params = params
        self.radio: Radio = params.radio
        self.sensitivity_dbm = self.radio.sensitivity_dbm
        self.noise_mw = linear(noise_floor_dbm)
        self.capture_threshold_db = float(capture_threshold_db)
        # Where the mean received power falls to the noise floor.
        margin = self.radio.tx_power_dbm - params.reference_loss_db - noise_floor_dbm
        kernels = load("netsim._kernels", 1)
        self.noise_range_m = float(
            kernels.range_at_margin_m(float(margin), params.reference_distance_m, params.path_loss_exponent)
        )

    def received_mw(self, distance_m: np.ndarray, n_robots: int | None = None) -> np.ndarray:
        """Mean power (mW) at each distance, as a team of ``n_robots`` computes it."""
        return linear(self.radio.received_dbm(path_loss_db(distance_m, self.params, n_robots)))


class Aloha:
    """ALOHA's access: a robot puts its head frame on the air at once (after its own earlier
    frames: a radio sends one frame at a time), and never sends a frame again."""

    name = "aloha"

    def __init__(self, medium: Medium, params: Any):
        self.medium = medium

    def contend(self, i: int) -> None:
        """Robot ``i`` has a new head frame."""
        if not self.medium.transmitting[i]:
            self.medium._start(i)

    def started(self, i: int) -> None:
        """Robot ``i`` put its head frame on the air."""

    def sensed_busy(self, robots: np.ndarray, now: float) -> None:
        """The medium turned busy at ``robots``."""

    def unicast_failed(self, i: int) -> str:
        """Robot ``i``'s unicast reached nobody: ``"again"`` (send it again), ``"drop"``
        (given up: a ``retry_limit`` drop) or ``"done"``."""
        return "done"

    def frame_done(self, i: int) -> None:
        """Robot ``i``'s head frame left its queue."""

    def ended(self, i: int, newly_idle: np.ndarray, now: float) -> None:
        """Robot ``i``'s frame left the air; ``newly_idle`` sense the medium idle again."""
        if self.medium.queue[i]:
            self.medium._start(i)


class Csma:
    """CSMA/DCF's access (module notes): backoff counted down over idle slots, frozen while
    the medium is busy, doubled on a failed unicast, which is sent again up to the retry
    limit. ``params``: :class:`~netsim.radio.mac_models.CsmaParams`."""

    name = "csma"

    def __init__(self, medium: Medium, params: Any):
        self.medium = medium
        n = medium.state.n
        self.slot_s, self.difs_s = float(params.slot_s), float(params.difs_s)
        self.cw_min, self.cw_max = int(params.cw_min), int(params.cw_max)
        self.retry_limit = int(params.retry_limit)
        # Slots left (-1: nothing to send), instant the count runs from (inf: frozen),
        # transmit instant (inf: none), contention window and retries of the head frame.
        self.backoff = np.full(n, -1, dtype=np.int64)
        self.count_from = np.full(n, math.inf)
        self.tx_at = np.full(n, math.inf)
        # (transmit instant, robot) for every finite instant set, stale ones left in place
        # (valid while tx_at still holds it): the earliest without an O(N) scan per wake-up.
        self._due: list[tuple[float, int]] = []
        self.cw = np.full(n, self.cw_min, dtype=np.int64)
        self.retries = np.zeros(n, dtype=np.int64)
        self._wake_token = 0
        self._wake_at = math.inf

    def contend(self, i: int) -> None:
        m = self.medium
        self.backoff[i] = m.rng.integers(self.cw[i] + 1)
        if m._kernels.senses_idle(m.cover, m.transmitting, i):
            self._count_down(np.array([i]), m.env.now)

    def started(self, i: int) -> None:
        self.tx_at[i] = math.inf
        self.backoff[i] = -1
        self.count_from[i] = math.inf

    def _count_down(self, robots: np.ndarray, now: float) -> None:
        """``robots`` sense the medium idle from ``now``: their backoffs count down after
        DIFS, and the earliest transmit instant wakes the medium."""
        self.count_from[robots] = now + self.difs_s
        self.tx_at[robots] = self.count_from[robots] + self.backoff[robots] * self.slot_s
        at = self.tx_at[robots].tolist()
        for r, t in zip(robots.tolist(), at):
            heapq.heappush(self._due, (t, r))
        self._wake(min(at))

    def _wake(self, first: float | None = None) -> None:
        """One kernel event, at the earliest transmit instant of all robots.

        The event pending at ``_wake_at`` is never later than the earliest instant: freezing
        only moves instants later (the event then finds nobody due and looks again), so a
        change that moves instants earlier need only compare its own (``first``) with it."""
        if first is None:
            due, tx_at = self._due, self.tx_at
            while due and tx_at[due[0][1]] != due[0][0]:
                heapq.heappop(due)
            first = due[0][0] if due else math.inf
        if first < self._wake_at:
            self._wake_at = first
            self._wake_token += 1
            token = self._wake_token
            env = self.medium.env
            scheduled_event(env, max(first - env.now, 0.0), URGENT, lambda _ev: self._on_wake(token))

    def _on_wake(self, token: int) -> None:
        if token != self._wake_token:
            return  # superseded by an earlier instant
        self._wake_at = math.inf
        now = self.medium.env.now
        due, tx_at, ready = self._due, self.tx_at, set()
        while due and due[0][0] <= now + _EPS_S:
            at, i = heapq.heappop(due)
            if tx_at[i] == at:
                ready.add(i)
        for i in sorted(ready):  # in robot order, as a scan of tx_at would find them
            self.medium._start(i)
        self._wake()

    def sensed_busy(self, robots: np.ndarray, now: float) -> None:
        """Those of ``robots`` counting down stop, keeping the slots left; those due now
        transmit anyway (their slot had begun)."""
        counting = robots[np.isfinite(self.count_from[robots])]
        if not len(counting):
            return
        since = now - self.count_from[counting]
        elapsed = np.where(since >= 0, np.floor(since / self.slot_s + 1e-6), -1).astype(np.int64)
        due = elapsed >= self.backoff[counting]
        stop = counting[~due]
        el = elapsed[~due]
        # A busy period counts as one slot of the countdown (802.11: a backoff slot boundary
        # falls at the end of DIFS; Bianchi's chain decrements at every slot, busy or idle).
        self.backoff[stop] -= np.where(el >= 0, el + 1, 0)
        self.count_from[stop] = math.inf
        self.tx_at[stop] = math.inf

    def unicast_failed(self, i: int) -> str:
        if self.retries[i] < self.retry_limit:
            self.retries[i] += 1
            self.cw[i] = min(2 * self.cw[i] + 1, self.cw_max)
            return "again"
        return "drop"

    def frame_done(self, i: int) -> None:
        self.retries[i] = 0
        self.cw[i] = self.cw_min

    def ended(self, i: int, newly_idle: np.ndarray, now: float) -> None:
        if self.medium.queue[i]:
            self.backoff[i] = self.medium.rng.integers(self.cw[i] + 1)
        resume = newly_idle[self.backoff[newly_idle] >= 0]
        if len(resume):
            self._count_down(resume, now)


class Medium:
    """The shared medium of one run (module notes): airtime, collisions and the frames'
    ends, whatever the access. ``params``: its keys of ``[channel]``
    (:class:`~netsim.radio.mac_models.AlohaParams` or
    :class:`~netsim.radio.mac_models.CsmaParams`); ``power``: the radio's mean received
    power (None: a frame is lost where another overlaps it); ``access``: when a robot puts
    its head frame on the air and whether it sends a failed one again (:class:`Aloha` or
    :class:`Csma`, made with the medium and ``params``)."""

    causes = MAC_DROP_CAUSES

    def __init__(
        self,
        channel: Channel,
        params: Any,
        rng: np.random.Generator,
        power: PowerModel | None = None,
        access: type[Aloha] | type[Csma] = Aloha,
    ):
        self.channel = channel
        self.env: simpy.Environment = channel.env
        self.state = channel.state
        n = self.state.n
        self.rng = rng
        self.data_rate_bps = float(params.data_rate_bps)
        self.preamble_s = float(params.preamble_s)
        self.queue_frames = int(params.queue_frames)
        self.power = power
        largest = float(self.state.range_m.max()) if n else 0.0
        rec = channel.reception
        # Shadowing or walls: a pair's power differs from the mean one.
        varies = rec is not None and (rec.shadowing is not None or rec.compiled.walls is not None)
        self.actual_power = self.power is not None and varies
        default = self.power.noise_range_m if self.power is not None else largest
        reach = channel.reception.reach_m if channel.reception is not None else largest
        # Receivers must be among the robots a frame disturbs, so the range the medium
        # uses covers the radio's reach (a set value is refused below it; the default,
        # under shadowing, can be shorter than the reach).
        self.interference_range_m = max(float(params.interference_range_m) or default, reach)
        # Unit disk, one range, interference range = range: the hearers are the disturbed.
        self.same_as_hearers = (
            channel.reception is None
            and self.interference_range_m == largest
            and bool((self.state.range_m == largest).all())
        )
        if self.same_as_hearers:
            self.index = channel.index
        else:
            self.index = RangeIndex(self.state, reach_m=self.interference_range_m)
        self.queue: list[deque[Frame]] = [deque() for _ in range(n)]
        self.transmitting = np.zeros(n, dtype=bool)
        # Frames of other senders on the air within interference range of each robot.
        self.cover = np.zeros(n, dtype=np.int64)
        # Sequence number of the latest frame start that disturbed each robot, and of each
        # robot's latest own transmission: a frame survives at a receiver when neither
        # moved past the frame's own number by its end.
        self.cover_seq = np.zeros(n, dtype=np.int64)
        self.tx_seq = np.zeros(n, dtype=np.int64)
        self.load_mw = np.zeros(n)
        self.on_air: dict[int, Frame] = {}
        self.seq = 0
        # A frame's end, its losses decided by overlap or, under a power model, by its SINR,
        # as one loop (netsim.radio._mac_kernels).
        self._kernels = load("netsim.radio._mac_kernels", n)
        self._hd, self._col = np.empty(n, dtype=bool), np.empty(n, dtype=bool)
        self._newly = np.empty(n + 1, dtype=np.int64)
        # Time each robot sensed the medium busy (own transmissions included).
        self.busy_since = np.zeros(n)
        self.busy_s = np.zeros(n)
        # The arrays the frame end's loop reads and updates (_mac_kernels' ``medium`` and
        # ``out``): kept for the run, so put together once.
        arrays = MediumArrays(self.cover, self.transmitting, self.tx_seq, self.cover_seq, self.busy_s, self.busy_since)
        self._medium = tuple(arrays)
        self._end_out = tuple(Ends(self._hd, self._col, self._newly))
        self.frames_sent = 0
        self.attempts = 0
        self.airtime_total_s = 0.0
        self.access = access(self, params)

    # -- handing frames over ---------------------------------------------------------
    def send(self, sender: int, dest: int, payload: object, deliver, kind: str) -> np.ndarray:
        """Queue a frame (``dest`` -1: broadcast); returns ``[sender]`` if queued, else empty."""
        ch = self.channel
        c = ch.counters_for(kind)
        c.sent[sender] += 1
        binned = ch._bin(kind)
        nbytes = ch.frame_bytes.get(kind)
        if nbytes is None:
            raise ValueError(f"no frame size for messages of kind {kind!r} (channel.frame_bytes)")
        q = self.queue[sender]
        if len(q) >= self.queue_frames:
            self._frame_dropped(sender, kind, c, binned, "queue_full", payload)
            self._notify(sender, _EMPTY, payload, deliver, kind, c, binned)
            return _EMPTY
        airtime = airtime_s(nbytes, self.data_rate_bps, self.preamble_s)
        frame = Frame(sender, dest, kind, payload, deliver, c, binned, airtime)
        q.append(frame)
        if len(q) == 1:
            self.access.contend(sender)
        return np.array([sender])

    def _frame_dropped(self, sender: int, kind: str, c, binned, cause: str, payload: object) -> None:
        k = self.causes.index(cause)
        c.dropped[k, sender] += 1
        if binned is not None:
            binned.add(SendTimeBins.DROPPED + k, 1)
        self.channel._dropped(kind, sender, _EMPTY, cause)  # a frame, not a reception: no receiver
        self._lost(kind, payload, cause, 1)

    def _lost(self, kind: str, payload: object, cause: str, count: int) -> None:
        tell = self.channel.medium_losses.get(kind)
        if tell is not None:
            tell(payload, cause, count)

    # -- a frame on the air ------------------------------------------------------------
    def _start(self, i: int) -> None:
        ch = self.channel
        now = self.env.now
        frame = self.queue[i][0]
        self.access.started(i)
        self.seq += 1
        seq = frame.seq = self.seq
        self.attempts += 1
        self.airtime_total_s += frame.airtime_s
        c = frame.counters
        if frame.dest < 0:
            receivers, dist = ch._hearers(i, frame.kind)
        else:
            receivers, dist = self._unicast_receiver(i, frame)
        if self.same_as_hearers and frame.dest < 0:
            disturbed, ddist = receivers, dist
        else:
            disturbed, ddist = self.index.within(now, i, self.interference_range_m)
        if len(receivers):
            receivers, kept = ch._decide(i, receivers, dist, c, frame.kind, frame.binned)
            assert kept is not None  # measured distances in, measured distances out
            dist = kept
        frame.power_dbm = ch.power_dbm(i, frame.kind, receivers, dist) if ch.measured else None
        if ch._rows is not None:
            frame.rows, ch._rows = ch._rows, None
        frame.receivers = receivers
        frame.hd_start = self.transmitting[receivers]
        frame.col_start = self.cover[receivers] > 0
        frame.interferers = disturbed
        was_idle = np.empty(len(disturbed), dtype=bool)
        self._kernels.idle_among(self.cover, self.transmitting, disturbed, was_idle)
        sender_idle = self._kernels.senses_idle(self.cover, self.transmitting, i)
        self.cover[disturbed] += 1
        self.cover_seq[disturbed] = seq
        self.transmitting[i] = True
        self.tx_seq[i] = seq
        if self.power is not None:
            frame.power_mw = self.power.received_mw(ddist, self.state.n)
            self.load_mw[disturbed] += frame.power_mw
            at = np.searchsorted(disturbed, receivers)
            frame.signal_mw = frame.rx_mw = frame.power_mw[at]
            if self.actual_power and len(receivers):
                # The signal is the power the radio found for each pair (shadowing, walls);
                # the frame's share of the interference stays the mean (docs/radio.md).
                frame.rx_mw = linear(ch.reception.received_dbm(now, i, receivers, dist))
            for other in self.on_air.values():
                other.peak_mw = np.maximum(other.peak_mw, self.load_mw[other.receivers])
            frame.peak_mw = self.load_mw[receivers]
            self.on_air[seq] = frame
        newly = disturbed[was_idle]
        self.busy_since[newly] = now
        if sender_idle:
            self.busy_since[i] = now
        if len(newly):
            self.access.sensed_busy(newly, now)
        scheduled_event(self.env, frame.airtime_s, URGENT, lambda _ev: self._end(frame))

    def _unicast_receiver(self, i: int, frame: Frame) -> tuple[np.ndarray, np.ndarray]:
        heard, dist = self.channel._unicast_hears(i, frame.dest, frame.kind)
        if heard:
            return np.array([frame.dest]), dist
        self.channel._out_of_range(frame.kind, i, frame.dest, frame.counters, frame.binned)
        return _EMPTY, np.empty(0)

    def _end(self, frame: Frame) -> None:
        now = self.env.now
        i, seq = frame.sender, frame.seq
        disturbed = frame.interferers
        rx = frame.receivers
        power = self.power
        sinr_db, capture_db = _NO_SINR, 0.0
        if power is not None:
            # One SINR per receiver: the number the frame's end decides on, and the one recorded.
            interference = np.maximum(frame.peak_mw - frame.signal_mw, 0.0)
            sinr_db = in_db(frame.rx_mw / (power.noise_mw + interference))
            capture_db = power.capture_threshold_db
        fields = (i, seq, now, disturbed, rx, frame.hd_start, frame.col_start, power is not None)
        leaving = tuple(Leaving(*fields, sinr_db, capture_db))
        m = self._kernels.end_frame(self._medium, leaving, self._end_out)
        hd, col, newly = self._hd[: len(rx)], self._col[: len(rx)], self._newly[:m].copy()
        if power is not None:
            del self.on_air[seq]
            self.load_mw[disturbed] -= frame.power_mw
            quiet = disturbed[self.cover[disturbed] == 0]
            self.load_mw[quiet] = 0.0  # no drift once nothing is on the air there
        if frame.rows is not None:
            self._record(frame, rx, hd, col, sinr_db if power is not None else None)
        ok = ~(hd | col)
        c, binned = frame.counters, frame.binned
        for cause, lost in (("half_duplex", hd), ("collision", col)):
            if lost.any():
                k = self.causes.index(cause)
                self.channel.kernels.count_each(c.dropped[k], rx[lost])
                if binned is not None:
                    binned.add(SendTimeBins.DROPPED + k, int(lost.sum()))
                self.channel._dropped(frame.kind, i, rx[lost], cause)
                self._lost(frame.kind, frame.payload, cause, int(lost.sum()))
        got = rx[ok]
        outcome = self.access.unicast_failed(i) if frame.dest >= 0 and not len(got) else "done"
        if outcome != "again":
            self.queue[i].popleft()
            self.frames_sent += 1
            if outcome == "drop":
                self._frame_dropped(i, frame.kind, c, binned, "retry_limit", frame.payload)
            self.access.frame_done(i)
            power = frame.power_dbm[ok] if frame.power_dbm is not None else None
            self._notify(i, got, frame.payload, frame.deliver, frame.kind, c, binned, power)
        self.access.ended(i, newly, now)

    def _record(
        self, frame: Frame, rx: np.ndarray, hd: np.ndarray, col: np.ndarray, sinr_db: np.ndarray | None
    ) -> None:
        """Close the rows of ``frame`` (netsim.radio.receptions): the receptions it lost at its
        end, and under a power model each receiver's SINR (``sinr_db``: its signal over the
        noise and the peak interference of the frame, the number the capture threshold
        decided on; None without a power model)."""
        rows, frame.rows = frame.rows, None
        if sinr_db is not None and len(rx):
            rows.set_sinr(rx, sinr_db)
        rows.mark(rx[hd], self.causes.index("half_duplex"))
        rows.mark(rx[col], self.causes.index("collision"))
        self.channel.receptions.close(rows)

    def _notify(self, sender: int, got: np.ndarray, payload, deliver, kind: str, c, binned, power_dbm=None) -> None:
        ch = self.channel
        delay = ch.latency_s
        if ch.latency_jitter_s > 0:
            assert ch.latency_rng is not None
            delay += ch.latency_rng.use(kind).random() * ch.latency_jitter_s
        if len(got):
            ch._at(delay, deliver, sender, got, payload, c, kind, binned, power_dbm)
        elif kind in ch.notify_empty:
            scheduled_event(self.env, delay, URGENT, lambda _ev: deliver(sender, _EMPTY, payload))

    # -- what the run reports ------------------------------------------------------------
    def busy_fraction(self, now: float) -> np.ndarray:
        """Share of ``[0, now]`` each robot sensed the medium busy (its own frames included)."""
        busy = np.empty(len(self.busy_s))
        self._kernels.busy_times(self._medium, float(now), busy)
        return busy / now if now > 0 else np.full(len(busy), math.nan)

    def summary(self, now: float) -> dict:
        ch = self.channel
        totals = {cause: 0 for cause in self.causes}
        received = 0
        for c in ch.counters.values():
            received += int(c.received.sum())
            for k, cause in enumerate(self.causes):
                totals[cause] += int(c.dropped[k].sum())
        decided = received + totals["collision"] + totals["half_duplex"]
        n = self.state.n
        return {
            "mac": self.access.name,
            "mac_frames": self.frames_sent,
            "mac_transmissions": self.attempts,
            "mac_airtime_s": self.airtime_total_s,
            "channel_utilisation": float(self.busy_fraction(now).mean()) if n else math.nan,
            "collision_ratio": totals["collision"] / decided if decided else math.nan,
            "receptions_dropped_collision": totals["collision"],
            "receptions_dropped_half_duplex": totals["half_duplex"],
            "frames_dropped_queue_full": totals["queue_full"],
            "frames_dropped_retry_limit": totals["retry_limit"],
        }

    def frame(self) -> pd.DataFrame:
        """The ``medium`` table: per message kind and robot, the channel's counts with the
        medium's causes, and the share of the run the robot sensed the medium busy."""
        busy = self.busy_fraction(self.env.now)
        rows = []
        for kind in sorted(self.channel.counters):
            df = self.channel.counters[kind].frame()
            df.insert(0, "kind", kind)
            rows.append(df)
        if not rows:
            return pd.DataFrame({c: pd.Series(dtype=t) for c, t in MEDIUM_SCHEMA.items()})
        out = pd.concat(rows, ignore_index=True)
        out["busy_fraction"] = busy[out["robot"].to_numpy()]
        return out


MEDIUM_SCHEMA = {
    "kind": "object",
    "robot": "int64",
    "sent": "int64",
    "received": "int64",
    **{f"dropped_{c}": "int64" for c in MAC_DROP_CAUSES},
    "busy_fraction": "float64",
}


def with_mac_causes(tables: dict) -> dict:
    """The schemas of ``tables`` with the medium's drop columns after the channel's, in the
    tables that hold the channel's counts (``acks``, ``ack_delivery``), and at the end of
    the message outcomes (``messages``)."""
    out = dict(tables)
    for name, extra in (("acks", MAC_CAUSES), ("ack_delivery", ("collision", "half_duplex"))):
        schema = out.get(name)
        if schema is None:
            continue
        cols = list(schema.items())
        last = max(k for k, (col, _) in enumerate(cols) if col.startswith("dropped_"))
        add = [(f"dropped_{c}", "int64") for c in extra]
        out[name] = dict(cols[: last + 1] + add + cols[last + 1 :])
    if "messages" in out:
        # Per message: its frames' receptions lost on the medium, and its frames dropped.
        out["messages"] = {**out["messages"], **{f"dropped_{c}": "int64" for c in MAC_CAUSES}}
    return out
