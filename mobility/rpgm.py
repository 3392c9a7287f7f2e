"""Reference point group mobility (Hong, Gerla, Pei and Chiang, MSWiM 1999), with the
member speed bound of BonnMotion's ``RPGM``: robots that move as teams.

Robots ``g * group_size`` to ``(g + 1) * group_size - 1`` form group ``g`` (the last group
may be smaller). Each group has a *reference point* that moves by random waypoint with the
usual keys (``speed_min_mps``, ``speed_max_mps``, ``pause_s``), its waypoints uniform over
the square shrunk by ``group_radius_m`` on every side, so that its members stay inside the
area. Each member keeps an *offset* from the reference point, drawn afresh at every
waypoint: by default (``offset_law = "uniform_radius"``, Hong et al.'s random motion vector
and BonnMotion's ``rndprox``) its length is uniform on ``[0, group_radius_m]`` and its
direction uniform, so the mean distance is half the radius; ``"uniform_area"`` draws it
uniformly over the disk instead (mean two thirds of the radius). While the reference point
goes from ``A`` to ``B``, a member goes in a straight line, in the same time, from ``A + o``
to ``B + o'``; as BonnMotion does, a new offset ``o'`` that would make the member faster
than ``speed_max_mps`` is drawn again (after :data:`MAX_DRAWS` draws the member keeps
``o``, and moves at the reference point's speed). Its offset at any instant is then on the
chord from ``o`` to ``o'`` of that disk, so **every member stays within**
``group_radius_m`` **of its reference point at every instant** and never moves faster
than ``speed_max_mps``, and every leg is straight (link events stay exact). While the
reference point pauses, its members stand still. The start is at rest, at the first
reference point plus each member's first offset (``world.placement`` does not apply).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

import numpy as np
import pandas as pd
import simpy
from netsim.mobility.speeds import SpeedParams

from netsim.area import Bounds
from netsim.config import world_bounds
from netsim.errors import ConfigError
from netsim.geometry import distances_m
from netsim.params import finite, non_negative, param, positive
from netsim.plugins import Parts, PluginSpec
from netsim.state import RobotState


class OffsetLaw(StrEnum):
    """How a member's offset from its reference point is drawn within ``group_radius_m``."""

    UNIFORM_RADIUS = "uniform_radius"  # distance uniform (Hong et al. 1999, BonnMotion)
    UNIFORM_AREA = "uniform_area"  # uniform over the disk


# Draws of a member's new offset before it keeps its old one (module notes): only a leg much
# shorter than the group's radius, at nearly the top speed, needs more than a few.
MAX_DRAWS = 1000


@dataclass(frozen=True)
class RpgmParams(SpeedParams):
    """Reference point group mobility's keys of ``[mobility]`` (the reference points' speeds
    and pause are random waypoint's)."""

    group_size: int = param(5, positive, "robots per group (robots g*size .. (g+1)*size - 1 form group g)")
    group_radius_m: float = param(50.0, finite(non_negative), "members stay within this of their reference point, m")
    offset_law: OffsetLaw = param(
        OffsetLaw.UNIFORM_RADIUS,
        None,
        'a member\'s offset: "uniform_radius" (distance uniform, as Hong et al. and BonnMotion) or "uniform_area"',
    )


def check(params: RpgmParams, config) -> None:
    if params.speed_max_mps <= 0:
        raise ConfigError("mobility.speed_max_mps", params.speed_max_mps, "must be > 0 for rpgm")
    if config.world.torus:
        raise ConfigError("mobility.model", "rpgm", "moves in a bounded area; set world.torus = false")
    area = world_bounds(config.world)
    shorter = min(area.width, area.height)
    if not 2 * params.group_radius_m < shorter:
        where = (
            f"world.side_m = {config.world.side_m}"
            if area.is_square_at_origin
            else f"the area's shorter side, {shorter:g} m (world.bounds_m)"
        )
        raise ConfigError(
            "mobility.group_radius_m",
            params.group_radius_m,
            f"must be less than half of {where} (the reference points need room)",
        )


def groups(n_robots: int, group_size: int) -> list[np.ndarray]:
    """The members of each group, in order.

    >>> [g.tolist() for g in groups(5, 2)]
    [[0, 1], [2, 3], [4]]
    """
    return [np.arange(g, min(g + group_size, n_robots)) for g in range(0, n_robots, group_size)]


def draw_offset(rng: np.random.Generator, radius_m: float, law: OffsetLaw) -> np.ndarray:
    """One offset within ``radius_m`` of the origin: its distance uniform on ``[0,
    radius_m]`` (``law`` uniform_radius) or uniform over the disk (uniform_area), its
    direction uniform."""
    u = rng.random()
    r = radius_m * (u if law == OffsetLaw.UNIFORM_RADIUS else np.sqrt(u))
    theta = rng.uniform(0.0, 2 * np.pi)
    return np.array([r * np.cos(theta), r * np.sin(theta)])


def member_offset(
    rng: np.random.Generator, m: RpgmParams, old: np.ndarray, move: np.ndarray, travel_s: float
) -> np.ndarray:
    """A member's offset at the reference point's next waypoint, ``move`` away and
    ``travel_s`` later, the member's offset now being ``old``: drawn by ``m.offset_law``
    until the member's speed ``|move + new - old| / travel_s`` is at most ``speed_max_mps``
    (BonnMotion's rule); ``old`` after :data:`MAX_DRAWS` draws, or for a leg of no time."""
    if travel_s <= 0.0:
        return old
    for _ in range(MAX_DRAWS):
        new = draw_offset(rng, m.group_radius_m, m.offset_law)
        if float(np.hypot(*(move + new - old))) <= m.speed_max_mps * travel_s:
            return new
    return old


def _reference_box(area: Bounds, radius_m: float) -> tuple[float | np.ndarray, float | np.ndarray]:
    """Where reference points may go: the area shrunk by ``radius_m``, so that every member
    (within ``radius_m`` of its reference point) stays in the area."""
    if area.is_square_at_origin:
        return radius_m, area.width - radius_m
    return area.lo + radius_m, area.hi - radius_m


def group_process(
    env: simpy.Environment,
    st: RobotState,
    m: RpgmParams,
    area: Bounds,
    members: np.ndarray,
    ref: np.ndarray,
    offsets: np.ndarray,
    group_rng: np.random.Generator,
    member_rngs: list[np.random.Generator],
    log: list[tuple[float, int, float, float]],
    group: int,
):
    """The reference point's random waypoint from ``ref``, its members following from their
    ``offsets`` (module notes); ``log`` gets two rows ``(t_s, group, x_m, y_m)`` as the reference point starts a leg:
    where it is, and where and when it will arrive."""
    lo, hi = _reference_box(area, m.group_radius_m)
    cause = "start"
    while True:
        dest = group_rng.uniform(lo, hi, 2)
        speed = group_rng.uniform(m.speed_min_mps, m.speed_max_mps)
        if speed <= 0.0:
            for i in members.tolist():
                st.set_leg(i, env.now, (0.0, 0.0), cause=cause)
            return  # a speed of exactly zero: the group never arrives
        travel_s = float(distances_m(ref, dest, None, st.n)[0]) / speed
        offsets = np.array(
            [member_offset(rng, m, offsets[k], dest - ref, travel_s) for k, rng in enumerate(member_rngs)]
        )
        ends = dest + offsets
        log.append((env.now, group, float(ref[0]), float(ref[1])))
        log.append((env.now + travel_s, group, float(dest[0]), float(dest[1])))
        if travel_s > 0.0:
            starts = st.positions_at(env.now, members)
            for k, i in enumerate(members.tolist()):
                st.set_leg(i, env.now, (ends[k] - starts[k]) / travel_s, cause=cause)
            yield env.timeout(travel_s)
        for k, i in enumerate(members.tolist()):
            st.arrive(i, env.now, ends[k], log=m.pause_s > 0)
        ref = dest
        cause = "waypoint"
        if m.pause_s > 0:
            yield env.timeout(m.pause_s)
            cause = "pause_end"


def build(m: RpgmParams, parts: Parts) -> None:
    w = parts.world
    teams = groups(w.n_robots, m.group_size)
    lo, hi = _reference_box(parts.state.bounds, m.group_radius_m)
    start = np.empty((w.n_robots, 2))
    plans = []
    for g, members in enumerate(teams):
        group_rng = parts.streams.get("mobility.group", g)
        member_rngs = [parts.streams.get("mobility", i) for i in members.tolist()]
        ref = group_rng.uniform(lo, hi, 2)
        offsets = np.array([draw_offset(rng, m.group_radius_m, m.offset_law) for rng in member_rngs])
        start[members] = ref + offsets
        plans.append((members, ref, offsets, group_rng, member_rngs))
    parts.state.place(start)
    log: list[tuple[float, int, float, float]] = []
    for g, (members, ref, offsets, group_rng, member_rngs) in enumerate(plans):
        parts.env.process(
            group_process(
                parts.env, parts.state, m, parts.state.bounds, members, ref, offsets, group_rng, member_rngs, log, g
            )
        )
    parts.trace.add_frame("reference_points", lambda: pd.DataFrame(log, columns=list(REFERENCE_SCHEMA)))


# The reference points' track: rows where each leg starts and ends (linear in between; the
# last leg's end may lie beyond the run's end).
REFERENCE_SCHEMA = {"t_s": "float64", "group": "int64", "x_m": "float64", "y_m": "float64"}

PLUGIN = PluginSpec(Params=RpgmParams, build=build, check=check, tables={"reference_points": REFERENCE_SCHEMA})
