"""The radio wing of the channel: propagation, shadowing, and walls from an occupancy map.

- :mod:`netsim.radio.propagation`: received power as a chain of small loss terms
  (log-distance path loss, shadowing, walls, or a unit disk with line of sight);
- :mod:`netsim.radio.shadowing`: log-normal shadowing per pair, reciprocal, spatially
  correlated as robots move (Gudmundson's exponential model);
- :mod:`netsim.radio.maps`: ROS ``map_server`` maps (YAML and PGM/PNG image);
- :mod:`netsim.radio.los`: line of sight and walls crossed, for many segments at once;
- :mod:`netsim.radio.free_space`: where robots may be and go on a map;
- :mod:`netsim.radio.examples`: the example maps shipped with netsim;
- :mod:`netsim.radio.checks`: the closed-form checks of the radio models.
- :mod:`netsim.radio.mac`: the shared medium (airtime, collisions, ALOHA, CSMA/DCF);
- :mod:`netsim.radio.mac_checks`: its closed-form checks (ALOHA, Bianchi, hidden terminals).

Nothing here reads a configuration or needs the simulation kernel: each piece takes numpy
arrays and explicit parameters.
"""


def compiled_kernels():
    """The compiled loops (:mod:`netsim.radio._kernels`), or None where numba is missing
    (it is a dependency; the numpy paths are kept for exotic platforms)."""
    try:
        from netsim.radio import _kernels
    except ImportError:  # pragma: no cover
        return None
    return _kernels
