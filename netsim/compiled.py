"""The compiled loops (kernels): written once, run compiled or as plain Python.

Each hot rule is one function in a kernel module (``_kernels.py``), written in numba's loop
style and marked :func:`jit`. Importing a kernel module loads no numba: its functions are
plain Python, which is how a small run calls them. :func:`load` decides, in this one place,
which a run gets: for :data:`SMALL_RUN_ROBOTS` robots or more the module's compiled copy
(:func:`compiled_copy`: every marked function compiled by numba from the same source), else
the module itself. Importing numba and loading its cached machine code costs more than a
small run's whole simulation; a loop over a few robots costs little in Python.
``NETSIM_COMPILED=0`` or ``=1`` in the environment forces one or the other (the outputs are
the same, bit for bit: the tests run both).
"""

from __future__ import annotations

import importlib
import os
import sys
import threading
import types
from collections.abc import Callable
from types import ModuleType
from typing import Any, TypeVar

import numpy as np

# numba vectorises loops with Intel's SVML where that library is installed (icc_rt), whose
# functions round their own way: a compiled kernel would then differ from its plain run.
os.environ.setdefault("NUMBA_DISABLE_INTEL_SVML", "1")

SMALL_RUN_ROBOTS = 20
# Kernel modules whose loops walk a map cell by cell (line of sight, walls swept, free
# destinations): compiled at any team size. A plain-Python walk pays the interpreter at
# every cell of every segment, and a small team on a map traces enough segments to cost
# more than numba's import.
WALKS_MAPS = frozenset({"netsim.world._kernels", "netsim.world._sweep_kernels"})

T = TypeVar("T")
U = TypeVar("U")
F = TypeVar("F", bound=Callable[..., Any])

_JIT = "__netsim_jit__"  # a kernel's numba options, set by jit
_WALKS = "__netsim_walks__"  # set by jit on a kernel that walks a map (jit's walks)
_COPIES: dict[str, ModuleType] = {}  # kernel module -> its compiled copy
# (kernel module, whether its map walks may run compiled) -> itself, or its plain copy
# (plain_copy): NETSIM_COMPILED set or cleared within a process gives the other one.
_PLAIN: dict[tuple[str, bool], ModuleType] = {}
_COPY_LOCK = threading.RLock()


def jit(walks: bool = False, **options: Any) -> Callable[[F], F]:
    """Mark a kernel: compiled with ``numba.njit(cache=True, **options)`` in its module's
    compiled copy, itself (plain Python) in the module. ``walks``: the kernel walks a map
    cell by cell, so a plain copy calls it compiled all the same, as it calls the kernels of
    :data:`WALKS_MAPS` (:func:`plain_copy`)."""

    def mark(function: F) -> F:
        setattr(function, _JIT, options)
        if walks:
            setattr(function, _WALKS, True)
        return function

    return mark


def is_kernel(value: object) -> bool:
    """Whether ``value`` is a function marked by :func:`jit`."""
    return isinstance(value, types.FunctionType) and hasattr(value, _JIT)


def compiled_wanted(n_robots: int | None) -> bool:
    """Whether a run of ``n_robots`` should use the compiled loops; None: a caller that
    cannot know the team's size (a batch tool) gets them compiled."""
    forced = os.environ.get("NETSIM_COMPILED", "")
    if forced in ("0", "1"):
        return forced == "1"
    return n_robots is None or n_robots >= SMALL_RUN_ROBOTS


def load(module: str, n_robots: int | None, values: int | None = None) -> ModuleType:
    """The kernel module ``module`` as a run of ``n_robots`` robots (None: not known) calls
    it: its compiled copy when wanted (:func:`compiled_wanted`, or a module of
    :data:`WALKS_MAPS` unless ``NETSIM_COMPILED=0``) and numba is there, else the module in
    plain Python (:func:`plain_copy`, whose kernels that walk a map run compiled all the
    same). ``values``: for a law called on a batch of values whose caller may not know the
    team (a map's walks among them), the batch's length stands for an unknown size. The
    one place that decides: no call site chooses for itself."""
    size = values if n_robots is None and values is not None else n_robots
    if module in WALKS_MAPS and size is not None:
        size = max(size, SMALL_RUN_ROBOTS)
    if compiled_wanted(size):
        try:
            return compiled_copy(module)
        except ImportError:  # pragma: no cover  (numba is a dependency; plain Python is the fallback)
            pass
    return plain_copy(module)


def plain_copy(module: str) -> ModuleType:
    """The kernel module ``module`` in plain Python: the module itself, unless it holds a
    kernel that walks a map (a kernel of a module of :data:`WALKS_MAPS`, or one marked by
    :func:`jit`'s ``walks``), which even a plain loop calls compiled (numba loaded at the
    first such call, not before: a run without a map never makes one). Then a copy of the
    module whose kernels see those kernels compiled."""
    walks_compiled = compiled_wanted(SMALL_RUN_ROBOTS)
    copy = _PLAIN.get((module, walks_compiled))
    if copy is not None:
        return copy
    plain = importlib.import_module(module)
    walks = {
        key: value
        for key, value in plain.__dict__.items()
        if is_kernel(value)
        and ((value.__module__ != module and value.__module__ in WALKS_MAPS) or getattr(value, _WALKS, False))
    }
    if not walks or not walks_compiled:
        _PLAIN[module, walks_compiled] = plain
        return plain
    copy = ModuleType(module, plain.__doc__)
    namespace = copy.__dict__
    namespace.update(plain.__dict__)
    for key, value in plain.__dict__.items():
        if key in walks:
            namespace[key] = _compiled_on_call(value)
        elif is_kernel(value) and value.__module__ == module:
            namespace[key] = _rebound(value, namespace)
    _PLAIN[module, walks_compiled] = copy
    return copy


def _rebound(function: types.FunctionType, namespace: dict[str, Any]) -> types.FunctionType:
    """``function`` with ``namespace`` for its globals (the same code)."""
    out = types.FunctionType(
        function.__code__, namespace, function.__name__, function.__defaults__, function.__closure__
    )
    out.__qualname__ = function.__qualname__
    out.__doc__ = function.__doc__
    return out


def _compiled_on_call(kernel: Callable[..., Any]) -> Callable[..., Any]:
    """A plain function calling the compiled ``kernel``, compiled at its first call."""
    name, module = kernel.__name__, kernel.__module__
    found: list[Callable[..., Any]] = []

    def call(*args: Any) -> Any:
        if not found:
            found.append(getattr(compiled_copy(module), name))
        return found[0](*args)

    call.__name__ = call.__qualname__ = name
    return call


def compiled_copy(module: str) -> ModuleType:
    """The compiled copy of the kernel module ``module``: a module of the same globals in
    which every function marked :func:`jit` is numba's compilation of the same source (its
    globals the copy's, so that a kernel calls the compiled kernels), and every kernel it
    imports from another kernel module is that module's compiled one. Made once per process;
    the machine code is cached on disk (:mod:`netsim.kernel_cache`)."""
    copy = _COPIES.get(module)
    if copy is not None:
        return copy
    with _COPY_LOCK:
        copy = _COPIES.get(module)
        if copy is None:
            copy = _COPIES[module] = _compile(module)
    return copy


def _compile(name: str) -> ModuleType:
    _numba_without_blas_probe()
    import numba

    from netsim import kernel_cache

    plain = importlib.import_module(name)
    copy = ModuleType(name, plain.__doc__)
    namespace = copy.__dict__
    namespace.update(plain.__dict__)
    for key, value in plain.__dict__.items():
        if not is_kernel(value):
            continue
        if value.__module__ != name:  # a kernel of another module, imported here
            namespace[key] = getattr(compiled_copy(value.__module__), value.__name__)
            continue
        namespace[key] = numba.njit(cache=True, **getattr(value, _JIT))(_rebound(value, namespace))
    kernel_cache.key(namespace)
    return copy


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


def filled(values: Any, shape: Any, dtype: Any = float) -> np.ndarray:
    """``values`` broadcast to ``shape``, as a new writable C-contiguous array: what a kernel
    is handed. numba compiles a kernel once for each array type, and a read-only view (what
    broadcasting gives where no copy is needed) is a type of its own: a second compiled copy
    to load for the same call."""
    return np.array(np.broadcast_to(np.asarray(values, dtype), shape), dtype=dtype, order="C")


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
