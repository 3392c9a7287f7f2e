"""Every example in the engine's and the plugins' docstrings runs and prints what it says,
each module imported by its package's name (``mobility/`` is ``netsim.mobility``: by its
folder's name it refuses to load, see its ``__init__``)."""

import doctest
import importlib
import pkgutil

import pytest

PACKAGES = ("netsim", "netsim.mobility", "netsim.protocols")


def modules() -> list[str]:
    names = set(PACKAGES)
    for package in PACKAGES:
        path = importlib.import_module(package).__path__
        names.update(m.name for m in pkgutil.walk_packages(path, package + "."))
    return sorted(names)


def test_the_walk_finds_the_plugins_modules_too():
    found = modules()
    assert {"netsim.mobility.local", "netsim.protocols.clustering", "netsim.radio.chain"} <= set(found)


@pytest.mark.parametrize("name", modules())
def test_docstring_examples(name):
    module = importlib.import_module(name)
    result = doctest.testmod(module, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    assert result.failed == 0
