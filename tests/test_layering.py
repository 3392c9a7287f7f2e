"""Imports flow one way: netsim imports no project package; protocols and mobility never
import each other; nothing imports experiments."""

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
FORBIDDEN = {
    "netsim": {"protocols", "mobility", "experiments"},
    "protocols": {"mobility", "experiments"},
    "mobility": {"protocols", "experiments"},
    "benchmarks": {"experiments"},
}


def _imports(path: Path):
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            yield from (a.name.split(".")[0] for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            yield node.module.split(".")[0]


@pytest.mark.parametrize("package", sorted(FORBIDDEN))
def test_imports_flow_one_way(package):
    files = list((ROOT / package).rglob("*.py"))
    assert files
    bad = [(f.relative_to(ROOT), m) for f in files for m in _imports(f) if m in FORBIDDEN[package]]
    assert bad == []
