"""The ``netsim`` command.

``netsim run [CONFIG] [--set KEY=VALUE ...] [--seed N] [--out DIR]``
    Simulate a scenario (the built-in default when no file is given) and write its
    results to DIR (default ``./netsim-out``).
``netsim bridge [CONFIG] [--set KEY=VALUE ...] [--rate R] [--out DIR] [--live [PORT]]``
    Run a scenario with ``mobility.model = "external"`` as ROS 2 nodes on DDS (docs/ros2.md).
``netsim scenario generate --n N --side M ... -o FILE``
    Write a random waypoint movement scenario in the ns-2 format.
``netsim sweep SWEEP.toml [--workers N | --scheduler tcp://host:port] [--out DIR]``
    Run a parameter sweep; started again, it skips the runs already done.
``netsim validate [--seed N] [--only ITEMS]``
    Check the model against closed-form results; exit status 1 if any check fails. With
    ``--seed N`` every check draws anew from N (default: the fixed seeds of the table in
    docs/validation.md); ``--only 21,22`` runs only the checks of those items.
``netsim figures [RUN_DIR] [--config FILE] [--set KEY=VALUE ...] [--out DIR] [--at T]``
    Draw the paper's Figs. 6-8 (deployment at T, every robot's path, final deployment with
    every robot's coverage disk), and fig_packets.png for a run with packets, from a run
    directory; without one, first run the built-in coverage scenario (or FILE) into DIR.
``netsim view RUN_DIR [--out FILE.html]``
    Write the replay of a run: one self-contained HTML file (default RUN_DIR/view.html).
``netsim export RUN_DIR --format bonnmotion|ns2|rosbag2 --out PATH``
    Write a run's motion (and for rosbag2 its links, roles, messages and packets) in a format robot
    teams' tools read.
``netsim config [CONFIG] [--set KEY=VALUE ...]``
    Print the configuration (the built-in default, or CONFIG with the overrides), every
    key with its meaning, the sections of the controllers it names included.
``netsim calibrate LOG [--sensitivity-dbm S] [--map MAP] [--out FILE.toml] [--plot FILE.png]``
    Fit the log-distance channel (reference loss, exponent, shadowing, wall loss) to a
    log of frames and write the ``[channel]`` fragment ``netsim run`` reads.

Bad input gives one line on standard error and exit status 2, and writes nothing; output
paths and the scheduler are checked before any simulation starts.
"""

from __future__ import annotations

import argparse
import errno
import gc
import math
import os
import re
import sys
import warnings
from collections.abc import Iterator, Mapping, Sequence
from contextlib import ExitStack, contextmanager
from pathlib import Path

from netsim import config as cfgmod
from netsim.errors import ConfigError, NetsimInputError
from netsim.formats import format_of_name, ns2
from netsim.tools.args import Parser
from netsim.tools.interrupt import (
    EXIT_INTERRUPTED,
    INTERRUPTED_LINE,
    KeptOnInterrupt,
    ignoring_interrupts,
    interrupted,
    kept_if_interrupted,
)
from netsim.tools.preflight import check_run

EXIT_INPUT = 2
FIGURE_SUFFIXES = (".png", ".svg", ".pdf")  # what a command's figure may be written as

# A disk or a quota that is full: the user's to fix, said in one line.
FULL_DISK = (errno.ENOSPC, errno.EDQUOT)


def _format_value(v) -> str:
    if isinstance(v, float):
        if math.isnan(v):
            return "-"
        return f"{v:,.4g}" if abs(v) < 1e4 else f"{v:,.0f}"
    if isinstance(v, int) and not isinstance(v, bool):
        return f"{v:,}"
    return str(v)


# Keys of the summary printed with what they are (summary.json keeps the keys alone).
SUMMARY_LABELS = {
    "link_duration_km_mean_s": "link_duration_km_mean_s (Kaplan-Meier)",
    "mean_link_duration_s": "mean_link_duration_s (complete links only)",
}


def summary_table(summary: dict) -> str:
    labels = {k: SUMMARY_LABELS.get(k, k) for k in summary}
    width = max(len(label) for label in labels.values())
    return "\n".join(f"  {labels[k]:<{width}}  {_format_value(v)}" for k, v in summary.items())


def check_set_pairs(overrides: list[str] | None, positional: str | None) -> None:
    """``--set KEY VALUE`` (a space for the ``=``) leaves VALUE to be read as the command's
    file or directory argument: when that names nothing, say what was meant. A key given
    twice is warned of (the last is taken)."""
    bare = [o for o in overrides or [] if "=" not in o]
    if bare and positional is not None and not Path(positional).exists():
        key = bare[-1]
        raise NetsimInputError(
            f"--set {key} {positional}: --set takes KEY=VALUE; did you mean --set {key}={positional}?"
        )
    # A key given twice overrides itself, as a script's own --set after its base ones would;
    # said, since it is as often a slip in a long command line.
    earlier: dict[str, str] = {}
    for given in overrides or []:
        key = cfgmod.override_key(given)
        if key in earlier:
            warnings.warn(
                f"--set {earlier[key]} and --set {given}: the last is taken", cfgmod.ConfigWarning, stacklevel=2
            )
        earlier[key] = given


@contextmanager
def told_once_checked() -> Iterator[None]:
    """Warnings given while a command's input is checked (a key set twice, a key of another
    model), held back until every check has passed: a refused input is one line, its error,
    not warnings about a run that will not be (as :func:`netsim.config.from_dict` holds its
    own)."""
    with warnings.catch_warnings(record=True) as caught:
        yield
    for w in caught:
        # Shown, not given again: the filters passed it where it was given, and a second pass
        # would match a filter's module against its file's path (-W default::...:netsim.x).
        warnings.showwarning(w.message, w.category, w.filename, w.lineno, w.file, w.line)


@contextmanager
def kept(out: Path, missing: str = "", results: str = "the run is") -> Iterator[None]:
    """Within, the ``results`` are in place in ``out``: a Ctrl-C, or a disk that fills, says
    they are kept (and what is ``missing``), not that nothing was written."""
    what = f"{results} written in {out}/" + (f", {missing}" if missing else "")
    try:
        with kept_if_interrupted(f"netsim: interrupted; {what}"):
            yield
    except OSError as exc:
        if exc.errno not in FULL_DISK:
            raise
        raise NetsimInputError(f"cannot write: {os.strerror(exc.errno)}; {what}") from None


def say_when_compiling(command: str, enabled: bool) -> None:
    """The first run of a version of netsim on a machine compiles its loops, and prints
    nothing meanwhile (the progress bar starts with the simulation): say so on standard
    error, once, when it starts."""
    if not enabled:
        return
    from netsim import kernel_cache

    def tell(directory: Path) -> None:
        print(
            f"{command}: compiling the simulator's loops this run uses (each once for this version "
            f"of netsim; other models' when a run first uses them; cached in {directory.parent})...",
            file=sys.stderr,
            flush=True,
        )

    kernel_cache.when_cold(tell)


def cmd_run(args) -> int:
    from netsim.run import execute
    from netsim.tools.output import RunWriter, claim_dir, manifest

    with ExitStack() as claimed:
        with told_once_checked():
            check_set_pairs(args.set, args.config)
            overrides = list(args.set or [])
            if args.seed is not None:
                # --seed is --set seed=, given last: a seed set too is overridden, as a key set twice is.
                for given in overrides:
                    if cfgmod.override_key(given) == "seed":
                        warnings.warn(
                            f"--set {given} and --seed {args.seed}: --seed is taken", cfgmod.ConfigWarning, stacklevel=2
                        )
                overrides.append(f"seed={args.seed}")
            config = cfgmod.load(args.config, overrides)
            check_run(config)
            if args.live is not None:
                from netsim.tools.bridge import LIVE_VIEW, check_extra, check_links_on

                check_links_on(config, "netsim run --live")
                check_extra("netsim run --live", (LIVE_VIEW,))
            # A directory that cannot take the results is refused before any warning is shown.
            out = claimed.enter_context(claim_dir(args.out, "--out", kind="run"))
        say_when_compiling("netsim run", not args.quiet)
        with RunWriter(out, config) as writer:
            # Each table is written as soon as it is made, while the next is made.
            # What the build loaded (numba and its registries, when the run uses compiled loops)
            # is frozen out of the collector's passes too (command()).
            if args.live is not None:
                from netsim.tools.bridge import run_live

                result = run_live(config, args.live, writer)
            else:
                result = execute(
                    config, progress=not args.quiet and not args.no_progress, emit=writer.table, built=_freeze_if_own
                )
            written = writer.finish(
                result.summary, manifest(config, 0, result.wall_s, occupancy=result.sim.parts.occupancy)
            )
            if args.view:
                from netsim.tools import viewer

                with kept(out, "its view.html is not"):
                    written.append(viewer.write(out))
    with kept(out):
        if not args.quiet:
            n, duration = config.world.n_robots, config.duration_s
            print(f"netsim run: {n} robot{'s' * (n != 1)}, {duration:g} s simulated in {result.wall_s:.2f} s wall")
            print(summary_table(result.summary))
            print(f"results: {out}/ ({', '.join(p.name for p in written)})")
    return 0


# The configuration keys `netsim scenario generate` sets, by the flag that sets each.
GENERATE_FLAGS = {
    "world.n_robots": "--n",
    "world.side_m": "--side",
    "mobility.speed_min_mps": "--speed-min",
    "mobility.speed_max_mps": "--speed-max",
    "mobility.pause_s": "--pause",
    "mobility.stationary_start": "--no-stationary-start",
    "duration_s": "--duration",
    "seed": "--seed",
}


def _flags_in(text: str) -> str:
    """``text`` with the configuration keys `scenario generate` sets named by their flags."""
    text = re.sub(r"(?:mobility\.)?stationary_start = false", "--no-stationary-start", text)
    text = re.sub(r"with (?:mobility\.)?stationary_start = true", "without --no-stationary-start", text)
    for key, flag in GENERATE_FLAGS.items():
        if key != "seed":  # "seed" is also a word of the rules' prose
            text = re.sub(rf"(?<![\w.]){re.escape(key)}(?![\w.])", flag, text)
    return text


def _in_flags(exc: ConfigError) -> NetsimInputError:
    """A configuration error of `scenario generate` told in the flags the user typed."""
    flag = GENERATE_FLAGS.get(exc.key)
    if flag is None:
        return exc
    value = not exc.value if flag == "--no-stationary-start" else exc.value
    return NetsimInputError(f"{flag} {value!r}: {_flags_in(exc.allowed)}")


def cmd_bridge(args) -> int:
    from netsim.bridge.settings import check_rate, load
    from netsim.tools.bridge import DDS, LIVE_VIEW, bridge, check_extra, check_links_on

    with told_once_checked():
        check_set_pairs(args.set, args.config)
        rate = check_rate(args.rate)
        config, settings = load(args.config, list(args.set or []))
        check_run(config)
        check_links_on(config, "netsim bridge")
        check_extra("netsim bridge", (DDS,) if args.live is None else (DDS, LIVE_VIEW))
    say_when_compiling("netsim bridge", not args.quiet)
    summary, out, written = bridge(args, config, settings, rate)
    if not args.quiet:
        print(summary_table(summary))
        print(f"results: {out}/ ({', '.join(p.name for p in written)})")
    return 0


def cmd_scenario_generate(args) -> int:
    from netsim.run import build

    tree = {
        "seed": args.seed,
        "duration_s": args.duration,
        "world": {"n_robots": args.n, "side_m": args.side},
        "mobility": {
            "model": "random_waypoint",
            "speed_min_mps": args.speed_min,
            "speed_max_mps": args.speed_max,
            "pause_s": args.pause,
            "stationary_start": not args.no_stationary_start,
        },
        "protocol": {"model": "none"},
        "output": {"position_interval_s": 0.0},  # the legs are the scenario: no samples
    }
    out = Path(args.output)
    try:
        with warnings.catch_warnings(record=True) as caught:
            config = cfgmod.from_dict(tree)
            check_run(config)
            check_out_file(args.output, "-o")
            read_as = format_of_name(out.name)
            if read_as != "ns2":
                # A trace is read back by its name: this one would be read as another format.
                raise NetsimInputError(
                    f"-o {out}: writes ns-2, and a name so is read back as {read_as}; give another name "
                    "(netsim export writes a run in the other formats)"
                )
            sim = build(config)
    except ConfigError as exc:
        raise _in_flags(exc) from None
    for w in caught:
        warnings.warn(_flags_in(str(w.message)), w.category, stacklevel=1)
    sim.run()
    header = (
        f"netsim scenario generate: random waypoint, nodes: {args.n}, side: {args.side} m, "
        f"speed: [{args.speed_min}, {args.speed_max}] m/s, pause: {args.pause} s, "
        f"duration: {args.duration} s, seed: {args.seed}, stationary start: {not args.no_stationary_start}"
    )
    tmp = out.with_name(f".{out.name}.tmp")
    try:
        ns2.write(tmp, sim.state.legs(), config.world.n_robots, config.duration_s, header, config.world.side_m)
        tmp.replace(out)
    finally:
        tmp.unlink(missing_ok=True)
    if not args.quiet:
        print(f"wrote {out}")
    return 0


def check_out_files(named: Mapping[str, str | None], figures: Sequence[str] = (), replace: bool = True) -> None:
    """Refuse, before any work, a command's output files (option -> path; None: not asked)
    that could not be written (:func:`check_out_file`; an existing one replaced with
    ``replace``), two options naming one file (the last written would replace the other),
    and a figure's (the options ``figures``) whose name ends in no :data:`FIGURE_SUFFIXES`."""
    given = {option: path for option, path in named.items() if path is not None}
    for option, path in given.items():
        check_out_file(path, option, replace=replace)
    seen: dict[Path, str] = {}
    for option, path in given.items():
        resolved = Path(path).resolve()
        if resolved in seen:
            raise NetsimInputError(f"{seen[resolved]} and {option} name one file, {path}: give each its own")
        seen[resolved] = option
    for option in figures:
        path = given.get(option)
        if path is not None and Path(path).suffix.lower() not in FIGURE_SUFFIXES:
            raise NetsimInputError(f"{option} {path!r}: must end in one of {', '.join(FIGURE_SUFFIXES)}")


def check_out_file(path: str | Path, option: str, make_parents: bool = False, replace: bool = False) -> None:
    """Refuse, before any work, a file that could not be written: its directory must exist
    and be writable, and the path must not be a directory, nor (unless ``replace``, for a
    file netsim names itself) a file that exists, as ``netsim export`` refuses it: a user's
    file is never overwritten silently. With ``make_parents`` the directory may be missing,
    to be made by the writer: then its nearest existing ancestor must be a writable
    directory."""
    from netsim.tools.output import names_a_directory, probe_writable

    if Path(path).is_dir():
        raise NetsimInputError(f"{option} {path}: is a directory; give the path of a file")
    if names_a_directory(path):
        raise NetsimInputError(f"{option} {path}: names a directory; give the path of a file")
    path = Path(path)
    if not replace and (path.exists() or path.is_symlink()):
        raise NetsimInputError(f"{option} {path}: exists already; give a new path")
    parent = path.parent
    while make_parents and not parent.exists() and not parent.is_symlink() and parent != parent.parent:
        parent = parent.parent
    if not parent.is_dir():
        what = "is a file" if parent.exists() else "does not exist"
        raise NetsimInputError(f"{option} {path}: the directory {parent} {what}")
    try:
        probe_writable(parent)
    except OSError as exc:
        raise NetsimInputError(f"{option} {path}: cannot write in {parent} ({exc.strerror or exc})") from None


# The most local worker processes a sweep may ask for, per core.
WORKERS_PER_CORE = 4


def cmd_sweep(args) -> int:
    from netsim.tools import sweep as sweepmod

    sweep = sweepmod.load_file(args.sweep)
    # The cores this process may run on (a container's share, not the host's).
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    if args.workers is not None and args.scheduler is not None:
        # The scheduler's cluster decides how many workers run: a count here would be dropped unsaid.
        raise NetsimInputError(
            f"--workers {args.workers} and --scheduler {args.scheduler}: give one (local worker processes, or a "
            "Dask cluster's)"
        )
    if args.workers is not None:
        sweepmod.check_workers(args.workers)
    if args.workers is not None and args.workers > WORKERS_PER_CORE * cores:
        raise NetsimInputError(
            f"--workers {args.workers}: at most {WORKERS_PER_CORE * cores} on this machine ({WORKERS_PER_CORE} a core: "
            "more processes than cores only slow runs that compute); a Dask cluster (--scheduler) spreads further"
        )
    out = Path(args.out) if args.out else Path("sweep-out") / sweep.name
    workers = args.workers or cores
    if args.connect_timeout is not None and not args.connect_timeout > 0:
        raise NetsimInputError(f"--connect-timeout {args.connect_timeout}: must be > 0 seconds")
    if args.connect_timeout is not None and args.scheduler is None:
        # Local workers connect to nothing: the timeout would be dropped unsaid.
        raise NetsimInputError(f"--connect-timeout {args.connect_timeout:g}: only with --scheduler (a Dask cluster's)")
    try:
        report = sweepmod.run_sweep(
            sweep,
            out,
            workers=workers,
            scheduler=args.scheduler,
            progress=not args.no_progress,
            connect_timeout_s=args.connect_timeout or sweepmod.CONNECT_TIMEOUT_S,
            option="--out" if args.out else "the default --out",
        )
    except BaseException as exc:
        # Every finished run is written as it ends, so an interrupted sweep did write.
        full = isinstance(exc, OSError) and exc.errno in FULL_DISK
        if not (interrupted(exc) or full) or not (out / "sweep.json").is_file():
            raise
        if full:
            raise NetsimInputError(
                f"cannot write: {os.strerror(exc.errno)}; the runs finished are kept in {out}/ (the same command "
                "resumes)"
            ) from None
        with ignoring_interrupts():  # a second Ctrl-C would add "nothing written" to this line
            print(
                f"netsim: interrupted; the runs finished are kept in {out}/ (the same command resumes)", file=sys.stderr
            )
        return EXIT_INTERRUPTED
    print(report.text())
    print(f"results: {out}/ (load with netsim.tools.sweep.load({str(out)!r}))")
    return 1 if report.failed else 0


def cmd_validate(args) -> int:
    from netsim.tools import validate

    seed = None if args.seed is None else validate.parse_seed(args.seed)
    only = None if args.only is None else validate.parse_only(args.only)
    say_when_compiling("netsim validate", True)
    results = validate.run_all(progress=not args.no_progress, seed=seed, only=only)
    print(validate.table(results))
    failed = [c for c in results if not c.passed]
    print(f"{len(results) - len(failed)} of {len(results)} checks passed")
    return 1 if failed else 0


def cmd_figures(args) -> int:
    from netsim.run import execute
    from netsim.tools import figures
    from netsim.tools.output import claim_dir, existing_dir, is_run_dir, manifest, write_run

    if args.run_dir:
        with told_once_checked():
            check_set_pairs(args.set, args.run_dir)
            if args.config or args.set:
                raise NetsimInputError("give either a run directory or a scenario (--config/--set), not both")
        run_dir = existing_dir(args.run_dir)
        if not (run_dir / "config.toml").is_file() and not is_run_dir(run_dir):
            raise NetsimInputError(f"{run_dir}: not a run directory (no config.toml or manifest.json)")
        with claim_dir(args.out or run_dir, "--out") as out:
            drawn = figures.draw(run_dir, out, at_s=args.at)
    else:
        with ExitStack() as claimed:
            with told_once_checked():
                check_set_pairs(args.set, args.run_dir)
                config = _figures_scenario(args)
                # A directory that cannot take the run is refused before any warning is shown.
                out = claimed.enter_context(claim_dir(args.out or "netsim-figures", "--out", kind="run"))
            say_when_compiling("netsim figures", not args.quiet)
            result = execute(config, progress=not args.quiet and not args.no_progress and "netsim figures")
            occupancy = result.sim.parts.occupancy
            write_run(
                out, config, result.frames, result.summary, manifest(config, 0, result.wall_s, occupancy=occupancy)
            )
            with kept(out, "its figures are not"):
                if not args.quiet:
                    n = config.world.n_robots
                    print(f"netsim figures: ran {n} robot{'s' * (n != 1)} for {config.duration_s:g} s -> {out}/")
                drawn = figures.draw(out, at_s=args.at)
    with kept(out, results="the figures are"):
        for d in drawn if not args.quiet else []:
            print(f"wrote {d.path}" + (f" ({d.note})" if d.note else ""))
    return 0


def _figures_scenario(args) -> cfgmod.Config:
    """The scenario `netsim figures` runs (the coverage scenario, or --config's), checked."""
    from netsim.tools import figures

    overrides = ([] if args.config else figures.COVERAGE_SCENARIO) + list(args.set or [])
    config = cfgmod.load(args.config, overrides)
    if args.at is not None and not 0 <= args.at <= config.duration_s:
        raise NetsimInputError(f"--at = {args.at:g}: must be a time between 0 and duration_s = {config.duration_s:g} s")
    check_run(config)
    return config


def cmd_view(args) -> int:
    from netsim.tools import viewer

    if args.out is not None:
        check_out_file(args.out, "--out", make_parents=True)
        if Path(args.out).suffix.lower() not in ("", ".html", ".htm"):  # a name of another kind of file
            raise NetsimInputError(f"--out {args.out}: the replay is a web page; name a .html file")
    elif Path(args.run_dir).is_dir():
        # The run's own replay (as `netsim run --view` writes it) is remade in place.
        check_out_file(Path(args.run_dir) / "view.html", "the replay", replace=True)
    path = viewer.write(args.run_dir, args.out)
    print(f"wrote {path} ({path.stat().st_size / 2**20:.2f} MiB): open it in a browser")
    return 0


def cmd_export(args) -> int:
    from netsim.tools.export import export

    out = export(args.run_dir, args.format, args.out)
    if args.format == "bonnmotion":
        from netsim.formats.bonnmotion import params_path

        print(f"wrote {out} and {params_path(out)}")
    else:
        print(f"wrote {out}")
    return 0


def cmd_calibrate(args) -> int:
    from netsim.tools import calibrate

    if args.out is not None:
        check_out_file(args.out, "--out")
        # The fragment is TOML whatever the name: another suffix would mislead the next reader.
        if Path(args.out).suffix.lower() != ".toml":
            raise NetsimInputError(f"--out {args.out}: name a .toml file (the fragment is TOML)")
    if args.plot is not None:
        check_out_files({"--plot": args.plot}, figures=("--plot",), replace=False)
        from netsim.tools.calibrate_figure import draw_calibration

        return calibrate.command(args, draw_calibration)
    return calibrate.command(args)


def cmd_config(args) -> int:
    from netsim.bridge import settings as bridge_settings

    config, bridge = None, None
    with told_once_checked():
        check_set_pairs(args.set, args.config)
        if args.config or args.set:
            # A bridge scenario's [bridge] table is checked as `netsim bridge` checks it, and
            # shown after the run's keys.
            config, bridge = bridge_settings.read(args.config, list(args.set or []))
    print(cfgmod.commented_toml(config) + bridge_settings.commented(bridge), end="")
    return 0


LIVE_PORT = 8765


def _port(text: str) -> int:
    try:
        port = int(text)
    except ValueError:
        port = -1
    if not 0 <= port <= 65535:
        raise argparse.ArgumentTypeError(f"{text!r}: must be a TCP port, 0 to 65535 (0: any free port)")
    return port


def parser() -> Parser:
    from netsim import __version__

    p = Parser(prog="netsim", description="Discrete-event simulator of multi-robot ad-hoc networks.")
    p.add_argument("--version", action="version", version=f"netsim {__version__}")
    sub = p.add_subparsers(dest="command", required=True)

    r = sub.add_parser("run", help="simulate a scenario and write its results")
    r.add_argument("config", nargs="?", help="TOML scenario file (default: the built-in scenario)")
    r.add_argument("--set", action="append", metavar="KEY=VALUE", help="override a configuration value")
    r.add_argument("--seed", type=int, help="seed of every random stream (same as --set seed=N)")
    r.add_argument(
        "--out",
        default="netsim-out",
        help="output directory (default: ./netsim-out); an earlier run there is replaced as a whole, "
        "a non-empty directory that holds no run is refused",
    )
    r.add_argument("--no-progress", action="store_true", help="no progress bar")
    r.add_argument("--quiet", action="store_true", help="print nothing but warnings and errors")
    r.add_argument("--view", action="store_true", help="also write the replay, DIR/view.html (see netsim view)")
    r.add_argument(
        "--live",
        nargs="?",
        const=LIVE_PORT,
        type=_port,
        metavar="PORT",
        help=f"run at real time, streamed to Foxglove over a WebSocket on 127.0.0.1:PORT (default {LIVE_PORT}; "
        "docs/ros2.md)",
    )
    r.set_defaults(func=cmd_run)

    b = sub.add_parser("bridge", help="run a scenario as ROS 2 nodes on DDS: robots driven by cmd_vel (docs/ros2.md)")
    b.add_argument("config", nargs="?", help="TOML scenario file with mobility.model = 'external' and a [bridge] table")
    b.add_argument("--set", action="append", metavar="KEY=VALUE", help="override a configuration value (bridge.* too)")
    b.add_argument("--rate", type=float, default=1.0, help="simulated seconds per wall second (default 1: real time)")
    b.add_argument(
        "--out",
        default="netsim-out",
        help="output directory (default: ./netsim-out), written when the run ends or is stopped (Ctrl-C)",
    )
    b.add_argument(
        "--live",
        nargs="?",
        const=LIVE_PORT,
        type=_port,
        metavar="PORT",
        help=f"also stream the run to Foxglove over a WebSocket on 127.0.0.1:PORT (default {LIVE_PORT})",
    )
    b.add_argument("--quiet", action="store_true", help="print nothing but warnings, errors and the lag")
    b.set_defaults(func=cmd_bridge)

    s = sub.add_parser("scenario", help="movement scenario files")
    ssub = s.add_subparsers(dest="scenario_command", required=True)
    g = ssub.add_parser("generate", help="write a random waypoint scenario in the ns-2 movement format")
    g.add_argument("--n", type=int, required=True, help="number of robots")
    g.add_argument("--side", type=float, required=True, help="side of the square area, m")
    g.add_argument("--speed-min", type=float, default=0.5, help="minimum speed, m/s")
    g.add_argument("--speed-max", type=float, required=True, help="maximum speed, m/s")
    g.add_argument("--pause", type=float, default=0.0, help="pause at each waypoint, s")
    g.add_argument("--duration", type=float, required=True, help="scenario length, s")
    g.add_argument("--seed", type=int, default=1)
    g.add_argument("--no-stationary-start", action="store_true", help="start from uniform positions at rest")
    g.add_argument("-o", "--output", required=True, help="file to write (a new path: an existing file is refused)")
    g.add_argument("--quiet", action="store_true", help="print nothing but warnings and errors")
    g.set_defaults(func=cmd_scenario_generate)

    w = sub.add_parser("sweep", help="run a parameter sweep (resumable; local pool or Dask cluster)")
    w.add_argument("sweep", help="sweep file (TOML)")
    w.add_argument("--workers", type=int, help="local worker processes (default: all cores)")
    w.add_argument("--scheduler", help="address of a running Dask scheduler, e.g. tcp://host:8786")
    w.add_argument("--out", help="sweep directory (default: ./sweep-out/<name>); a sweep's directory is resumed")
    w.add_argument(
        "--connect-timeout",
        type=float,
        metavar="S",
        help="with --scheduler: how long to try to reach the scheduler, s (default: 10)",
    )
    w.add_argument("--no-progress", action="store_true", help="no progress bar")
    w.set_defaults(func=cmd_sweep)

    v = sub.add_parser("validate", help="check the model against the closed-form results of docs/validation.md")
    v.add_argument("--no-progress", action="store_true", help="no progress bar")
    # Strings, checked by validate: a bad value is one line naming the flag (not argparse's usage).
    v.add_argument(
        "--seed",
        metavar="N",
        help="draw every check's randomness anew from seed N >= 0 (default: the fixed seeds of docs/validation.md)",
    )
    v.add_argument("--only", metavar="ITEMS", help="run only the checks of these items, e.g. 21,22")
    v.set_defaults(func=cmd_validate)

    f = sub.add_parser(
        "figures",
        help="draw the paper's Figs. 6-8, and a run's packets' figure (runs the coverage scenario if no run given)",
    )
    f.add_argument("run_dir", nargs="?", help="a run's output directory (default: run the coverage scenario)")
    f.add_argument("--config", help="scenario file to run instead of the built-in coverage scenario")
    f.add_argument("--set", action="append", metavar="KEY=VALUE", help="override a configuration value")
    f.add_argument("--out", help="where to write (default: RUN_DIR, or ./netsim-figures)")
    f.add_argument(
        "--at",
        type=float,
        metavar="T",
        help="time of the deployment figure, Fig. 6, s (default: when coverage control starts; without coverage, "
        "the first sample with every robot in a group)",
    )
    f.add_argument("--no-progress", action="store_true", help="no progress bar")
    f.add_argument("--quiet", action="store_true", help="print nothing but warnings and errors")
    f.set_defaults(func=cmd_figures)

    vw = sub.add_parser("view", help="write an interactive replay of a run: one self-contained HTML file")
    vw.add_argument("run_dir", help="a run's output directory")
    vw.add_argument("--out", help="file to write, a new path (default: RUN_DIR/view.html, which is remade in place)")
    vw.set_defaults(func=cmd_view)

    x = sub.add_parser("export", help="write a run in the formats robot teams use (BonnMotion, ns-2, ROS 2 bag)")
    x.add_argument("run_dir", help="a run's output directory")
    x.add_argument("--format", required=True, help="bonnmotion, ns2 or rosbag2")
    x.add_argument("--out", required=True, help="file (bonnmotion: NAME.movements[.gz], ns2) or new folder (rosbag2)")
    x.set_defaults(func=cmd_export)

    c = sub.add_parser(
        "config", help="print the configuration (the default, or a file with overrides) with every key explained"
    )
    c.add_argument("config", nargs="?", help="TOML scenario file (default: the built-in scenario)")
    c.add_argument("--set", action="append", metavar="KEY=VALUE", help="override a configuration value")
    c.set_defaults(func=cmd_config)

    from netsim.radio.propagation import LogDistanceParams

    cal = sub.add_parser(
        "calibrate", help="fit the log-distance channel to a log of frames; write the [channel] fragment"
    )
    cal.add_argument("log", help="CSV or Parquet log: t_s, src, dst, rssi_dbm, and distance_m or both ends' positions")
    cal.add_argument(
        "--sensitivity-dbm",
        type=float,
        help="the radio's sensitivity, dBm (default: the weakest power of a received frame)",
    )
    cal.add_argument("--map", help="occupancy map (map_server YAML, or office / cave) to fit the loss per wall")
    cal.add_argument("--out", help="TOML file to write, a new path (default: print the fragment)")
    cal.add_argument(
        "--plot", help="figure to write, a new .png, .svg or .pdf: the log's powers and share heard beside the fit"
    )
    cal.add_argument(
        "--tx-power-dbm",
        type=float,
        default=LogDistanceParams.tx_power_dbm,
        help=f"transmit power, dBm (default: channel.tx_power_dbm's, {LogDistanceParams.tx_power_dbm:g})",
    )
    cal.add_argument(
        "--reference-distance-m",
        type=float,
        default=LogDistanceParams.reference_distance_m,
        help="d0 of reference_loss_db, m (default: channel.reference_distance_m's, "
        f"{LogDistanceParams.reference_distance_m:g})",
    )
    cal.set_defaults(func=cmd_calibrate)
    return p


def _one_line_warning(message, category, filename, lineno, file=None, line=None):
    print(f"netsim: warning: {message}", file=sys.stderr)


def _options_before_the_command(p: Parser, argv: list[str]) -> None:
    """``netsim --seed 3 run ...``: argparse would take ``3`` for an unknown command; say
    where the option goes instead (one line, exit 2)."""
    if not argv or not argv[0].startswith("-") or argv[0] in ("-h", "--help", "--version"):
        return
    command = next((a for a in argv if a in p.subcommands.choices), None)
    if command is not None:
        p.error(f"{argv[0]} goes after the command: netsim {command} {argv[0]} ...")


def main(argv=None) -> int:
    p = parser()
    _options_before_the_command(p, list(sys.argv[1:] if argv is None else argv))
    args = p.parse_args(argv)
    warnings.showwarning = _one_line_warning
    try:
        return args.func(args)
    except NetsimInputError as exc:
        print(f"netsim: error: {exc}", file=sys.stderr)
        return EXIT_INPUT
    except KeptOnInterrupt as exc:
        with ignoring_interrupts():  # a second Ctrl-C would add "nothing written" to this line
            print(exc.args[0], file=sys.stderr)
        return EXIT_INTERRUPTED
    except OSError as exc:
        if exc.errno not in FULL_DISK:
            raise
        # A file being written goes to a hidden temporary beside it: name its folder.
        where = f" in {Path(exc.filename).parent}" if exc.filename else ""
        print(f"netsim: error: cannot write{where}: {os.strerror(exc.errno)}", file=sys.stderr)
        return EXIT_INPUT
    except BaseException as exc:  # Ctrl-C, or what a compiled call made of it (netsim.tools.command)
        if not interrupted(exc):
            raise
        print(INTERRUPTED_LINE, file=sys.stderr)
        return EXIT_INTERRUPTED


# The status of a command whose stdout's reader went away: 128 + SIGPIPE, as the shell
# reports a command that signal ended.
EXIT_BROKEN_PIPE = 141

# Whether this process is the command's own (command()): only then is the collector's state changed.
_OWN_PROCESS = False


def _freeze_if_own(_sim: object = None) -> None:
    if _OWN_PROCESS:
        gc.freeze()


def _stdout_gone() -> bool:
    """Whether stdout's reader went away: a pipe with no reader left reports an error to a
    poll of its writing end (where poll is missing: flushing stdout fails)."""
    try:
        fd = sys.stdout.fileno()
    except (AttributeError, OSError, ValueError):
        return False
    import select

    if hasattr(select, "poll"):
        poller = select.poll()
        poller.register(fd, select.POLLOUT)
        return any(events & select.POLLERR for _, events in poller.poll(0))
    try:
        sys.stdout.flush()
    except BrokenPipeError:
        return True
    except (OSError, ValueError):
        pass
    return False


def command() -> None:
    """The ``netsim`` command: :func:`main`, in a process of its own. Its two process-wide
    switches are made here, and nowhere in the library (importing netsim or running a
    simulation from Python changes neither).

    - What the imports loaded (numpy, pandas, the engine: many long-lived objects, no
      garbage) is frozen out of the garbage collector's passes (``gc.freeze``), which would
      otherwise walk it again and again during the run; so is what a run's build loads
      (numba and its registries, for a run that uses the compiled loops).
    - When main returns, every table is written and closed; what the interpreter would
      still do is tear down every object of numpy, pandas and numba one by one, so the
      output streams and logs are flushed and the process ends at once (``os._exit``) with
      main's code. If another thread is still running, the process ends the usual way,
      waiting for it.
    """
    global _OWN_PROCESS
    _OWN_PROCESS = True
    gc.freeze()
    try:
        code = main()
    except BrokenPipeError:
        if not _stdout_gone():
            raise  # another pipe (a worker's, an output's): a failure of its own
        # The reader of stdout went away (`netsim run | head`): what it asked for is done
        # and written; end as a command killed by SIGPIPE would, without a traceback, and
        # send the rest of stdout nowhere so that the flush below cannot raise again.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        code = EXIT_BROKEN_PIPE
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except BrokenPipeError:  # the reader went away: nothing more can reach it
            if stream is sys.stdout and code == 0:
                code = EXIT_BROKEN_PIPE
        except (OSError, ValueError):  # a closed stream
            pass
    if "logging" in sys.modules:
        sys.modules["logging"].shutdown()
    import threading

    if threading.active_count() > 1 or not isinstance(code, int):
        sys.exit(code)  # None, a message: sys.exit's own rules
    os._exit(code)


if __name__ == "__main__":
    command()
