"""Gauss-Markov mobility (Liang and Haas, INFOCOM 1999), as ns-3's
``GaussMarkovMobilityModel`` moves a node in the plane.

Every ``update_interval_s`` each robot draws its next speed and direction from its last
ones, the means and a Gaussian:

    s_n = alpha s_{n-1} + (1 - alpha) mean_speed + sqrt(1 - alpha^2) speed_sigma Z
    d_n = alpha d_{n-1} + (1 - alpha) mean_direction + sqrt(1 - alpha^2) direction_sigma Z'

and moves in a straight line at ``s_n (cos d_n, sin d_n)`` until the next update (a leg of
cause ``"turn"``). ``alpha = 0`` is memoryless (a random walk), ``alpha = 1`` a straight
line at the mean velocity. Each robot's mean direction is drawn uniformly on [0, 2 pi) at
the start, and it starts at its means, as in ns-3. The speed process has mean
``mean_speed_mps`` at every update (it starts there) and lag-one autocorrelation
``alpha``; a negative ``s_n`` moves the robot backwards along ``d_n`` (as in ns-3).

Borders, as ns-3 handles them: when the position one interval ahead lies outside the area,
the velocity's offending component is reversed and the mean direction mirrored (``pi -
d`` for a vertical border, ``-d`` for a horizontal one), and the direction is reset to the
mean. A robot that would still leave the area (an interval's travel longer than its
distance to the opposite border) is held at the border as ns-3 clamps it: it slides along
the border (a leg of cause ``"border"``), or stops in a corner, until the next update.
Every leg stays straight, so link events stay exact.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import simpy

from netsim.area import Bounds, as_bounds, exit_times
from netsim.compiled import load
from netsim.errors import ConfigError
from netsim.geometry import SPEED_OF_LIGHT_MPS, drivable
from netsim.params import Params, finite, param, positive, probability, speed
from netsim.placement import initial_positions
from netsim.plugins import Parts, PluginSpec
from netsim.state import RobotState


def _at_most_a_hundred_radians(v: float) -> str | None:
    # Far below where the direction's arithmetic overflows, far above where it is uniform.
    return None if 0 <= v <= 100 else "must be in [0, 100] rad (beyond a few radians the direction is uniform)"


@dataclass(frozen=True)
class GaussMarkovParams(Params):
    """Gauss-Markov's keys of ``[mobility]``."""

    section = "mobility"
    alpha: float = param(0.75, probability, "memory of speed and direction, in [0, 1] (0: random walk)")
    mean_speed_mps: float = param(1.0, speed, "mean speed, m/s")
    speed_sigma_mps: float = param(0.2, speed, "standard deviation of the speed, m/s")
    direction_sigma_rad: float = param(
        0.4, _at_most_a_hundred_radians, "standard deviation of the direction, rad, in [0, 100]"
    )
    update_interval_s: float = param(
        1.0, finite(positive), "time between updates of speed and direction, s", schedules="robot"
    )


# Standard deviations of the speed's draws allowed below light: a draw past 12 of them has a
# chance of about 1e-33, so no run is stopped midway by a speed the keys allowed.
SPEED_SIGMAS_BELOW_LIGHT = 12.0


def check(params: GaussMarkovParams, config) -> None:
    if config.world.torus:
        raise ConfigError("mobility.model", "gauss_markov", "moves in a bounded area; set world.torus = false")
    top = params.mean_speed_mps + SPEED_SIGMAS_BELOW_LIGHT * params.speed_sigma_mps
    if not drivable((top, 0.0)):
        raise ConfigError(
            "mobility.speed_sigma_mps",
            params.speed_sigma_mps,
            f"mobility.mean_speed_mps + {SPEED_SIGMAS_BELOW_LIGHT:g} x it must be at most {SPEED_OF_LIGHT_MPS:g} "
            "(m/s: the speed drawn could pass light and stop the run)",
        )


def _clamped_legs(
    p: np.ndarray, v: np.ndarray, duration_s: float, box: float | Bounds
) -> list[tuple[float, np.ndarray]]:
    """The legs ``(start offset s, velocity)`` of a robot moving from ``p`` at ``v`` for
    ``duration_s`` with its position clamped to the area (Bounds, or the side of the square
    ``[0, side]^2``): each coordinate that reaches a border stops there, the other goes on."""
    area = as_bounds(box)
    lo, hi = (area.x_min, area.y_min), (area.x_max, area.y_max)
    legs = [(0.0, v.copy())]
    t, here, vel = 0.0, p.copy(), v.copy()
    while True:
        hit = float(exit_times(here[None], vel[None], area.lo, area.hi)[0])
        if t + hit >= duration_s:
            return legs
        t += hit
        here = area.clip(here + vel * hit)
        for k in range(2):
            if (vel[k] > 0 and here[k] >= hi[k]) or (vel[k] < 0 and here[k] <= lo[k]):
                vel[k] = 0.0
        legs.append((t, vel.copy()))


def noise_scale(alpha: float) -> float:
    """The factor of each update's Gaussian, ``sqrt(1 - alpha^2)``: it keeps the stationary
    standard deviations of speed and direction at ``speed_sigma_mps`` and
    ``direction_sigma_rad`` whatever ``alpha`` (a probability). The process is the
    shadowing's (AR(1)), so the scale is its rule, :func:`netsim._kernels.innovation_scale`."""
    return float(load("netsim._kernels", 1).innovation_scale(alpha))


def gauss_markov_robot(
    env: simpy.Environment, st: RobotState, m: GaussMarkovParams, box: float | Bounds, i: int, rng: np.random.Generator
):
    """The life of robot ``i`` in the area ``box`` (Bounds, or the side of the square ``[0,
    side]^2``): one update every ``update_interval_s``, forever."""
    area = as_bounds(box)
    mean_dir = rng.uniform(0.0, 2 * math.pi)
    speed, direction = m.mean_speed_mps, mean_dir
    keep = noise_scale(m.alpha)
    dt = m.update_interval_s
    cause = "start"
    while True:
        z = rng.standard_normal(2)
        speed = m.alpha * speed + (1 - m.alpha) * m.mean_speed_mps + keep * m.speed_sigma_mps * z[0]
        direction = m.alpha * direction + (1 - m.alpha) * mean_dir + keep * m.direction_sigma_rad * z[1]
        v = speed * np.array([math.cos(direction), math.sin(direction)])
        here = st.positions_at(env.now, [i])[0]
        ahead = here + v * dt
        out_x = ahead[0] < area.x_min or ahead[0] > area.x_max
        out_y = ahead[1] < area.y_min or ahead[1] > area.y_max
        if out_x:
            v[0] = -v[0]
            mean_dir = math.pi - mean_dir
        if out_y:
            v[1] = -v[1]
            mean_dir = -mean_dir
        if out_x or out_y:
            direction = mean_dir
        start = env.now
        for k, (offset, vel) in enumerate(_clamped_legs(here, v, dt, area)):
            if offset > 0:
                yield env.timeout(start + offset - env.now)
                # Land exactly on the border, not a rounding error outside it.
                st.arrive(i, env.now, area.clip(st.positions_at(env.now, [i])[0]), log=False)
                st.set_leg(i, env.now, vel, cause="border")
            else:
                st.set_leg(i, env.now, vel, cause=cause if k == 0 else "border")
        yield env.timeout(start + dt - env.now)
        cause = "turn"


def build(m: GaussMarkovParams, parts: Parts) -> None:
    w = parts.world
    parts.state.place(initial_positions(w, parts.streams, parts.occupancy, parts.channel))
    for i in range(w.n_robots):
        rng = parts.streams.get("mobility", i)
        parts.env.process(gauss_markov_robot(parts.env, parts.state, m, parts.state.bounds, i, rng))


PLUGIN = PluginSpec(Params=GaussMarkovParams, build=build, check=check)
