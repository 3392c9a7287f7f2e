"""Occupancy maps in the ROS ``map_server`` format: a YAML file and its PGM or PNG image.

The format a robot team's SLAM already writes (``map_saver``)::

    image: office.pgm          # relative to the YAML file's folder
    resolution: 0.25           # metres per pixel
    origin: [0.0, 0.0, 0.0]    # pose (x, y, yaw) of the lower-left pixel's corner
    negate: 0
    occupied_thresh: 0.65
    free_thresh: 0.196
    mode: trinary              # optional: trinary (default) or scale

Pixels are read exactly as ROS 2's ``map_server`` (Nav2) reads them: the mean of the
channels ``c`` (in ``trinary`` mode an alpha channel is averaged in too; in ``scale`` mode it
is not, and a pixel that is not fully opaque is unknown), ``p = (255 - c) / 255`` (``p = c / 255`` with
``negate``); a cell is **occupied** when ``p > occupied_thresh``, **free** when
``p < free_thresh``, and **unknown** otherwise (``scale`` mode's intermediate values
count as unknown here). Row 0 of the image is the top of the map: the grid here is flipped
so that row ``j`` covers ``y`` in ``[oy + j res, oy + (j + 1) res)``, as in ROS's
``OccupancyGrid``.

What the cells mean in netsim:

- **occupied** cells are walls: under the unit disk they block a link, under log-distance
  each run of them that a link's line crosses costs ``wall_loss_db``;
- **unknown** cells do not block radio (only occupied cells are walls) but robots never go
  there: motion, placement and waypoints use free cells only;
- a point belongs to the cell ``floor((p - origin) / res)`` (half-open cells, as ROS's
  ``worldToMap``); a point on the map's far edge belongs to the last cell.

Maps whose origin has a non-zero yaw are refused (rotate the image instead), and so are
16-bit images and ``mode: raw`` (no thresholds, so no walls).

The simulated area (``world.bounds_m``, by default ``[0, side]^2``; ``"map"``: the map's
whole extent, in its own frame) must lie inside the map: :meth:`OccupancyMap.check_area`.
"""

from __future__ import annotations

import hashlib
import math
import re
from dataclasses import dataclass
from functools import cached_property, lru_cache
from importlib import resources
from pathlib import Path

import numpy as np

from netsim.area import KEY as BOUNDS_KEY
from netsim.area import Bounds, as_bounds
from netsim.compiled import load
from netsim.errors import ConfigError, did_you_mean, not_a_file
from netsim.geometry import cell_centres_m

MAP_KEY = "world.map"
REQUIRED = ("image", "resolution", "origin", "negate", "occupied_thresh", "free_thresh")
EXAMPLES = ("office", "cave")


@dataclass(frozen=True, eq=False)
class OccupancyMap:
    """A map's cells, row 0 at the bottom (lowest ``y``), and where they lie in the world."""

    occupied: np.ndarray  # (H, W) bool: walls
    free: np.ndarray  # (H, W) bool: where robots may be
    resolution_m: float
    origin_m: tuple[float, float]
    source: str = ""

    def __post_init__(self):
        if self.occupied.shape != self.free.shape or self.occupied.ndim != 2 or self.occupied.size == 0:
            raise ValueError("occupied and free must be non-empty 2-D arrays of the same shape")
        if not (math.isfinite(self.resolution_m) and self.resolution_m > 0):
            raise ValueError("resolution_m must be a finite number > 0")

    @property
    def shape(self) -> tuple[int, int]:
        return self.occupied.shape

    @cached_property
    def sha256(self) -> str:
        """A fingerprint of what a run takes from the map (its cells, free and occupied,
        their size and where they lie): a run records it, so that a tool reading the run
        later can tell a map file edited since from the one the run had."""
        digest = hashlib.sha256()
        digest.update(repr((self.shape, float(self.resolution_m), tuple(map(float, self.origin_m)))).encode())
        digest.update(np.packbits(self.occupied).tobytes())
        digest.update(np.packbits(self.free).tobytes())
        return digest.hexdigest()

    @cached_property
    def not_free(self) -> np.ndarray:
        """Cells robots may not enter (occupied or unknown)."""
        return np.ascontiguousarray(~self.free)

    @property
    def extent_m(self) -> tuple[float, float, float, float]:
        """``(x_min, x_max, y_min, y_max)`` of the map in world coordinates."""
        h, w = self.shape
        ox, oy = self.origin_m
        return ox, ox + w * self.resolution_m, oy, oy + h * self.resolution_m

    def to_grid(self, points_m) -> tuple[np.ndarray, np.ndarray]:
        """Grid coordinates ``(u, v)`` of points: cell ``(floor(u), floor(v))``, in cell units."""
        return grid_coords(points_m, self.origin_m, self.resolution_m)

    def _where(self, points_m) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Of each point: on the map, in a free cell, its cell's column and row (the map
        loops' rules, :func:`netsim.world._kernels.map_cells`)."""
        u, v = self.to_grid(points_m)
        k = len(u)
        on, free = np.empty(k, bool), np.empty(k, bool)
        i, j = np.empty(k, np.int64), np.empty(k, np.int64)
        h, w = self.shape
        flat = np.ascontiguousarray(self.free).reshape(-1)
        load("netsim.world._kernels", None, values=k).map_cells(flat, h, w, u, v, on, free, i, j)
        return on, free, i, j

    def cells(self, points_m) -> tuple[np.ndarray, np.ndarray]:
        """Column ``i`` and row ``j`` of the cell of each point (far edges in the last cell)."""
        _, _, i, j = self._where(points_m)
        return i, j

    def nearest_cells(self, points_m) -> tuple[np.ndarray, np.ndarray]:
        """Column ``i`` and row ``j`` of the cell of each point, a point off the map in the
        nearest cell at its edge (:func:`netsim.world._kernels.clamped_cell`)."""
        u, v = self.to_grid(points_m)
        i, j = np.empty(len(u), np.int64), np.empty(len(u), np.int64)
        h, w = self.shape
        load("netsim.world._kernels", None, values=len(u)).clamped_cells(u, v, h, w, i, j)
        return i, j

    def contains(self, points_m) -> np.ndarray:
        """Whether each point lies on the map (its closed extent)."""
        return self._where(points_m)[0]

    def is_free(self, points_m) -> np.ndarray:
        """Whether each point lies on the map in a free cell."""
        return self._where(points_m)[1]

    def cell_centres_m(self) -> tuple[np.ndarray, np.ndarray]:
        """World ``x`` of every column's centre and ``y`` of every row's centre."""
        h, w = self.shape
        r = self.resolution_m
        return cell_centres_m(self.origin_m[0], r, np.arange(w)), cell_centres_m(self.origin_m[1], r, np.arange(h))

    def check_area(self, area: float | Bounds, bounds_given: bool = False) -> None:
        """Refuse a map that does not cover the area (``Bounds``, or the side of the square
        ``[0, side]^2``) or has no free cell in it. ``bounds_given``: the area is
        ``world.bounds_m`` as the user set it, and an area the map does not cover is told as
        that key's value; else it is the square ``[0, world.side_m]^2`` (or the map's own
        extent), and the map is told as too small."""
        b = as_bounds(area)
        x0, x1, y0, y1 = self.extent_m
        name = self.source or "<map>"
        covers = f"covers x in [{x0:g}, {x1:g}], y in [{y0:g}, {y1:g}]"
        tol = 1e-9 * max(1.0, b.width, b.height, abs(b.x_min), abs(b.y_min))
        inside = not (x0 > b.x_min + tol or y0 > b.y_min + tol or x1 < b.x_max - tol or y1 < b.y_max - tol)
        if bounds_given and not inside:
            raise ConfigError(
                BOUNDS_KEY,
                b.as_list(),
                f"is not inside world.map = {name!r}, which {covers}; set world.bounds_m inside it",
            )
        if not inside:
            side_m = b.width
            w_m, h_m = x1 - x0, y1 - y0
            if w_m < side_m - tol or h_m < side_m - tol:
                raise ConfigError(
                    MAP_KEY,
                    name,
                    f"covers {w_m:g} m x {h_m:g} m, smaller than the area ({side_m:g} m x {side_m:g} m, world.side_m):"
                    f' set world.side_m to at most {min(w_m, h_m):g}, or world.bounds_m = "map" for the whole map',
                )
            raise ConfigError(
                MAP_KEY,
                name,
                f"with origin [{x0:g}, {y0:g}] {covers}, which does not contain the area [0, {side_m:g}] x "
                f"[0, {side_m:g}]; the origin must be <= 0 and the map reach world.side_m (or set world.bounds_m)",
            )
        cx, cy = self.cell_centres_m()
        cols = (cx >= b.x_min) & (cx <= b.x_max)
        rows = (cy >= b.y_min) & (cy <= b.y_max)
        if not self.free[np.ix_(rows, cols)].any():
            raise ConfigError(MAP_KEY, name, f"has no free cell inside the area {b.as_list()}")


def grid_coords(points_m, origin_m, cell_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Coordinates ``(u, v)`` of points on a grid with its corner at ``origin_m`` and cells
    ``cell_m`` wide: cell ``(floor(u), floor(v))``, in cell units (the kernel ``on_grid``)."""
    p = np.ascontiguousarray(points_m, dtype=float).reshape(-1, 2)
    u, v = np.empty(len(p)), np.empty(len(p))
    ox, oy = float(origin_m[0]), float(origin_m[1])
    load("netsim.world._kernels", None, values=len(p)).grid_coords(p, ox, oy, float(cell_m), u, v)
    return u, v


def occupancy_from_pixels(
    pixels: np.ndarray,
    negate: bool,
    occupied_thresh: float,
    free_thresh: float,
    mode: str = "trinary",
    has_alpha: bool = False,
) -> tuple[np.ndarray, np.ndarray]:
    """``map_server``'s reading of an 8-bit image ``(H, W)`` or ``(H, W, C)``, top row first.

    Returns ``(occupied, free)`` in image order (row 0 at the top).

    >>> px = np.array([[0, 100, 254]], dtype=np.uint8)
    >>> occ, free = occupancy_from_pixels(px, False, 0.65, 0.196)
    >>> occ.tolist(), free.tolist()
    ([[True, False, False]], [[False, False, True]])
    """
    px = np.asarray(pixels)
    if px.ndim == 2:
        px = px[:, :, None]
    c = px.shape[2]
    # As ROS 2's map_server (Nav2): the shade is the mean of red, green and blue (a gray
    # channel is all three), and trinary mode averages an alpha channel in as a fourth; scale
    # mode leaves it out, and a pixel not fully opaque is unknown whatever its colour (the
    # unknown cells map_saver writes in scale mode are transparent).
    n_colour = c - 1 if has_alpha else c
    if n_colour not in (1, 3):
        raise ValueError(f"pixels of {c} channels: 1 (gray) or 3 (RGB) colour channels, besides an alpha")
    rgb_sum = px[:, :, :n_colour].astype(float).sum(axis=2) * (3 // n_colour)
    scale_alpha = has_alpha and mode != "trinary"
    if has_alpha and not scale_alpha:
        colour = (rgb_sum + px[:, :, c - 1]) / 4.0
    else:
        colour = rgb_sum / 3.0
    if negate:
        colour = 255.0 - colour
    p = (255.0 - colour) / 255.0
    occupied = p > occupied_thresh
    free = (p < free_thresh) & ~occupied
    if scale_alpha:
        opaque = px[:, :, c - 1] == 255
        occupied &= opaque
        free &= opaque
    return occupied, free


# YAML 1.1 (PyYAML) reads an exponent without a dot (as yaml-cpp writes -1000 at map_saver's
# precision: -1e+03), or without a sign, as text; YAML 1.2 and map_server read a number.
_EXPONENT_NUMBER = re.compile(r"[-+]?([0-9]+\.?[0-9]*|\.[0-9]+)[eE][-+]?[0-9]+")


def _yaml_number(value):
    """``value`` as map_server reads a YAML scalar: a number, or None when it is not one."""
    if isinstance(value, str) and _EXPONENT_NUMBER.fullmatch(value.strip()):
        return float(value)
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    return value


def _number(key, where, name, value, check, allowed):
    given, value = value, _yaml_number(value)
    if value is None:
        raise ConfigError(key, where, f"'{name}: {given!r}' {allowed}")
    if not (math.isfinite(value) and check(value)):
        raise ConfigError(key, where, f"'{name}: {value!r}' {allowed}")
    return float(value)


def example_path(name: str) -> Path:
    """The YAML file of a map shipped with netsim (``"office"`` or ``"cave"``)."""
    return Path(str(resources.files("netsim.world").joinpath("example_maps", f"{name}.yaml")))


def load_map(value: str | Path, key: str = MAP_KEY) -> OccupancyMap:
    """Read a ``map_server`` map: the path of its YAML file, or the name of an example map.

    Every problem is a :class:`~netsim.errors.ConfigError` naming ``key`` and ``value``.
    """
    import yaml
    from PIL import Image, UnidentifiedImageError

    where = str(value)
    path = example_path(where) if where in EXAMPLES else Path(where)
    if not path.is_file():
        raise ConfigError(
            key,
            where,
            f"must be the path of a map_server YAML file or one of {', '.join(EXAMPLES)} ({not_a_file(path)})"
            + did_you_mean(path.name, EXAMPLES),
        )
    try:
        meta = yaml.safe_load(path.read_text())
    except (yaml.YAMLError, UnicodeDecodeError) as exc:
        first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise ConfigError(key, where, f"is not valid YAML ({first})") from None
    if not isinstance(meta, dict):
        raise ConfigError(key, where, f"must be a YAML mapping with the keys {', '.join(REQUIRED)}")
    missing = [k for k in REQUIRED if k not in meta]
    if missing:
        raise ConfigError(key, where, f"lacks {', '.join(missing)} (a map_server YAML needs {', '.join(REQUIRED)})")

    resolution = _number(key, where, "resolution", meta["resolution"], lambda v: v > 0, "must be a number > 0 (m)")
    origin = meta["origin"]
    if isinstance(origin, list | tuple):
        origin = [o if _yaml_number(o) is None else _yaml_number(o) for o in origin]
    if (
        not isinstance(origin, list | tuple)
        or len(origin) != 3
        or any(isinstance(o, bool) or not isinstance(o, int | float) or not math.isfinite(o) for o in origin)
    ):
        raise ConfigError(key, where, f"'origin: {origin!r}' must be [x, y, yaw], three finite numbers")
    if origin[2] != 0:
        raise ConfigError(key, where, f"'origin: {origin!r}': a yaw other than 0 is not supported (rotate the image)")
    negate = meta["negate"]
    if negate not in (0, 1) or (not isinstance(negate, bool | int)):
        raise ConfigError(key, where, f"'negate: {negate!r}' must be 0 or 1")
    occ_t = _number(
        key, where, "occupied_thresh", meta["occupied_thresh"], lambda v: 0 <= v <= 1, "must be a number in [0, 1]"
    )
    free_t = _number(
        key, where, "free_thresh", meta["free_thresh"], lambda v: 0 <= v <= 1, "must be a number in [0, 1]"
    )
    if free_t > occ_t:
        raise ConfigError(
            key, where, f"'free_thresh: {free_t:g}' must not exceed 'occupied_thresh: {occ_t:g}' (bad thresholds)"
        )
    mode = meta.get("mode", "trinary")
    if mode not in ("trinary", "scale"):
        raise ConfigError(key, where, f"'mode: {mode!r}' must be trinary or scale (raw maps carry no walls)")
    image = meta["image"]
    if not isinstance(image, str) or not image:
        raise ConfigError(key, where, f"'image: {image!r}' must name the map's image file")
    image_path = _beside(path, image)
    if not image_path.is_file():
        raise ConfigError(key, where, f"'image: {image}': {not_a_file(image_path)} ({image_path})")
    try:
        with Image.open(image_path) as img:
            img.load()
            pixels, has_alpha = _pixels(img, key, where, image)
    except (UnidentifiedImageError, OSError, SyntaxError, ValueError) as exc:
        raise ConfigError(key, where, f"'image: {image}' is not a readable PGM or PNG image ({exc})") from None
    occupied, free = occupancy_from_pixels(pixels, bool(negate), occ_t, free_t, mode, has_alpha)
    # Image row 0 is the top of the map; the grid's row 0 is its bottom (lowest y).
    return OccupancyMap(
        np.ascontiguousarray(occupied[::-1]),
        np.ascontiguousarray(free[::-1]),
        resolution,
        (float(origin[0]), float(origin[1])),
        where,
    )


def _pixels(img, key, where, image) -> tuple[np.ndarray, bool]:
    mode = img.mode
    if mode in ("I", "I;16", "I;16B", "I;16L", "F"):
        raise ConfigError(key, where, f"'image: {image}' has {mode} pixels; save it with 8 bits per channel")
    if mode == "1":
        img = img.convert("L")
    elif mode == "P":
        img = img.convert("RGBA" if "transparency" in img.info else "RGB")
    elif mode not in ("L", "LA", "RGB", "RGBA"):
        img = img.convert("RGB")
    return np.asarray(img, dtype=np.uint8), img.mode in ("LA", "RGBA")


def save_map(
    path: str | Path,
    occupied: np.ndarray,
    free: np.ndarray,
    resolution_m: float,
    origin_m=(0.0, 0.0),
    occupied_thresh: float = 0.65,
    free_thresh: float = 0.196,
) -> Path:
    """Write a map as ``map_saver`` does: a PGM (occupied 0, free 254, unknown 205) and its
    YAML, its numbers in their shortest exact form (a georeferenced origin read back as given).

    ``occupied`` and ``free`` are in grid order (row 0 at the bottom). Returns the YAML path.
    """
    from PIL import Image

    path = Path(path)
    px = np.full(occupied.shape, 205, dtype=np.uint8)
    px[free] = 254
    px[occupied] = 0
    image = path.with_suffix(".pgm")
    Image.fromarray(px[::-1]).save(image)
    path.write_text(
        f"image: {image.name}\n"
        f"resolution: {float(resolution_m)!r}\n"
        f"origin: [{float(origin_m[0])!r}, {float(origin_m[1])!r}, 0.0]\n"
        "negate: 0\n"
        f"occupied_thresh: {float(occupied_thresh)!r}\n"
        f"free_thresh: {float(free_thresh)!r}\n"
    )
    return path


def _stamp(value: str) -> tuple:
    """The version of map ``value``: its YAML file's and its image's (an image edited
    beside an unchanged YAML file is another map)."""
    path = example_path(value) if value in EXAMPLES else Path(value)
    return (value, *_file_stamp(path), *_file_stamp(_image_named(path)))


def _file_stamp(path: Path | None) -> tuple:
    try:
        st = path.stat() if path is not None else None
    except OSError:
        st = None
    return (None, None) if st is None else (st.st_mtime_ns, st.st_size)


def _image_named(path: Path) -> Path | None:
    """The image a map's YAML file names, if it names one (:func:`load_map` says what is
    wrong with one that does not)."""
    import yaml

    try:
        meta = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError, UnicodeDecodeError):
        return None
    image = meta.get("image") if isinstance(meta, dict) else None
    if not isinstance(image, str) or not image:
        return None
    return _beside(path, image)


def _beside(yaml_path: Path, image: str) -> Path:
    """The image a map's YAML file names: a relative name is of its folder."""
    return Path(image) if Path(image).is_absolute() else yaml_path.parent / image


@lru_cache(maxsize=8)
def _cached(stamp: tuple, key: str) -> OccupancyMap:
    return load_map(stamp[0], key)


def cached_map(value: str | Path, key: str = MAP_KEY) -> OccupancyMap:
    """:func:`load_map`, read once per file version (a sweep's runs share one map)."""
    return _cached(_stamp(str(value)), key)
