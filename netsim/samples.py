"""The output layer's buffers for tables sampled during a run (a protocol's groups and
beliefs, say): each sample written as it comes into one buffer per column, the table at
the end the buffers' filled part."""

from __future__ import annotations

import math
import mmap
import sys
from collections.abc import Callable, Mapping

import numpy as np
import pandas as pd


def copy_on_write() -> bool:
    """Whether pandas copies a table's column before writing to one it shares (always
    from pandas 3; an option before)."""
    return int(pd.__version__.split(".")[0]) >= 3 or pd.get_option("mode.copy_on_write") is True


def _multiples(interval_s: float, end_s: float) -> int:
    """How many multiples of ``interval_s`` from 0 fall short of ``end_s`` by more than a
    rounding error (:func:`ended_at`: one within it is the instant at the end)."""
    if interval_s <= 0:
        return 0
    k = (end_s - _rounding(end_s)) / interval_s
    if not math.isfinite(k):
        return sys.maxsize
    k = max(int(math.ceil(k)), 0)
    if k > 2**52:
        return k  # past any memory: a count to refuse, where one more or less is no matter
    # The quotient's own rounding: step to the first multiple that reaches the end's band.
    while k > 0 and ended_at([(k - 1) * interval_s], end_s):
        k -= 1
    while not ended_at([k * interval_s], end_s):
        k += 1
    return k


def sample_count(interval_s: float, end_s: float) -> int:
    """How many instants :func:`sample_times` gives, counted without making them (a count
    past any memory is still a number to refuse)."""
    k = _multiples(interval_s, end_s)
    return k + 1 if interval_s > 0 and k < sys.maxsize else k


def sample_times(interval_s: float, end_s: float) -> np.ndarray:
    """The instants of every table sampled over a run (positions, a protocol's groups and
    beliefs): ``k interval_s`` from 0 (a product, never a sum of intervals, so that every
    table names an instant alike) while short of ``end_s``, then ``end_s`` itself, where the
    run ends (a multiple within a rounding error of it is that instant). None for an
    interval of 0."""
    if interval_s <= 0:
        return np.empty(0)
    return np.append(np.arange(_multiples(interval_s, end_s), dtype=float) * interval_s, end_s)


def _rounding(end_s: float) -> float:
    return 1e-9 * max(1.0, abs(end_s))


def ended_at(times: list[float], end_s: float) -> bool:
    """Whether sampling ``times`` already hold the instant ``end_s`` (a multiple of an
    interval may fall a rounding error short of it: that sample is it)."""
    return bool(times) and times[-1] >= end_s - _rounding(end_s)


class Samples:
    """A table sampled during the run: each sample's columns (arrays of one length) and its
    time ``t_s``, written as they come into one buffer per column, so that the table at the
    end is the buffers' filled part (no concatenation: at 10,000 robots the samples are
    hundreds of MB, and every fresh page costs a fault).

    When short, a buffer grows, at least to double, to what the remaining samples need at a
    typical sample's rows (the current one's; for a sample written in place,
    :meth:`reserve`, the latest one's), with a margin, plus the most rows one sample may
    take: so it grows once or twice in a run. Capacity never written is never touched, so
    costs no memory."""

    MARGIN = 1.25

    def __init__(self, expected: int = 1) -> None:
        self.times: list[float] = []
        self.expected = max(int(expected), 1)
        self.rows = 0
        self.last_rows = 0  # the latest sample's
        self._t = np.empty(0)
        self._buffers: dict[str, np.ndarray] = {}
        self._handed_out: pd.DataFrame | None = None  # :meth:`frame`'s

    def __len__(self) -> int:
        return len(self.times)

    def add(self, now: float, columns: dict[str, np.ndarray]) -> Samples:
        m = len(next(iter(columns.values()))) if columns else 0
        room = self.reserve({name: np.asarray(col).dtype for name, col in columns.items()}, m, m)
        for name, col in columns.items():
            room[name][:] = col
        return self.commit(now, m)

    def reserve(self, dtypes: Mapping[str, np.dtype], rows: int, typical: int) -> dict[str, np.ndarray]:
        """Room for a sample of at most ``rows`` rows, to be filled and then kept by
        :meth:`commit`: each column's buffer (``dtypes``, in the table's order: the first
        sample's make the buffers) from the next free row on, ``rows`` long. When short,
        the buffers grow to what the remaining samples need at ``typical`` rows each, at
        least double."""
        if not self._buffers:
            self._buffers = {name: np.empty(0, dtype=dtype) for name, dtype in dtypes.items()}
        at, end = self.rows, self.rows + rows
        if end > len(self._t):
            left = max(self.expected - len(self.times), 1)
            self._grow(max(2 * len(self._t), at + int(self.MARGIN * typical * left) + rows))
        return {name: buf[at:end] for name, buf in self._buffers.items()}

    def commit(self, now: float, rows: int) -> Samples:
        """Keep the first ``rows`` rows of the room :meth:`reserve` gave as the sample at
        ``now``."""
        at, end = self.rows, self.rows + rows
        self._t[at:end] = now
        self.times.append(now)
        self.rows = end
        self.last_rows = rows
        return self

    def _grow(self, capacity: int) -> None:
        def grown(buf: np.ndarray) -> np.ndarray:
            new = column_buffer(capacity, buf.dtype)
            new[: self.rows] = buf[: self.rows]
            return new

        self._t = grown(self._t)
        self._buffers = {name: grown(buf) for name, buf in self._buffers.items()}
        # The old buffers are no longer the run's: a table handed out may keep them alone.
        self._handed_out = None

    def frame(self, convert: Mapping[str, Callable[[np.ndarray], object]] | None = None) -> pd.DataFrame:
        """All samples, in order, as one table: ``t_s`` first, then the columns (each
        passed through ``convert[name]`` if given)."""
        rows = self.rows
        out: dict[str, object] = {"t_s": self._t[:rows]}
        for name, buf in self._buffers.items():
            col = buf[:rows]
            out[name] = convert[name](col) if convert and name in convert else col
        # The columns are the buffers' filled part, never written again (later samples go
        # after it, or into a grown buffer): copying them into blocks would only cost. The
        # caller's table must not write them either (a later collect reads them): handed
        # out beside a table kept here, pandas' copy on write copies a column the caller
        # writes to; without copy on write (pandas 2 by default), a copy is handed out.
        kept = pd.DataFrame(out, copy=False)
        if not copy_on_write():
            return kept.copy()
        self._handed_out = kept
        return kept.copy(deep=False)


def column_buffer(capacity: int, dtype: np.dtype) -> np.ndarray:
    """An empty array of ``capacity`` items of ``dtype`` whose memory is touched only where
    written, in pages of 4 KiB: numpy asks for huge pages (2 MiB) for large arrays, and where
    the kernel compacts memory to find one at its first write (transparent huge pages'
    ``defrag = madvise``, a common default) can cost far more per huge page than the faults
    of its 512 small pages. Arrays of objects: numpy's."""
    dtype = np.dtype(dtype)
    if dtype.hasobject or capacity == 0:
        return np.empty(capacity, dtype=dtype)
    size = capacity * dtype.itemsize
    # Private: a process forked later (a worker) writes its own copy, never this one.
    private = getattr(mmap, "MAP_PRIVATE", None)
    memory = mmap.mmap(-1, size, flags=private | mmap.MAP_ANONYMOUS) if private is not None else mmap.mmap(-1, size)
    if hasattr(mmap, "MADV_NOHUGEPAGE"):  # where huge pages are always used unless refused
        memory.madvise(mmap.MADV_NOHUGEPAGE)
    return np.frombuffer(memory, dtype=dtype, count=capacity)
