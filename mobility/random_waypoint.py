"""Random waypoint (paper section 1.1; docs/model.md section 2).

Each robot picks a destination uniformly in the area (``world.bounds_m``) and a speed uniform on
``[speed_min_mps, speed_max_mps]``, travels there in a straight line, pauses ``pause_s``,
and repeats; robots are independent. A leg costs two kernel events (arrival, end of
pause) and nothing in between: positions are exact at any time from the leg.

Started from a uniform placement, the model is not in its stationary regime: robots
bunch toward the centre and the average speed falls over time (to zero when
``speed_min_mps = 0``; Yoon, Liu and Noble 2003). The default is therefore Navidi and
Camp's stationary start ("perfect simulation", IEEE TMC 2004): at t = 0 positions, speeds
and pauses already follow the stationary distribution, so measurements need no warm-up.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import simpy
from netsim.mobility.speeds import SpeedParams

from netsim.area import Bounds, as_bounds
from netsim.errors import ConfigError
from netsim.geometry import distances_m
from netsim.metrics import MEAN_LEG_UNIT_SQUARE, mean_distance_rectangle
from netsim.params import param
from netsim.placement import initial_positions
from netsim.plugins import Parts, PluginSpec
from netsim.state import RobotState
from netsim.world.free_space import draw_destinations


@dataclass(frozen=True)
class RandomWaypointParams(SpeedParams):
    """Random waypoint's keys of ``[mobility]``."""

    stationary_start: bool | str = param(
        "auto",
        None,
        "start in the stationary regime (no warm-up): true, false, or 'auto' (where it can be drawn: "
        "no map, uniform placement, speed_min_mps > 0)",
        coerce=lambda key, value: _stationary(key, value),
    )


def _stationary(key: str, value) -> bool | str:
    if isinstance(value, bool) or value == "auto":
        return value
    raise ConfigError(key, value, "must be true, false or 'auto'")


def starts_stationary(params: RandomWaypointParams, world) -> bool:
    """Whether the run starts in the stationary regime: as set, or with ``"auto"`` wherever
    its law is known (an open square, positions drawn uniformly, a least speed above 0)."""
    if params.stationary_start != "auto":
        return bool(params.stationary_start)
    return not world.map and world.placement == "uniform" and params.speed_min_mps > 0


def check(params: RandomWaypointParams, config) -> None:
    """Random waypoint needs a speed above 0; its stationary start draws positions itself
    and has no stationary regime with ``speed_min_mps = 0``."""
    if params.speed_max_mps <= 0:
        raise ConfigError("mobility.speed_max_mps", params.speed_max_mps, "must be > 0 for random waypoint")
    if params.stationary_start is True and config.world.map:
        raise ConfigError(
            "mobility.stationary_start",
            True,
            "cannot be used on a map (world.map): random waypoint's stationary law there has no closed form; "
            "set stationary_start = false",
        )
    if params.stationary_start is True:
        if config.world.placement != "uniform":
            raise ConfigError(
                "world.placement",
                config.world.placement,
                "cannot be combined with mobility.stationary_start = true (the stationary "
                "start draws positions itself); set stationary_start = false",
            )
        if params.speed_min_mps <= 0:
            raise ConfigError(
                "mobility.speed_min_mps",
                params.speed_min_mps,
                "must be > 0 with stationary_start = true (with 0 there is no stationary "
                "regime: the average speed decays to zero); set it > 0 or stationary_start = false",
            )


class Start(NamedTuple):
    """Where each robot is at t = 0 and what it is doing."""

    position_m: np.ndarray  # (n, 2)
    destination_m: np.ndarray  # (n, 2); equal to position for paused robots
    speed_mps: np.ndarray  # (n,); 0 for paused robots
    pause_left_s: np.ndarray  # (n,); residual pause, 0 for moving robots


def mean_inverse_speed(v_min: float, v_max: float) -> float:
    """``E[1/V]`` for V uniform on ``[v_min, v_max]`` (infinite when ``v_min = 0``)."""
    if v_min == v_max:
        return 1.0 / v_max
    if v_min == 0:
        return math.inf
    return math.log(v_max / v_min) / (v_max - v_min)


def paused_fraction(area: float | Bounds, v_min: float, v_max: float, pause_s: float) -> float:
    """Long-run fraction of time a robot is paused: ``E[T_p] / (E[T_p] + E[L] E[1/V])``
    (``area``: Bounds, or the side of the square ``[0, side]^2``)."""
    if pause_s == 0:
        return 0.0
    b = as_bounds(area)
    leg = MEAN_LEG_UNIT_SQUARE * b.width if b.width == b.height else mean_distance_rectangle(b.width, b.height)
    return pause_s / (pause_s + leg * mean_inverse_speed(v_min, v_max))


def stationary_start(
    rng: np.random.Generator, n: int, area: float | Bounds, v_min: float, v_max: float, pause_s: float
) -> Start:
    """Draw the state of ``n`` robots from the stationary distribution (Navidi and Camp),
    in the rectangle ``area`` (Bounds, or the side of the square ``[0, side]^2``).

    With probability ``p_p`` a robot is paused at a uniform point with a residual pause
    uniform on ``(0, pause_s)``. Otherwise it is on a leg drawn with probability
    proportional to its length (two uniform points, accepted with probability
    ``|P2 - P1| / diagonal``), at a uniform point of it, heading to P2, with speed
    ``v_min (v_max / v_min)^U`` (the speed density ``1 / (v ln(v_max / v_min))``).
    """
    if v_max <= 0:
        raise ConfigError("mobility.speed_max_mps", v_max, "must be > 0 for random waypoint")
    if v_min <= 0:
        raise ConfigError(
            "mobility.speed_min_mps",
            v_min,
            "must be > 0 with stationary_start = true (with 0 there is no stationary "
            "regime: the average speed decays to zero); set it > 0 or stationary_start = false",
        )
    b = as_bounds(area)
    p_pause = paused_fraction(b, v_min, v_max, pause_s)
    paused = rng.random(n) < p_pause
    moving = np.flatnonzero(~paused)
    pos = np.empty((n, 2))
    dest = np.empty((n, 2))
    speed = np.zeros(n)
    pause_left = np.zeros(n)

    k = int(paused.sum())
    pos[paused] = b.uniform(rng, k)
    dest[paused] = pos[paused]
    pause_left[paused] = rng.uniform(0, pause_s, k) if k else 0.0

    m = len(moving)
    diagonal = b.diagonal
    starts, ends = [], []
    need = m
    while need > 0:
        batch = max(2 * need, 16)
        p1 = b.uniform(rng, batch)
        p2 = b.uniform(rng, batch)
        accept = rng.random(batch) * diagonal < distances_m(p1, p2, None, n)
        starts.append(p1[accept][:need])
        ends.append(p2[accept][:need])
        need -= int(min(accept.sum(), need))
    p1 = np.concatenate(starts) if starts else np.empty((0, 2))
    p2 = np.concatenate(ends) if ends else np.empty((0, 2))
    frac = rng.random(m)
    pos[moving] = p1 + frac[:, None] * (p2 - p1)
    dest[moving] = p2
    u = rng.random(m)
    speed[moving] = v_max if v_min == v_max else v_min * (v_max / v_min) ** u
    return Start(pos, dest, speed, pause_left)


def _fresh_start(positions: np.ndarray) -> Start:
    n = len(positions)
    return Start(positions, positions.copy(), np.zeros(n), np.zeros(n))


def waypoint_robot(
    env: simpy.Environment,
    st: RobotState,
    m: RandomWaypointParams,
    area: Bounds,
    i: int,
    start: Start,
    rng: np.random.Generator,
    occupancy=None,
):
    """The life of robot ``i``: legs and pauses, forever (on a map, legs in free cells)."""
    # Why the next leg starts: the start, the end of a pause, or (no pause) the waypoint.
    cause = "start"
    if start.pause_left_s[i] > 0:
        yield env.timeout(start.pause_left_s[i])
        cause = "pause_end"
    elif start.speed_mps[i] > 0:
        dest = start.destination_m[i]
        yield env.timeout(st.head_to(i, env.now, dest, start.speed_mps[i], cause))
        st.arrive(i, env.now, dest, log=m.pause_s > 0)
        cause = "waypoint"
        if m.pause_s > 0:
            yield env.timeout(m.pause_s)
            cause = "pause_end"
    while True:
        if occupancy is None:
            dest = area.uniform(rng, 1)[0]
        else:
            dest = draw_destinations(occupancy, rng, st.positions_at(env.now, [i]), area)[0]
        speed = rng.uniform(m.speed_min_mps, m.speed_max_mps)
        if speed <= 0.0:
            st.set_leg(i, env.now, (0.0, 0.0), cause=cause)
            return  # a speed of exactly zero: the robot never arrives
        yield env.timeout(st.head_to(i, env.now, dest, speed, cause))
        st.arrive(i, env.now, dest, log=m.pause_s > 0)
        cause = "waypoint"
        if m.pause_s > 0:
            yield env.timeout(m.pause_s)
            cause = "pause_end"


def build(m: RandomWaypointParams, parts: Parts) -> None:
    w = parts.world
    if starts_stationary(m, w):
        start = stationary_start(
            parts.streams.get("mobility.start"),
            w.n_robots,
            parts.state.bounds,
            m.speed_min_mps,
            m.speed_max_mps,
            m.pause_s,
        )
    else:
        if m.speed_min_mps == 0:
            warnings.warn(
                "mobility.speed_min_mps = 0 without a stationary start: the average speed of "
                "random waypoint decays toward zero over the run (Yoon, Liu and Noble 2003)",
                stacklevel=2,
            )
        start = _fresh_start(initial_positions(w, parts.streams, parts.occupancy, parts.channel))
    parts.state.place(start.position_m)
    for i in range(w.n_robots):
        parts.env.process(
            waypoint_robot(
                parts.env,
                parts.state,
                m,
                parts.state.bounds,
                i,
                start,
                parts.streams.get("mobility", i),
                parts.occupancy,
            )
        )


PLUGIN = PluginSpec(Params=RandomWaypointParams, build=build, check=check, default=True, respects_map=True)
