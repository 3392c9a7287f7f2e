"""Models found by name: the paper's "reserved interfaces" for users' own algorithms.

A plugin is a callable ``install(sim) -> object | None`` that sets up its processes on a
:class:`~netsim.sim.Simulation`. Built-in ones are entry points in ``pyproject.toml``
(groups ``netsim.mobility``, ``netsim.protocols``, ``netsim.controllers``); a user's own is
named ``"package.module:function"`` in the configuration. So the engine never imports
the packages that build on it.
"""

from __future__ import annotations

import importlib
import os
import sys
from collections.abc import Callable
from importlib.metadata import entry_points
from typing import Any, Protocol

from netsim.errors import ConfigError

MOBILITY = "netsim.mobility"
PROTOCOLS = "netsim.protocols"
CONTROLLERS = "netsim.controllers"


class Plugin(Protocol):
    def __call__(self, sim: Any) -> object | None: ...


def _import_user_module(name: str):
    """Import ``name``; a module in the current directory counts, as with ``python -m``
    (a console script's import path does not include it)."""
    try:
        return importlib.import_module(name)
    except ModuleNotFoundError as exc:
        if exc.name != name.split(".")[0] or os.getcwd() in sys.path:
            raise
        sys.path.insert(0, os.getcwd())
        return importlib.import_module(name)


def available(group: str) -> list[str]:
    return sorted(ep.name for ep in entry_points(group=group))


def resolve(group: str, name: str, key: str) -> Callable:
    """The plugin ``name`` of ``group``; ``key`` is the configuration key, for errors."""
    if ":" in name:
        module_name, _, attr = name.partition(":")
        try:
            obj = _import_user_module(module_name)
            for part in attr.split("."):
                obj = getattr(obj, part)
        except (ImportError, AttributeError) as exc:
            raise ConfigError(key, name, f"cannot be loaded ({exc})") from None
        if not callable(obj):
            raise ConfigError(key, name, "is not callable")
        return obj
    found = [ep for ep in entry_points(group=group) if ep.name == name]
    if not found:
        choices = ", ".join(repr(n) for n in available(group)) or "none installed"
        raise ConfigError(key, name, f"unknown; choose one of {choices}, or 'package.module:function'")
    return found[0].load()
