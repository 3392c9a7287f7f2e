"""Output directories: checked before any work, written so that nothing is ever half-written.

:func:`claim_dir` makes sure a directory can take results *before* a simulation starts
(it is not a file, does not lie under a file, can be created and written), and removes
what it created if the work then fails, so a failed command leaves nothing behind.

A run's directory holds that run's files and nothing else. :func:`write_run` first writes
every file into a private temporary directory inside the output directory; then, if the
directory holds an earlier run (it has a ``manifest.json``), that run's files are removed
(``manifest.json`` first, so a directory with a manifest always holds one complete run);
then the new files are moved into place with atomic renames, ``manifest.json`` last. A
non-empty directory that holds no run is refused: netsim never mixes its tables with
files it did not write.
"""

from __future__ import annotations

import json
import os
import platform
import secrets
import shutil
import sys
import tempfile
import tomllib
import warnings
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from contextlib import contextmanager
from importlib import metadata
from pathlib import Path

import numpy as np
import pandas as pd
import tomli_w

from netsim.config import Config, from_dict, to_dict
from netsim.errors import ConfigError, NetsimInputError
from netsim.tools.interrupt import ignoring_interrupts, interrupted

# The distributions named in a manifest, with the module each installs.
VERSIONED = {
    "netsim-robots": "netsim",
    "simpy": "simpy",
    "numpy": "numpy",
    "scipy": "scipy",
    "networkx": "networkx",
    "pandas": "pandas",
    "pyarrow": "pyarrow",
}


def versions() -> dict[str, str]:
    """The versions of Python and of the distributions netsim runs on."""
    out = {"python": platform.python_version()}
    for dist, module in VERSIONED.items():
        out[dist] = _version(dist, module)
    return out


def _version(dist: str, module: str) -> str:
    # A loaded module's own __version__ is its distribution's; reading the installed
    # metadata instead parses a file per distribution, after every run.
    loaded = sys.modules.get(module)
    version = getattr(loaded, "__version__", None)
    if isinstance(version, str):
        return version
    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return "not installed"


def _plain(value):
    """JSON has no NaN or infinity: write them as null."""
    if isinstance(value, float) and (value != value or value in (float("inf"), float("-inf"))):
        return None
    return value


TMP_PREFIX = ".netsim-tmp-"
RUN_FILES = ("config.toml", "manifest.json", "summary.json", "view.html")
# What a bridge session writes besides (netsim.tools.bridge): a run's file only where the
# run was one, so that a user's scenario of that name beside another run is left alone.
BRIDGE_FILE = "bridge.toml"


def names_a_directory(path: str | Path) -> bool:
    """Whether ``path`` as typed names a directory: it ends with a separator, or its last
    part is ``.`` or ``..`` (``Path`` drops the separator and the ``.``)."""
    text = os.fspath(path)
    return text.endswith(tuple(filter(None, (os.sep, os.altsep)))) or os.path.basename(text) in (".", "..")


def is_run_dir(path: str | Path) -> bool:
    """A directory written by :func:`write_run` (it has a ``manifest.json``)."""
    return (Path(path) / "manifest.json").is_file()


def existing_dir(run_dir: str | Path) -> Path:
    """``run_dir`` as a path; one that is no directory is refused alike by every command
    that reads a run (:class:`NetsimInputError`)."""
    run_dir = Path(run_dir)
    if run_dir.exists() and not run_dir.is_dir():
        raise NetsimInputError(f"{run_dir}: is a file, not a run directory (the --out of a `netsim run`)")
    if not run_dir.is_dir():
        raise NetsimInputError(f"{run_dir}: no such run directory (the --out of a `netsim run`)")
    return run_dir


# The columns the readers of a run (view, export, figures) take from its tables by name:
# a run written before a table gained another column is read all the same.
READ_COLUMNS = {
    "positions": ("t_s", "robot", "x_m", "y_m"),
    "legs": ("t_s", "robot", "x_m", "y_m", "vx_mps", "vy_mps"),
    "links": ("a", "b", "t_up_s", "t_down_s"),
    "roles": ("t_s", "robot", "role", "leader"),
    "groups": ("t_s", "robot", "group", "primary"),
    "beliefs": (
        "t_s",
        "robot",
        "believed_neighbours",
        "true_neighbours",
        "stale_neighbours",
        "missing_neighbours",
        "leader_in_range",
    ),
    "neighbour_beliefs": ("t_s", "robot", "neighbour", "believed", "in_range"),
    "messages": ("msg_id", "src", "dst", "t_sent_s", "delivered", "t_delivered_s"),
    "hops": ("msg_id", "hop", "sender", "receiver", "t_sent_s", "t_received_s"),
    "packets": ("flow", "packet", "src", "dst", "t_sent_s", "delivered", "t_delivered_s", "hops", "latency_s"),
    "ack_delivery": ("t_s", "delivery_ratio"),
    "coverage": ("t_s", "covered_fraction_leaders", "covered_fraction_all"),
}


# The columns of a run's tables that hold robot ids, each within the run's team.
ROBOT_COLUMNS = {
    "positions": ("robot",),
    "legs": ("robot",),
    "links": ("a", "b"),
    "roles": ("robot",),
    "groups": ("robot", "group"),
    "beliefs": ("robot",),
    "neighbour_beliefs": ("robot", "neighbour"),
    "messages": ("src", "dst"),
    "hops": ("sender", "receiver"),
    "packets": ("src", "dst"),
}


def read_run_table(run_dir: Path, name: str, n_robots: int) -> pd.DataFrame | None:
    """The run's table ``name`` (``name.parquet``), None where the run has none; a file
    that cannot be read as Parquet (cut short, overwritten), lacks a column the tools
    read, or names a robot outside the run's ``n_robots`` (a table of another run, or a
    config.toml edited since) is refused in one line."""
    path = run_dir / f"{name}.parquet"
    if not path.is_file():
        return None
    try:
        table = pd.read_parquet(path)
    except (OSError, ValueError, TypeError, NotImplementedError) as exc:  # pyarrow's errors derive from these
        first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise NetsimInputError(f"{path}: cannot be read as Parquet ({first})") from None
    missing = [c for c in READ_COLUMNS.get(name, ()) if c not in table.columns]
    if missing:
        raise NetsimInputError(
            f"{path}: lacks the column{'s' if len(missing) > 1 else ''} {', '.join(missing)} of the run's "
            f"{name} table (changed since the run wrote it?)"
        )
    for column in ROBOT_COLUMNS.get(name, ()):
        if column in table.columns and len(table):
            ids = table[column].to_numpy()
            low, high = ids.min(), ids.max()
            if low < 0 or high >= n_robots:
                bad = low if low < 0 else high
                raise NetsimInputError(
                    f"{path}: names robot {bad} ({column}), but config.toml has {n_robots} robots "
                    "(a table of another run, or the configuration edited since?)"
                )
    if name == "legs":
        _check_legs(path, table, n_robots)
    return table


def _check_legs(path: Path, legs: pd.DataFrame, n_robots: int) -> None:
    """A legs table the tools can follow: every robot has a leg (its start), and every
    time, position and velocity is a number, no time before the run."""
    missing = np.setdiff1d(np.arange(n_robots), legs["robot"].to_numpy())
    if len(missing):
        raise NetsimInputError(
            f"{path}: robot {missing[0]} has no leg, but config.toml has {n_robots} robots "
            "(a table of another run, or the configuration edited since?)"
        )
    values = legs[["t_s", "x_m", "y_m", "vx_mps", "vy_mps"]].to_numpy(dtype=float)
    if not np.isfinite(values).all() or (legs["t_s"].to_numpy() < 0).any():
        raise NetsimInputError(f"{path}: holds a time before 0 or a value that is not a finite number (damaged?)")


def read_run_summary(run_dir: Path) -> dict:
    """The run's ``summary.json`` ({} where the run has none); one that is not JSON is
    refused in one line."""
    return _read_run_json(run_dir / "summary.json", "the run's measures")


def read_run_manifest(run_dir: Path) -> dict:
    """The run's ``manifest.json`` ({} where the run has none); one that is not JSON is
    refused in one line."""
    return _read_run_json(run_dir / "manifest.json", "what the run was")


def _read_run_json(path: Path, what: str) -> dict:
    if not path.is_file():
        return {}
    try:
        table = json.loads(path.read_text())
    except (ValueError, OSError) as exc:  # JSONDecodeError and UnicodeDecodeError are ValueErrors
        raise NetsimInputError(f"{path}: cannot be read as JSON ({exc})") from None
    if not isinstance(table, dict):
        raise NetsimInputError(f"{path}: holds no table of {what}")
    return table


def read_run_config(run_dir: Path) -> dict:
    """The run's ``config.toml`` as a table, ``duration_s`` where the run ended: a session
    ended before its planned end (a bridge's Ctrl-C) has its tables end at its summary's
    ``duration_s``, and what reads them (export, replay, figures) must end there too, not
    carry the robots' last legs on to the plan's. A run without a config, or one that is
    not TOML, is refused in one line."""
    path = run_dir / "config.toml"
    if not path.is_file():
        raise NetsimInputError(f"{run_dir}: not a run directory (no config.toml)")
    try:
        table = tomllib.loads(path.read_text())
    except (tomllib.TOMLDecodeError, UnicodeDecodeError, OSError) as exc:
        raise NetsimInputError(f"{path}: cannot be read as TOML ({exc})") from None
    # A run writes its whole configuration: without these it is not a run's.
    missing = [k for k in ("duration_s", "world") if k not in table]
    if missing:
        raise NetsimInputError(f"{path}: holds no run's configuration (no {' or '.join(missing)})")
    try:
        ended = read_run_summary(run_dir).get("duration_s")
    except NetsimInputError:
        ended = None  # a damaged summary: the plan's end, as before the summary was read
    planned = table["duration_s"]
    numbers = all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in (ended, planned))
    if numbers and 0 < ended < planned:
        table["duration_s"] = float(ended)
    return table


def load_run_config(run_dir: Path) -> Config:
    """The run's configuration (:func:`read_run_config`), checked and resolved, without
    the warnings a run gives of it: they were given when it ran, and a session ended early
    would be warned of what its shorter end leaves out (a flow that starts after it)."""
    tree = read_run_config(run_dir)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            return from_dict(tree)
        except ConfigError as exc:
            world = tree.get("world") if isinstance(tree.get("world"), dict) else {}
            gone = isinstance(exc.value, str) and not Path(exc.value).exists()
            if exc.key == "world.map" and world.get("map") == exc.value and gone:
                # A run moved to another machine: its map stayed behind, at the path it ran with.
                raise ConfigError(
                    exc.key,
                    exc.value,
                    f"{exc.allowed}: the run's map, read from where it ran; copy the map there, or set world.map in "
                    f"{Path(run_dir) / 'config.toml'} to where it is now",
                ) from None
            raise


def earlier_run_files(out: Path) -> list[Path]:
    """The files of the run already in ``out``: ``config.toml``, ``manifest.json``,
    ``summary.json``, the tables (``*.parquet``), a bridge session's ``bridge.toml``, the
    replay (``view.html``) and the figures
    drawn from them (``fig*.png``). Empty when ``out`` holds no run."""
    if not is_run_dir(out):
        return []
    bridge = _was_a_bridge(out)
    ours = [p for p in out.iterdir() if p.is_file() and (_is_run_file(p.name) or bridge and p.name == BRIDGE_FILE)]
    return sorted(ours)


def _is_run_file(name: str) -> bool:
    # A figure drawn from the earlier run is stale with it.
    return name in RUN_FILES or name.endswith(".parquet") or (name.startswith("fig") and name.endswith(".png"))


def _was_a_bridge(run_dir: Path) -> bool:
    """Whether the run in ``run_dir`` was a bridge session (its summary has the bridge's
    figures)."""
    try:
        summary = json.loads((run_dir / "summary.json").read_text())
    except (OSError, ValueError):
        return False
    return isinstance(summary, dict) and "bridge_rate" in summary


def _foreign_entries(out: Path) -> list[str]:
    return sorted(p.name for p in out.iterdir() if not p.name.startswith(TMP_PREFIX))


def check_run_dir(path: str | Path, option: str = "--out") -> None:
    """Refuse a directory that is neither new, nor empty, nor an earlier run's."""
    out = Path(path)
    if out.is_dir() and not is_run_dir(out):
        entries = _foreign_entries(out)
        if entries:
            shown = ", ".join(entries[:3]) + (", ..." if len(entries) > 3 else "")
            raise NetsimInputError(
                f"{option} {out}: the directory is not empty ({shown}) and holds no netsim run (no manifest.json); "
                "give a new or empty directory (a directory holding an earlier run is replaced as a whole)"
            )


def check_sweep_dir(path: str | Path, option: str = "--out") -> None:
    """Refuse a non-empty directory that is not a sweep's (it has no ``sweep.json``)."""
    out = Path(path)
    if out.is_dir() and not (out / "sweep.json").is_file():
        entries = _foreign_entries(out)
        if entries:
            shown = ", ".join(entries[:3]) + (", ..." if len(entries) > 3 else "")
            raise NetsimInputError(
                f"{option} {out}: the directory is not empty ({shown}) and holds no sweep (no sweep.json); "
                "give a new or empty directory, or the directory of the same sweep to resume it"
            )


def _unwritable(option: str, path: Path, why: str) -> NetsimInputError:
    return NetsimInputError(f"{option} {path}: {why}")


@contextmanager
def claim_dir(path: str | Path, option: str = "--out", kind: str = "any", tables: Sequence[str] = ()) -> Iterator[Path]:
    """Make sure ``path`` can take results before the work starts; undo on failure.

    The directory (and any missing parents) is created and a probe file written and
    removed in it, so every reason it could not take the results (a file in the way, no
    permission, a read-only file system) shows now, as a :class:`NetsimInputError`,
    instead of after the work. ``kind = "run"`` also refuses a non-empty directory that
    holds no run (:func:`check_run_dir`), ``"sweep"`` one that holds no sweep (and probes
    the folders a sweep resumed there writes: ``runs``, ``failed`` and the kept ``tables``'
    own, those that exist). While the body runs the directory is locked (:func:`_lock_dir`):
    a second command given it is refused. If the
    body raises, the directories created here are removed again (when empty), so a
    failed command leaves nothing behind.
    """
    out = Path(path)
    created: list[Path] = []
    lock: int | None = -1
    doing = "cannot be used"  # what failed, should an OSError come
    try:
        missing = _missing_dirs(out, option)
        doing = "cannot be created"
        for d in reversed(missing):
            d.mkdir()
            created.append(d)
        # Locked before its content is judged: a command writing there now is told as
        # such, not as files that hold no run.
        doing = "cannot be opened"
        lock = _lock_dir(out)
        if lock is None:
            raise NetsimInputError(f"{option} {out}: another netsim command is writing there now; choose another")
        doing = "cannot be used"
        if kind == "run":
            check_run_dir(out, option)
        elif kind == "sweep":
            check_sweep_dir(out, option)
        doing = "cannot be written"
        probe_writable(out)
        # A sweep resumed writes into the folders an earlier one made, perhaps someone else's.
        for sub in _sweep_folders(out, tables) if kind == "sweep" else ():
            doing = f"cannot be resumed: {sub} cannot be written"
            probe_writable(sub)
    except BaseException as exc:
        _remove_empty(created)
        if lock is not None and lock >= 0:
            os.close(lock)
        if isinstance(exc, OSError):
            raise _unwritable(option, out, f"{doing} ({exc.strerror or exc})") from None
        raise
    try:
        yield out
    except BaseException:
        _remove_empty(created)
        raise
    finally:
        if lock >= 0:
            os.close(lock)


def _lock_dir(folder: Path) -> int | None:
    """An open descriptor of ``folder`` holding its lock (``flock``, released when closed
    or when the process ends, however it ends), so that two commands never write one
    directory at once; None when another holds it. Where ``flock`` is missing, no lock (-1)."""
    try:
        import fcntl
    except ImportError:  # not POSIX
        return -1
    fd = os.open(folder, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        os.close(fd)
        return None
    except OSError:  # a file system without locks: write unlocked, as where flock is missing
        os.close(fd)
        return -1
    return fd


def probe_writable(folder: Path) -> None:
    """Write and remove a file in ``folder``: raises the OSError that writing there would."""
    fd, tmp = tempfile.mkstemp(prefix=TMP_PREFIX, dir=folder)
    os.close(fd)
    os.unlink(tmp)


def _sweep_folders(out: Path, tables: Sequence[str]) -> list[Path]:
    """The folders a sweep resumed in ``out`` writes that already exist (or something else
    in their place): ``runs``, ``failed``, ``tables`` and the kept ``tables``' own."""
    names = ["runs", "failed", "tables", *(f"tables/{t}" for t in tables)]
    return [out / name for name in names if (out / name).exists()]


def _missing_dirs(out: Path, option: str) -> list[Path]:
    """The directories to create for ``out``, deepest first; refuse files in the way."""
    if out.is_symlink() and not out.exists():
        raise _unwritable(option, out, "is a broken symbolic link")
    if out.exists() and not out.is_dir():
        raise _unwritable(option, out, "is a file, not a directory")
    missing = []
    probe = out
    while not probe.exists() and not probe.is_symlink() and probe != probe.parent:
        missing.append(probe)
        probe = probe.parent
    if probe.exists() and not probe.is_dir():
        raise _unwritable(option, out, f"cannot be created: {probe} is a file")
    return missing


def _remove_empty(created: list[Path]) -> None:
    for d in reversed(created):
        try:
            d.rmdir()
        except OSError:
            return  # not empty (or gone): leave it and its parents


# Tables written at once by a RunWriter.
WRITERS = min(4, os.cpu_count() or 1)


def write_run(
    out_dir: str | Path, config: Config, frames: dict[str, pd.DataFrame], summary: dict, manifest: dict
) -> list[Path]:
    """Write ``config.toml``, ``manifest.json``, ``summary.json`` and one Parquet file per
    table, replacing the earlier run's files if ``out_dir`` holds one."""
    with RunWriter(out_dir, config) as writer:
        for name, frame in frames.items():
            writer.table(name, frame)
        return writer.finish(summary, manifest)


class RunWriter:
    """:func:`write_run` in steps, so that tables are written while later ones are being
    made (:func:`netsim.run.execute`'s ``emit``): ``table`` for each table as it comes,
    then ``finish``. Used as a context manager: if the body raises, nothing is written.
    Its temporary directory is made with the first table, so a run that fails or is
    killed before it ends leaves none.

    The tables are written a few at a time in threads: pyarrow encodes and compresses
    without holding the interpreter, so the largest tables (the groups and beliefs of a
    long run) share the cores with each other and with the making of the next. Each file
    is written as alone."""

    def __init__(self, out_dir: str | Path, config: Config):
        self.out = Path(out_dir)
        self.config = config
        check_run_dir(self.out)
        self._tmp: Path | None = None
        self._pool: ThreadPoolExecutor | None = None
        self._names: set[str] = set()
        self._writes: list[Future] = []

    def __enter__(self) -> RunWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
        if self._tmp is not None:
            shutil.rmtree(self._tmp, ignore_errors=True)

    def _start(self) -> Path:
        if self._tmp is None:
            self.out.mkdir(parents=True, exist_ok=True)
            self._tmp = Path(tempfile.mkdtemp(prefix=TMP_PREFIX, dir=self.out))
            self._pool = ThreadPoolExecutor(max_workers=WRITERS)
            (self._tmp / "config.toml").write_text(tomli_w.dumps(to_dict(self.config)))
        return self._tmp

    def table(self, name: str, frame: pd.DataFrame) -> None:
        """Start writing the table ``name`` (once: a second table of one name is refused).

        Its Arrow form is made here, on the caller's thread: it shares the frame's columns,
        which nothing writes once a table is made, while pandas may rearrange a frame's own
        structures when it is read, which a writing thread therefore never does."""
        if name in self._names:
            raise ValueError(f"two tables named {name!r} in one run")
        self._names.add(name)
        path = self._start() / f"{name}.parquet"
        if frame.attrs:  # no netsim table has any (write_table: pandas' own writer, at once)
            write_table(frame, path)
            return
        assert self._pool is not None
        self._writes.append(self._pool.submit(write_arrow, arrow_table(frame), path))

    def finish(self, summary: dict, manifest: dict) -> list[Path]:
        """Wait for the tables, write the summary and the manifest, and move every file
        into place (module notes); the paths written."""
        for write in self._writes:
            write.result()  # a failed write raises here
        if interrupted():
            # Ctrl-C that a compiled call swallowed: the run is given up all the same.
            raise KeyboardInterrupt
        tmp, out = self._start(), self.out
        (tmp / "summary.json").write_text(json.dumps({k: _plain(v) for k, v in summary.items()}, indent=2) + "\n")
        (tmp / "manifest.json").write_text(json.dumps({k: _plain(v) for k, v in manifest.items()}, indent=2) + "\n")
        # Ctrl-C held off: an interrupt never leaves half of one run and half of the other;
        # one that comes meanwhile comes too late, and the command ends as a finished run does.
        with ignoring_interrupts():
            # The earlier run goes as a whole, its manifest first: a directory with a manifest
            # always holds one complete run, and never tables of two runs side by side.
            old = earlier_run_files(out)
            (out / "manifest.json").unlink(missing_ok=True)
            for f in old:
                f.unlink(missing_ok=True)
            new = sorted(tmp.iterdir(), key=lambda f: (f.name == "manifest.json", f.name))
            written = []
            for f in new:
                os.replace(f, out / f.name)
                written.append(out / f.name)
        return sorted(written)


def write_table(frame: pd.DataFrame, path: Path) -> None:
    """``frame.to_parquet(path, index=False)``, the same file, written by pyarrow directly:
    pandas' way there costs more per table (its engine lookup and file handle)."""
    if frame.attrs:  # no netsim table has any; pandas keeps them in the file
        frame.to_parquet(path, index=False)
        return
    write_arrow(arrow_table(frame), path)


def arrow_table(frame: pd.DataFrame):
    """``frame`` as the Arrow table pandas would write (its metadata included), but that a
    text column (object) with no value in any row is text as pandas writes text (Arrow's
    ``large_string``), not Arrow's ``null`` type: so that one table of two runs has one
    schema, and the runs read as one dataset."""
    import pyarrow as pa

    table = pa.Table.from_pandas(frame, preserve_index=False)
    for i, field in enumerate(table.schema):
        if pa.types.is_null(field.type) and frame[field.name].dtype == object:
            text = pa.large_string()
            table = table.set_column(i, pa.field(field.name, text), table.column(i).cast(text))
    return table


def write_arrow(table, path: Path) -> None:
    """Write an Arrow table (of :func:`arrow_table`) as pandas' ``to_parquet`` would."""
    import pyarrow.parquet as pq

    pq.write_table(table, str(path), compression="snappy")


def manifest(config: Config, run: int, wall_s: float, argv=None, occupancy=None) -> dict:
    """What a run was: its seed, index, wall time, command, platform and versions; on a map,
    the fingerprint of ``occupancy``, the map the run was built on (its ``parts``'), read
    from ``world.map`` again where not given."""
    out = {
        "seed": config.seed,
        "run": run,
        "wall_s": round(wall_s, 3),
        "command": " ".join(argv if argv is not None else sys.argv),
        "platform": platform.platform(),
        "versions": versions(),
    }
    if occupancy is None and config.world.map:
        from netsim.world.maps import cached_map

        occupancy = cached_map(config.world.map)
    if occupancy is not None:
        out["map_sha256"] = occupancy.sha256
    return out


def run_map(run_dir: Path, config: Config):
    """The run's occupancy map (None in open space), read again from ``world.map``; refused
    in one line when its cells are not those the run had (the fingerprint its manifest
    recorded): the walls drawn would be walls the run never met."""
    if not config.world.map:
        return None
    from netsim.world.maps import cached_map

    occupancy = cached_map(config.world.map)
    recorded = read_run_manifest(run_dir).get("map_sha256")
    if recorded is not None and recorded != occupancy.sha256:
        raise NetsimInputError(
            f"world.map {config.world.map!r}: its cells are not those the run {run_dir} had "
            "(edited since?): restore the map the run used"
        )
    return occupancy


def write_atomically(path: Path, write: Callable[[Path], None]) -> None:
    """Write through a temporary file beside ``path`` and rename it into place. The
    temporary file is created by ``write`` itself, so it gets the mode every other output
    gets (from the umask), not the private 0600 of :func:`tempfile.mkstemp`."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{secrets.token_hex(6)}.tmp")
    try:
        write(tmp)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
