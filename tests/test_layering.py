"""Imports flow one way between the project's packages: each package imports only the
packages it is allowed to, and no chain of imports (at run time, inside functions, or for
type checking alone) leads from a package back to itself."""

import ast
from pathlib import Path

import networkx as nx
import pytest

ROOT = Path(__file__).resolve().parents[1]

# The packages below the engine's top level: each is one node of the import graph. The
# engine's own modules (netsim/state.py, netsim/config.py, ...) are each a node of their own,
# so that the radio may use the engine's base (state, events) while the run builder uses
# the radio, and a cycle through any of them still shows.
SUBPACKAGES = (
    "netsim.world",
    "netsim.radio",
    "netsim.links",
    "netsim.formats",
    "netsim.tools",
    "netsim.envs",
    "netsim.bridge",
)
# The environments are the other end of the engine: built on it and the tools, used by no model.
ENGINE = {"netsim", *SUBPACKAGES} - {"netsim.envs"}
# The models build on the engine's core, never on the application built on it (the CLI,
# sweeps, figures): a model runs wherever the engine does.
CORE = ENGINE - {"netsim.tools", "netsim.bridge"}
ALLOWED = {
    "netsim": {"netsim", "netsim.world", "netsim.radio", "netsim.links"},
    # The world (maps, free space, line of sight) is the ground the radio and the motion stand on.
    "netsim.world": {"netsim", "netsim.world"},
    "netsim.radio": {"netsim", "netsim.world", "netsim.radio"},
    "netsim.links": {"netsim", "netsim.world", "netsim.radio", "netsim.links"},
    "netsim.formats": {"netsim", "netsim.formats"},
    "netsim.tools": ENGINE,
    # The environments draw frames with the figures' code: built on the tools, like them.
    "netsim.envs": ENGINE | {"netsim.envs"},
    # ROS 2 and the live view (netsim bridge, --live): a run driven and watched from outside,
    # built on the engine; its commands are the tools'.
    "netsim.bridge": {"netsim", "netsim.world", "netsim.radio", "netsim.links", "netsim.bridge"},
    "protocols": CORE | {"protocols"},
    # Motion plans on the radio it is handed (its parameters' methods), never imports it.
    "mobility": (CORE - {"netsim.radio"}) | {"mobility"},
    "hooks": CORE | {"hooks"},
    "benchmarks": ENGINE | {"netsim.envs", "protocols", "mobility", "hooks", "benchmarks"},
    "experiments": ENGINE | {"netsim.envs", "protocols", "mobility", "hooks", "experiments"},
}
PROJECT = {"netsim", "protocols", "mobility", "hooks", "experiments", "benchmarks"}


# The models install under the engine's namespace (``netsim.mobility``) from the
# repository's top-level folders: each is its own package of the layering all the same.
MODELS = ("mobility", "protocols", "hooks")


def _path_of(dotted: str) -> Path:
    parts = dotted.split(".")
    if len(parts) > 1 and parts[0] == "netsim" and parts[1] in MODELS:
        parts = parts[1:]
    return ROOT.joinpath(*parts)


def _is_module(dotted: str) -> bool:
    path = _path_of(dotted)
    return path.with_suffix(".py").is_file() or (path / "__init__.py").is_file()


def imports(path: Path):
    """Every project module ``path`` imports, dotted (``from a import b`` is ``a.b`` when
    ``b`` is a module, else ``a``); absolute imports only, wherever they stand."""
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names = [
                f"{node.module}.{a.name}" if _is_module(f"{node.module}.{a.name}") else node.module for a in node.names
            ]
        else:
            continue
        yield from (n for n in names if n.split(".")[0] in PROJECT)


def package_of(dotted: str) -> str:
    """The package a module belongs to, as :data:`ALLOWED` names them."""
    parts = dotted.split(".")
    if parts[0] != "netsim":
        return parts[0]
    if len(parts) > 1 and parts[1] in MODELS:
        return parts[1]
    return next((p for p in SUBPACKAGES if dotted == p or dotted.startswith(p + ".")), "netsim")


def node_of(dotted: str) -> str:
    """The module's node of the import graph: its subpackage, or itself (engine modules)."""
    pkg = package_of(dotted)
    return dotted if pkg == "netsim" else pkg


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[0] in MODELS:
        parts = ["netsim", *parts]
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def files(package: str) -> list[Path]:
    found = list(ROOT.joinpath(*package.split(".")).rglob("*.py"))
    return [f for f in found if package_of(module_name(f)) == package]


@pytest.mark.parametrize("package", sorted(ALLOWED))
def test_each_package_imports_only_what_it_may(package):
    """A package imports only the packages :data:`ALLOWED` lists for it: the engine no
    model, the radio neither the link solvers nor the tools, protocols and mobility never
    each other, nothing the experiments."""
    found = files(package)
    assert found
    bad = [(f.relative_to(ROOT), m) for f in found for m in imports(f) if package_of(m) not in ALLOWED[package]]
    assert bad == []


def test_every_package_is_covered():
    """Every directory of Python modules in the project belongs to a package the layering
    names (a new subpackage of the engine must be given its place)."""
    dirs = {module_name(f.parent / "__init__.py") for top in PROJECT for f in ROOT.joinpath(top).rglob("*.py")}
    assert {package_of(d) for d in dirs} <= set(ALLOWED)
    engine_dirs = {d for d in dirs if d.startswith("netsim.") and package_of(d) not in MODELS}
    assert {d for d in engine_dirs if not any(d == p or d.startswith(p + ".") for p in SUBPACKAGES)} == set()


def import_graph() -> nx.DiGraph:
    graph = nx.DiGraph()
    for package in ALLOWED:
        for f in files(package):
            src = node_of(module_name(f))
            graph.add_node(src)
            graph.add_edges_from((src, node_of(m)) for m in imports(f) if node_of(m) != src)
    return graph


@pytest.mark.slow
def test_no_import_cycles():
    """No chain of imports leads from a package (or an engine module) back to itself."""
    graph = import_graph()
    assert {"netsim.radio", "netsim.links", "netsim.tools", "netsim.config"} <= set(graph)
    assert list(nx.simple_cycles(graph)) == []


@pytest.mark.slow
def test_no_import_cycles_between_modules():
    """No chain of imports leads from a module back to itself, inside a subpackage too
    (the package graph above sees a subpackage as one node), imports inside functions
    included."""
    graph = nx.DiGraph()
    for package in ALLOWED:
        for f in files(package):
            src = module_name(f)
            graph.add_edges_from((src, m) for m in imports(f) if m != src)
    assert list(nx.simple_cycles(graph)) == []


@pytest.mark.parametrize("folder", ["mobility", "protocols", "hooks"])
def test_a_plugin_folder_imports_only_as_the_package_it_is(folder, monkeypatch):
    """``mobility/``, ``protocols/`` and ``hooks/`` are ``netsim.mobility``,
    ``netsim.protocols`` and ``netsim.hooks``: imported by the folder's name from the
    repository's root (a script or pytest run there) they refuse, in one line, instead of
    loading their modules a second time (whose types numba's kernel cache would keep, and a
    later run could not load)."""
    import importlib
    import sys

    monkeypatch.syspath_prepend(str(ROOT))
    monkeypatch.delitem(sys.modules, folder, raising=False)
    with pytest.raises(ImportError) as refused:
        importlib.import_module(folder)
    assert str(refused.value) == f"'{folder}' is the package netsim.{folder}: import it by that name"
    assert folder not in sys.modules
