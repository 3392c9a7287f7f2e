"""Imports flow one way: netsim imports no project package; protocols and mobility never
import each other; nothing imports experiments; the engine core (``netsim/`` apart from
``netsim/tools/`` and the environments of ``netsim/envs/``) never imports the tools and
environments built on it."""

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
FORBIDDEN = {
    "netsim": {"protocols", "mobility", "hooks", "experiments"},
    "protocols": {"mobility", "hooks", "experiments"},
    "mobility": {"protocols", "hooks", "experiments"},
    "hooks": {"protocols", "mobility", "experiments"},
    "benchmarks": {"experiments"},
}


def _modules(path: Path):
    """Every module ``path`` imports, dotted, as written (absolute imports only)."""
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            yield from (a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            yield node.module
            yield from (f"{node.module}.{a.name}" for a in node.names)


@pytest.mark.parametrize("package", sorted(FORBIDDEN))
def test_imports_flow_one_way(package):
    files = list((ROOT / package).rglob("*.py"))
    assert files
    bad = [(f.relative_to(ROOT), m) for f in files for m in _modules(f) if m.split(".")[0] in FORBIDDEN[package]]
    assert bad == []


def core_files() -> list[Path]:
    built_on = {"tools", "envs"}
    return [f for f in (ROOT / "netsim").rglob("*.py") if not built_on & set(f.relative_to(ROOT / "netsim").parts)]


def test_the_core_never_imports_the_tools():
    files = core_files()
    assert len(files) > 10
    bad = [
        (f.relative_to(ROOT), m) for f in files for m in _modules(f) if m.startswith(("netsim.tools", "netsim.envs"))
    ]
    assert bad == []
