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


def initial_positions(world: WorldParams, streams: Streams) -> np.ndarray:
    """The placement ``world.placement`` names (``world``: the world's parameters), its
    random draws from the stream ``"placement"``."""
    place = PLACEMENTS.get(world.placement)
    if place is None:
        return from_csv(world.placement, world.n_robots, world.side_m)
    return place(world, streams)
