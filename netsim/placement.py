"""Initial placement of robots (``world.placement``) in the world's area (``world.bounds_m``):
uniform, grid, centre (uniform in a central square, a dense start for coverage), or read
from a CSV file of ``x_m,y_m`` rows (in the world frame).
Mobility models start from :func:`initial_positions`."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from netsim.area import Bounds, as_bounds
from netsim.config import world_bounds
from netsim.errors import ConfigError
from netsim.rng import Streams

if TYPE_CHECKING:
    from netsim.config import WorldParams


def uniform(rng: np.random.Generator, n: int, area: float | Bounds) -> np.ndarray:
    """Uniform over the area (``Bounds``, or the side of the square ``[0, side]^2``)."""
    return as_bounds(area).uniform(rng, n)


def centre(rng: np.random.Generator, n: int, area: float | Bounds, centre_side_m: float) -> np.ndarray:
    """Uniform in the square of side ``centre_side_m`` at the middle of the area."""
    b = as_bounds(area)
    if b.is_square_at_origin:
        low: float | np.ndarray = (b.width - centre_side_m) / 2
    else:
        low = 0.5 * (b.lo + b.hi) - centre_side_m / 2
    return low + rng.uniform(0.0, centre_side_m, size=(n, 2))


def _centre_square(b: Bounds, centre_side_m: float) -> tuple[np.ndarray, np.ndarray]:
    if b.is_square_at_origin:
        low = (b.width - centre_side_m) / 2
        high = (b.width + centre_side_m) / 2
        return np.array([low, low]), np.array([high, high])
    mid = 0.5 * (b.lo + b.hi)
    return mid - centre_side_m / 2, mid + centre_side_m / 2


def grid(n: int, area: float | Bounds) -> np.ndarray:
    """Robots at the centres of the cells of a ``k x k`` grid over the area, ``k =
    ceil(sqrt(n))``, filled row by row."""
    b = as_bounds(area)
    k = math.ceil(math.sqrt(n))
    idx = np.arange(n)
    if b.is_square_at_origin:
        cell = b.width / k
        return np.column_stack(((idx % k + 0.5) * cell, (idx // k + 0.5) * cell))
    return np.column_stack((b.x_min + (idx % k + 0.5) * (b.width / k), b.y_min + (idx // k + 0.5) * (b.height / k)))


def from_csv(path: str, n: int, area: float | Bounds) -> np.ndarray:
    key = "world.placement"
    b = as_bounds(area)
    p = Path(path)
    if not p.is_file():
        raise ConfigError(key, path, 'must be "uniform", "grid", "centre" or the path of an existing CSV file')
    try:
        df = pd.read_csv(p)
    except Exception as exc:  # pandas raises several parser errors; all mean a bad file
        raise ConfigError(key, path, f"is not a readable CSV file ({exc})") from None
    if list(df.columns[:2]) != ["x_m", "y_m"] or len(df.columns) != 2:
        raise ConfigError(key, path, f"must have exactly the columns x_m,y_m (found {list(df.columns)})")
    if len(df) != n:
        raise ConfigError(key, path, f"has {len(df)} rows but world.n_robots = {n}")
    try:
        xy = df.to_numpy(dtype=float)
    except ValueError:
        raise ConfigError(key, path, "has values that are not numbers") from None
    if not np.isfinite(xy).all():
        raise ConfigError(key, path, "has missing, NaN or infinite values")
    if not b.contains(xy).all():
        if b.is_square_at_origin:
            raise ConfigError(key, path, f"has positions outside the area [0, {b.width}] (world.side_m)")
        raise ConfigError(key, path, f"has positions outside the area {b.as_list()} (world.bounds_m)")
    return xy


# The placements by name; any other value of world.placement is the path of a CSV file.
PLACEMENTS: dict[str, Callable[[Any, Bounds, Streams], np.ndarray]] = {
    "uniform": lambda w, area, streams: uniform(streams.get("placement"), w.n_robots, area),
    "grid": lambda w, area, streams: grid(w.n_robots, area),
    "centre": lambda w, area, streams: centre(streams.get("placement"), w.n_robots, area, w.centre_side_m),
}


def initial_positions(world: WorldParams, streams: Streams, occupancy: Any = None) -> np.ndarray:
    """The placement ``world.placement`` names (``world``: the world's parameters) in the
    world's area (``world.bounds_m``), its random draws from the stream ``"placement"``. On
    a map (``occupancy``) robots are placed in free cells only (:func:`on_map`)."""
    area = world_bounds(world)
    if occupancy is not None:
        return on_map(world, area, streams, occupancy)
    place = PLACEMENTS.get(world.placement)
    if place is None:
        return from_csv(world.placement, world.n_robots, area)
    return place(world, area, streams)


def on_map(world: WorldParams, area: Bounds, streams: Streams, occupancy: Any) -> np.ndarray:
    """Placement on a map: ``uniform`` is uniform over the free part of the area, ``centre``
    uniform over the free part of the central square; ``grid`` and a CSV file must put every
    robot in a free cell."""
    from netsim.world.free_space import sample_free

    key = "world.placement"
    n = world.n_robots
    if world.placement == "uniform":
        return sample_free(occupancy, streams.get("placement"), n, area)
    if world.placement == "centre":
        rng = streams.get("placement")
        low, high = _centre_square(area, world.centre_side_m)
        out = np.empty((0, 2))
        for _ in range(200):
            cand = sample_free(occupancy, rng, max(2 * n, 64), area)
            inside = ((cand >= low) & (cand <= high)).all(axis=1)
            out = np.concatenate([out, cand[inside]])
            if len(out) >= n:
                return out[:n]
        raise ConfigError(
            key, world.placement, "the central square (world.centre_side_m) has too little free space on world.map"
        )
    xy = grid(n, area) if world.placement == "grid" else from_csv(world.placement, n, area)
    bad = np.flatnonzero(~occupancy.is_free(xy))
    if len(bad):
        x, y = xy[bad[0]]
        raise ConfigError(
            key,
            world.placement,
            f"puts robot {int(bad[0])} at ({x:g}, {y:g}), not in a free cell of world.map ({len(bad)} robots are not)",
        )
    return xy
