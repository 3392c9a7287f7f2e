"""The record of every reception the channel decides: ``receptions.parquet``
(``output.receptions = true``; docs/outputs.md, docs/radio.md "Signal columns").

A frame's rows are the robots the channel decides it for, *within the radio's reach*: a
broadcast's candidates (every robot within the radio's reach, the distance beyond which no
shadowing within its clip lets a frame clear the sensitivity; under the unit disk, within
the sender's range), and a unicast's destination (always, so that every drop the channel
counts has its row). Each row carries the decision where the channel makes it: the radio
(cause ``out_of_range``: power below the sensitivity, a wall, beyond range), the receiver
switched off (``not_alive``), the loss model (``loss``) and, under a shared medium, the
frame's end (``half_duplex``, ``collision``).

The channel and its medium fill a frame's :class:`FrameRows` while they decide it and hand
it to :meth:`ReceptionLog.close` once decided: at once without a medium, at the frame's end
with one. Without the log attached (the default) the channel does none of this work.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pandas as pd

from netsim.geometry import in_box
from netsim.trajectory import LegTable

RECEPTIONS_SCHEMA = {
    "t_s": "float64",
    "src": "int64",
    "dst": "int64",
    "kind": "object",
    "distance_m": "float64",
    "rx_power_dbm": "float64",
    "sinr_db": "float64",
    "received": "bool",
    "cause": "object",
    "src_x_m": "float64",
    "src_y_m": "float64",
    "dst_x_m": "float64",
    "dst_y_m": "float64",
}

# A row's cause while nothing dropped it (received, once the frame is decided).
NO_CAUSE = -1


class FrameRows:
    """One frame's rows while the channel decides it: the receivers in question ``dst``,
    their distance, power (dBm, NaN without a power law), SINR (dB) and cause (index into
    the log's causes, :data:`NO_CAUSE` while none)."""

    __slots__ = ("t_s", "src", "kind", "dst", "distance_m", "power_dbm", "sinr_db", "cause")

    def __init__(
        self,
        t_s: float,
        src: int,
        kind: str,
        dst: np.ndarray,
        distance_m: np.ndarray,
        power_dbm: np.ndarray,
        sinr_db: float,
    ):
        self.t_s, self.src, self.kind = t_s, src, kind
        self.dst = np.array(dst, dtype=np.int64)
        self.distance_m = np.array(distance_m, dtype=float)
        self.power_dbm = power_dbm
        self.sinr_db = np.full(len(self.dst), sinr_db)
        self.cause = np.full(len(self.dst), NO_CAUSE, dtype=np.int64)

    def mark(self, robots: np.ndarray, cause: int) -> None:
        """``robots`` (among ``dst``) were dropped for ``cause``, unless already dropped."""
        hit = np.isin(self.dst, robots) & (self.cause == NO_CAUSE)
        self.cause[hit] = cause

    def failed(self) -> FrameRows:
        """These rows but those not decided yet: a frame still on the air when the run ends
        has dropped some receivers where it went on the air (the drops counted) and left the
        others to an end that never came."""
        out = object.__new__(FrameRows)
        out.t_s, out.src, out.kind = self.t_s, self.src, self.kind
        keep = self.cause != NO_CAUSE
        for name in ("dst", "distance_m", "power_dbm", "sinr_db", "cause"):
            setattr(out, name, getattr(self, name)[keep])
        return out

    def set_sinr(self, robots: np.ndarray, sinr_db: np.ndarray) -> None:
        """The SINR (dB) the medium found at ``robots`` (among ``dst``) at the frame's end."""
        at = {int(r): k for k, r in enumerate(self.dst.tolist())}
        for r, s in zip(robots.tolist(), np.asarray(sinr_db).tolist()):
            self.sinr_db[at[r]] = s


class ReceptionLog:
    """Every reception of a run's ``channel`` (module notes), kept as the channel decides."""

    def __init__(self, channel: Any):
        self.channel = channel
        self.causes: tuple[str, ...] = channel.causes
        rec = channel.reception
        # The power of a pair: log-distance path loss with its shadowing and walls; no law, no power.
        self.powered = rec is not None and rec.compiled.log is not None
        self.out_of_range = self.causes.index("out_of_range")
        self._frames: list[FrameRows] = []
        # Frames opened and not closed yet, by identity: under a medium, those on the air.
        self._open: dict[int, FrameRows] = {}

    def code(self, cause: str) -> int:
        return self.causes.index(cause)

    def open(
        self,
        t: float,
        sender: int,
        kind: str,
        candidates: np.ndarray,
        distances_m: np.ndarray,
        heard: np.ndarray | None,
        sinr_db: float,
    ) -> FrameRows:
        """A frame's rows: ``candidates`` at ``distances_m``, of which the radio kept
        ``heard`` (None: all); the power of each, as the radio just decided it."""
        k = len(candidates)
        power = np.full(k, math.nan)
        if self.powered and k:
            rec = self.channel.reception
            within = rec.within_reach(distances_m)
            if heard is None or within.all():
                power = rec.received_dbm(t, sender, candidates, distances_m)
            elif within.any():
                power[within] = rec.received_dbm(t, sender, candidates[within], distances_m[within])
        rows = FrameRows(t, sender, kind, candidates, distances_m, power, sinr_db)
        if heard is not None:
            rows.cause[~np.asarray(heard, dtype=bool)] = self.out_of_range
        self._open[id(rows)] = rows
        return rows

    def close(self, rows: FrameRows) -> None:
        """``rows``' frame is decided: keep them."""
        del self._open[id(rows)]
        if len(rows.dst):
            self._frames.append(rows)

    def frame(self, legs: pd.DataFrame, n: int, side_m: float | None = None, torus: bool = False) -> pd.DataFrame:
        """The table (:data:`RECEPTIONS_SCHEMA`), in order of the frames' start (a frame's
        rows in the order of its receivers), with both ends' positions at ``t_s`` from the
        run's ``legs`` (of ``n`` robots; folded into the square of ``side_m`` on a torus, as
        ``positions.parquet``): what ``netsim calibrate`` reads a pair's travel and walls from.
        A frame still on the air at the end gives the rows of the receivers it had dropped."""
        # A frame the run's end cut short keeps the rows its drops were counted for.
        cut = [f for f in (rows.failed() for rows in self._open.values()) if len(f.dst)]
        fs = self._frames + cut
        if not fs:
            return pd.DataFrame({c: pd.Series(dtype=t) for c, t in RECEPTIONS_SCHEMA.items()})
        counts = [len(f.dst) for f in fs]
        cause = np.concatenate([f.cause for f in fs])
        names = np.array([None, *self.causes], dtype=object)
        df = pd.DataFrame(
            {
                "t_s": np.repeat([f.t_s for f in fs], counts).astype(float),
                "src": np.repeat([f.src for f in fs], counts).astype(np.int64),
                "dst": np.concatenate([f.dst for f in fs]),
                "kind": np.repeat(np.array([f.kind for f in fs], dtype=object), counts),
                "distance_m": np.concatenate([f.distance_m for f in fs]),
                "rx_power_dbm": np.concatenate([f.power_dbm for f in fs]),
                "sinr_db": np.concatenate([f.sinr_db for f in fs]),
                "received": cause == NO_CAUSE,
                "cause": names[cause + 1],
            }
        )
        # Under a medium a frame is decided at its end: back in order of the starts.
        order = np.argsort(df["t_s"].to_numpy(), kind="stable")
        df = df.iloc[order].reset_index(drop=True)
        t, k = df["t_s"].to_numpy(), len(df)
        table = LegTable(legs, n)
        robots, times = np.r_[df["src"].to_numpy(), df["dst"].to_numpy()], np.r_[t, t]
        xy = table.at(table.legs_at(robots, times), times)
        if torus:
            xy = in_box(xy, side_m)
        df["src_x_m"], df["src_y_m"], df["dst_x_m"], df["dst_y_m"] = xy[:k, 0], xy[:k, 1], xy[k:, 0], xy[k:, 1]
        return df
