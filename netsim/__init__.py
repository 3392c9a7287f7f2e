"""netsim: a discrete-event simulator of multi-robot wireless ad-hoc networks.

Engine only: the simulation object, robot state, channel, timers, topology, trace and
configuration. Mobility models and protocols are plugins found by name.
"""

from netsim.config import Config, load
from netsim.errors import ConfigError, NetsimInputError
from netsim.sim import Simulation

__all__ = ["Config", "ConfigError", "NetsimInputError", "Simulation", "load"]
__version__ = "0.1.0"
