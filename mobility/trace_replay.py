"""Replay of recorded or generated motion (``mobility.model = "trace"``): an ns-2 movement
file (ns-2's ``setdest``, BonnMotion's ns-2 export, ``netsim scenario generate``; as ns-2
replays it, or as ns-3's ``Ns2MobilityHelper`` does with ``ns2_semantics = "ns3"``), a
BonnMotion ``.movements`` file, or a ROS 2 bag of the robots' poses (docs/model.md
section 2.2).

Before the run, the trace's motion is replayed once up to ``duration_s`` on a robot state
that checks the area (:meth:`RobotState.check_motion`): a robot that leaves it is one line
naming the robot, the time and the file's line, and nothing is simulated."""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from enum import StrEnum
from pathlib import Path
from typing import Any

import numpy as np
import simpy

from netsim.area import Bounds
from netsim.config import ConfigWarning, world_bounds
from netsim.errors import ConfigError, NetsimInputError
from netsim.formats import format_of_name, ns2
from netsim.formats.waypoints import Waypoints
from netsim.params import Params, each_once, file_path, param
from netsim.plugins import Parts, PluginSpec
from netsim.state import MotionError, RobotState, border_tolerance_m
from netsim.trajectory import LegTable, jumped


class Ns2Semantics(StrEnum):
    """What an ns-2 file's lines do: as ns-2 replays them, or as ns-3's helper does."""

    NS2 = "ns2"
    NS3 = "ns3"


class TraceFormat(StrEnum):
    """The format of ``mobility.trace_file``."""

    AUTO = "auto"
    NS2 = "ns2"
    BONNMOTION = "bonnmotion"
    ROSBAG2 = "rosbag2"


# How a file guessed to be of a format is said to have been read.
READ_AS = {TraceFormat.NS2: "ns-2", TraceFormat.BONNMOTION: "BonnMotion", TraceFormat.ROSBAG2: "a bag"}


def _topics(key: str, value: Any) -> tuple[str, ...]:
    if isinstance(value, str):
        value = [value]
    if not isinstance(value, (list, tuple)) or not all(isinstance(t, str) and t for t in value):
        raise ConfigError(key, value, "must be a list of topic names, robot i following topics[i]")
    return each_once(key, tuple(value), "each robot follows a topic of its own")


def _trace_path(key: str, value: Any) -> str:
    """A trace's path made absolute, as a map's; "" (none) as given."""
    return file_path(key, value, 'must be the path of a movement file or a rosbag2 folder, or ""')


@dataclass(frozen=True)
class TraceParams(Params):
    """The trace replay's keys of ``[mobility]``."""

    section = "mobility"
    trace_file: str = param(
        "",
        None,
        "ns-2 or BonnMotion movement file, or rosbag2 folder, replayed by model = 'trace'",
        coerce=_trace_path,
    )
    trace_format: TraceFormat = param(
        TraceFormat.AUTO,
        None,
        "'auto' (.movements[.gz]: BonnMotion, a folder: rosbag2, else ns-2), 'ns2', 'bonnmotion', 'rosbag2'",
    )
    topics: tuple[str, ...] = param(
        (), None, "rosbag2: the pose topic of each robot, in order (default: /robot_<i>/...)", coerce=_topics
    )
    ns2_semantics: Ns2Semantics = param(
        Ns2Semantics.NS2,
        None,
        "ns-2 files: 'ns2' (a scheduled set X_ moves the robot at its time; lines applied in time order) "
        "or 'ns3' (as ns-3's Ns2MobilityHelper: a scheduled set X_ also places it from the start)",
    )

    def check(self) -> None:
        if not self.trace_file:
            raise ConfigError("mobility.trace_file", self.trace_file, "must name a file when model = 'trace'")
        fmt = trace_format(self)
        # Keys of one format set for a trace of another: the user meant something the run ignores.
        for key, given, reads, kind in (
            ("topics", bool(self.topics), TraceFormat.ROSBAG2, "ROS 2 bags"),
            ("ns2_semantics", self.ns2_semantics is not Ns2Semantics.NS2, TraceFormat.NS2, "ns-2 files"),
        ):
            if given and fmt is not reads:
                warnings.warn(
                    f"mobility.{key}: applies to {kind} only, and {self.trace_file} is read as {READ_AS[fmt]}; ignored",
                    ConfigWarning,
                    stacklevel=2,
                )

    def inputs(self) -> dict[str, str]:
        return {"mobility.trace_file": self.trace_file}


def trace_format(params: TraceParams) -> TraceFormat:
    """The format of the trace: the one set, or the one its name tells."""
    if params.trace_format is not TraceFormat.AUTO:
        return params.trace_format
    by_name = format_of_name(params.trace_file)
    if by_name == "ns2" and Path(params.trace_file).is_dir():
        return TraceFormat.ROSBAG2  # a bag is a folder
    return TraceFormat(by_name)


def frame_holding(x_m: np.ndarray, y_m: np.ndarray) -> str:
    """``world.bounds_m`` for positions spanning ``x_m``, ``y_m``: whole metres around them,
    so that the text pasted holds them (rounded to fewer digits it could cut them), and a
    metre across a trace that stays on one line."""
    lo_x, lo_y = math.floor(float(np.min(x_m))), math.floor(float(np.min(y_m)))
    hi_x = max(math.ceil(float(np.max(x_m))), lo_x + 1)
    hi_y = max(math.ceil(float(np.max(y_m))), lo_y + 1)
    return f"[{lo_x}, {lo_y}, {hi_x}, {hi_y}]"


def replayed_span(scen: ns2.Scenario, duration_s: float) -> tuple[np.ndarray, np.ndarray]:
    """The x and y of the ends of every leg the robots of ``scen`` take up to ``duration_s``,
    wherever that is (a leg is straight: its ends hold it), a leg cut by a jump ending where
    the robot jumped from."""
    st = RobotState(scen.n_robots, 1.0, 1.0)
    st.place(scen.initial_m)
    env = simpy.Environment(initial_time=0.0)
    env.process(replay(env, st, scen))
    env.run(until=duration_s)
    table = LegTable(st.legs(), scen.n_robots)
    _, ends, _ = table.ends(duration_s)
    return np.r_[table.p[:, 0], ends[:, 0]], np.r_[table.p[:, 1], ends[:, 1]]


def _check_area(
    x_m: np.ndarray, y_m: np.ndarray, params: TraceParams, world, span=None, stated: str | None = None
) -> None:
    """Every position of the trace lies in the world's area (``world.bounds_m``); ``span``
    (a callable giving the x and y the motion reaches) for a frame to propose, when the
    positions checked are not all the trace reaches; ``stated``, the area the file states
    (a BonnMotion ``.params``), proposed first."""
    x, y = x_m[~np.isnan(x_m)], y_m[~np.isnan(y_m)]
    area = world_bounds(world)
    # As the run checks its robots' motion: a position past a border by its rounding is on it.
    tol = border_tolerance_m(area)
    if area.is_square_at_origin:
        xy = np.concatenate([x, y])
        side = world.side_m
        if len(xy) and xy.min() < -tol:
            # A square side can only grow to the right and up: a trace below 0 needs a frame,
            # which a torus (its square is [0, side]^2) cannot take.
            below = (
                f"gives the area [0, {side:g}]^2, and {params.trace_file} has coordinates below 0 (x from "
                f"{x.min():g} to {x.max():g}, y from {y.min():g} to {y.max():g})"
            )
            if world.torus:
                raise ConfigError("world.side_m", side, f"{below}: a torus is that square; shift the trace into it")
            reached = "them" if span is None else "them and the motion up to duration_s"
            frame = (
                f"{stated} (the area its .params states)" if stated else frame_holding(*(span() if span else (x, y)))
            )
            raise ConfigError(
                "world.side_m", side, f"{below}: set world.bounds_m to a frame holding {reached}, such as {frame}"
            )
        if len(xy) and xy.max() > side + tol:
            raise ConfigError(
                "world.side_m",
                side,
                f"is smaller than the area of {params.trace_file} (coordinates from {xy.min():g} to {xy.max():g})",
            )
        return
    if (len(x) and (x.min() < area.x_min - tol or x.max() > area.x_max + tol)) or (
        len(y) and (y.min() < area.y_min - tol or y.max() > area.y_max + tol)
    ):
        raise ConfigError(
            "world.bounds_m",
            area.as_list(),
            f"does not contain the positions of {params.trace_file} (x from {x.min():g} to {x.max():g}, "
            f"y from {y.min():g} to {y.max():g})",
        )


def _stated_area(given: dict[str, str], x_m: np.ndarray, y_m: np.ndarray) -> str | None:
    """The area a BonnMotion file's ``.params`` (``given``) states when it reaches below 0
    (``x_min``, ``y_min`` and the size ``x``, ``y``, as netsim exports a map's frame) and
    holds the positions, as ``world.bounds_m`` takes it; None otherwise."""
    try:
        x0, y0, w, h = (float(given[k]) for k in ("x_min", "y_min", "x", "y"))
    except (KeyError, ValueError):
        return None
    if not all(map(math.isfinite, (x0, y0, w, h))) or w <= 0 or h <= 0 or min(x0, y0) >= 0:
        return None
    stated = Bounds(x0, y0, x0 + w, y0 + h)
    if not stated.contains(np.c_[x_m, y_m], border_tolerance_m(stated)).all():
        return None
    return f"[{x0!r}, {y0!r}, {x0 + w!r}, {y0 + h!r}]"


def _warn_of_wraps(wp: Waypoints, params: TraceParams, side_m: float) -> None:
    """On a torus, say where a robot's next recorded pose, some time later, lies more than
    half the square away on an axis: the trace is followed straight across the square
    between them, where the robot likely wrapped about a border (a torus run's bag holds
    sampled poses only). Not for waypoints, whose legs may be that long, and whose exports
    write a wrap as a jump, two poses at one instant."""
    same = wp.robot[1:] == wp.robot[:-1]
    later = np.diff(wp.t_s) > 0
    far = (np.abs(np.diff(wp.x_m)) > side_m / 2) | (np.abs(np.diff(wp.y_m)) > side_m / 2)
    wraps = np.flatnonzero(same & later & far)
    if len(wraps):
        k = int(wraps[0])
        warnings.warn(
            f"mobility.trace_file: {params.trace_file}: {len(wraps):,} time(s) a robot's next pose lies more than "
            f"half the square away (robot {int(wp.robot[k])} at t = {float(wp.t_s[k + 1]):g} s): on the torus it "
            "goes straight across the square between them, where it likely wrapped about a border; replay a torus "
            "run from its ns-2 or BonnMotion export",
            stacklevel=3,
        )


def _check_count(n: int, params: TraceParams, world) -> None:
    if n != world.n_robots:
        nodes = f"{n} node{'s' if n != 1 else ''}"
        raise ConfigError(
            "world.n_robots", world.n_robots, f"must equal the {nodes} of {params.trace_file}: set it to {n}"
        )


def _read(params: TraceParams, fmt: TraceFormat, world) -> tuple[ns2.Scenario | Waypoints, dict[str, str]]:
    """The trace, and what a BonnMotion file's ``.params`` says (empty for the others)."""
    try:
        if fmt is TraceFormat.NS2:
            return ns2.read(params.trace_file, world.n_robots, params.ns2_semantics.value), {}
        if fmt is TraceFormat.BONNMOTION:
            from netsim.formats import bonnmotion

            return bonnmotion.read(params.trace_file)
        from netsim.formats import rosbag2

        return rosbag2.read(params.trace_file, params.topics), {}
    except NetsimInputError as exc:
        guessed = ""
        if params.trace_format is TraceFormat.AUTO and not Path(params.trace_file).is_dir():
            others = " or ".join(repr(str(f)) for f in TraceFormat if f not in (TraceFormat.AUTO, fmt))
            guessed = (
                f" (read as {READ_AS[fmt]}, the format guessed from the name: set mobility.trace_format = "
                f"{others} for another)"
            )
        elif params.trace_format is not TraceFormat.AUTO:
            guessed = f" (read as {READ_AS[fmt]}, as mobility.trace_format = {str(params.trace_format)!r} asks)"
        raise NetsimInputError(f"mobility.trace_file: {exc}{guessed}") from None


def load(params: TraceParams, world, duration_s: float) -> tuple[ns2.Scenario | Waypoints, dict[str, str]]:
    """The motion of ``params.trace_file``, checked against the world's size (an ns-2 file's
    up to ``duration_s``, by :func:`check_motion`), and what a BonnMotion file's ``.params``
    says."""
    fmt = trace_format(params)
    # The reader's warnings (lines skipped) are given once the file is taken: a file refused
    # is its one error line.
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        scen, given = _read(params, fmt, world)
        _check_count(scen.n_robots, params, world)
        if isinstance(scen, ns2.Scenario):
            # Where the robots start; the motion after is checked as replayed, up to the run's
            # end (check_motion), not by where a setdest heads, which the run may never reach.
            xy = scen.initial_m.reshape(-1, 2)
            _check_area(xy[:, 0], xy[:, 1], params, world, lambda: replayed_span(scen, duration_s))
        else:
            x, y = np.ravel(scen.x_m), np.ravel(scen.y_m)
            _check_area(x, y, params, world, stated=_stated_area(given, x, y))
            if world.torus and fmt is TraceFormat.ROSBAG2:
                _warn_of_wraps(scen, params, world.side_m)
    for w in caught:
        warnings.warn(w.message, w.category, stacklevel=2)
    return scen, given


def check_motion(scen: ns2.Scenario, params: TraceParams, world, duration_s: float) -> None:
    """Replay ``scen`` up to ``duration_s`` on a state that checks the area (the run's own
    check, :meth:`RobotState.check_motion`), each leg noted with the file's line that made
    it: a robot that leaves is one line naming it, the time and the line, before the run."""
    st = RobotState(scen.n_robots, world.side_m, 1.0, world.torus, world_bounds(world))
    st.check_motion()
    st.place(scen.initial_m)
    env = simpy.Environment(initial_time=0.0)
    env.process(replay(env, st, scen, note=params.trace_file))
    try:
        env.run(until=duration_s)
        st.check_until(duration_s)
    except MotionError as exc:
        x, y = replayed_span(scen, duration_s)
        inside = world_bounds(world).contains(np.c_[x, y], border_tolerance_m(world_bounds(world))).all()
        # Out of the area: the frame that holds the whole replay, where world.bounds_m may
        # be set to it (a torus is its square).
        frame = ""
        if not inside and not world.torus:
            frame = f"; world.bounds_m = {frame_holding(x, y)} holds its motion up to duration_s"
        raise MotionError(f"mobility.trace_file: {exc}{frame}") from None


def _warn_if_short(wp: Waypoints, params: TraceParams, given: dict[str, str], duration_s: float) -> None:
    """A recorded trace that ends before the run (its last pose, or the ``duration`` its
    BonnMotion ``.params``, ``given``, states): the robots then stand still."""
    declared = ""
    end_s = float(wp.t_s.max())
    if "duration" in given:
        from netsim.formats import bonnmotion

        name = bonnmotion.params_path(Path(params.trace_file)).name
        try:
            end_s, declared = float(given["duration"]), f" (duration={given['duration']} in {name})"
        except ValueError:
            pass
    if end_s < duration_s:
        warnings.warn(
            f"mobility.trace_file: {params.trace_file} ends at {end_s:g} s{declared}, before duration_s = "
            f"{duration_s:g}: the robots stand still at their last positions from then on",
            stacklevel=2,
        )


def replay(env: simpy.Environment, st: RobotState, scen: ns2.Scenario, note: str = ""):
    """One process applies the events in time order (:class:`netsim.formats.ns2.Scenario`); with
    ``note`` (the file's name), each leg is noted with the line that made it."""
    for t, i, kind, x, y, line in scen.events.itertuples(index=False):
        if t > env.now:
            yield env.timeout(t - env.now)
        if note:
            st.leg_notes[i] = f"{note}:{line}"
        if kind == "velocity":
            st.set_leg(i, env.now, (x, y), cause="trace")
        elif kind == "stop":
            st.set_leg(i, env.now, (0.0, 0.0), cause="waypoint")
        else:
            st.set_leg(i, env.now, (0.0, 0.0), start_m=(x, y), cause="jump")


def follow(env: simpy.Environment, st: RobotState, wp: Waypoints):
    """One process walks every robot's waypoints in time order: at each, the robot is put
    exactly there (rounding of the leg before removed) and moves on toward the next."""
    for t, i, x, y, vx, vy in wp.commands():
        if t > env.now:
            yield env.timeout(t - env.now)
        here = st.positions_at(env.now, [i])[0]
        moving = bool(st.velocity_mps[i].any())
        if jumped(here, (x, y)):
            # A jump is one whether the robot moves on or stands there: the link solvers
            # rebuild their pairs for a jump only.
            st.set_leg(i, env.now, (vx, vy), start_m=(x, y), cause="jump")
        elif vx == 0.0 and vy == 0.0:
            if moving or here[0] != x or here[1] != y:
                st.arrive(i, env.now, np.array([x, y]), cause="trace")
        else:
            st.arrive(i, env.now, np.array([x, y]), log=False)
            st.set_leg(i, env.now, (vx, vy), cause="trace")


def build(params: TraceParams, parts: Parts) -> None:
    scen, given = load(params, parts.world, parts.duration_s)
    if isinstance(scen, ns2.Scenario):
        check_motion(scen, params, parts.world, parts.duration_s)
    else:
        _warn_if_short(scen, params, given, parts.duration_s)
    parts.state.place(scen.initial_m if isinstance(scen, ns2.Scenario) else scen.initial_m())
    proc = (
        replay(parts.env, parts.state, scen) if isinstance(scen, ns2.Scenario) else follow(parts.env, parts.state, scen)
    )
    parts.env.process(proc)


PLUGIN = PluginSpec(Params=TraceParams, build=build)
