"""Traffic flows: the ``[traffic]`` section (docs/routing.md, "Traffic flows").

A flow is a constant-bit-rate stream of packets from one robot to another:
``{src, dst, start_s, stop_s, rate_bps, packet_bytes}``. Its packets leave ``src`` at
``start_s``, then every ``packet_bytes * 8 / rate_bps`` seconds while before ``stop_s``
(and the run's end). A packet larger than ``channel.max_frame_bytes`` travels as several
frames and counts as delivered only when every one of them has arrived.

The engine holds the flows and their timing; the protocol that relays messages carries
them (``PluginSpec.carries_flows``) and writes ``flows.parquet`` and ``packets.parquet``.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from netsim.errors import ConfigError
from netsim.params import Params, coerce_value, param

FLOW_KEYS = ("src", "dst", "start_s", "stop_s", "rate_bps", "packet_bytes")


class Flow(NamedTuple):
    """One flow of ``traffic.flows``."""

    src: int
    dst: int
    start_s: float
    stop_s: float
    rate_bps: float
    packet_bytes: int

    @property
    def interval_s(self) -> float:
        """Time between two packets of the flow: a packet's bits over the rate."""
        return self.packet_bytes * 8.0 / self.rate_bps


def _flow(key: str, value: Any) -> dict[str, Any]:
    """One flow (a table of the six keys), checked; as a plain dict (TOML writes it back)."""
    if not isinstance(value, dict):
        raise ConfigError(key, value, "must be a table {src, dst, start_s, stop_s, rate_bps, packet_bytes}")
    for k in value:
        if k not in FLOW_KEYS:
            raise ConfigError(f"{key}.{k}", value[k], "unknown key; allowed: " + ", ".join(FLOW_KEYS))
    missing = [k for k in FLOW_KEYS if k not in value]
    if missing:
        raise ConfigError(key, value, "misses " + ", ".join(missing))
    out: dict[str, Any] = {}
    for k in FLOW_KEYS:
        kind = int if k in ("src", "dst", "packet_bytes") else float
        out[k] = v = coerce_value(f"{key}.{k}", value[k], kind)
        if k in ("src", "dst") and v < 0:
            raise ConfigError(f"{key}.{k}", v, "must be a robot's id (>= 0)")
        if k == "start_s" and not (v >= 0 and math.isfinite(v)):
            raise ConfigError(f"{key}.{k}", v, "must be >= 0 and finite")
        if k in ("rate_bps", "packet_bytes") and not (v > 0 and math.isfinite(v)):
            raise ConfigError(f"{key}.{k}", v, "must be > 0 and finite")
    if not out["stop_s"] > out["start_s"]:
        raise ConfigError(f"{key}.stop_s", out["stop_s"], f"must be after {key}.start_s = {out['start_s']:g}")
    if out["src"] == out["dst"]:
        raise ConfigError(f"{key}.dst", out["dst"], "must differ from src (a flow goes from one robot to another)")
    return out


def _flows(key: str, value: Any) -> tuple[dict[str, Any], ...]:
    if not isinstance(value, list | tuple):
        raise ConfigError(key, value, "must be a list of flows [{src, dst, start_s, stop_s, rate_bps, packet_bytes}]")
    return tuple(_flow(f"{key}[{i}]", v) for i, v in enumerate(value))


@dataclass(frozen=True)
class TrafficParams(Params):
    """``[traffic]``: flows beside the protocol's random pairs (``protocol.message_rate_hz``)."""

    section = "traffic"
    flows: tuple[dict[str, Any], ...] = param(
        (),
        None,
        "constant-bit-rate flows, each {src, dst, start_s, stop_s, rate_bps, packet_bytes} (ids, s, bit/s, bytes)",
        coerce=_flows,
    )

    def flow_list(self) -> list[Flow]:
        """The flows as :class:`Flow` tuples, in the order given (flow ``k`` is the ``k``-th)."""
        return [Flow(**f) for f in self.flows]


# The most frames the flows may send in one run: beyond, their schedules alone take
# gigabytes and no run ends (a rate or size mistyped by orders of magnitude).
MAX_FRAMES_PER_RUN = 100_000_000


def check_flows(params: TrafficParams, n_robots: int, duration_s: float, max_frame_bytes: int) -> None:
    """Every flow names robots of the team, and the flows send at most
    :data:`MAX_FRAMES_PER_RUN` frames in the run; a flow that starts at or after the run's
    end is told (it sends nothing)."""
    frames = 0
    for i, f in enumerate(params.flows):
        for k in ("src", "dst"):
            if f[k] >= n_robots:
                raise ConfigError(
                    f"traffic.flows[{i}].{k}", f[k], f"no such robot: ids are 0 to {n_robots - 1} (world.n_robots)"
                )
        flow = Flow(**f)
        if flow.start_s >= duration_s:
            warnings.warn(
                f"traffic.flows[{i}] starts at {flow.start_s:g} s, at or after the run's end "
                f"(duration_s = {duration_s:g}): it sends nothing",
                stacklevel=2,
            )
            continue
        packets = packet_count(flow, duration_s)
        frames += packets * frame_count(flow.packet_bytes, max_frame_bytes)
        refuse_frames(
            f"traffic.flows[{i}]",
            f,
            frames,
            f"the flows up to this one would send {_count(frames)} frames in the run (this one "
            f"{_count(packets)} packets of {flow.packet_bytes:,} bytes, channel.max_frame_bytes = {max_frame_bytes})",
        )


def _count(n: float) -> str:
    """A count as a reader takes it in: digits with separators, or three significant ones
    past a thousand million million."""
    return f"{n:,}" if n < 1e15 else f"{n:.3g}"


def refuse_frames(key: str, value: object, frames: float, would: str, change: str = "") -> None:
    """Refuse ``key`` when its traffic ``would`` send more than :data:`MAX_FRAMES_PER_RUN`
    frames (``frames``) in the run; ``change`` says what to change, if anything."""
    if frames > MAX_FRAMES_PER_RUN:
        raise ConfigError(key, value, f"{would}; at most {MAX_FRAMES_PER_RUN:,}{change}")


class Traffic(NamedTuple):
    """What a protocol that carries flows is handed (``Parts.traffic``): the flows, and the
    largest payload of one frame, bytes."""

    flows: tuple[Flow, ...]
    max_frame_bytes: int


def fragment_bytes(packet_bytes: int, max_frame_bytes: int) -> list[int]:
    """The frames a packet travels as: full frames of ``max_frame_bytes``, then the rest.

    >>> fragment_bytes(4000, 1500)
    [1500, 1500, 1000]
    >>> fragment_bytes(512, 1500)
    [512]
    """
    full, rest = divmod(packet_bytes, max_frame_bytes)
    return [max_frame_bytes] * full + ([rest] if rest else [])


def frame_count(packet_bytes: int, max_frame_bytes: int) -> int:
    """How many frames a packet travels as (:func:`fragment_bytes`' length).

    >>> frame_count(4000, 1500), frame_count(512, 1500), frame_count(3000, 1500)
    (3, 1, 2)
    """
    return -(-packet_bytes // max_frame_bytes)


def packet_count(flow: Flow, end_s: float) -> int:
    """How many packets ``flow`` sends before ``stop_s`` and the run's end ``end_s``
    (:func:`send_times`' length)."""
    end = min(flow.stop_s, end_s)
    if not flow.start_s < end:
        return 0
    count = math.ceil((end - flow.start_s) / flow.interval_s)
    # start + k * interval rounds: the last may land on the end, which is not sent.
    return count - (flow.start_s + (count - 1) * flow.interval_s >= end)


def send_times(flow: Flow, end_s: float) -> list[float]:
    """When ``flow``'s packets leave its source, up to (not including) ``stop_s`` and the
    run's end ``end_s``; computed as ``start + k * interval`` (no rounding drift).

    >>> send_times(Flow(0, 1, 1.0, 2.0, 8000.0, 250), 10.0)
    [1.0, 1.25, 1.5, 1.75]
    """
    step = flow.interval_s
    return [flow.start_s + k * step for k in range(packet_count(flow, end_s))]


def pathed_deliveries(packets: Any) -> Any:
    """The rows of a ``packets.parquet`` table a route's stretch is measured on: delivered,
    with a path between their ends when sent (a packet sent with none may still arrive: it
    waited for a route, or the team moved)."""
    return packets[packets["delivered"].to_numpy(bool) & np.isfinite(packets["shortest_hops"].to_numpy(float))]
