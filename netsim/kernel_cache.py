"""numba's on-disk cache of the compiled kernels, keyed by the sources they are built from.

numba checks a cached function against its own source file only (numba issue 1833): a
kernel that calls a kernel of another module (``netsim.protocols._kernels`` calls
``netsim._kernels``), or reads a constant imported from one, would go on running the old
code after an edit of that other module alone, silently. So every kernel module ends with
``key(globals())``: the cache of each function it compiles goes to a directory named by
the module and a hash of numba's and Python's versions and of every source the module
reaches by imports: its own, and, through any chain of modules of the same distribution
(its top-level package) or of the engine (``netsim``), each one's source, a kernel module
standing there by its own key. A constant re-exported through a plain module, or a kernel
reached through a plain facade, is therefore in the hash as surely as a direct import. An
edit anywhere below a kernel gives it a new directory, where it is compiled again.

The directories sit under ``$NUMBA_CACHE_DIR`` when it is set, else under
``$XDG_CACHE_HOME/netsim-robots/kernels`` (``~/.cache/netsim-robots/kernels`` by default).
Each module keeps its ``KEPT_VERSIONS`` most recently used directories (so that two
checkouts used in turn, as a before-and-after measurement does, both stay compiled); older
ones are deleted when a module is keyed. Only the kernels' own functions are pointed
there, while :func:`key` runs: the rest of the process's numba settings are left as they
were.

What a source file gives the hash (its digest and the modules it imports from) is kept
beside the directories, in ``sources.json``, by the file's path, modification time (ns) and
size, so that a process does not read and scan every source again: a file whose time or
size differs is read again. A file changed in the last ``SETTLE_S`` seconds is not kept
there (an edit within the same tick of a coarse clock, at the same size, would otherwise
look unchanged), as git treats a file changed in the second its index was written.

An index that cannot be read (it names a type whose module this process cannot import)
is a miss, not an error: the kernel is compiled again and the index written anew, with
this signature alone (the others are compiled again when next asked for).

A module none of whose functions has code numba can load (:func:`is_cold`) will be
compiled, which takes a while the first time a version runs from a checkout: a command
that wants to say so asks :func:`when_cold` to be told.
"""

from __future__ import annotations

import hashlib
import importlib.util
import json
import os
import pickle
import re
import shutil
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

_KEYS: dict[str, str] = {}  # kernel module -> its key
_LOCK = threading.Lock()  # numba's cache directory is one global setting while a module is keyed
KEPT_VERSIONS = 4
_PATHS: dict[str, str | None] = {}  # module not loaded -> its file, None if no module
_SOURCES: dict[str, tuple[tuple[str, int, int], bytes, list[str]]] = {}  # module -> (file's stamp, digest, imports)
_ON_COLD: list[Callable[[Path], object]] = []  # told once, of the first cold directory (when_cold)
SOURCES_FILE = "sources.json"
SETTLE_S = 2.0
_KEPT: dict[str, list] = {}  # "module file" -> [mtime_ns, size, digest (hex), imports], as in SOURCES_FILE
_KEPT_STATE = {"read": False, "new": False}


def base_directory() -> Path:
    """Where the keyed directories go (module notes)."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        return Path(os.environ["NUMBA_CACHE_DIR"])
    cache_home = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(cache_home) / "netsim-robots" / "kernels"


def when_cold(callback: Callable[[Path], object] | None) -> None:
    """Have ``callback(directory)`` called once, the next time a kernel module is keyed
    whose loops are about to be compiled rather than loaded (:func:`is_cold`); None: no
    call."""
    with _LOCK:
        _ON_COLD[:] = [] if callback is None else [callback]


def is_cold(dispatchers: list[Any]) -> bool:
    """Whether numba will compile the module of these compiled functions rather than load
    it: none of them has an index it can use (one stamped with its source as it is now).
    numba files a function's code under a folder named by its source file's own folder, so
    the code another checkout compiled (the same sources at another path) is not this
    one's, though it is in the same keyed directory."""
    for dispatcher in dispatchers:
        index = getattr(getattr(dispatcher, "_cache", None), "_cache_file", None)
        load_index = getattr(index, "_load_index", None)
        if load_index is None or load_index():
            return False
    return bool(dispatchers)


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


def _module_path(name: str) -> str | None:
    """Where module ``name`` lives (its ``.py`` file, or its package's ``__init__.py``),
    found from its parents' locations without importing anything: an import inside a
    function has not run yet, and a name may be an attribute (``from a import b``)."""
    module = sys.modules.get(name)
    if module is not None:
        return getattr(module, "__file__", None)
    if name in _PATHS:
        return _PATHS[name]
    parent, _, child = name.rpartition(".")
    found = None
    if not parent or parent in sys.modules:
        # The import system's own finders (an installed layout, a folder mapped into a
        # package) locate it; only the parent, loaded already, is imported on the way.
        try:
            spec = importlib.util.find_spec(name)
        except (ImportError, ValueError, AttributeError):
            spec = None
        found = spec.origin if spec is not None and spec.has_location else None
    else:
        above = _module_path(parent)
        if above is not None and os.path.basename(above) == "__init__.py":
            folder = os.path.dirname(above)
            for candidate in (os.path.join(folder, f"{child}.py"), os.path.join(folder, child, "__init__.py")):
                if os.path.isfile(candidate):
                    found = candidate
                    break
    _PATHS[name] = found
    return found


def _read(name: str, file: str) -> tuple[bytes, list[str]]:
    """The digest of a source file and the modules it imports from, read once per version
    of the file (many kernel modules reach the same sources): in this process, or kept in
    :data:`SOURCES_FILE` (module notes)."""
    stat = os.stat(file)
    stamp = (file, stat.st_mtime_ns, stat.st_size)
    if _SOURCES.get(name, (None,))[0] != stamp:
        entry = f"{name} {file}"
        kept = _kept().get(entry)
        if kept is not None and kept[:2] == [stat.st_mtime_ns, stat.st_size]:
            _SOURCES[name] = (stamp, bytes.fromhex(kept[2]), list(kept[3]))
        else:
            with open(file, "rb") as f:
                source = f.read()
            package = name if os.path.basename(file) == "__init__.py" else name.rpartition(".")[0]
            _SOURCES[name] = (stamp, hashlib.sha256(source).digest(), imported_modules(source.decode(), package))
            if time.time_ns() - stat.st_mtime_ns > SETTLE_S * 1e9:
                _KEPT[entry] = [stat.st_mtime_ns, stat.st_size, _SOURCES[name][1].hex(), _SOURCES[name][2]]
                _KEPT_STATE["new"] = True
    _, digest, imports = _SOURCES[name]
    return digest, imports


def _kept() -> dict[str, list]:
    """What :data:`SOURCES_FILE` holds, read once per process (nothing where it cannot be read)."""
    if not _KEPT_STATE["read"]:
        _KEPT_STATE["read"] = True
        try:
            kept = json.loads((base_directory() / SOURCES_FILE).read_text())
        except (OSError, ValueError):
            kept = {}
        if isinstance(kept, dict):
            _KEPT.update(
                (k, v)
                for k, v in kept.items()
                if isinstance(v, list) and len(v) == 4 and isinstance(v[2], str) and isinstance(v[3], list)
            )
    return _KEPT


def _keep_sources() -> None:
    """Write :data:`SOURCES_FILE` when this process read a source it did not hold, whole or
    not at all (another process reads it meanwhile); a directory that cannot be written
    only costs the next process the reading."""
    if not _KEPT_STATE["new"]:
        return
    _KEPT_STATE["new"] = False
    path = base_directory() / SOURCES_FILE
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        partial = path.with_name(f"{SOURCES_FILE}.{os.getpid()}.{threading.get_ident()}")
        # Sources that are gone (a removed checkout, a test's copy) leave the file.
        for entry in [e for e in _KEPT if not os.path.exists(e.partition(" ")[2])]:
            del _KEPT[entry]
        partial.write_text(json.dumps(_KEPT))
        os.replace(partial, path)
    except OSError:
        pass


def source_key(module_name: str) -> str:
    """The hash of numba's and Python's versions and of every source ``module_name``
    reaches by imports, its own included (module notes). A module of another distribution
    counts by its own file alone (its version shows there): the chain is not followed into
    it. The hash depends on the sources alone, not on what this process loaded first."""
    import numba

    home = {module_name.split(".")[0], "netsim"}
    reached: dict[str, bytes] = {}
    stack = [module_name]
    while stack:
        name = stack.pop()
        if name in reached:
            continue
        file = _module_path(name)
        if file is None or not file.endswith(".py"):
            reached[name] = b""
            continue
        reached[name], imports = _read(name, file)
        if name.split(".")[0] in home:
            stack.extend(imports)
    digest = hashlib.sha256(f"numba {numba.__version__}; python {sys.version}\n".encode())
    for name in sorted(reached):
        if reached[name]:
            digest.update(name.encode() + b"\n" + reached[name])
    return digest.hexdigest()[:20]


def _prune(module_name: str, kept: Path) -> None:
    """Delete all but the ``KEPT_VERSIONS`` most recently used directories of a module."""
    base = kept.parent
    kept.mkdir(parents=True, exist_ok=True)
    os.utime(kept)  # marks it used
    mine = [d for d in base.glob(f"{module_name}-*") if d.is_dir() and d.name.rpartition("-")[0] == module_name]
    mine.sort(key=lambda d: d.stat().st_mtime, reverse=True)
    for old in mine[KEPT_VERSIONS:]:
        if old != kept:
            shutil.rmtree(old, ignore_errors=True)


def _read_index_or_miss(cache: Any) -> None:
    """Make a function's cache index that cannot be read a miss, not an error. numba pickles
    the argument types of every compiled signature into the index, so a type from a module
    that a later process cannot import (a user's tuple handed to a kernel, a module loaded
    under a second name) would make every later call of that kernel fail to load it. As a
    miss, the kernel is compiled again and the index written anew with what can be read."""
    index_file: Any = getattr(cache, "_cache_file", None)
    load_index = getattr(index_file, "_load_index", None)
    if load_index is None:  # pragma: no cover  (another numba's layout: its own behaviour)
        return

    def read_or_miss() -> dict:
        try:
            return load_index()
        # What unpickling raises for a class it cannot find or rebuild, or for a truncated
        # file; a disk's error (OSError) still stops the call.
        except (ImportError, AttributeError, TypeError, ValueError, EOFError, pickle.UnpicklingError):
            return {}

    index_file._load_index = read_or_miss


def key(namespace: dict[str, Any]) -> Path:
    """Point the cache of every compiled function defined in the module whose globals are
    ``namespace`` at its keyed directory; returns that directory. Called once, at the end
    of each kernel module."""
    from numba.core import config
    from numba.core.dispatcher import Dispatcher

    name = namespace["__name__"]
    with _LOCK:
        module_key = source_key(name)
        _keep_sources()
        directory = base_directory() / f"{name}-{module_key}"
        _prune(name, directory)
        # numba's settings are set from the environment when it loads: untyped.
        kept = config.CACHE_DIR  # type: ignore[attr-defined]
        config.CACHE_DIR = str(directory)  # type: ignore[attr-defined]
        own = [v for v in namespace.values() if isinstance(v, Dispatcher) and v.py_func.__module__ == name]
        try:
            for value in own:
                value.enable_caching()  # a cache located under config.CACHE_DIR now
                _read_index_or_miss(getattr(value, "_cache", None))
        finally:
            config.CACHE_DIR = kept  # type: ignore[attr-defined]
        _KEYS[name] = module_key
        told = _ON_COLD[:] if _ON_COLD and is_cold(own) else []
        if told:
            _ON_COLD.clear()
    for callback in told:
        callback(directory)
    return directory


def keyed_modules() -> dict[str, str]:
    """The kernel modules keyed so far in this process, with their keys."""
    return dict(_KEYS)
