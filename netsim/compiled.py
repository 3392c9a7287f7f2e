"""Whether the hot path runs its compiled (numba) loops, and loading them.

The per-message work of the channel and the Ack beacon (range queries, neighbour tables)
has compiled twins of its numpy code; each computes exactly what the numpy code computes
(tests compare them with ``==``). Importing numba and loading its cached machine code
costs about 0.4 s, more than a small run's whole simulation, so runs of fewer than
:data:`SMALL_RUN_ROBOTS` robots keep the numpy code. ``NETSIM_COMPILED=0`` or ``=1`` in the
environment forces one or the other (for the comparisons; the outputs are the same).
"""

from __future__ import annotations

import importlib
import os
from types import ModuleType

SMALL_RUN_ROBOTS = 20


def compiled_wanted(n_robots: int) -> bool:
    """Whether a run of ``n_robots`` should use the compiled loops."""
    forced = os.environ.get("NETSIM_COMPILED", "")
    if forced in ("0", "1"):
        return forced == "1"
    return n_robots >= SMALL_RUN_ROBOTS


def load(module: str, n_robots: int) -> ModuleType | None:
    """The module of compiled loops ``module`` when wanted for ``n_robots``, else None
    (also where numba is missing: it is a dependency, the numpy code is the fallback)."""
    if not compiled_wanted(n_robots):
        return None
    try:
        return importlib.import_module(module)
    except ImportError:  # pragma: no cover
        return None
