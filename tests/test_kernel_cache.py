"""The compiled kernels' cache cannot go stale: it is keyed by the sources of each kernel
module and of every module it imports from (netsim.kernel_cache)."""

import importlib
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from netsim import kernel_cache

ROOT = Path(__file__).resolve().parents[1]
KERNEL_MODULES = sorted(
    ".".join(p.relative_to(ROOT).with_suffix("").parts)
    for package in ("netsim", "protocols", "mobility", "hooks")
    for p in (ROOT / package).rglob("*_kernels.py")
)


def test_every_kernel_module_keys_its_cache():
    """Each module of compiled kernels in the tree, once imported, has pointed its cache at
    a directory keyed by its sources."""
    assert "protocols._kernels" in KERNEL_MODULES and "netsim._kernels" in KERNEL_MODULES
    for name in KERNEL_MODULES:
        importlib.import_module(name)
    assert set(KERNEL_MODULES) <= set(kernel_cache.keyed_modules())


def test_a_modules_key_follows_what_it_imports_from(tmp_path, monkeypatch):
    """A module's key changes with its own source and with the source of a module it
    imports a constant from, and with the key of a kernel module it imports."""
    pkg = tmp_path / "keyprobe"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "constants.py").write_text("EDGE = 1.0\n")
    (pkg / "user.py").write_text("from .constants import EDGE\n\nTWICE = 2 * EDGE\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    importlib.import_module("keyprobe.user")
    first = kernel_cache.source_key("keyprobe.user")
    assert kernel_cache.source_key("keyprobe.user") == first
    (pkg / "constants.py").write_text("EDGE = 2.0\n")
    second = kernel_cache.source_key("keyprobe.user")
    assert second != first
    monkeypatch.setitem(kernel_cache._KEYS, "keyprobe.constants", "an-earlier-key")
    assert kernel_cache.source_key("keyprobe.user") not in (first, second)
    for name in ("keyprobe.user", "keyprobe.constants", "keyprobe"):
        sys.modules.pop(name, None)


# Robot 0's Ack at t = 10 s, from rest at the origin moving at 1 m/s along x: its x is the
# caller's (protocols._kernels.make_ack) use of the callee netsim._kernels.position.
PROBE = """
import numpy as np
from protocols import _kernels as k

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
    (not its caller's module) changes what protocols._kernels.make_ack computes."""
    tree = tmp_path / "tree"
    ignore = shutil.ignore_patterns("__pycache__")
    for package in ("netsim", "protocols"):
        shutil.copytree(ROOT / package, tree / package, ignore=ignore)
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
