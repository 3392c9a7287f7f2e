"""Initial placement of robots (``world.placement``): uniform, grid, centre (uniform in a
central square, a dense start for coverage), or read from a CSV file of ``x_m,y_m`` rows.
Mobility models start from :func:`initial_positions`."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from netsim.errors import ConfigError
from netsim.rng import Streams

if TYPE_CHECKING:
    from netsim.config import WorldParams


def uniform(rng: np.random.Generator, n: int, side_m: float) -> np.ndarray:
    return rng.uniform(0.0, side_m, size=(n, 2))


def centre(rng: np.random.Generator, n: int, side_m: float, centre_side_m: float) -> np.ndarray:
    """Uniform in the square of side ``centre_side_m`` at the middle of the area."""
    low = (side_m - centre_side_m) / 2
    return low + rng.uniform(0.0, centre_side_m, size=(n, 2))


def grid(n: int, side_m: float) -> np.ndarray:
    """Robots at the centres of the cells of a ``k x k`` grid, ``k = ceil(sqrt(n))``,
    filled row by row."""
    k = math.ceil(math.sqrt(n))
    cell = side_m / k
    idx = np.arange(n)
    return np.column_stack(((idx % k + 0.5) * cell, (idx // k + 0.5) * cell))


def from_csv(path: str, n: int, side_m: float) -> np.ndarray:
    key = "world.placement"
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
    if (xy < 0).any() or (xy > side_m).any():
        raise ConfigError(key, path, f"has positions outside the area [0, {side_m}] (world.side_m)")
    return xy


# The placements by name; any other value of world.placement is the path of a CSV file.
PLACEMENTS: dict[str, Callable[[Any, Streams], np.ndarray]] = {
    "uniform": lambda w, streams: uniform(streams.get("placement"), w.n_robots, w.side_m),
    "grid": lambda w, streams: grid(w.n_robots, w.side_m),
    "centre": lambda w, streams: centre(streams.get("placement"), w.n_robots, w.side_m, w.centre_side_m),
}


def initial_positions(world: WorldParams, streams: Streams, occupancy: Any = None) -> np.ndarray:
    """The placement ``world.placement`` names (``world``: the world's parameters), its
    random draws from the stream ``"placement"``. On a map (``occupancy``) robots are placed
    in free cells only (:func:`on_map`)."""
    if occupancy is not None:
        return on_map(world, streams, occupancy)
    place = PLACEMENTS.get(world.placement)
    if place is None:
        return from_csv(world.placement, world.n_robots, world.side_m)
    return place(world, streams)


def on_map(world: WorldParams, streams: Streams, occupancy: Any) -> np.ndarray:
    """Placement on a map: ``uniform`` is uniform over the free part of the area, ``centre``
    uniform over the free part of the central square; ``grid`` and a CSV file must put every
    robot in a free cell."""
    from netsim.radio.free_space import sample_free

    key = "world.placement"
    n, side = world.n_robots, world.side_m
    if world.placement == "uniform":
        return sample_free(occupancy, streams.get("placement"), n, side)
    if world.placement == "centre":
        rng = streams.get("placement")
        low, high = (side - world.centre_side_m) / 2, (side + world.centre_side_m) / 2
        out = np.empty((0, 2))
        for _ in range(200):
            cand = sample_free(occupancy, rng, max(2 * n, 64), side)
            inside = ((cand >= low) & (cand <= high)).all(axis=1)
            out = np.concatenate([out, cand[inside]])
            if len(out) >= n:
                return out[:n]
        raise ConfigError(
            key, world.placement, "the central square (world.centre_side_m) has too little free space on world.map"
        )
    xy = grid(n, side) if world.placement == "grid" else from_csv(world.placement, n, side)
    bad = np.flatnonzero(~occupancy.is_free(xy))
    if len(bad):
        x, y = xy[bad[0]]
        raise ConfigError(
            key,
            world.placement,
            f"puts robot {int(bad[0])} at ({x:g}, {y:g}), not in a free cell of world.map ({len(bad)} robots are not)",
        )
    return xy
