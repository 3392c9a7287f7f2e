"""``netsim export``: a finished run in the formats robot teams' tools read.

- ``bonnmotion``: the robots' motion as a BonnMotion ``.movements`` file (``.gz``:
  compressed) with its ``.params`` beside it, from ``legs.parquet`` (exact: every leg's
  start and the positions at the run's end);
- ``ns2``: the same motion as an ns-2 movement file (``setdest`` per leg);
- ``rosbag2``: a ROS 2 bag (a new folder) with the sampled poses, the links, the roles,
  the messages and the packets (:mod:`netsim.formats.rosbag2`), for ``ros2 bag``, RViz and
  Foxglove.

Written to a temporary name first and moved into place, so a failure leaves nothing.
"""

from __future__ import annotations

import os
import shutil
import tempfile
import warnings
from pathlib import Path

import pandas as pd

from netsim.config import world_bounds
from netsim.errors import NetsimInputError
from netsim.formats import format_of_name, ns2
from netsim.tools.output import existing_dir, is_run_dir, load_run_config, names_a_directory, read_run_table

FORMATS = ("bonnmotion", "ns2", "rosbag2")


def _table(run_dir: Path, name: str, n_robots: int, needed: bool = True) -> pd.DataFrame | None:
    table = read_run_table(run_dir, name, n_robots)
    if table is None and needed:
        raise NetsimInputError(f"{run_dir}: the run has no {name}.parquet, which this export needs")
    return table


def check_out(out: Path, fmt: str) -> None:
    """Refuse, before any work, an output that exists or whose folder cannot be written."""
    if out.exists():
        raise NetsimInputError(f"--out {out}: exists already; give a new path")
    parent = out.parent
    if not parent.is_dir():
        what = "is a file" if parent.exists() else "does not exist"
        raise NetsimInputError(f"--out {out}: the directory {parent} {what}")
    try:
        probe = tempfile.mkdtemp(prefix=f".{out.name}.", dir=parent)
        Path(probe).rmdir()
    except OSError as exc:
        raise NetsimInputError(f"--out {out}: cannot write in {parent} ({exc.strerror or exc})") from None
    # A trace is read back by its name (mobility.trace_format = "auto"): a name another
    # format's would be read as that one, or a compressed one that is not compressed.
    read_as = format_of_name(out.name)
    if fmt == "ns2" and read_as != "ns2":
        raise NetsimInputError(f"--out {out}: an ns-2 file named so would be read back as {read_as}; give another name")
    if fmt == "ns2" and out.suffix == ".gz":
        raise NetsimInputError(f"--out {out}: an ns-2 file is written as plain text; give a name without .gz")
    if fmt == "rosbag2" and out.suffix.lower() in (".mcap", ".db3", ".bag"):
        raise NetsimInputError(
            f"--out {out}: a bag is a folder (its storage file inside it); give the folder's name, without {out.suffix}"
        )
    if fmt == "bonnmotion":
        from netsim.formats.bonnmotion import params_path

        if read_as != "bonnmotion":
            raise NetsimInputError(f"--out {out}: a BonnMotion file is named NAME.movements or NAME.movements.gz")
        params = params_path(out)
        if params.exists():
            raise NetsimInputError(f"--out {out}: {params}, written beside it, exists already; give a new name")


def export(run_dir: str | Path, fmt: str, out: str | Path) -> Path:
    """Write ``run_dir`` as ``fmt`` to ``out``; returns ``out``."""
    from netsim.formats import waypoints

    if fmt not in FORMATS:
        raise NetsimInputError(f"--format {fmt}: must be one of {', '.join(FORMATS)}")
    if fmt != "rosbag2" and names_a_directory(out):  # a bag is a directory; the others are files
        raise NetsimInputError(f"--out {out}: names a directory; give the path of a file")
    out = Path(out)
    run_dir = existing_dir(run_dir)
    if not is_run_dir(run_dir):
        raise NetsimInputError(f"{run_dir}: not a run directory (no manifest.json)")
    check_out(out, fmt)
    config = load_run_config(run_dir)
    n, duration, area = config.world.n_robots, config.duration_s, world_bounds(config.world)
    if fmt == "rosbag2":
        if config.world.torus:
            warnings.warn(
                "a torus run's bag holds its sampled poses only: replayed as a trace, a robot goes straight across "
                "the square between the two samples about a border; replay a torus run from --format ns2 or bonnmotion",
                stacklevel=2,
            )
        frames = {
            name: _table(run_dir, name, n, name == "positions")
            for name in ("positions", "links", "roles", "messages", "packets")
        }
        if frames["positions"] is not None and frames["positions"].empty:
            raise NetsimInputError(f"{run_dir}: positions.parquet is empty (set output.position_interval_s > 0)")
        from netsim.formats import rosbag2

        # The bag's files are named after its folder: write it under its own name in a
        # temporary folder, then move it into place.
        tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
        try:
            rosbag2.write(tmp / out.name, {k: v for k, v in frames.items() if v is not None})
            (tmp / out.name).replace(out)
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
        return out
    legs = _table(run_dir, "legs", n)
    if config.world.torus:
        # The formats know no torus: legs that run on past a border are cut there, and the
        # robot jumps to the opposite one.
        from netsim.trajectory import folded_legs

        legs = folded_legs(legs, n, config.world.side_m, duration)
    fd, name = tempfile.mkstemp(
        prefix=f".{out.name}.", suffix=".gz" if out.name.endswith(".gz") else "", dir=out.parent
    )
    os.close(fd)
    Path(name).unlink()
    tmp = Path(name)
    try:
        if fmt == "ns2":
            if area.x_min < 0 or area.y_min < 0:
                warnings.warn(
                    f"the run's area [{area.x_min:g}, {area.y_min:g}, {area.x_max:g}, {area.y_max:g}] reaches below 0, "
                    "where ns-2's topography starts: ns-2 refuses those destinations (netsim and ns-3 read them); "
                    "BonnMotion's x_min, y_min carry it",
                    stacklevel=2,
                )
            ns2.write(tmp, legs, n, duration, f"netsim export of {run_dir}", area)
        else:
            from netsim.formats import bonnmotion

            bonnmotion.write(tmp, waypoints.from_legs(legs, n, duration), area, duration)
            bonnmotion.params_path(tmp).replace(bonnmotion.params_path(out))
        tmp.replace(out)
    finally:
        tmp.unlink(missing_ok=True)
    return out
