"""BonnMotion's native movement format (``.movements``, gzip-compressed ``.movements.gz``),
in and out.

One line per node, in node order: ``t1 x1 y1 t2 x2 y2 ...``, the node's waypoints (three
numbers each; four, ``t x y z``, for a 3D scenario, whose ``z`` is dropped), times
non-decreasing. The node moves in a straight line between consecutive waypoints and stays
at its last one. BonnMotion writes its parameters beside it, in ``NAME.params`` (``x=``,
``y=``: the area's size, ``duration=``, ``nn=``: the number of nodes, ``J=3D`` for 3D);
when that file is there its node count is checked against the run's. Its area is not: the
run's own area (``world``) holds the robots, and every position is checked against it.
"""

from __future__ import annotations

import gzip
import math
from pathlib import Path

import numpy as np

from netsim.area import Bounds, as_bounds
from netsim.errors import NetsimInputError, not_a_file
from netsim.formats.waypoints import Waypoints


def params_path(path: Path) -> Path:
    """``NAME.params`` beside ``NAME.movements`` or ``NAME.movements.gz``."""
    name = path.name
    for suffix in (".movements.gz", ".movements"):
        if name.endswith(suffix):
            return path.with_name(name[: -len(suffix)] + ".params")
    return path.with_name(name + ".params")


def read_params(path: Path) -> dict[str, str]:
    """The ``key=value`` lines of a ``.params`` file (empty when there is none)."""
    if not path.is_file():
        return {}
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise NetsimInputError(f"{path}: cannot be read as a BonnMotion parameters file ({exc})") from None
    out = {}
    for line in text.splitlines():
        if "=" in line and not line.lstrip().startswith("#"):
            key, value = line.split("=", 1)
            out[key.strip()] = value.strip()
    return out


def _text(path: Path) -> str:
    try:
        if path.name.endswith(".gz"):
            with gzip.open(path, "rt") as f:
                return f.read()
        return path.read_text()
    except (OSError, EOFError, UnicodeDecodeError) as exc:
        raise NetsimInputError(f"{path}: cannot be read as a BonnMotion movements file ({exc})") from None


def read(path: str | Path) -> tuple[Waypoints, dict[str, str]]:
    """The waypoints of a ``.movements`` file and its parameters (from ``.params`` beside
    it, if any); :class:`NetsimInputError` naming the file and line for a malformed one."""
    path = Path(path)
    if not path.is_file():
        raise NetsimInputError(f"{str(path)!r}: {not_a_file(path)}")
    params = read_params(params_path(path))
    width = 4 if params.get("J", "").upper() == "3D" else 3
    robots, times, xs, ys = [], [], [], []
    node = 0
    for lineno, line in enumerate(_text(path).splitlines(), 1):
        fields = line.split()
        if not fields or line.lstrip().startswith("#"):
            continue
        try:
            values = np.array([_number(f) for f in fields])
        except ValueError:
            bad = next(f for f in fields if not _is_number(f))
            raise NetsimInputError(f"{path}:{lineno}: {bad!r} is not a number") from None
        if len(values) % width:
            raise NetsimInputError(
                f"{path}:{lineno}: {len(values)} numbers do not make whole waypoints "
                f"({'t x y z' if width == 4 else 't x y'}): the last one is broken"
            )
        if not np.isfinite(values).all():
            raise NetsimInputError(f"{path}:{lineno}: numbers must be finite")
        w = values.reshape(-1, width)
        if (np.diff(w[:, 0]) < 0).any():
            k = int(np.flatnonzero(np.diff(w[:, 0]) < 0)[0]) + 1
            raise NetsimInputError(f"{path}:{lineno}: waypoint {k + 1}: time {w[k, 0]:g} goes back")
        if w[0, 0] < 0:
            raise NetsimInputError(f"{path}:{lineno}: negative time {w[0, 0]:g}")
        robots.append(np.full(len(w), node))
        times.append(w[:, 0])
        xs.append(w[:, 1])
        ys.append(w[:, 2])
        node += 1
    if node == 0:
        raise NetsimInputError(f"{path}: no movement line (one line of 't x y ...' per node)")
    if "nn" in params and params["nn"].isdigit() and int(params["nn"]) != node:
        raise NetsimInputError(f"{params_path(path)}: nn = {params['nn']} but {path} has {node} node lines")
    wp = Waypoints.of(np.concatenate(robots), np.concatenate(times), np.concatenate(xs), np.concatenate(ys), str(path))
    return wp, params


def _number(text: str) -> float:
    """``text`` as BonnMotion (Java's ``Double.parseDouble``) reads it: Python's ``float``
    alone also takes digits grouped by underscores, ``1_0``, which BonnMotion refuses."""
    if "_" in text:
        raise ValueError(text)
    return float(text)


def _is_number(text: str) -> bool:
    try:
        _number(text)
    except ValueError:
        return False
    return True


def write(path: str | Path, wp: Waypoints, area: float | Bounds, duration_s: float) -> None:
    """``wp`` as a ``.movements`` file (gzip-compressed when ``path`` ends in ``.gz``), and
    its ``.params`` beside it. Numbers are written with Python's shortest round-trip
    ``repr``, so reading the file back gives the same positions.

    Positions stay in the run's frame. BonnMotion's area is ``[0, x] x [0, y]``: for an area
    (Bounds, or the side of the square ``[0, side]^2``) in the positive quadrant ``x`` and
    ``y`` are its far corner; for one reaching below 0 (a map's frame), ``x`` and ``y`` are
    its size and the extra keys ``x_min`` and ``y_min`` its near corner."""
    b = as_bounds(area)
    path = Path(path)
    lines = []
    for i in range(wp.n_robots):
        rows = wp.robot == i
        triples = zip(wp.t_s[rows].tolist(), wp.x_m[rows].tolist(), wp.y_m[rows].tolist())
        lines.append(" ".join(f"{t!r} {x!r} {y!r}" for t, x, y in triples))
    text = "\n".join(lines) + "\n"
    if path.name.endswith(".gz"):
        with gzip.open(path, "wt") as f:
            f.write(text)
    else:
        path.write_text(text)
    params: dict[str, object] = {"model": "netsim"}
    if b.x_min >= 0 and b.y_min >= 0:
        params.update(x=b.x_max, y=b.y_max)
    else:
        params.update(x=b.width, y=b.height, x_min=b.x_min, y_min=b.y_min)
    params.update(duration=duration_s, nn=wp.n_robots, J="2D")
    params_path(path).write_text("".join(f"{k}={_plain(v)}\n" for k, v in params.items()))


def _plain(v: object) -> str:
    return repr(v) if isinstance(v, float) and not math.isnan(v) else str(v)
