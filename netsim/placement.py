"""Initial placement of robots (``world.placement``) in the world's area (``world.bounds_m``):
uniform, grid, centre (uniform in a central square, a dense start for coverage), connected
(a dense start whose network is whole on the run's own links, :func:`connected`), or read
from a CSV file of ``x_m,y_m`` rows (in the world frame).
Mobility models start from :func:`initial_positions`."""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from netsim.area import Bounds, as_bounds
from netsim.compiled import load
from netsim.config import NAMED_PLACEMENTS, ConfigWarning, world_bounds
from netsim.errors import ConfigError, did_you_mean
from netsim.geometry import cell_centres_m, link_ranges_m
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
    return np.column_stack(
        (cell_centres_m(b.x_min, b.width / k, idx % k), cell_centres_m(b.y_min, b.height / k, idx // k))
    )


def from_csv(path: str, n: int, area: float | Bounds) -> np.ndarray:
    key = "world.placement"
    b = as_bounds(area)
    p = Path(path)
    if not p.is_file():
        named = ", ".join(f'"{name}"' for name in NAMED_PLACEMENTS)
        meant = did_you_mean(path, NAMED_PLACEMENTS)
        raise ConfigError(key, path, f"must be {named} or the path of an existing CSV file{meant}")
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
    _warn_if_shared(path, xy)
    return xy


def _warn_if_shared(path: str, xy: np.ndarray) -> None:
    # No robot stands where another stands, and two on one point have no direction between
    # them: the forces that spread a team push them alike, so they move as one.
    _, first, counts = np.unique(xy, axis=0, return_index=True, return_counts=True)
    if (counts == 1).all():
        return
    shared = np.flatnonzero((xy == xy[first[np.argmax(counts > 1)]]).all(axis=1))
    x, y = xy[shared[0]]
    more = int(counts[counts > 1].sum()) - len(shared)
    also = f" (and {more} more robots on other shared points)" if more else ""
    robots = ", ".join(str(r) for r in shared[:5]) + (", ..." if len(shared) > 5 else "")
    warnings.warn(
        f"world.placement = '{path}': robots {robots} share the position ({x:g}, {y:g}){also}: "
        "no robot can stand where another stands, and forces that spread a team move them as one",
        ConfigWarning,
        stacklevel=3,
    )


# The placements by name; any other value of world.placement is the path of a CSV file.
PLACEMENTS: dict[str, Callable[[Any, Bounds, Streams], np.ndarray]] = {
    "uniform": lambda w, area, streams: uniform(streams.get("placement"), w.n_robots, area),
    "grid": lambda w, area, streams: grid(w.n_robots, area),
    "centre": lambda w, area, streams: centre(streams.get("placement"), w.n_robots, area, w.centre_side_m),
}


def check_placement(world: WorldParams) -> None:
    """Raise, before any run, the :class:`ConfigError` a run would raise for
    ``world.placement`` naming no placement and no usable CSV file (a CSV file is read and
    checked against the team and the area as a run reads it)."""
    if world.placement not in NAMED_PLACEMENTS:
        from_csv(world.placement, world.n_robots, world_bounds(world))


def initial_positions(world: WorldParams, streams: Streams, occupancy: Any = None, channel: Any = None) -> np.ndarray:
    """The placement ``world.placement`` names (``world``: the world's parameters) in the
    world's area (``world.bounds_m``), its random draws from the stream ``"placement"``. On
    a map (``occupancy``) robots are placed in free cells only (:func:`on_map`).
    ``channel``: the run's (:class:`~netsim.radio.channel.Channel`), whose links
    ``"connected"`` keeps whole."""
    area = world_bounds(world)
    if world.placement == "connected":
        return connected(world, area, streams.get("placement"), occupancy, channel)
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


CONNECTED_KEY = "world.placement"
# Candidates drawn per round, and rounds per robot, before connected placement gives up.
CONNECTED_BATCH = 64
CONNECTED_ROUNDS = 200


def start_point(world: WorldParams, area: Bounds) -> np.ndarray:
    """``world.start_m``, or the area's centre for ``"centre"``."""
    if world.start_m == "centre":
        return np.array([0.5 * (area.x_min + area.x_max), 0.5 * (area.y_min + area.y_max)])
    return np.array(world.start_m, dtype=float)


def connected(
    world: WorldParams, area: Bounds, rng: np.random.Generator, occupancy: Any = None, channel: Any = None
) -> np.ndarray:
    """``world.placement = "connected"``: robots whose links at ``t = 0`` (the run's radio:
    range, line of sight, wall loss) form one network, in the square of side
    ``world.centre_side_m`` centred on ``world.start_m`` (clipped to the area) and, on a
    map, in the free region of the start point (:func:`netsim.world.free_space.free_region`).

    Robot 0 is drawn uniform over that space; each next robot is the first of a stream of
    such draws (``CONNECTED_BATCH`` at a time) that has a link to a robot already placed,
    so the links form a spanning tree at least. Draws come from ``rng`` alone: the same
    seed, the same start. A ``ConfigError`` when a robot finds no place in
    ``CONNECTED_BATCH * CONNECTED_ROUNDS`` draws (the space is too small or too walled for
    the team) or when links are not decided by positions (shadowing)."""
    start = start_point(world, area)
    if not area.contains(start[None, :])[0]:
        raise ConfigError("world.start_m", list(start), f"is outside the area {area.as_list()} (world.bounds_m)")
    linked = _linked(channel)
    draw = _start_space(world, area, start, occupancy)
    n = world.n_robots
    out = np.empty((n, 2))
    out[0] = draw(rng, 1)[0]
    ranges = _ranges(channel, n)
    for k in range(1, n):
        for _ in range(CONNECTED_ROUNDS):
            cand = draw(rng, CONNECTED_BATCH)
            c, p = np.divmod(np.arange(CONNECTED_BATCH * k), k)
            a = np.full(len(c), k)
            up = linked(a, p, cand[c], out[p], ranges).reshape(CONNECTED_BATCH, k).any(axis=1)
            if up.any():
                out[k] = cand[int(np.argmax(up))]
                break
        else:
            raise ConfigError(
                CONNECTED_KEY,
                "connected",
                f"found no place for robot {k} linked to the {k} already placed in "
                f"{CONNECTED_BATCH * CONNECTED_ROUNDS} draws: too many robots (world.n_robots = {n}) for "
                "the space near world.start_m (enlarge world.centre_side_m)",
            )
    return out


def _ranges(channel: Any, n: int) -> np.ndarray:
    if channel is None:
        raise ValueError('world.placement = "connected" needs the run\'s channel')
    return np.broadcast_to(np.asarray(channel.state.range_m, dtype=float), (n,))


def _linked(channel: Any) -> Callable[..., np.ndarray]:
    """The link's state of pairs ``a, b`` at positions ``pa, pb`` as the channel decides it
    at ``t = 0``: the unit disk of the ranges in open space, else the radio's own decision
    (:func:`netsim.links.wall_sweeps.linked`); on a torus over the nearest image."""
    reception = None if channel is None else channel.reception
    if reception is None:
        box = float(channel.state.side_m) if channel is not None and channel.state.torus else 0.0

        def disk(a: np.ndarray, b: np.ndarray, pa: np.ndarray, pb: np.ndarray, ranges: np.ndarray) -> np.ndarray:
            m = len(a)
            ends = np.concatenate([pa, pb]).astype(float)
            rows = np.arange(m)
            radius = link_ranges_m(ranges, a, b)
            return load("netsim._kernels", len(ranges)).in_range(ends, rows, rows + m, radius, box)

        return disk
    shadow = reception.shadowing
    if shadow is not None and shadow.sigma_db > 0:
        raise ConfigError(
            CONNECTED_KEY,
            "connected",
            "needs links that positions decide; under shadowing (channel.shadowing_sigma_db > 0) "
            "each frame draws its own",
        )
    from netsim.links.wall_sweeps import envelope_radii, linked

    def radio(a: np.ndarray, b: np.ndarray, pa: np.ndarray, pb: np.ndarray, ranges: np.ndarray) -> np.ndarray:
        return linked(reception, envelope_radii(reception, ranges)[1], a, b, pa, pb)

    return radio


def _start_space(
    world: WorldParams, area: Bounds, start: np.ndarray, occupancy: Any
) -> Callable[[np.random.Generator, int], np.ndarray]:
    """A function ``draw(rng, k)``: ``k`` points uniform over the start space (the square
    about ``start`` in the area, and on a map the free region's cells in it)."""
    half = world.centre_side_m / 2
    lo = np.maximum(start - half, [area.x_min, area.y_min])
    hi = np.minimum(start + half, [area.x_max, area.y_max])
    if occupancy is None:
        return lambda rng, k: lo + rng.uniform(0.0, 1.0, size=(k, 2)) * (hi - lo)
    from netsim.world.free_space import draw_free, free_cells, free_region

    if not occupancy.is_free(start[None, :])[0]:
        raise ConfigError(
            "world.start_m", [float(v) for v in start], f"is not in a free cell of world.map ({occupancy.source})"
        )
    region = free_region(occupancy, area, start[None, :])
    cells = free_cells(occupancy, region, Bounds(float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1])))
    return lambda rng, k: draw_free(occupancy, cells, rng, k)
