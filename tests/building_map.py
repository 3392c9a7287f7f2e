"""A real-world-sized map for the tests (imported by the tests that use it): a 40 m x 40 m
floor at 5 cm per cell, as a ROS ``map_saver`` map of a building would be, with rooms, doors,
a diagonal wall drawn as a staircase of pixels, and pillars."""

from __future__ import annotations

import numpy as np

from netsim.radio.maps import OccupancyMap


def building_map(side_m: float = 40.0, resolution_m: float = 0.05, seed: int = 0) -> OccupancyMap:
    """Rooms of 5-8 m behind walls 10-15 cm thick, each wall with a door (1 m), a diagonal
    wall and some pillars; the outer edge is open."""
    rng = np.random.default_rng(seed)
    n = int(round(side_m / resolution_m))
    occ = np.zeros((n, n), bool)

    def px(x_m: float) -> int:
        return int(round(x_m / resolution_m))

    x = 4.0
    while x < side_m - 4.0:
        thick = int(rng.integers(2, 4))
        i = px(x)
        occ[:, i : i + thick] = True
        for y0 in np.arange(2.0, side_m - 2.0, 7.0):
            door = y0 + rng.uniform(0.5, 5.0)
            occ[px(door) : px(door + 1.0), i : i + thick] = False
        x += rng.uniform(5.0, 8.0)
    y = 3.0
    while y < side_m - 4.0:
        thick = int(rng.integers(2, 4))
        j = px(y)
        occ[j : j + thick, :] = True
        for x0 in np.arange(1.0, side_m - 2.0, 6.0):
            door = x0 + rng.uniform(0.5, 4.0)
            occ[j : j + thick, px(door) : px(door + 1.0)] = False
        y += rng.uniform(5.0, 8.0)
    # A diagonal wall one pixel thick: its cells touch only at corners.
    for k in range(px(12.0)):
        occ[px(20.0) + k, px(6.0) + k] = True
    for _ in range(30):
        cx, cy = rng.uniform(1.0, side_m - 1.0, 2)
        occ[px(cy) : px(cy) + 6, px(cx) : px(cx) + 6] = True
    return OccupancyMap(occ, ~occ, resolution_m, (0.0, 0.0), source="building")
