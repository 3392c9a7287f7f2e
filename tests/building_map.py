"""A real-world-sized map for the tests (imported by the tests that use it): a 40 m x 40 m
floor at 5 cm per cell (:func:`netsim.world.examples.building_floor`)."""

from __future__ import annotations

from netsim.world.examples import BUILDING_RESOLUTION_M, building_floor
from netsim.world.maps import OccupancyMap


def building_map(side_m: float = 40.0, seed: int = 0) -> OccupancyMap:
    """The floor as an :class:`~netsim.world.maps.OccupancyMap`."""
    occupied, free = building_floor(side_m, seed)
    return OccupancyMap(occupied, free, BUILDING_RESOLUTION_M, (0.0, 0.0), source="building")
