"""Parameter sweeps: many runs of one base scenario, resumable, on a local process pool or
a Dask cluster.

A sweep file (TOML)::

    name = "speed"
    replications = 5
    tables = ["links"]                 # per-run tables to keep besides the metrics
    [base]                             # any scenario keys, as in `netsim run` files
    duration_s = 300.0
    [base.world]
    n_robots = 50
    [grid]                             # every combination of these values ...
    "mobility.speed_max_mps" = [1.0, 5.0, 10.0]
    "mobility.pause_s" = [0.0, 30.0]
    [random]                           # ... or random points in ranges (not both)
    samples = 20
    seed = 1
    [random.ranges]
    "channel.loss_probability" = [0.0, 0.5]

Each run is a point and a replication index; its id is a hash of its fully resolved
configuration and replication, so the same run has the same id in every sweep that
contains it. Replications keep the seed and advance the run number of the random
streams. Every finished run is written atomically to ``runs/<id>.parquet`` (one row:
every parameter, the seed, the replication, every summary metric), with its kept tables
under ``tables/<table>/<id>.parquet``; a run that raises is written to
``failed/<id>.json`` with its error, and the sweep goes on. Started again, a sweep skips
the runs already in ``runs/`` and retries the failed ones.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
import os
import signal
import sys
import tomllib
import traceback
import warnings
from collections.abc import Callable, Iterator, Sequence
from collections.abc import Set as AbstractSet
from contextlib import contextmanager
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import pandas as pd

from netsim import config as cfgmod
from netsim.errors import ConfigError, NetsimInputError, not_a_file
from netsim.tools.interrupt import interrupted
from netsim.tools.output import write_atomically, write_table
from netsim.tools.preflight import check_run

MAX_RUNS = 1_000_000  # a typo in a sweep file must not ask for more memory than the machine has
# A sweep's runs table holds seeds as signed 64-bit integers: past them the column would
# turn to floats, and the seed stored would not be the one that ran.
SEED_LIMIT = 2**63

SWEEP_KEYS = {"name", "replications", "tables", "base", "base_file", "grid", "random"}


@dataclass(frozen=True)
class Run:
    run_id: str
    point: dict  # the swept values, by dotted key
    replication: int
    config: dict  # the fully resolved configuration, as a nested dict


@dataclass(frozen=True)
class Sweep:
    name: str
    replications: int
    tables: tuple[str, ...]
    base: dict
    points: tuple[dict, ...]
    # What the sweep file's points deserve a word on, said by runs() once every point is
    # valid: a refusal is then the command's one line.
    notes: tuple[str, ...] = ()

    def runs(self, here: bool = True) -> list[Run]:
        """Every run, each point's configuration resolved and checked as ``netsim run``
        checks it before it starts (its memory against this machine's only when ``here``:
        not for a scheduler's workers); points that resolve to one configuration run once."""
        out: dict[str, Run] = {}
        repeated = 0
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", cfgmod.ConfigWarning)
            for point in self.points:
                config = point_config(self.base, point)
                try:
                    check_run(config, here)
                except ConfigError as exc:
                    raise NetsimInputError(f"sweep point {point}: {exc}") from None
                if config.seed >= SEED_LIMIT:
                    raise NetsimInputError(
                        f"sweep point {point}: seed = {config.seed}: must be below 2^63 in a sweep (its runs table "
                        "holds seeds as 64-bit integers)"
                    )
                resolved = cfgmod.to_dict(config)
                if run_id(resolved, 0) in out:
                    repeated += 1
                    continue
                for rep in range(self.replications):
                    key = run_id(resolved, rep)
                    out[key] = Run(key, point, rep, resolved)
        for note in self.notes:
            warnings.warn(note, cfgmod.ConfigWarning, stacklevel=2)
        # The keys a point's model does not use: said once, not once per point.
        for message in dict.fromkeys(str(w.message) for w in caught if issubclass(w.category, cfgmod.ConfigWarning)):
            warnings.warn(message, cfgmod.ConfigWarning, stacklevel=2)
        if repeated:
            # Comparing models over a key only one of them reads gives such points.
            warnings.warn(
                f"{repeated} of {len(self.points)} points resolve to the configuration of a point before them (a "
                "value listed twice, or a key their model does not use): each configuration is run once",
                cfgmod.ConfigWarning,
                stacklevel=2,
            )
        return list(out.values())


def point_config(base: dict, point: dict) -> cfgmod.Config:
    """The configuration of ``point`` (dotted keys and values) over the scenario tree ``base``."""
    tree = base
    for key, value in point.items():
        tree = cfgmod.merge(tree, cfgmod.nest(key, value))
    try:
        return cfgmod.from_dict(tree)
    except ConfigError as exc:
        raise NetsimInputError(f"sweep point {point}: {exc}") from None


def run_id(resolved_config: dict, replication: int) -> str:
    """Content address of a run: its resolved configuration and replication index."""
    text = json.dumps({"config": resolved_config, "replication": replication}, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def _err(what: str) -> NetsimInputError:
    return NetsimInputError(f"sweep file: {what}")


def parse(tree: dict, where: Path | None = None) -> Sweep:
    """Validate a sweep description (as loaded from TOML)."""
    unknown = set(tree) - SWEEP_KEYS
    if unknown:
        hint = ""
        scenario = sorted(unknown & set(cfgmod.to_dict(cfgmod.from_dict({}))))
        if scenario:
            # A scenario file given where a sweep file is expected.
            hint = (
                f"; a sweep file puts a scenario's keys (such as {scenario[0]!r}) under [base] (or names a "
                'scenario file with base_file = "scenario.toml") and the values to sweep under [grid] or [random]'
            )
        raise _err(f"unknown key(s) {sorted(unknown)}; allowed: {sorted(SWEEP_KEYS)}{hint}")
    name = tree.get("name", "sweep")
    if not isinstance(name, str) or not name or any(c in name for c in "/\\\0") or name in (".", ".."):
        raise _err(f"name = {name!r}: must be a non-empty string without '/', '\\' or NUL, not '.' or '..'")
    reps = tree.get("replications", 1)
    if isinstance(reps, bool) or not isinstance(reps, int) or reps < 1:
        raise _err(f"replications = {reps!r}: must be an integer >= 1")
    tables = tree.get("tables", [])
    if not isinstance(tables, list) or any(not isinstance(t, str) for t in tables):
        raise _err(f"tables = {tables!r}: must be a list of table names")
    base = tree.get("base", {})
    if not isinstance(base, dict):
        raise _err("[base] must be a table of scenario keys")
    if "base_file" in tree:
        if not isinstance(tree["base_file"], str) or "\0" in tree["base_file"]:
            raise _err(f"base_file = {tree['base_file']!r}: must be the path of a TOML scenario file")
        path = Path(tree["base_file"])
        if where is not None and not path.is_absolute():
            path = where.parent / path
        if not path.is_file():
            raise _err(f"base_file = {str(path)!r}: {not_a_file(path)}")
        try:
            base = cfgmod.merge(tomllib.loads(path.read_text()), base)
        except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
            raise _err(f"base_file = {str(path)!r} is not valid TOML: {exc}") from None
    if ("grid" in tree) == ("random" in tree):
        raise _err("give exactly one of [grid] and [random]")
    try:
        base_config = cfgmod.from_dict(base)
    except ConfigError as exc:
        # A key the points give may be one another rule of the base needs (the trace file
        # of a trace model): the base is then checked with the first point.
        try:
            base_config = point_config(base, _first_point(tree))
        except (NetsimInputError, TypeError, ValueError):
            raise _err(f"[base] {exc}") from None
    known = set(cfgmod.all_keys(base_config))
    notes: list[str] = []
    if "grid" in tree:
        points = _grid(tree["grid"], known)
    else:
        floats = {k for k, v in flatten(cfgmod.to_dict(base_config)).items() if isinstance(v, float)}
        points = _random(tree["random"], known, floats, notes)
    both = sorted(set(points[0]) & set(flatten(base))) if points else []
    if both:
        # Allowed (a scenario file's value under a swept key), but the base's value is never run.
        warnings.warn(
            f"[base] {', '.join(both)}: swept too; each point's value is run, never the base's",
            cfgmod.ConfigWarning,
            stacklevel=2,
        )
    if tables:
        writable = known_tables(base, points)
        if any(t not in writable for t in tables):
            raise _err(f"tables = {tables!r}: must be a list drawn from {sorted(writable)}")
    if len(points) * reps > MAX_RUNS:
        raise _err(f"{len(points):,} points x {reps:,} replications: at most {MAX_RUNS:,} runs in one sweep")
    return Sweep(name, reps, tuple(tables), base, tuple(points), tuple(notes))


def known_tables(base: dict, points: Sequence[dict] = ()) -> set[str]:
    """The tables a sweep on the scenario tree ``base`` may keep: those its runs write, over
    the base and every point (a point may switch on a model, a hook, a medium or the
    receptions)."""
    from netsim.run import tables

    out: set[str] = set()
    if not points:
        out.update(tables(point_config(base, {})))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", cfgmod.ConfigWarning)  # said once, by Sweep.runs
        for point in points:
            out.update(tables(point_config(base, point)))
    return out


def _check_key(key: str, known: set[str], value: object = None) -> None:
    if key not in known:
        if isinstance(value, dict) and any(k.startswith(f"{key}.") for k in known):
            # TOML reads an unquoted dotted key as a table: the key the user meant is inside.
            inner = next(iter(value), "")
            raise _err(
                f"{key!r} is not a configuration key: a dotted key is quoted in TOML "
                f'("{key}.{inner}" = [...]), else it is read as a table'
            )
        raise _err(f"{key!r} is not a configuration key{cfgmod.did_you_mean(key, known)} (see `netsim config`)")


def check_workers(workers) -> None:
    """Refuse a count of local worker processes below 1 in one line (it ran serially)."""
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise NetsimInputError(f"--workers {workers}: must be at least 1")


def _first_point(tree: dict) -> dict:
    """The first value of each axis of ``[grid]`` (the low end of each range of ``[random]``),
    as far as they are given as lists; every point is checked in full later."""
    spec = tree.get("random")
    axes = tree.get("grid") if "grid" in tree else spec.get("ranges") if isinstance(spec, dict) else None
    if not isinstance(axes, dict):
        return {}
    return {k: v[0] for k, v in axes.items() if isinstance(k, str) and isinstance(v, list) and v}


def _grid(grid, known: set[str]) -> list[dict]:
    if not isinstance(grid, dict) or not grid:
        raise _err("[grid] must map configuration keys to lists of values")
    for key, values in grid.items():
        _check_key(key, known, values)
        if not isinstance(values, list) or not values:
            raise _err(f"[grid] {key} = {values!r}: must be a non-empty list")
    keys = list(grid)
    size = math.prod(len(grid[k]) for k in keys)
    if size > MAX_RUNS:
        raise _err(f"[grid] has {size:,} points; at most {MAX_RUNS:,} runs are allowed in one sweep")
    return [dict(zip(keys, combo)) for combo in itertools.product(*(grid[k] for k in keys))]


def _random(spec, known: set[str], floats: AbstractSet[str], notes: list[str]) -> list[dict]:
    """The points of ``[random]`` (``floats``: the keys of real numbers); what deserves a
    word goes to ``notes``."""
    if not isinstance(spec, dict):
        raise _err("[random] must be a table")
    unknown = set(spec) - {"samples", "seed", "ranges"}
    if unknown:
        raise _err(f"[random] unknown key(s) {sorted(unknown)}; allowed: samples, seed, ranges")
    samples, seed, ranges = spec.get("samples"), spec.get("seed", 0), spec.get("ranges")
    if isinstance(samples, bool) or not isinstance(samples, int) or not 1 <= samples <= MAX_RUNS:
        raise _err(f"[random] samples = {samples!r}: must be an integer from 1 to {MAX_RUNS:,}")
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise _err(f"[random] seed = {seed!r}: must be an integer >= 0")
    if not isinstance(ranges, dict) or not ranges:
        raise _err("[random.ranges] must map configuration keys to [low, high]")
    rng = np.random.default_rng(seed)
    columns = {}
    for key, bounds in ranges.items():
        _check_key(key, known, bounds)
        if not (
            isinstance(bounds, list)
            and len(bounds) == 2
            and all(isinstance(b, (int, float)) and not isinstance(b, bool) for b in bounds)
        ):
            raise _err(f"[random.ranges] {key} = {bounds!r}: must be [low, high] (two numbers)")
        lo, hi = bounds
        if not lo <= hi:
            raise _err(f"[random.ranges] {key} = {bounds!r}: low must not exceed high")
        if all(isinstance(b, int) and not isinstance(b, bool) for b in bounds):
            if not -(2**63) <= lo <= hi < 2**63 - 1:
                raise _err(f"[random.ranges] {key} = {bounds!r}: integers must lie within 64 bits")
            columns[key] = rng.integers(lo, hi + 1, samples).tolist()
            if key in floats and lo < hi:
                notes.append(
                    f"[random.ranges] {key} = {bounds!r}: whole-number bounds draw whole numbers; "
                    f"[{float(lo)!r}, {float(hi)!r}] draws uniformly between them"
                )
        else:
            if not all(-1e308 <= b <= 1e308 for b in bounds) or not math.isfinite(hi - lo):
                raise _err(f"[random.ranges] {key} = {bounds!r}: low and high must be finite (within ±1e308)")
            # Equal bounds (0.0 and -0.0 included, which numpy's uniform refuses) fix the value.
            columns[key] = [float(lo)] * samples if lo == hi else rng.uniform(lo, hi, samples).tolist()
    points = [{k: columns[k][i] for k in columns} for i in range(samples)]
    # Integer ranges draw the same point again: one run of it (replications repeat runs).
    distinct = list({json.dumps(p, sort_keys=True): p for p in points}.values())
    if len(distinct) < samples:
        notes.append(
            f"[random] {samples} samples drew {len(distinct)} distinct point{'s' if len(distinct) != 1 else ''};"
            " each is run once"
        )
    return distinct


def load_file(path: str | Path) -> Sweep:
    p = Path(path)
    if not p.is_file():
        raise _err(f"{str(p)!r}: {not_a_file(p)}")
    try:
        tree = tomllib.loads(p.read_text())
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise _err(f"{str(p)!r} is not valid TOML: {exc}") from None
    return parse(tree, p)


# -- one run -------------------------------------------------------------------------------
def flatten(tree: dict, prefix: str = "") -> dict:
    out = {}
    for k, v in tree.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict):
            out.update(flatten(v, key + "."))
        else:
            out[key] = str(v) if isinstance(v, list) else v
    return out


def execute_run(run: Run, tables: tuple[str, ...] = ()) -> dict:
    """Run one point (in whatever process or machine): returns its row and kept tables, a
    table its models do not write as an empty one (so that the run is known to have kept it)."""
    from netsim.run import execute

    result = execute(cfgmod.from_dict(run.config), run=run.replication)
    row = {"run_id": run.run_id, "replication": run.replication, **flatten(run.config)}
    for key, value in result.summary.items():
        if key not in ("seed", "mobility", "protocol", "robots", "duration_s"):
            row[key] = value
    return {"row": row, "tables": {t: result.frames.get(t, pd.DataFrame()) for t in tables}}


def _die_with_parent() -> None:
    """Pool initializer: a worker leaves Ctrl-C to the sweep process, which ends the workers
    (a worker stopped by it would report a failed run), and dies at once of SIGTERM, as
    the pool ends it (the command's handler, inherited by the fork, would print its
    traceback); on Linux, a worker is killed when the sweep process dies, so a killed sweep
    leaves no orphaned workers behind."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    if sys.platform.startswith("linux"):
        import ctypes

        pr_set_pdeathsig = 1
        ctypes.CDLL("libc.so.6", use_errno=True).prctl(pr_set_pdeathsig, signal.SIGKILL)


def _safe_execute(run: Run, tables) -> dict:
    try:
        return {"ok": True, **execute_run(run, tables)}
    except Exception as exc:  # a failing run must not stop the sweep
        return {"ok": False, "error": f"{type(exc).__name__}: {exc}", "traceback": traceback.format_exc()}


# -- persistence ---------------------------------------------------------------------------
def done_ids(out_dir: Path, tables: Sequence[str] = ()) -> set[str]:
    """The runs finished in ``out_dir``: their row is written (last), and each of ``tables``
    was kept (a table added to a sweep's list runs its finished runs again)."""
    done = {p.stem for p in (out_dir / "runs").glob("*.parquet")}
    for table in tables:
        done &= {p.stem for p in (out_dir / "tables" / table).glob("*.parquet")}
    return done


def _record(out_dir: Path, run: Run, outcome: dict) -> None:
    if outcome["ok"]:
        for name, frame in outcome["tables"].items():
            frame = frame.assign(run_id=run.run_id)
            write_atomically(out_dir / "tables" / name / f"{run.run_id}.parquet", lambda p, f=frame: write_table(f, p))
        row = pd.DataFrame([outcome["row"]])
        write_atomically(out_dir / "runs" / f"{run.run_id}.parquet", lambda p: write_table(row, p))
        (out_dir / "failed" / f"{run.run_id}.json").unlink(missing_ok=True)
    else:
        info = {
            "run_id": run.run_id,
            "point": run.point,
            "replication": run.replication,
            "error": outcome["error"],
            "traceback": outcome["traceback"],
        }
        write_atomically(
            out_dir / "failed" / f"{run.run_id}.json", lambda p: p.write_text(json.dumps(info, indent=2, default=str))
        )


@dataclass
class Report:
    total: int
    skipped: int
    done: int
    failed: list[dict]

    def text(self) -> str:
        lines = [f"{self.total} runs: {self.skipped} already done, {self.done} done now, {len(self.failed)} failed"]
        for f in self.failed:
            lines.append(f"  failed {f['run_id']} {f['point']} replication {f['replication']}: {f['error']}")
        return "\n".join(lines)


CONNECT_TIMEOUT_S = 10.0


def connect(address: str, timeout_s: float = CONNECT_TIMEOUT_S):
    """A Dask client of the scheduler at ``address``, or a one-line
    :class:`NetsimInputError` after at most ``timeout_s`` seconds."""
    from distributed import Client
    from distributed.comm import parse_address

    hint = "expected the address of a running Dask scheduler, e.g. tcp://host:8786"
    try:
        _, location = parse_address(address)
        if ":" not in location:
            raise ValueError("no port")
    except (ValueError, TypeError):
        raise NetsimInputError(f"--scheduler {address!r}: not a scheduler address; {hint}") from None
    try:
        return Client(address, timeout=timeout_s)
    except (OSError, TimeoutError, ValueError) as exc:
        why = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise NetsimInputError(
            f"--scheduler {address}: no Dask scheduler answered within {timeout_s:g} s "
            f"(connect timeout; --connect-timeout to change it): {why}"
        ) from None


def run_sweep(
    sweep: Sweep,
    out_dir: str | Path,
    workers: int = 1,
    scheduler=None,
    progress: bool = True,
    connect_timeout_s: float = CONNECT_TIMEOUT_S,
    option: str = "--out",
) -> Report:
    """Run every run of ``sweep`` not yet done in ``out_dir``; returns a report.

    ``scheduler`` is the address of a running Dask scheduler or a ``distributed.Client``;
    ``option``: how a refusal names ``out_dir`` (the option that gave it).
    Everything that can be checked is checked before anything is written: the runs, the
    output directory, the scheduler."""
    from netsim.progress import progress_bar
    from netsim.tools.output import claim_dir

    check_workers(workers)
    runs = sweep.runs(here=scheduler is None)
    ids = [r.run_id for r in runs]
    refuse_another_sweeps_dir(Path(out_dir), sweep.name, option)
    with claim_dir(out_dir, option, kind="sweep", tables=sweep.tables) as out:
        client = connect(scheduler, connect_timeout_s) if isinstance(scheduler, str) else scheduler
        try:
            description = {
                "name": sweep.name,
                "replications": sweep.replications,
                "tables": list(sweep.tables),
                "base": sweep.base,
                "points": list(sweep.points),
                "run_ids": ids,
            }
            write_atomically(out / "sweep.json", lambda p: p.write_text(json.dumps(description, indent=2, default=str)))
            finished = done_ids(out, sweep.tables)
            todo = [r for r in runs if r.run_id not in finished]
            failed: list[dict] = []
            bar = progress_bar(len(runs), sweep.name, "runs", enabled=progress, initial=len(runs) - len(todo), lines=10)

            def account(run: Run, outcome: dict) -> None:
                if not outcome["ok"] and interrupted():
                    # A run that Ctrl-C reached in its worker did not fail: it was stopped.
                    raise KeyboardInterrupt
                _record(out, run, outcome)
                if not outcome["ok"]:
                    failed.append(
                        {
                            "run_id": run.run_id,
                            "point": run.point,
                            "replication": run.replication,
                            "error": outcome["error"],
                        }
                    )
                # One refresh per run: the postfix waits for the update.
                bar.set_postfix(failed=len(failed), remaining=bar.total - bar.n - 1, refresh=False)
                bar.update(1)

            if client is not None:
                _run_dask(todo, sweep.tables, client, account)
            elif workers <= 1:
                for run in todo:
                    account(run, _safe_execute(run, sweep.tables))
            else:
                _run_pool(todo, sweep.tables, workers, account)
            bar.close()
        finally:
            if isinstance(scheduler, str) and client is not None:
                client.close()
    return Report(len(runs), len(runs) - len(todo), len(todo) - len(failed), failed)


def _numbered_execute(job: tuple[int, Run, Any]) -> tuple[int, dict]:
    k, run, tables = job
    return k, _safe_execute(run, tables)


@contextmanager
def process_pool(workers: int, jobs: int) -> Iterator[Any]:
    """A ``multiprocessing`` pool of ``workers`` local processes (no more than ``jobs``: each
    costs an interpreter and the model's imports). Whatever leaves the block early (Ctrl-C,
    an error in the caller's loop) ends the workers at once, not after the runs they hold;
    Ctrl-C is the caller's alone (:func:`_die_with_parent`)."""
    import multiprocessing

    pool = multiprocessing.Pool(max(1, min(workers, jobs)), initializer=_die_with_parent)
    try:
        yield pool
        pool.close()
    except BaseException:
        pool.terminate()
        raise
    finally:
        pool.join()


def _star(fn: Callable[..., Any], job: tuple) -> Any:
    return fn(*job)


def pooled(
    fn: Callable[..., Any],
    jobs: Sequence[Any],
    workers: int,
    desc: str,
    progress: bool = True,
    star: bool = False,
    describe: Callable[[Any], str] | None = None,
) -> Iterator[Any]:
    """``fn(job)`` (``fn(*job)`` with ``star``) of every job on :func:`process_pool`, each
    result yielded in the jobs' order as soon as it and those before it are done, with a
    progress bar of runs on standard error (:func:`netsim.progress.progress_bar`; the
    latest result told by ``describe(result)``)."""
    from netsim.progress import progress_bar

    call = partial(_star, fn) if star else fn
    # In a log, a line per run: each run's result is told.
    lines = max(len(jobs), 1)
    with process_pool(workers, len(jobs)) as pool, progress_bar(len(jobs), desc, "runs", progress, lines=lines) as bar:
        for result in pool.imap(call, jobs):
            if describe is not None:
                bar.set_postfix(latest=describe(result), refresh=False)
            bar.update()
            yield result


def _run_pool(todo: list[Run], tables, workers: int, account) -> None:
    """The runs on a pool of ``workers`` local processes, each accounted as it ends.
    Whatever ends the loop early (Ctrl-C, a run's files that cannot be written) ends the
    workers at once; a run not accounted yet is run again by the same command."""
    with process_pool(workers, len(todo)) as pool:
        jobs = [(k, run, tables) for k, run in enumerate(todo)]
        for k, outcome in pool.imap_unordered(_numbered_execute, jobs):
            account(todo[k], outcome)


def refuse_another_sweeps_dir(out: Path, name: str, option: str = "--out") -> None:
    """A directory holding a sweep of another name is refused: run into it, this sweep's
    runs would hide that one's from :func:`load`. (A sweep of the same name, its points
    changed, is that sweep run again: :func:`load` gives its runs, and the others stay on
    disk for when those points come back.) :func:`run_sweep` asks it; a script that writes
    a file its sweep reads asks it first."""
    try:
        held = json.loads((out / "sweep.json").read_text()).get("name")
    except (OSError, ValueError, AttributeError):
        return
    if isinstance(held, str) and held != name:
        raise NetsimInputError(f"{option} {out}: holds the sweep {held!r}, not {name!r}; give another directory")


def _run_dask(todo: list[Run], tables, client, account) -> None:
    from distributed import as_completed

    futures = {client.submit(_safe_execute, run, tables, pure=False): run for run in todo}
    for fut in as_completed(futures):
        account(futures[fut], fut.result())


# -- results -------------------------------------------------------------------------------
def add_runner_arguments(parser, name: str, reps: int) -> None:
    """The options every sweep script shares: ``--reps``, ``--seed``, ``--workers``,
    ``--scheduler`` and ``--out`` (default ``experiments-out/<name>``)."""
    parser.add_argument("--reps", type=int, default=reps, help="replications per point")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 1, help="local worker processes")
    parser.add_argument("--scheduler", help="Dask scheduler address, instead of local workers")
    parser.add_argument("--out", default=f"experiments-out/{name}", help="output directory")


def run_script(main: Callable[[], object], resumable: bool = False) -> None:
    """Run a script's ``main``: bad input (a malformed option, an unreachable scheduler) is
    one line on stderr and exit status 2, and Ctrl-C one line and status 130, as with
    ``netsim``. The line says what is kept: what the script said it had put in place
    (:func:`netsim.tools.interrupt.kept_if_interrupted`, whose line is printed as given);
    else, ``resumable``, the finished runs of the sweeps it runs; else nothing."""
    from netsim.tools.interrupt import EXIT_INTERRUPTED, KeptOnInterrupt, ignoring_interrupts, interrupted

    name = Path(sys.argv[0]).name
    try:
        main()
    except NetsimInputError as exc:
        print(f"{name}: error: {exc}", file=sys.stderr)
        raise SystemExit(2) from None
    except BaseException as exc:
        if isinstance(exc, SystemExit) or not interrupted(exc):
            raise
        if isinstance(exc, KeptOnInterrupt):
            line = exc.args[0]
        else:
            kept = "the runs finished are kept (the same command resumes)" if resumable else "nothing written"
            line = f"{name}: interrupted; {kept}"
        with ignoring_interrupts():  # a second Ctrl-C would cut this line
            print(line, file=sys.stderr)
        raise SystemExit(EXIT_INTERRUPTED) from None


def _files(out_dir: Path, folder: Path) -> list[Path]:
    """The run files in ``folder`` of the sweep last run in ``out_dir``. A directory keeps
    the runs of every sweep run in it (run ids are content addresses, so a sweep run there
    again reuses them), and ``sweep.json`` lists the latest sweep's; a directory from
    before that list reads whole."""
    files = sorted(folder.glob("*.parquet"))
    try:
        ids = json.loads((out_dir / "sweep.json").read_text()).get("run_ids")
    except (OSError, ValueError, AttributeError):  # none, unreadable, not JSON, not a table
        return files
    if not isinstance(ids, list):
        return files
    wanted = set(map(str, ids))
    return [f for f in files if f.stem in wanted]


def _sweep_dir(out_dir: str | Path) -> Path:
    """``out_dir``, if a sweep ran there (else one line: a mistyped folder would read as a
    sweep without runs, and fail later on a missing column)."""
    out = Path(out_dir)
    if not out.is_dir():
        raise NetsimInputError(f"{out}: {'is not a directory' if out.exists() else 'no such directory'}")
    if not (out / "sweep.json").is_file() and not (out / "runs").is_dir():
        raise NetsimInputError(f"{out}: holds no sweep (netsim sweep writes sweep.json and runs/ there)")
    return out


def load(out_dir: str | Path) -> pd.DataFrame:
    """Every finished run of the sweep last run in ``out_dir`` as one tidy frame, one row
    per run, sorted by run id (not the runs of other sweeps the directory keeps); empty
    while no run has finished. A directory that holds no sweep is one line."""
    out_dir = _sweep_dir(out_dir)
    files = _files(out_dir, out_dir / "runs")
    if not files:
        return pd.DataFrame()
    return (
        pd.concat([pd.read_parquet(f) for f in files], ignore_index=True).sort_values("run_id").reset_index(drop=True)
    )


def load_table(out_dir: str | Path, table: str) -> pd.DataFrame:
    """A kept per-run table of every finished run of the sweep last run in ``out_dir``,
    with its ``run_id``. A run is finished once its row is in ``runs/`` (its tables are
    written first): a table whose run was interrupted before its row is left out. A table
    the sweep does not keep (``tables`` in its file) is one line, once a run has finished."""
    out = _sweep_dir(out_dir)
    finished = done_ids(out)
    if finished and not (out / "tables" / table).is_dir():
        kept = sorted(p.name for p in (out / "tables").iterdir() if p.is_dir()) if (out / "tables").is_dir() else []
        raise NetsimInputError(
            f"{out}: the sweep kept no table {table!r} (kept: {', '.join(kept) or 'none'}; "
            "a sweep keeps the tables its file lists in tables = [...])"
        )
    files = [f for f in _files(out, out / "tables" / table) if f.stem in finished]
    frames = [pd.read_parquet(f) for f in files]
    # A run whose models write no such table kept an empty one of its run_id alone.
    frames = [f for f in frames if list(f.columns) != ["run_id"]]
    if not frames:
        return pd.DataFrame()
    return pd.concat(frames, ignore_index=True)


def t_interval(values: npt.ArrayLike, level: float = 0.95) -> tuple[float, float, float, float]:
    """Mean, standard deviation and the ends of the Student-t confidence interval of the mean
    of ``values`` (NaN where too few: no mean without values, no spread with one)."""
    from scipy import stats

    v = np.asarray(values, dtype=float)
    n = len(v)
    mean = float(v.mean()) if n else float("nan")
    sd = float(v.std(ddof=1)) if n > 1 else float("nan")
    half = float(stats.t.ppf(0.5 + level / 2, n - 1) * sd / np.sqrt(n)) if n > 1 else float("nan")
    return mean, sd, mean - half, mean + half


def aggregate(df: pd.DataFrame, by: list[str], metrics: list[str], level: float = 0.95) -> pd.DataFrame:
    """Mean, standard deviation, count and Student-t confidence interval of each metric over
    the replications of each group."""
    missing = [c for c in [*by, *metrics] if c not in df]
    if missing:
        raise NetsimInputError(
            f"no column {', '.join(map(repr, missing))} among the runs' "
            f"({len(df.columns)} columns{'' if len(df.columns) else ': no run'})"
        )
    rows = []
    for key, g in df.groupby(by, sort=True):
        key = key if isinstance(key, tuple) else (key,)
        row = dict(zip(by, key))
        for m in metrics:
            v = g[m].dropna().to_numpy(float)
            mean, sd, low, high = t_interval(v, level)
            row.update({f"{m}_mean": mean, f"{m}_std": sd, f"{m}_n": len(v), f"{m}_ci_low": low, f"{m}_ci_high": high})
        rows.append(row)
    return pd.DataFrame(rows)
