"""The two example maps shipped with netsim, drawn by code so that they can be regenerated.

- ``office``: a 200 m x 200 m floor at 0.25 m per pixel: four east-west corridors (3 m wide)
  lined on both sides with 10 m x ~20 m rooms, each with a 1.5 m door onto its corridor,
  three north-south corridors joining them, and an open-plan hall; interior walls 0.25 m
  thick, the outer wall 0.5 m.
- ``cave``: a 200 m x 200 m cave at 0.25 m per pixel: a winding tunnel 5-9 m wide across the
  map, two side galleries ending in chambers, rock everywhere else (one wall between two
  tunnels, however thick the rock).

Both are plain ``map_server`` maps (``office.yaml`` + ``office.pgm``), usable by name
(``world.map = "office"``) or copied as a starting point. Regenerate them with::

    python -m netsim.world.examples [folder]

:func:`building_floor` draws a third, not shipped, at the scale of a SLAM map of a real
building (5 cm per pixel), for tests and benchmarks: write it with
``save_map(path, *building_floor(), BUILDING_RESOLUTION_M)``.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from netsim.geometry import cell_centres_m, distances_m
from netsim.world.maps import save_map

RESOLUTION_M = 0.25
SIDE_M = 200.0


def _px(x_m: float) -> int:
    return int(round(x_m / RESOLUTION_M))


def office() -> tuple[np.ndarray, np.ndarray]:
    """``(occupied, free)`` of the office floor, row 0 at the bottom."""
    n = _px(SIDE_M)
    occ = np.zeros((n, n), dtype=bool)

    def wall_x(x, y0, y1):  # a vertical wall one pixel thick starting at x
        occ[_px(y0) : _px(y1), _px(x)] = True

    def wall_y(y, x0, x1):
        occ[_px(y), _px(x0) : _px(x1)] = True

    def opening(x0, x1, y0, y1):
        occ[_px(y0) : _px(y1), _px(x0) : _px(x1)] = False

    corridors_y = (25.0, 75.0, 125.0, 175.0)
    corridors_x = (50.0, 100.0, 150.0)
    half = 1.5
    # Room rows: the bands between a corridor's side and the walls at y = 0, 50, 100, 150, 200.
    for c in corridors_y:
        wall_y(c - half, 0, SIDE_M)
        wall_y(c + half, 0, SIDE_M)
    for y in (50.0, 100.0, 150.0):
        wall_y(y, 0, SIDE_M)
    # Walls between rooms every 10 m, and a door in each room's corridor-side wall.
    for c in corridors_y:
        for lo, hi, door_y in ((c - 25.0, c - half, c - half), (c + half, c + 25.0, c + half)):
            for x in np.arange(10.0, SIDE_M, 10.0):
                wall_x(x, lo, hi)
            for x in np.arange(0.0, SIDE_M, 10.0):
                opening(x + 4.25, x + 5.75, door_y, door_y + RESOLUTION_M)
    # North-south corridors cut through every room row, walled on both sides.
    for c in corridors_x:
        occ[:, _px(c - half) : _px(c + half)] = False
        for band in range(4):
            y0, y1 = 50.0 * band, 50.0 * band + 50.0
            for cy in corridors_y:
                if y0 < cy < y1:
                    wall_x(c - half, y0, cy - half)
                    wall_x(c - half, cy + half, y1)
                    wall_x(c + half - RESOLUTION_M, y0, cy - half)
                    wall_x(c + half - RESOLUTION_M, cy + half, y1)
    # An open-plan hall between the corridors at y = 75 and 125, x in [110, 140]: no interior
    # walls, 4 m openings onto both corridors.
    opening(110.0 + RESOLUTION_M, 140.0, 76.5 + RESOLUTION_M, 123.5)
    opening(118.0, 122.0, 76.5, 76.5 + RESOLUTION_M)
    opening(128.0, 132.0, 123.5, 123.5 + RESOLUTION_M)
    # The outer wall, 0.5 m thick.
    t = _px(0.5)
    occ[:t, :] = occ[-t:, :] = True
    occ[:, :t] = occ[:, -t:] = True
    return occ, ~occ


def _polyline(points, step_m=0.25):
    """Dense points along a polyline."""
    pts = np.asarray(points, dtype=float)
    out = []
    for a, b in zip(pts[:-1], pts[1:]):
        k = max(int(np.ceil(distances_m(a, b)[0] / step_m)), 1)
        out.append(a + (b - a) * (np.arange(k) / k)[:, None])
    out.append(pts[-1:])
    return np.concatenate(out)


def cave() -> tuple[np.ndarray, np.ndarray]:
    """``(occupied, free)`` of the cave, row 0 at the bottom."""
    from scipy.ndimage import distance_transform_edt

    n = _px(SIDE_M)
    x = np.linspace(8.0, 192.0, 400)
    main = np.column_stack([x, 100.0 + 55.0 * np.sin(2 * np.pi * (x - 8.0) / 150.0) + 8.0 * np.sin(x / 9.0)])
    main_r = 3.5 + 1.0 * np.sin(x / 7.0)
    y1 = np.linspace(main[100, 1], 185.0, 120)
    north = np.column_stack([main[100, 0] + 10.0 * np.sin((y1 - y1[0]) / 12.0), y1])
    y2 = np.linspace(main[300, 1], 15.0, 120)
    south = np.column_stack([main[300, 0] - 12.0 * np.sin((y2[0] - y2) / 10.0), y2])
    paths = [(main, main_r), (north, np.full(len(north), 2.6)), (south, np.full(len(south), 2.6))]
    free = np.zeros((n, n), dtype=bool)
    for pts, r in paths:
        dense = _polyline(pts)
        rr = np.interp(np.linspace(0, 1, len(dense)), np.linspace(0, 1, len(r)), r)
        i = np.clip((dense[:, 0] / RESOLUTION_M).astype(int), 0, n - 1)
        j = np.clip((dense[:, 1] / RESOLUTION_M).astype(int), 0, n - 1)
        centre = np.zeros((n, n), dtype=bool)
        centre[j, i] = True
        radius = np.zeros((n, n))
        radius[j, i] = rr
        # Within the tunnel's radius at its nearest centre point (the radius varies slowly).
        dist, (jj, ii) = distance_transform_edt(~centre, return_indices=True)
        free |= dist * RESOLUTION_M < radius[jj, ii]
    # Two chambers at the galleries' ends.
    yc = xc = cell_centres_m(0.0, RESOLUTION_M, np.arange(n))
    for (cx, cy), chamber_m in ((north[-1], 9.0), (south[-1], 7.0)):
        free |= (xc[None, :] - cx) ** 2 + (yc[:, None] - cy) ** 2 < chamber_m * chamber_m
    t = _px(0.5)
    free[:t, :] = free[-t:, :] = False
    free[:, :t] = free[:, -t:] = False
    return ~free, free


MAKERS = {"office": office, "cave": cave}

BUILDING_RESOLUTION_M = 0.05


def building_floor(side_m: float = 40.0, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """``(occupied, free)`` of a ``side_m`` square floor at 5 cm per pixel, row 0 at the
    bottom: rooms of 5-8 m behind walls 10-15 cm thick, each wall with a door (1 m) every
    6-7 m, a diagonal wall one pixel thick (its pixels touching only at corners) and 30
    pillars of 30 cm; the outer edge open. ``seed`` draws the layout."""
    rng = np.random.default_rng(seed)
    res = BUILDING_RESOLUTION_M
    n = int(round(side_m / res))
    occ = np.zeros((n, n), bool)

    def px(x_m: float) -> int:
        return int(round(x_m / res))

    x = 4.0
    while x < side_m - 4.0:
        thick, i = int(rng.integers(2, 4)), px(x)
        occ[:, i : i + thick] = True
        for y0 in np.arange(2.0, side_m - 2.0, 7.0):
            door = y0 + rng.uniform(0.5, 5.0)
            occ[px(door) : px(door + 1.0), i : i + thick] = False
        x += rng.uniform(5.0, 8.0)
    y = 3.0
    while y < side_m - 4.0:
        thick, j = int(rng.integers(2, 4)), px(y)
        occ[j : j + thick, :] = True
        for x0 in np.arange(1.0, side_m - 2.0, 6.0):
            door = x0 + rng.uniform(0.5, 4.0)
            occ[j : j + thick, px(door) : px(door + 1.0)] = False
        y += rng.uniform(5.0, 8.0)
    for k in range(px(min(12.0, side_m / 3))):
        occ[px(side_m / 2) + k, px(side_m / 6) + k] = True
    for _ in range(30):
        cx, cy = rng.uniform(1.0, side_m - 1.0, 2)
        occ[px(cy) : px(cy) + 6, px(cx) : px(cx) + 6] = True
    return occ, ~occ


def write_examples(folder: str | Path) -> list[Path]:
    """Write ``office.yaml/.pgm`` and ``cave.yaml/.pgm`` into ``folder``."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    return [save_map(folder / f"{name}.yaml", *make(), RESOLUTION_M) for name, make in MAKERS.items()]


if __name__ == "__main__":
    target = sys.argv[1] if len(sys.argv) > 1 else Path(__file__).with_name("example_maps")
    for p in write_examples(target):
        print(p)
