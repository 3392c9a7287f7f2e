"""The flows of ``traffic.flows`` carried by a protocol that relays messages (docs/routing.md).

Each packet of a flow leaves its source at its time (:func:`netsim.traffic.send_times`) as
one message per frame (:func:`netsim.traffic.fragment_bytes`), each relayed on its own. A
packet is delivered when its last frame arrives, and only if every frame does; it is
dropped when the first of its frames is, and that frame says where and why. The tables:
``packets`` (one row per packet) and ``flows`` (one row per flow).

A routing protocol sends the messages between random pairs (``protocol.message_rate_hz``)
the same way: packets of flow ``-1`` (:meth:`FlowTraffic.start_pairs`).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

import numpy as np
import pandas as pd
import simpy

from netsim.traffic import Flow, Traffic, fragment_bytes, pathed_deliveries, send_times

PACKETS_SCHEMA = {
    "flow": "int64",
    "packet": "int64",
    "src": "int64",
    "dst": "int64",
    "bytes": "int64",
    "frames": "int64",
    "t_sent_s": "float64",
    "delivered": "bool",
    "t_delivered_s": "float64",
    "latency_s": "float64",
    "hops": "int64",
    "shortest_hops": "float64",
    "frames_delivered": "int64",
    "t_dropped_s": "float64",
    "drop_robot": "int64",
    "drop_cause": "object",
}

FLOWS_SCHEMA = {
    "flow": "int64",
    "src": "int64",
    "dst": "int64",
    "packets_sent": "int64",
    "packets_delivered": "int64",
    "delivery_ratio": "float64",
    "goodput_bps": "float64",
    "latency_p50_s": "float64",
    "latency_p95_s": "float64",
    "mean_hops": "float64",
}

# A packet some of whose frames were still on their way when the run ended.
IN_FLIGHT = "in_flight"
# The flow of the messages between random pairs in the packets table.
PAIRS_FLOW = -1
# A packet's row's key for the message id of its first frame (not a column).
FIRST_FRAME = "_first_frame"

# send(src, dst, kind, on_outcome) -> message id: the protocol's relay.
# on_outcome(msg_id, delivered, now, hops, robot, cause).
Outcome = Callable[[int, bool, float, int, int, str], None]
Send = Callable[[int, int, str, Outcome], int]
# shortest_hops(msg_id) -> the hops of the shortest path from the message's source to its
# destination on the true topology when it was sent (inf: none), as the protocol measured it.
Shortest = Callable[[int], float]


def frame_kind(nbytes: int) -> str:
    """The channel's kind for a flow's frame of ``nbytes`` (a medium's airtime follows it)."""
    return f"flow_{nbytes}B"


class FlowTraffic:
    """Sends the flows' packets through ``send`` and keeps every packet's fate."""

    def __init__(
        self, traffic: Traffic, env: simpy.Environment, frame_bytes: dict[str, int], send: Send, shortest_hops: Shortest
    ):
        self.flows: tuple[Flow, ...] = traffic.flows
        self.max_frame_bytes = traffic.max_frame_bytes
        self.env, self.send, self.shortest_hops = env, send, shortest_hops
        self.frame_bytes = frame_bytes
        # The channel's kinds of the frames sent (frame_kind of each size).
        self.kinds: set[str] = set()
        # One entry per packet, in order of sending: its row (a dict of PACKETS_SCHEMA).
        self._packets: list[dict] = []
        # Per message id that ``send`` gave a frame: the flow and the packet it is of.
        self._packet_of: dict[int, tuple[int, int]] = {}

    def _sizes(self, nbytes: int) -> list[int]:
        """The frames' sizes of a packet of ``nbytes``, each size's kind made known to the
        channel (a medium's airtime follows it) and kept in :attr:`kinds`."""
        sizes = fragment_bytes(nbytes, self.max_frame_bytes)
        for size in set(sizes):
            self.frame_bytes[frame_kind(size)] = size
            self.kinds.add(frame_kind(size))
        return sizes

    def start(self, end_s: float) -> None:
        """Start every flow's packets, up to the run's end ``end_s``."""
        for k, flow in enumerate(self.flows):
            sizes = self._sizes(flow.packet_bytes)
            times = send_times(flow, end_s)
            if times:
                self.env.process(self._source(k, flow, times, sizes))

    def start_pairs(self, n: int, rate_hz: float, message_bytes: int, rng: np.random.Generator) -> None:
        """Messages of ``message_bytes`` between uniformly random pairs of the ``n`` robots,
        a Poisson process of ``rate_hz``, drawn from ``rng`` as the clustering's relay draws
        them (the same stream gives the same pairs at the same times); packets of flow
        :data:`PAIRS_FLOW`. A team of one robot sends nothing (and draws nothing)."""
        if n < 2:
            return
        sizes = self._sizes(message_bytes)
        self.env.process(self._pairs(n, rate_hz, message_bytes, sizes, rng))

    def _pairs(self, n: int, rate_hz: float, message_bytes: int, sizes: list[int], rng: np.random.Generator):
        env = self.env
        p = 0
        while True:
            yield env.timeout(rng.exponential(1.0 / rate_hz))
            src = int(rng.integers(n))
            dst = int(rng.integers(n - 1))
            dst += dst >= src
            self._send_packet(PAIRS_FLOW, p, Flow(src, dst, env.now, env.now, 0.0, message_bytes), sizes)
            p += 1

    def _source(self, k: int, flow: Flow, times: list[float], sizes: list[int]):
        env = self.env
        for p, t in enumerate(times):
            if t > env.now:
                yield env.timeout(t - env.now)
            self._send_packet(k, p, flow, sizes)

    def _send_packet(self, k: int, p: int, flow: Flow, sizes: list[int]) -> None:
        row = {
            "flow": k,
            "packet": p,
            "src": flow.src,
            "dst": flow.dst,
            "bytes": flow.packet_bytes,
            "frames": len(sizes),
            "t_sent_s": self.env.now,
            "delivered": False,
            "t_delivered_s": np.nan,
            "latency_s": np.nan,
            "hops": 0,
            "shortest_hops": np.nan,
            "frames_delivered": 0,
            "t_dropped_s": np.nan,
            "drop_robot": -1,
            "drop_cause": "",
        }
        self._packets.append(row)
        # The row is the outcome's state: bound to it, no lookup by message id.
        told = self._teller(row)
        mids = [self.send(flow.src, flow.dst, frame_kind(nbytes), told) for nbytes in sizes]
        for mid in mids:
            self._packet_of[mid] = (k, p)
        # The row's own key, outside the table's columns.
        row[FIRST_FRAME] = mids[0] if mids else -1

    def packet_of(self, msg_ids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The flow and the packet (packets.parquet's) of each frame of ``msg_ids``."""
        pairs = np.array([self._packet_of[int(m)] for m in msg_ids], dtype=np.int64).reshape(-1, 2)
        return pairs[:, 0], pairs[:, 1]

    @staticmethod
    def _teller(row: dict) -> Outcome:
        def told(msg_id: int, delivered: bool, now: float, hops: int, robot: int, cause: str) -> None:
            if delivered:
                row["frames_delivered"] += 1
                row["hops"] = max(row["hops"], hops)
                if row["frames_delivered"] == row["frames"]:
                    row.update(delivered=True, t_delivered_s=now, latency_s=now - row["t_sent_s"])
            elif not row["drop_cause"]:
                # The first frame lost loses the packet: it says where and why.
                row.update(t_dropped_s=now, drop_robot=robot, drop_cause=cause)

        return told

    def packets_frame(self) -> pd.DataFrame:
        """One row per packet sent (PACKETS_SCHEMA); a packet neither delivered nor dropped
        when the run ended is ``in_flight``; ``hops`` of a delivered packet is its longest
        frame's path (0 if not delivered); ``shortest_hops`` the shortest path's when the
        packet was sent, as the protocol measured it for its first frame."""
        for row in self._packets:
            # Read at the end: the clustering's oracle measures a path sent at 0 once the
            # channel's links are first solved.
            mid = row[FIRST_FRAME]
            row["shortest_hops"] = self.shortest_hops(mid) if mid >= 0 else np.nan
        df = pd.DataFrame(self._packets, columns=list(PACKETS_SCHEMA))
        df = df.astype(PACKETS_SCHEMA)
        pending = ~df["delivered"] & (df["drop_cause"] == "")
        df.loc[pending, "drop_cause"] = IN_FLIGHT
        # A delivered packet has no cause: missing, as receptions.parquet's `cause` of a reception.
        df.loc[df["delivered"], "drop_cause"] = None
        df.loc[~df["delivered"], "hops"] = 0
        return df

    def flows_frame(self) -> pd.DataFrame:
        """One row per flow (FLOWS_SCHEMA); goodput is the bits of the packets delivered over
        the time the flow was on within the run (NaN if it never was)."""
        return flows_table(self.flows, self.packets_frame(), self.env.now)


def packet_delivery(frames: Mapping[str, pd.DataFrame]) -> dict:
    """The summary's ``packet_delivery_ratio``: the packets of ``packets.parquet`` delivered
    whole (a packet still in flight at the end counts as not delivered); and its
    ``packet_path_stretch``: the mean over the delivered packets that had a path when sent
    of their hops over that path's (``hops / shortest_hops``; NaN if none had); nothing when
    no packet was sent."""
    packets = frames.get("packets")
    if packets is None or not len(packets):
        return {}
    got = pathed_deliveries(packets)
    stretch = float((got["hops"] / got["shortest_hops"]).mean()) if len(got) else np.nan
    return {"packet_delivery_ratio": float(packets["delivered"].mean()), "packet_path_stretch": stretch}


def flows_table(flows: tuple[Flow, ...], packets: pd.DataFrame, end_s: float) -> pd.DataFrame:
    """The ``flows`` table of the ``packets`` table of a run that ended at ``end_s``."""
    rows = []
    by_flow = dict(tuple(packets.groupby("flow"))) if len(packets) else {}
    for k, f in enumerate(flows):
        pk = by_flow.get(k, packets.iloc[:0])
        got = pk[pk["delivered"]]
        sent, delivered = len(pk), len(got)
        on_s = min(f.stop_s, end_s) - f.start_s
        lat = got["latency_s"].to_numpy()
        rows.append(
            {
                "flow": k,
                "src": f.src,
                "dst": f.dst,
                "packets_sent": sent,
                "packets_delivered": delivered,
                "delivery_ratio": delivered / sent if sent else np.nan,
                "goodput_bps": float(got["bytes"].sum()) * 8.0 / on_s if on_s > 0 else np.nan,
                "latency_p50_s": float(np.percentile(lat, 50)) if delivered else np.nan,
                "latency_p95_s": float(np.percentile(lat, 95)) if delivered else np.nan,
                "mean_hops": float(got["hops"].mean()) if delivered else np.nan,
            }
        )
    return pd.DataFrame(rows, columns=list(FLOWS_SCHEMA)).astype(FLOWS_SCHEMA)
