"""Protocols for netsim: the Ack beacon and neighbour tables (and what builds on them)."""

# The package netsim.protocols; by its folder's name its modules would load a second time
# (the reason is in netsim.mobility's __init__).
if __name__ != "netsim.protocols":
    raise ImportError(f"{__name__!r} is the package netsim.protocols: import it by that name")
