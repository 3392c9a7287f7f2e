"""Random direction: robots keep a uniformly random heading and speed.

In a bounded area (the rectangle ``world.bounds_m``) a robot travels until it reaches the
border, pauses ``pause_s``, and leaves in a new direction drawn uniformly among those pointing back inside. On a torus
(``world.torus = true``) there is no border: a robot keeps its heading for
``turn_interval_s`` (``inf``: for ever, the constant-velocity model whose link durations
have a closed form, docs/validation.md item 6), then draws a new one.

On a map (``world.map``) a robot starts in a free cell and travels in its heading until the
border or the first cell that is not free, whichever comes first, stopping just short of it
(:func:`netsim.world.free_space.free_fraction`), then pauses and turns. A heading that
leaves no room to move (facing a wall) is drawn again.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import simpy
from netsim.mobility.speeds import SpeedParams

from netsim.area import Bounds, time_to_border
from netsim.errors import ConfigError
from netsim.params import param, positive
from netsim.placement import initial_positions
from netsim.plugins import Parts, PluginSpec
from netsim.state import RobotState
from netsim.world.free_space import free_fraction

# On a map: headings tried before a robot facing walls gives up, and the shortest leg kept.
_HEADING_TRIES = 64
_MIN_LEG_M = 1e-3


@dataclass(frozen=True)
class RandomDirectionParams(SpeedParams):
    """Random direction's keys of ``[mobility]``."""

    turn_interval_s: float = param(
        math.inf, positive, "random direction on a torus: time between turns (inf: never)", schedules="robot"
    )


def check(params: RandomDirectionParams, config) -> None:
    if params.speed_max_mps <= 0:
        raise ConfigError("mobility.speed_max_mps", params.speed_max_mps, "must be > 0 for random direction")


def _inward_heading(rng, p: np.ndarray, area: Bounds) -> np.ndarray:
    """A uniform heading, mirrored so that it does not point out of the area."""
    lo, hi = (area.x_min, area.y_min), (area.x_max, area.y_max)
    theta = rng.uniform(0.0, 2 * math.pi)
    u = np.array([math.cos(theta), math.sin(theta)])
    for k in range(2):
        if (p[k] <= lo[k] and u[k] < 0) or (p[k] >= hi[k] and u[k] > 0):
            u[k] = -u[k]
    return u


def direction_robot(
    env: simpy.Environment,
    st: RobotState,
    m: RandomDirectionParams,
    area: Bounds,
    i: int,
    rng: np.random.Generator,
    occupancy=None,
):
    cause = "start"
    while True:
        speed = rng.uniform(m.speed_min_mps, m.speed_max_mps)
        here = st.positions_at(env.now, [i])[0]
        if st.torus:
            theta = rng.uniform(0.0, 2 * math.pi)
            st.set_leg(i, env.now, (speed * math.cos(theta), speed * math.sin(theta)), cause=cause)
            if math.isinf(m.turn_interval_s):
                return
            yield env.timeout(m.turn_interval_s)
            cause = "turn"
            continue
        v = speed * _inward_heading(rng, here, area)
        travel = float(time_to_border(here[None], v[None], area)[0])
        if occupancy is not None and speed > 0 and not math.isinf(travel):
            for _ in range(_HEADING_TRIES):
                f = float(free_fraction(occupancy, here[None], (here + v * travel)[None])[0])
                if f * travel * speed > _MIN_LEG_M:
                    break
                v = speed * _inward_heading(rng, here, area)
                travel = float(time_to_border(here[None], v[None], area)[0])
            else:
                f = 0.0
            travel *= f
            if travel <= 0.0:
                st.set_leg(i, env.now, (0.0, 0.0), cause=cause)
                return  # walled in: no heading leads anywhere
            st.set_leg(i, env.now, v, cause=cause)
            yield env.timeout(travel)
            # The wall it headed for is its border.
            st.arrive(i, env.now, here + v * travel, log=m.pause_s > 0, cause="border")
            cause = "border"
            if m.pause_s > 0:
                yield env.timeout(m.pause_s)
                cause = "pause_end"
            continue
        if speed <= 0 or math.isinf(travel):
            st.set_leg(i, env.now, (0.0, 0.0), cause=cause)
            return
        st.set_leg(i, env.now, v, cause=cause)
        yield env.timeout(travel)
        st.arrive(i, env.now, area.landing(here, v, travel), log=m.pause_s > 0, cause="border")
        cause = "border"
        if m.pause_s > 0:
            yield env.timeout(m.pause_s)
            cause = "pause_end"


def build(m: RandomDirectionParams, parts: Parts) -> None:
    w = parts.world
    parts.state.place(initial_positions(w, parts.streams, parts.occupancy, parts.channel))
    for i in range(w.n_robots):
        rng = parts.streams.get("mobility", i)
        parts.env.process(direction_robot(parts.env, parts.state, m, parts.state.bounds, i, rng, parts.occupancy))


PLUGIN = PluginSpec(Params=RandomDirectionParams, build=build, check=check, respects_map=True)
