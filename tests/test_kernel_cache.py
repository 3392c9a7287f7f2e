"""The compiled kernels' cache cannot go stale: it is keyed by the sources of each kernel
module and of every module it imports from (netsim.kernel_cache)."""

import importlib
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from netsim import kernel_cache

ROOT = Path(__file__).resolve().parents[1]
# The models' folders install under netsim's namespace (netsim.protocols, ...).
KERNEL_MODULES = sorted(
    ".".join(([] if package == "netsim" else ["netsim"]) + list(p.relative_to(ROOT).with_suffix("").parts))
    for package in ("netsim", "protocols", "mobility", "hooks")
    for p in (ROOT / package).rglob("*_kernels.py")
)


def test_every_kernel_module_keys_its_cache():
    """The compiled copy of each kernel module in the tree (netsim.compiled.compiled_copy)
    has pointed the cache of every kernel it compiles at a directory keyed by its sources."""
    from numba.core.dispatcher import Dispatcher

    from netsim.compiled import compiled_copy

    assert "netsim.protocols._kernels" in KERNEL_MODULES and "netsim._kernels" in KERNEL_MODULES
    for name in KERNEL_MODULES:
        copy = compiled_copy(name)
        own = [v for v in vars(copy).values() if isinstance(v, Dispatcher) and v.py_func.__module__ == name]
        assert own, name
        keyed = kernel_cache.base_directory() / f"{name}-{kernel_cache.keyed_modules()[name]}"
        assert all(str(keyed) in str(v._cache._cache_path) for v in own), name


def _package(tmp_path, monkeypatch, name: str, files: dict[str, str]) -> Path:
    pkg = tmp_path / name
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    for file, text in files.items():
        (pkg / file).write_text(text)
    monkeypatch.syspath_prepend(str(tmp_path))
    return pkg


def _forget(prefix: str) -> None:
    for name in [m for m in sys.modules if m == prefix or m.startswith(prefix + ".")]:
        del sys.modules[name]


def test_a_modules_key_follows_what_it_imports_from(tmp_path, monkeypatch):
    """A module's key changes with its own source and with the source of a module it
    imports a constant from, and is the same when computed again."""
    pkg = _package(
        tmp_path, monkeypatch, "keyprobe", {"constants.py": "EDGE = 1.0\n", "user.py": "from .constants import EDGE\n"}
    )
    importlib.import_module("keyprobe.user")
    first = kernel_cache.source_key("keyprobe.user")
    assert kernel_cache.source_key("keyprobe.user") == first
    (pkg / "constants.py").write_text("EDGE = 2.0\n")
    assert kernel_cache.source_key("keyprobe.user") != first
    (pkg / "user.py").write_text("from .constants import EDGE  # edited\n")
    _forget("keyprobe")


def _new_process(monkeypatch, cache) -> None:
    """kernel_cache as a fresh process finds it: nothing read yet, the kept sources on disk."""
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(cache))
    monkeypatch.setattr(kernel_cache, "_SOURCES", {})
    monkeypatch.setattr(kernel_cache, "_KEPT", {})
    monkeypatch.setattr(kernel_cache, "_KEPT_STATE", {"read": False, "new": False})


def _age(path: Path, seconds: float) -> None:
    then = path.stat().st_mtime_ns - int(seconds * 1e9)
    os.utime(path, ns=(then, then))


def test_a_kept_source_is_used_only_at_the_same_time_and_size(tmp_path, monkeypatch):
    """A source read by one process is kept (sources.json) and not read again by the next
    while its time and size stay; an edit at the same size but a later time is read again,
    and a file changed less than SETTLE_S ago is never kept."""
    pkg = _package(
        tmp_path, monkeypatch, "keptprobe", {"constants.py": "EDGE = 1.0\n", "user.py": "from .constants import EDGE\n"}
    )
    for f in pkg.iterdir():
        _age(f, 60.0)
    importlib.import_module("keptprobe.user")
    cache = tmp_path / "cache"
    _new_process(monkeypatch, cache)
    first = kernel_cache.source_key("keptprobe.user")
    kernel_cache._keep_sources()
    assert (cache / kernel_cache.SOURCES_FILE).exists()

    _new_process(monkeypatch, cache)
    opened = []
    real_open = open
    monkeypatch.setattr("builtins.open", lambda file, *a, **k: opened.append(str(file)) or real_open(file, *a, **k))
    assert kernel_cache.source_key("keptprobe.user") == first
    assert not [f for f in opened if "keptprobe" in f]

    (pkg / "constants.py").write_text("EDGE = 2.0\n")  # the same size, a later time
    _new_process(monkeypatch, cache)
    second = kernel_cache.source_key("keptprobe.user")
    assert second != first
    kernel_cache._keep_sources()
    kept = json.loads((cache / kernel_cache.SOURCES_FILE).read_text())
    now = (pkg / "constants.py").stat()
    stamps = [v[:2] for k, v in kept.items() if k.startswith("keptprobe.constants ")]
    assert [now.st_mtime_ns, now.st_size] not in stamps  # changed just now: this version not kept
    _new_process(monkeypatch, cache)
    assert kernel_cache.source_key("keptprobe.user") == second
    # A source that is gone leaves the file at its next write.
    _age(pkg / "constants.py", 60.0)
    (pkg / "user.py").unlink()
    _new_process(monkeypatch, cache)
    kernel_cache.source_key("keptprobe.constants")
    kernel_cache._keep_sources()
    kept = json.loads((cache / kernel_cache.SOURCES_FILE).read_text())
    assert [k.partition(" ")[0] for k in kept if k.startswith("keptprobe.")] == ["keptprobe.constants"]
    _forget("keptprobe")


def test_a_constant_re_exported_through_a_plain_module_is_in_the_key(tmp_path, monkeypatch):
    """A kernel module reading a constant that a plain module re-exports from a third one:
    editing the third alone changes the kernel module's key (a hash one import deep misses it)."""
    files = {
        "constants.py": "EDGE = 1.0\n",
        "facade.py": "from stale_const.constants import EDGE\n",
        "kern.py": "from stale_const.facade import EDGE\n",
    }
    pkg = _package(tmp_path, monkeypatch, "stale_const", files)
    importlib.import_module("stale_const.kern")
    first = kernel_cache.source_key("stale_const.kern")
    (pkg / "constants.py").write_text("EDGE = 2.0\n")
    assert kernel_cache.source_key("stale_const.kern") != first
    _forget("stale_const")


def test_a_kernel_reached_through_a_plain_facade_is_in_the_key(tmp_path, monkeypatch):
    """A kernel module calling a kernel of another kernel module through a plain facade
    module: editing that other kernel module alone changes the caller's key, wherever the
    processes' imports stood when the caller was keyed."""
    files = {
        "_inner.py": "def step(x):\n    return x + 1.0\n",
        "facade.py": "from stale_facade._inner import step\n",
        "kern.py": "def later():\n    from stale_facade.facade import step\n\n    return step\n",
    }
    pkg = _package(tmp_path, monkeypatch, "stale_facade", files)
    importlib.import_module("stale_facade.kern")  # facade and _inner are not loaded yet
    first = kernel_cache.source_key("stale_facade.kern")
    (pkg / "_inner.py").write_text("def step(x):\n    return x + 2.0\n")
    assert kernel_cache.source_key("stale_facade.kern") != first
    _forget("stale_facade")


def test_numbas_version_is_in_the_key(monkeypatch):
    """Machine code compiled by one numba is never served to another."""
    import numba

    first = kernel_cache.source_key("netsim._kernels")
    monkeypatch.setattr(numba, "__version__", "0.0.0")
    assert kernel_cache.source_key("netsim._kernels") != first


def test_old_keyed_directories_are_pruned(tmp_path, monkeypatch):
    """A module keeps its KEPT_VERSIONS most recently used directories; older ones go, and
    another module's directories are untouched."""
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    old = []
    for age in range(kernel_cache.KEPT_VERSIONS + 2):
        d = tmp_path / f"pkg._kernels-{age:020d}"
        d.mkdir()
        os.utime(d, (1_000_000 - age, 1_000_000 - age))
        old.append(d)
    other = tmp_path / "pkg._kernels_other-00000000000000000000"
    other.mkdir()
    kept = tmp_path / "pkg._kernels-ffffffffffffffffffff"
    kernel_cache._prune("pkg._kernels", kept)
    assert kept.is_dir() and other.is_dir()
    assert [d.is_dir() for d in old] == [True] * (kernel_cache.KEPT_VERSIONS - 1) + [False] * 3


# Robot 0's Ack at t = 10 s, from rest at the origin moving at 1 m/s along x: its x is the
# caller's (netsim.protocols._kernels.make_ack) use of the callee netsim._kernels.position.
PROBE = """
import numpy as np
from netsim.protocols import _kernels as k

assert k.__file__.startswith(%r), k.__file__
n, slots = 1, 4
motion = (np.array([[0.0, 0.0]]), np.array([[1.0, 0.0]]), np.array([0.0]), False, 1000.0)
beacon = (np.zeros((n, 3), np.int64), np.zeros(n, bool), np.ones(n, np.int64))
roles = (np.zeros(n, np.int64), np.full(n, -1, np.int64))
table = (np.full((n, slots), -1, np.int64), np.tile(k.EMPTY_RECORD, (n, slots, 1)), 3.0)
ack = k.make_ack(0, 10.0, motion, beacon, roles, table)
print(ack[4])
"""


@pytest.mark.slow
def test_an_edited_callee_in_another_module_changes_its_callers_result(tmp_path):
    """In a copy of the tree, with a warm cache: editing netsim._kernels.position alone
    (not its caller's module) changes what netsim.protocols._kernels.make_ack computes."""
    tree = tmp_path / "tree"
    ignore = shutil.ignore_patterns("__pycache__")
    shutil.copytree(ROOT / "netsim", tree / "netsim", ignore=ignore)
    # The copy's netsim holds the protocols where an installed netsim has them.
    shutil.copytree(ROOT / "protocols", tree / "netsim" / "protocols", ignore=ignore)
    (tree / "probe.py").write_text(PROBE % str(tree))
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache"), "PYTHONDONTWRITEBYTECODE": "1"}

    def x_of_the_ack() -> float:
        run = subprocess.run([sys.executable, "probe.py"], cwd=tree, env=env, capture_output=True, text=True)
        assert run.returncode == 0, run.stderr[-2000:]
        return float(run.stdout.split()[-1])

    assert x_of_the_ack() == 10.0
    assert x_of_the_ack() == 10.0  # from the cache
    callee = tree / "netsim" / "_kernels.py"
    source = callee.read_text()
    edited = source.replace("    dt = t - t0_s[i]\n", "    dt = t - t0_s[i] + 1000.0\n", 1)
    assert edited != source
    callee.write_text(edited)
    assert x_of_the_ack() == 1010.0


USER_TYPE = """
from typing import NamedTuple
import numpy as np

class Motion(NamedTuple):
    origin_m: np.ndarray
    velocity_mps: np.ndarray
    t0_s: np.ndarray
    torus: bool
    side_m: float
"""

PAIR_REACH = """
import sys
import numpy as np
from netsim.compiled import load

kind = sys.argv[1]
k = load("netsim._kernels", 10**6)
parts = (np.zeros((2, 2)), np.zeros((2, 2)), np.zeros(2), False, 0.0)
if kind == "user":
    sys.path.insert(0, sys.argv[2])
    import userplug

    parts = userplug.Motion(*parts)
print(k.pair_reach(parts, 0, 1, 0.0, 1.0)[0])
"""


@pytest.mark.slow
def test_an_index_naming_a_module_gone_is_a_miss(tmp_path):
    """A user's tuple type handed to a kernel lands in the kernel's cache index; a later
    process that cannot import that type's module compiles the kernel again (and rewrites
    the index) instead of failing on every call."""
    plug = tmp_path / "plug"
    plug.mkdir()
    (plug / "userplug.py").write_text(USER_TYPE)
    (tmp_path / "probe.py").write_text(PAIR_REACH)
    # Compiled whatever the suite's setting: the index is numba's.
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache"), "NETSIM_COMPILED": "1"}

    def reach(*args: str) -> str:
        run = subprocess.run([sys.executable, "probe.py", *args], cwd=tmp_path, env=env, capture_output=True, text=True)
        assert run.returncode == 0, run.stderr[-2000:]
        return run.stdout.split()[-1]

    assert reach("user", str(plug)) == "True"
    assert reach("plain") == "True"  # the index names userplug, which this process cannot import
    assert reach("plain") == "True"
    assert reach("user", str(plug)) == "True"
