"""The shared medium against its closed forms (docs/validation.md, "Shared medium").

Each check drives a :class:`~netsim.radio.mac.Medium` on static robots with a traffic of its
own (no protocol above), measures, and returns the theory beside it:

- :func:`aloha_periodic`: ALOHA, ``n`` robots in mutual range, one frame of airtime ``T``
  per period ``t`` each, at independent uniform phases: a reception succeeds with
  probability ``(1 - 2T/t)^(n - 1)``; :func:`half_duplex_pair`, the same with two robots,
  where every loss is to half duplex;
- :func:`aloha_poisson`: ALOHA, Poisson traffic of load ``G`` (frames per frame time from
  the ``n - 1`` robots other than the sender): ``e^(-2G)``;
- :func:`csma_saturation`: CSMA (802.11 DCF, basic access), ``n`` saturated robots sending
  unicast frames: throughput against :func:`bianchi_throughput`;
- :func:`hidden_terminals`: A and C out of each other's range, both in range of B, periodic
  frames under CSMA: B receives A's frames with ALOHA's pair probability ``1 - 2T/t``;
  the control, A and B both sending in each other's range, loses at most
  :func:`same_slot_bound`.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from scipy.optimize import brentq

from netsim.config import from_dict
from netsim.radio.mac_models import CsmaParams


class MacCheck(NamedTuple):
    item: str
    theory: float
    measured: float
    tolerance: float


def medium_run(positions, mac: str, range_m: float = 50.0, seed: int = 1, **channel):
    """A run of static robots at ``positions`` with no protocol, the medium ``mac``: the
    :class:`~netsim.sim.Simulation` (drive it with ``sim.channel`` and ``sim.env``)."""
    from netsim.run import build

    positions = np.asarray(positions, dtype=float)
    cfg = from_dict(
        {
            "seed": seed,
            "world": {"n_robots": len(positions), "side_m": 10_000.0},
            "mobility": {"model": "static"},
            "channel": {"mac": mac, **channel, **({} if "propagation" in channel else {"range_m": range_m})},
            "protocol": {"model": "none"},
            "output": {"position_interval_s": 0.0},
        }
    )
    sim = build(cfg)
    sim.state.place(positions)
    return sim


def cluster(n: int, spread_m: float = 1.0) -> np.ndarray:
    """``n`` robots on a line ``spread_m`` long: all in mutual range."""
    return np.column_stack([np.linspace(100.0, 100.0 + spread_m, n), np.full(n, 100.0)])


def _reception_success(sim, kind: str) -> tuple[int, int]:
    """(received, received + lost to the medium) of ``kind``'s frames."""
    c = sim.channel.counters_for(kind)
    causes = sim.channel.causes
    lost = c.dropped[causes.index("collision")] + c.dropped[causes.index("half_duplex")]
    return int(c.received.sum()), int(c.received.sum() + lost.sum())


def periodic_rounds(sim, senders, period_s: float, rounds: int, rng: np.random.Generator, dest: int = -1) -> None:
    """Schedule ``rounds`` independent rounds: in each, every sender draws a phase uniform on
    ``[0, t)`` and sends at phase, phase + t, phase + 2t; the middle frames (kind ``"mid"``)
    are the ones measured (each sees neighbours on both sides, as in a steady state)."""
    env, ch = sim.env, sim.channel
    gap = period_s  # long enough for every frame of a round to end before the next starts
    span = 3 * period_s + gap

    def noop(_s, _r, _p):
        return None

    def send_at(t: float, i: int, kind: str):
        def fire(_ev):
            ch.broadcast(i, None, noop, kind=kind)

        ev = env.timeout(t - env.now)
        ev.callbacks.append(fire)

    for r in range(rounds):
        phases = rng.uniform(0.0, period_s, len(senders))
        for i, ph in zip(senders, phases.tolist()):
            for k, kind in enumerate(("edge", "mid", "edge")):
                send_at(r * span + ph + k * period_s, int(i), kind)


def _sized(sim, airtime: float, rate_bps: float = 1e6) -> None:
    """Frames of every kind used here take ``airtime`` (no preamble: set it to 0)."""
    nbytes = airtime * rate_bps / 8.0
    if abs(nbytes - round(nbytes)) > 1e-9:
        raise ValueError(f"airtime {airtime} s is not a whole number of bytes at {rate_bps} bit/s")
    for kind in ("edge", "mid", "poisson", "sat"):
        sim.channel.frame_bytes[kind] = int(round(nbytes))


def aloha_periodic(n: int = 10, airtime_ratio: float = 0.02, rounds: int = 400, seed: int = 1) -> MacCheck:
    """ALOHA, periodic frames at uniform phases: success ``(1 - 2T/t)^(n - 1)``."""
    period = 1.0
    airtime = airtime_ratio * period
    sim = medium_run(cluster(n), "aloha", seed=seed, preamble_s=0.0, data_rate_bps=1e6, latency_s=0.0)
    _sized(sim, airtime)
    periodic_rounds(sim, range(n), period, rounds, np.random.default_rng(seed))
    sim.env.run()
    got, decided = _reception_success(sim, "mid")
    theory = (1.0 - 2.0 * airtime_ratio) ** (n - 1)
    se = aloha_periodic_se(n, airtime_ratio, rounds)
    return MacCheck(f"ALOHA periodic, n = {n}, T/t = {airtime_ratio}", theory, got / decided, 4.0 * se)


def half_duplex_pair(airtime_ratio: float = 0.1, rounds: int = 1000, seed: int = 1) -> MacCheck:
    """ALOHA, two robots in range sending periodic frames: the only frame that can spoil a
    reception is the receiver's own, so every loss is to half duplex, and the success is
    :func:`aloha_periodic`'s with ``n = 2``, ``1 - 2T/t``; a medium that let a sender
    receive would deliver every frame."""
    c = aloha_periodic(n=2, airtime_ratio=airtime_ratio, rounds=rounds, seed=seed)
    return c._replace(item=f"ALOHA periodic, a pair, T/t = {airtime_ratio} (every loss half duplex)")


def aloha_periodic_se(n: int, airtime_ratio: float, rounds: int) -> float:
    """Standard error of :func:`aloha_periodic`'s measured success over ``rounds`` rounds.

    In mutual range a frame that overlaps another fails at every receiver (at the other
    frame's sender by half duplex, elsewhere by collision), so the ``n - 1`` receptions of a
    frame succeed or fail together, and two frames that overlap fail together. With ``x =
    T/t`` and ``S`` a round's successful frames, ``p = (1 - 2x)^(n-1)`` and two frames whose
    phases lie ``d`` apart on the circle (``d`` uniform on ``[0, 1/2]``) both succeed when
    ``d >= x`` and none of the ``n - 2`` others falls within ``x`` of either, an arc of
    ``2x + min(d, 2x)``:

        P2 = 2 ((1 - 3x)^(n-1) - (1 - 4x)^(n-1)) / (n - 1) + (1 - 4x)^(n-1)
        Var(S) = n p (1 - p) + n (n - 1) (P2 - p^2)

    and the measured success ``sum S / (n rounds)`` has variance ``Var(S) / (n^2 rounds)``.
    """
    x = airtime_ratio
    p = (1.0 - 2.0 * x) ** (n - 1)
    both = 2.0 * ((1.0 - 3.0 * x) ** (n - 1) - (1.0 - 4.0 * x) ** (n - 1)) / (n - 1) + (1.0 - 4.0 * x) ** (n - 1)
    var_s = n * p * (1.0 - p) + n * (n - 1) * (both - p * p)
    return math.sqrt(var_s / (n * n * rounds))


def aloha_poisson(n: int = 40, load: float = 0.5, frames: int = 20_000, seed: int = 1) -> MacCheck:
    """ALOHA, Poisson traffic: a reception succeeds with probability ``e^(-2G)``, ``G`` the
    frames the other ``n - 1`` robots start per frame time."""
    airtime = 1e-3
    rate_per_robot = load / ((n - 1) * airtime)
    duration = frames / (n * rate_per_robot)
    sim = medium_run(
        cluster(n), "aloha", seed=seed, preamble_s=0.0, data_rate_bps=1e6, latency_s=0.0, queue_frames=1000
    )
    _sized(sim, airtime)
    rng = np.random.default_rng(seed)
    env, ch = sim.env, sim.channel

    def noop(_s, _r, _p):
        return None

    for i in range(n):
        t = np.cumsum(rng.exponential(1.0 / rate_per_robot, int(duration * rate_per_robot * 1.5) + 20))
        for when in t[t < duration].tolist():
            ev = env.timeout(when)
            ev.callbacks.append(lambda _ev, i=i: ch.broadcast(i, None, noop, kind="poisson"))
    env.run()
    got, decided = _reception_success(sim, "poisson")
    theory = math.exp(-2.0 * load)
    se = aloha_poisson_se(load, decided / (n - 1))
    return MacCheck(f"ALOHA Poisson, G = {load}, n = {n}", theory, got / decided, 4.0 * se)


def aloha_poisson_se(load: float, frames: float) -> float:
    """Standard error of :func:`aloha_poisson`'s measured success over ``frames`` frames.

    The ``n - 1`` receptions of a frame succeed or fail together (as in
    :func:`aloha_periodic_se`), so the count is over frames; and two frames that overlap
    both fail, which adds to the binomial variance. Frames are a Poisson process of ``g =
    G`` frames per frame time ``T`` (a robot's own frames, which queue behind each other,
    are a share ``1 / (n - 1)`` of them, left out). Two frames ``u`` apart both succeed
    with probability 0 for ``u < T``, ``e^(-g (2 + u/T))`` for ``T <= u < 2T`` and
    ``e^(-4g)`` beyond; with ``p = e^(-2g)`` the ratio of successes to frames then has, by
    the delta method over a long window,

        Var = (p (1 - p) + 2 e^(-3g) (1 - e^(-g))) / frames.
    """
    p = math.exp(-2.0 * load)
    extra = 2.0 * math.exp(-3.0 * load) * (1.0 - math.exp(-load))
    return math.sqrt((p * (1.0 - p) + extra) / frames) if frames > 0 else math.inf


def _binomial_se(p: float, count: float) -> float:
    return math.sqrt(p * (1.0 - p) / count) if count > 0 else math.inf


# -- 802.11 DCF against Bianchi ----------------------------------------------------------
def bianchi_tau(n: int, w: int, m: int) -> tuple[float, float]:
    """Bianchi's (2000) fixed point: a station's transmission probability per slot ``tau``
    and the conditional collision probability ``p``, for ``n`` stations, initial window
    ``W`` (backoff uniform on ``0..W-1``) and ``m`` doublings."""

    def tau_of(p: float) -> float:
        if abs(1.0 - 2.0 * p) < 1e-12:
            p += 1e-9
        return 2.0 * (1.0 - 2.0 * p) / ((1.0 - 2.0 * p) * (w + 1) + p * w * (1.0 - (2.0 * p) ** m))

    if n == 1:
        return tau_of(0.0), 0.0
    p = brentq(lambda p: p - (1.0 - (1.0 - tau_of(p)) ** (n - 1)), 1e-12, 1.0 - 1e-12)
    return tau_of(p), p


def bianchi_throughput(n: int, w: int, m: int, slot_s: float, payload_s: float, ts_s: float, tc_s: float) -> float:
    """Bianchi's saturation throughput: the share of time spent on payload of successful
    frames, ``S = Ps Ptr E[P] / ((1 - Ptr) sigma + Ptr Ps Ts + Ptr (1 - Ps) Tc)``."""
    tau, _ = bianchi_tau(n, w, m)
    ptr = 1.0 - (1.0 - tau) ** n
    ps = n * tau * (1.0 - tau) ** (n - 1) / ptr
    return ps * ptr * payload_s / ((1.0 - ptr) * slot_s + ptr * ps * ts_s + ptr * (1.0 - ps) * tc_s)


def csma_saturation(n: int, duration_s: float = 20.0, seed: int = 1, payload_bytes: int = 512) -> MacCheck:
    """``n`` saturated robots in mutual range, each sending unicast frames to the next one
    (802.11b-like: 1 Mb/s, slot 20 us, DIFS 50 us, CW 31..1023, preamble 192 us): measured
    share of time carrying successful payload against Bianchi's, with ``Ts = Tc = preamble
    + payload + DIFS`` (basic access; the MAC acknowledgement is not put on the air: a
    sender learns at the frame's end whether it got through)."""
    rate, slot, difs, pre = 1e6, 20e-6, 50e-6, 192e-6
    sim = medium_run(
        cluster(n),
        "csma",
        seed=seed,
        preamble_s=pre,
        data_rate_bps=rate,
        slot_s=slot,
        difs_s=difs,
        cw_min=31,
        cw_max=1023,
        retry_limit=10_000,
        latency_s=0.0,
    )
    sim.channel.frame_bytes["sat"] = payload_bytes
    sim.channel.notify_empty.add("sat")
    env, ch = sim.env, sim.channel
    delivered = [0]

    def done(sender, receivers, _p):
        if len(receivers):
            delivered[0] += 1
        ch.unicast(sender, (sender + 1) % n, None, done, kind="sat")

    for i in range(n):
        for _ in range(2):  # one on the air, one waiting: never an empty queue
            ch.unicast(i, (i + 1) % n, None, done, kind="sat")
    env.run(until=duration_s)
    payload = payload_bytes * 8.0 / rate
    measured = delivered[0] * payload / duration_s
    t = pre + payload + difs
    theory = bianchi_throughput(n, 32, 5, slot, payload, t, t)
    return MacCheck(f"CSMA saturation, n = {n}", theory, measured, 0.05 * theory)


def hidden_terminals(
    airtime_ratio: float = 0.05, rounds: int = 1000, seed: int = 1, range_m: float = 50.0, mac: str = "csma"
) -> tuple[MacCheck, MacCheck]:
    """A, B, C on a line, A and C ``1.8 range`` apart (hidden from each other), B between:
    under CSMA, B receives A's and C's periodic frames with ALOHA's pair probability
    ``1 - 2T/t``. The control: A and B alone, both sending periodic frames: they hear each
    other, so B loses A's frames only when both reach the end of their backoff in the same
    slot (:func:`same_slot_bound`). ``mac``: the medium of both cases (``"aloha"`` makes the
    control fail: B then loses ``2T/t`` of A's frames to its own)."""
    period = 1.0
    airtime = airtime_ratio * period
    out = []
    for label, xs, senders in (
        (f"hidden terminals A-B-C, {mac}, B's success", [0.0, 0.9 * range_m, 1.8 * range_m], [0, 2]),
        (f"A-B alone, both sending, {mac}, B's success", [0.0, 0.9 * range_m], [0, 1]),
    ):
        pos = np.column_stack([np.array(xs) + 100.0, np.full(len(xs), 100.0)])
        sim = medium_run(pos, mac, range_m=range_m, seed=seed, preamble_s=0.0, data_rate_bps=1e6, latency_s=0.0)
        _sized(sim, airtime)
        periodic_rounds(sim, senders, period, rounds, np.random.default_rng(seed))
        sim.env.run()
        c, causes = sim.channel.counters_for("mid"), sim.channel.causes
        got = int(c.received[1])
        lost = int(c.dropped[causes.index("collision"), 1] + c.dropped[causes.index("half_duplex"), 1])
        decided = got + lost
        if len(xs) == 3:
            theory = 1 - 2 * airtime_ratio
            # A's and C's frames of a round fail together (they overlap each other): one
            # independent outcome per round, not per reception.
            tol = 4.0 * _binomial_se(theory, decided / 2)
        else:
            # The bound under CSMA's backoff (ALOHA has none: the backoff's defaults).
            m = sim.channel.mac.access if mac == "csma" else CsmaParams()
            p = same_slot_bound(period, m.difs_s, m.slot_s, m.cw_min)
            theory = 1.0
            tol = p + 4.0 * _binomial_se(1.0 - p, decided)
        out.append(MacCheck(label, theory, got / decided, tol))
    return out[0], out[1]


def same_slot_bound(period_s: float, difs_s: float, slot_s: float, cw: int) -> float:
    """Upper bound on the share of A's periodic frames that B, which hears A and sends
    periodic frames too (one per ``period_s``, independent phases), loses under CSMA.

    B loses a frame of A only if both transmit at once, which needs both counting down at
    the same time: B's frame handed over within ``difs_s + cw slot_s`` of A's (probability
    at most ``2 (difs_s + cw slot_s) / period_s``; a frame handed over while the other is on
    the air defers to its end and the other has nothing left to send), and B's backoff
    ending in A's slot (at most ``1 / (cw + 1)`` of B's uniform draws)."""
    return min(1.0, 2.0 * (difs_s + cw * slot_s) / period_s / (cw + 1))


# -- interference adds up (log-distance) ---------------------------------------------------
def interference_sum(
    cells: int = 50, rounds: int = 40, interferers: int = 3, seed: int = 1
) -> tuple[MacCheck, int, int]:
    """ALOHA under log-distance (no shadowing): every reception decided as the brute-force
    SINR rule says, interference summed over every frame on the air.

    Each cell (cells far beyond the interference range of each other) holds a receiver B, a
    sender A at 30 m and ``interferers`` robots at 2.2 to 4.5 times that distance, each of
    which alone leaves a signal-to-interference ratio of 10 to 20 dB. In every round A sends
    one frame and each interferer one frame starting within one airtime of A's, at a uniform
    offset. B gets A's frame exactly when ``S >= capture (N + I)``, ``S`` the mean power of
    A at B, ``N`` the noise floor and ``I`` the largest, over the instants of A's frame, of
    the summed mean powers at B of the other frames then on the air (senders within the
    interference range of B). Returns the check (receptions decided otherwise than the rule:
    0), the receptions, and how many of them the strongest interferer alone would decide
    otherwise (what makes the check able to fail)."""
    from netsim.radio.propagation import LogDistanceParams, path_loss_db

    radio = LogDistanceParams()
    period, airtime, d_signal = 1.0, 0.01, 30.0
    rng = np.random.default_rng(seed)
    k = interferers + 2
    pos = np.zeros((cells * k, 2))
    for c in range(cells):
        centre = np.array([1000.0 * (c % 8) + 500.0, 1000.0 * (c // 8) + 500.0])
        pos[c * k] = centre + d_signal * np.array([1.0, 0.0])  # A
        pos[c * k + 1] = centre  # B
        angle = rng.uniform(0.0, 2.0 * math.pi, interferers)
        dist = d_signal * rng.uniform(2.2, 4.5, interferers)
        pos[c * k + 2 : c * k + k] = centre + dist[:, None] * np.column_stack([np.cos(angle), np.sin(angle)])
    sim = medium_run(
        pos, "aloha", seed=seed, propagation="log_distance", preamble_s=0.0, data_rate_bps=1e6, latency_s=0.0
    )
    _sized(sim, airtime)
    env, ch, medium = sim.env, sim.channel, sim.channel.mac
    heard: set[tuple[int, int]] = set()

    def deliver(_s, receivers, payload):
        cell, r = payload
        if cell * k + 1 in receivers.tolist():
            heard.add((cell, r))

    def noop(_s, _r, _p):
        return None

    def send_at(t: float, i: int, payload, fn):
        ev = env.timeout(t)
        ev.callbacks.append(lambda _ev: ch.broadcast(i, payload, fn, kind="edge"))

    offsets = rng.uniform(-airtime, airtime, (cells, rounds, interferers))
    for c in range(cells):
        for r in range(rounds):
            start = r * period + 0.5
            send_at(start, c * k, (c, r), deliver)
            for j in range(interferers):
                send_at(start + offsets[c, r, j], c * k + 2 + j, None, noop)
    env.run()

    def power_mw(d):
        return 10.0 ** ((radio.tx_power_dbm - path_loss_db(np.maximum(d, radio.reference_distance_m), radio)) / 10.0)

    noise_mw = 10.0 ** (sim.config.channel.noise_floor_dbm / 10.0)
    capture = 10.0 ** (sim.config.channel.capture_threshold_db / 10.0)
    wrong = differs = 0
    for c in range(cells):
        b = pos[c * k + 1]
        # Distances measured apart from the engine's kernel: the reference stays independent.
        signal = float(power_mw(np.hypot(*(pos[c * k] - b))))
        d_i = np.hypot(*(pos[c * k + 2 : c * k + k] - b).T)
        p_i = np.where(d_i <= medium.interference_range_m, power_mw(d_i), 0.0)
        for r in range(rounds):
            s_i = offsets[c, r]  # the interferers' starts, relative to A's
            # The summed interference is largest at A's start or at a later start within A's frame.
            worst = max(float(p_i[(s_i <= at) & (s_i + airtime > at)].sum()) for at in [0.0, *s_i[s_i > 0.0].tolist()])
            strongest = float(p_i[(s_i < airtime) & (s_i + airtime > 0.0)].max(initial=0.0))
            ok = signal >= capture * (noise_mw + worst)
            wrong += ok != ((c, r) in heard)
            differs += ok != (signal >= capture * (noise_mw + strongest))
    check = MacCheck(
        f"ALOHA, log-distance, {interferers} interferers: receptions off the summed-SINR rule", 0.0, wrong, 0.0
    )
    return check, cells * rounds, differs


def run_all() -> list[MacCheck]:
    checks = [aloha_periodic(), aloha_poisson()]
    checks += [csma_saturation(n) for n in (5, 10, 20, 50)]
    checks += list(hidden_terminals())
    return checks
