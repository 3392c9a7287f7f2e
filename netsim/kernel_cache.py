"""numba's on-disk cache of the compiled kernels, keyed by the sources they are built from.

numba checks a cached function against its own source file only (numba issue 1833): a
kernel that calls a kernel of another module (``protocols._kernels`` calls
``netsim._kernels``), or reads a constant imported from one, would go on running the old
code after an edit of that other module alone, silently. So every kernel module ends with
``key(globals())``: the cache of each function it compiles goes to a directory named by a
hash of the module's own source and of every module it imports from (a kernel module
stands there by its own key, so the hash follows the calls all the way down). An edit
anywhere below a kernel gives it a new directory, where it is compiled again; going back
to earlier sources finds their directory still there.

The directories sit under ``$NUMBA_CACHE_DIR`` when it is set, else under
``$XDG_CACHE_HOME/netsim-robots/kernels`` (``~/.cache/netsim-robots/kernels`` by default).
Only the kernels' own functions are pointed there, while :func:`key` runs: the rest of
the process's numba settings are left as they were.

A directory with no compiled code in it means the module's loops will be compiled, not
loaded, which takes a while the first time a version runs on a machine: a command that
wants to say so asks :func:`when_cold` to be told.
"""

from __future__ import annotations

import hashlib
import os
import re
import sys
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

_KEYS: dict[str, str] = {}  # kernel module -> its key
_LOCK = threading.Lock()  # numba's cache directory is one global setting while a module is keyed
_ON_COLD: list[Callable[[Path], object]] = []  # told once, of the first cold directory (when_cold)


def base_directory() -> Path:
    """Where the keyed directories go (module notes)."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        return Path(os.environ["NUMBA_CACHE_DIR"])
    cache_home = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(cache_home) / "netsim-robots" / "kernels"


def when_cold(callback: Callable[[Path], object] | None) -> None:
    """Have ``callback(directory)`` called once, the next time a kernel module is keyed to
    a directory that holds no compiled code yet (its loops are about to be compiled rather
    than loaded); None: no call."""
    with _LOCK:
        _ON_COLD[:] = [] if callback is None else [callback]


def is_cold(directory: Path) -> bool:
    """Whether ``directory`` (a module's keyed directory) holds no compiled code: numba
    writes an index (``*.nbi``) beside each function's code."""
    return not any(directory.rglob("*.nbi"))


# Import statements, read by pattern rather than by parsing the module (which costs more
# than loading its cached code): ``from`` with its dots, module and names (parenthesised
# over lines, or to the end of the line), and plain ``import``.
_FROM = re.compile(r"^[ \t]*from[ \t]+(\.*)([\w.]*)[ \t]+import[ \t]+(\([^)]*\)|[^\n#]*)", re.M)
_IMPORT = re.compile(r"^[ \t]*import[ \t]+([^\n#]+)", re.M)


def imported_modules(source: str, package: str | None) -> list[str]:
    """The modules ``source`` imports from, by absolute name (relative imports resolved
    against ``package``); ``from a import b`` names ``a`` and, where ``b`` is itself a
    module, ``a.b``. A line of a docstring that reads like an import counts too: it can
    only add a file to the hash."""
    names: list[str] = []
    for dots, module, imported in _FROM.findall(source):
        base = module
        if dots:
            parts = (package or "").split(".")
            parts = parts[: len(parts) - len(dots) + 1]
            base = ".".join([*parts, module] if module else parts)
        names.append(base)
        for alias in imported.strip("()").split(","):
            if alias.split():
                names.append(f"{base}.{alias.split()[0]}")
    for listed in _IMPORT.findall(source):
        names += [alias.split()[0] for alias in listed.split(",") if alias.split()]
    return names


def source_key(module_name: str) -> str:
    """The hash of ``module_name``'s source and of what it imports from (module notes):
    a module already keyed counts by its key, any other by its source file, if it has one."""
    module = sys.modules[module_name]
    path = Path(module.__file__ or "")
    source = path.read_bytes()
    digest = hashlib.sha256(source)
    for name in imported_modules(source.decode(), module.__package__):
        if name in _KEYS:
            digest.update(f"{name}={_KEYS[name]}\n".encode())
            continue
        found = sys.modules.get(name)
        file = getattr(found, "__file__", None)
        if found is not None and file and file.endswith(".py"):
            digest.update(f"{name}\n".encode())
            digest.update(Path(file).read_bytes())
    return digest.hexdigest()[:20]


def key(namespace: dict[str, Any]) -> Path:
    """Point the cache of every compiled function defined in the module whose globals are
    ``namespace`` at its keyed directory; returns that directory. Called once, at the end
    of each kernel module."""
    from numba.core import config
    from numba.core.dispatcher import Dispatcher

    name = namespace["__name__"]
    with _LOCK:
        module_key = source_key(name)
        directory = base_directory() / module_key
        # numba's settings are set from the environment when it loads: untyped.
        kept = config.CACHE_DIR  # type: ignore[attr-defined]
        config.CACHE_DIR = str(directory)  # type: ignore[attr-defined]
        try:
            for value in list(namespace.values()):
                if isinstance(value, Dispatcher) and value.py_func.__module__ == name:
                    value.enable_caching()  # a cache located under config.CACHE_DIR now
        finally:
            config.CACHE_DIR = kept  # type: ignore[attr-defined]
        _KEYS[name] = module_key
        told = _ON_COLD[:] if _ON_COLD and is_cold(directory) else []
        if told:
            _ON_COLD.clear()
    for callback in told:
        callback(directory)
    return directory


def keyed_modules() -> dict[str, str]:
    """The kernel modules keyed so far in this process, with their keys."""
    return dict(_KEYS)
