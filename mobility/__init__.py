"""Mobility models for netsim: how robots move. Each model is a plugin (docs/plugins.md)."""

# This folder is the package netsim.mobility. Imported by its folder's name (a script or
# pytest run from the repository's root) its modules would load a second time, as other
# modules: numba's cache of the kernels would then keep types of that copy, which a later
# run, where no such copy exists, cannot load.
if __name__ != "netsim.mobility":
    raise ImportError(f"{__name__!r} is the package netsim.mobility: import it by that name")
