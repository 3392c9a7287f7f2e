"""Independent random streams, one per named component.

Every draw in a run comes from a generator keyed by ``(seed, run, name, index)``, so
switching the protocol, or adding draws to one component, never changes another
component's draws (as ns-3's ``AssignStreams``). Replications keep the seed and advance
``run``.
"""

from __future__ import annotations

import zlib

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
