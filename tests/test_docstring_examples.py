"""Every example in the engine's and the plugins' docstrings runs and prints what it says,
each module imported by its package's name (``mobility/`` is ``netsim.mobility``: by its
folder's name it refuses to load, see its ``__init__``)."""

import doctest
import importlib
import importlib.util
import pkgutil
from pathlib import Path

import pytest

PACKAGES = ("netsim", "netsim.mobility", "netsim.protocols", "netsim.hooks")


def modules() -> list[str]:
    """Every module of the packages, by name."""
    names = set(PACKAGES)
    for package in PACKAGES:
        path = importlib.import_module(package).__path__
        names.update(m.name for m in pkgutil.walk_packages(path, package + "."))
    return sorted(names)


def with_examples() -> list[str]:
    """The modules whose source holds an example (a line starting ``>>>``)."""
    out = []
    for name in modules():
        spec = importlib.util.find_spec(name)
        assert spec is not None and spec.origin is not None, name
        text = Path(spec.origin).read_text(encoding="utf-8")
        if any(line.lstrip().startswith(">>> ") for line in text.splitlines()):
            out.append(name)
    return out


def test_the_walk_finds_the_plugins_modules_and_their_examples():
    """The walk reaches the plugins' packages, whose folders are not their names, and the
    modules with examples are found among them."""
    found = modules()
    assert {"netsim.mobility.local", "netsim.protocols.clustering", "netsim.hooks.link_breaks"} <= set(found)
    assert {"netsim.mobility.local", "netsim.radio.chain"} <= set(with_examples())


@pytest.mark.parametrize("name", with_examples())
def test_docstring_examples(name):
    try:
        module = importlib.import_module(name)
    except ModuleNotFoundError as missing:  # a module of an optional extra ([rl], [ros2], ...)
        if missing.name is None or missing.name.split(".")[0] == "netsim":
            raise
        pytest.skip(f"{name} needs {missing.name}")
    result = doctest.testmod(module, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    assert result.attempted > 0 and result.failed == 0
