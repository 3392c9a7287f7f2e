"""Logging and analysis hooks: plugins that subscribe to the run's events (``[events] hooks``)."""

# The package netsim.hooks; by its folder's name its modules would load a second time
# (the reason is in netsim.mobility's __init__).
if __name__ != "netsim.hooks":
    raise ImportError(f"{__name__!r} is the package netsim.hooks: import it by that name")
