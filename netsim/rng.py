"""Independent random streams, one per named component.

Every draw in a run comes from a generator keyed by ``(seed, run, name, index)``, so
switching the protocol, or adding draws to one component, never changes another
component's draws (as ns-3's ``AssignStreams``). Replications keep the seed and advance
``run``.
"""

from __future__ import annotations

import zlib
from typing import Any

import numpy as np


def stream(seed: int, run: int, name: str, index: int = 0) -> np.random.Generator:
    """Return the generator of component ``name`` (robot or sub-stream ``index``).

    >>> a = stream(1, 0, "mobility", 3).random()
    >>> b = stream(1, 0, "mobility", 3).random()
    >>> a == b
    True
    """
    key = (int(run), zlib.crc32(name.encode()), int(index))
    return np.random.Generator(np.random.PCG64(np.random.SeedSequence(int(seed), spawn_key=key)))


class Streams:
    """The random streams of one run."""

    def __init__(self, seed: int, run: int = 0):
        self.seed = int(seed)
        self.run = int(run)

    def get(self, name: str, index: int = 0) -> np.random.Generator:
        return stream(self.seed, self.run, name, index)


class KindStreams:
    """One stream per kind of frame, named ``<name>.<kind>``, behind one generator's face.

    A component that draws for every frame (the channel's loss model, its latency jitter)
    draws from the stream of the frame's kind, chosen by :meth:`use` before it draws; any
    :class:`numpy.random.Generator` method reaches the chosen stream. So traffic of one kind
    (messages, a routing protocol's hellos) never changes the draws of another (the Acks).
    """

    def __init__(self, streams: Streams, name: str):
        self._streams = streams
        self._name = name
        self._by_kind: dict[str, np.random.Generator] = {}
        self.current = self.use("ack")

    def use(self, kind: str) -> np.random.Generator:
        """Make the stream of frames of ``kind`` the one drawn from, and return it."""
        g = self._by_kind.get(kind)
        if g is None:
            g = self._by_kind[kind] = self._streams.get(f"{self._name}.{kind}")
        self.current = g
        return g

    def __getattr__(self, name: str) -> Any:
        if name.startswith("_"):  # not a generator's method (copy and pickle look for these)
            raise AttributeError(name)
        return getattr(self.current, name)
