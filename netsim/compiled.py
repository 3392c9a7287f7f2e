"""Whether the hot path runs its compiled (numba) loops, and loading them.

The per-message work of the channel and the Ack beacon (range queries, neighbour tables)
has compiled twins of its numpy code; each computes exactly what the numpy code computes
(tests compare them with ``==``). Importing numba and loading its cached machine code
costs more than a small run's whole simulation, so runs of fewer than
:data:`SMALL_RUN_ROBOTS` robots keep the numpy code. ``NETSIM_COMPILED=0`` or ``=1`` in the
environment forces one or the other (for the comparisons; the outputs are the same).
"""

from __future__ import annotations

import importlib
import os
import sys
import threading
from collections.abc import Callable
from types import ModuleType
from typing import TypeVar

SMALL_RUN_ROBOTS = 20

T = TypeVar("T")
U = TypeVar("U")


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
    loaded = sys.modules.get(module)
    if loaded is not None:  # asked for at every rebuild of the range index
        return loaded
    try:
        _numba_without_blas_probe()
        return importlib.import_module(module)
    except ImportError:  # pragma: no cover
        return None


def _numba_without_blas_probe() -> None:
    """Load numba's numpy registry without its probe for scipy's BLAS.

    On its first compile or cache load numba imports ``numba.np.arraymath``, which tries
    ``import scipy.linalg.cython_blas`` to decide whether its ``np.correlate`` and
    ``np.convolve`` may call BLAS (else a plain loop, the same results). Importing
    scipy.linalg is a noticeable part of a large run's whole process, and no compiled loop
    here uses BLAS. So while that module loads, the probe finds nothing; the
    entry is removed at once, so that scipy.linalg imports as usual afterwards. Where
    scipy.linalg is already loaded the probe costs nothing and is left alone.
    """
    if "numba.np.arraymath" in sys.modules or "scipy.linalg" in sys.modules:
        return
    probe = "scipy.linalg.cython_blas"
    sys.modules[probe] = None  # type: ignore[assignment]  # an import of it now fails at once
    try:
        importlib.import_module("numba.np.arraymath")
    finally:
        del sys.modules[probe]


def cores() -> int:
    """The cores this process may run on."""
    affinity = getattr(os, "sched_getaffinity", None)
    return len(affinity(0)) if affinity is not None else os.cpu_count() or 1


def side_by_side(first: Callable[[], T], second: Callable[[], U]) -> tuple[T, U]:
    """``(first(), second())``, ``second`` run in a thread of its own meanwhile: for two
    compiled loops that release the GIL (``nogil``), each on its own part of the work, on a
    machine of two cores or more (where no thread can be started, one after the other). An
    exception in either is raised here, once both are done."""
    box: list = []

    def run() -> None:
        try:
            box.append(second())
        except BaseException as error:  # raised in the caller's thread below
            box.append(error)

    thread = threading.Thread(target=run, name="netsim-side-by-side")
    try:
        thread.start()
    except RuntimeError:  # no thread to be had (a limit on threads): one after the other
        a = first()
        run()
    else:
        try:
            a = first()
        finally:
            thread.join()
    (b,) = box
    if isinstance(b, BaseException):
        raise b
    return a, b
