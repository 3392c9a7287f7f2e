"""netsim: a discrete-event simulator of multi-robot wireless ad-hoc networks.

Engine only: the simulation object, robot state, channel, timers, topology, trace and
configuration. Mobility models and protocols are plugins found by name.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from netsim.config import Config, load
    from netsim.errors import ConfigError, NetsimInputError
    from netsim.sim import Simulation

__all__ = ["Config", "ConfigError", "NetsimInputError", "Simulation", "load"]
__version__ = "0.1.0"

# Importing the package loads none of the engine's libraries (numpy, pandas, pyarrow) until
# one of these names is asked for: the command line pauses the garbage collector while
# they load (netsim.tools.command), which it can only do if nothing has loaded them yet.
_WHERE = {
    "Config": "netsim.config",
    "load": "netsim.config",
    "ConfigError": "netsim.errors",
    "NetsimInputError": "netsim.errors",
    "Simulation": "netsim.sim",
}


def __getattr__(name: str) -> Any:
    if name not in _WHERE:
        raise AttributeError(f"module 'netsim' has no attribute {name!r}")
    value = getattr(importlib.import_module(_WHERE[name]), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted([*__all__, "__version__"])
