"""Connected coverage by virtual forces (paper section 1.4; docs/model.md section 5): the
controller plugin ``coverage``.

Why the whole team must spread
------------------------------
A connected team of N robots with disks of radius ``r`` covers at most ``U(N) = r^2 (pi +
1.9132 (N - 1))`` (:func:`netsim.metrics.connected_coverage_bound`): each robot but the
first adds at most a disk minus the lens it must share with a neighbour in range. Dense
arrangements fall far short of it: a connected hexagonal lattice of all robots (spacing
``r``) covers ``0.866 r^2`` per robot, 45 % of the ``1.913 r^2`` the bound allows; leaders
on the ``sqrt(3) r`` hexagon with one gateway per edge, the paper's picture, about ``0.65
r^2``. So the paper's controller, where members follow their leader rigidly, covers what
the groups formed at the start happen to span (a quarter of the area in the built-in
scenario). To cover more, every robot must spread into a sparse, tree-like net in which
most robots keep one or two neighbours near full range and stay well away from the rest.

The architecture (docs/model.md section 5)
-------------------------------------
- Leaders decide. Each control period a leader computes, for itself and for each member
  whose Acks it hears, the virtual force (:mod:`netsim.mobility.forces`, the configured law,
  plus the border's push) from the robots that robot knows of: those it hears and those
  they hear, at the positions last heard (an Ack carries its sender's table; a member's
  Ack brings its knowledge to its leader). The relation is symmetric (i knows j if and
  only if j knows i), as it must be: with one-sided knowledge the forces are not
  reciprocal and the team drifts for ever. ``knowledge = "global"``: the true positions of
  every robot within ``2 r_c``, for comparison.
- Members move only by their leader's commands, sent over the channel; a member that
  misses its command holds for that step.
- The step is made safe for connectivity by :func:`netsim.mobility.spread.plan_spread`: a
  minimum spanning forest of the links up now is kept, each end of a kept link ending the
  step within its half of the link's allowed length (module notes there). Because each end
  keeps to its own half, a robot that holds instead of moving never breaks a kept link:
  the network stays connected at every instant even when commands are lost.
- The team unfolds. Forces among neighbours alone balance inside
  the team: it grows into a disk of evenly spaced robots whose kept tree is taut and
  folded, far below the bound. So every robot is also pushed away from the centre of its
  component of the network, in proportion to its distance from it (``expansion``, a
  centrifugal field, capped): the kept tree straightens into branches that run outwards
  and part, and the inside of the team empties where no robot adds area. The centre is
  knowledge of the whole team, which the global plan has; with the local plan each robot
  pushes from the centre it estimates with the robots it hears
  (:func:`netsim.mobility.local.centre_estimates`).
- A link is what the channel makes under the run's radio, the same as ``links.parquet``:
  the controller gets the run's link state when built (``parts.links``), counts the
  components of its links in the ``coverage`` and ``control`` tables, and its plan keeps
  them up by the radio's rules (:mod:`netsim.mobility.keep`: the disk exactly; shadowing with a
  fade margin and a bound on travel; walls swept exactly over the step).
- On a map (docs/model.md 5.3, :mod:`netsim.mobility.geodesic`) walls push as borders do,
  robots push each other only in sight, and wishes that run into a wall slide along it.
  The global plan moves there by its expansion alone (unless ``expansion = 0``), with
  neither push: every robot down the distance through free space to the nearest free cell
  no robot covers yet; its planned step slides too before the exact cut, and the forest
  prefers the links that last over the wished step (:func:`netsim.mobility.keep.prefer`).
  The local plan's robots move the same way toward the nearest free cell none they know
  of has covered (:mod:`netsim.mobility.explored`), and take turns
  (:func:`netsim.mobility.local.turn_takers`).
- The hierarchy adapts. A member that its forces carry beyond its leader's range is
  released: it hears no more commands and holds; after ``tau`` it leaves the group (rule
  3) and joins a leader it hears, or is elected leader (rule 6), or becomes leader after
  another ``tau`` (rule 4), and from then on it moves again, by its own decisions or its
  new leader's. So groups split as the team spreads, the inverse of rule 5's merge (which
  still joins groups whose leaders come within range). When control stops, the
  clustering settles on the still network: leaders independent, every member in range of
  its leader.

Stopping: in ``"spread"`` control ends once the covered fraction of ``min(1, U(N) / A)``
(the coverage samples) has risen less than ``stop_gain`` over ``stop_hold_s`` (and, on a map
with the expansion on, the robots came no nearer the free space their expansion seeks),
or no robot
has moved faster than ``stop_speed_mps`` for ``stop_hold_s``. (Under the Ack-based
knowledge the net keeps creeping at a few centimetres per second long after it has
stopped gaining area; a motion-only rule would not end.)

``members = "follow"`` keeps the paper's controller, for comparison: forces among leaders
only (the leaders they hear and those their neighbours hear), members translating
rigidly with their leader, and the bridges between groups kept by
:func:`netsim.mobility.bridges.plan_follow`; its stopping rule: every leader's force has asked
for less than ``stop_speed_mps`` for ``stop_hold_s``. Under loss a member that misses a
command can break a bridge there: connectivity is measured, not guaranteed.

What is not distributed (``plan = "global"``, the default): each step's plan is computed
in one pass for the whole team (the spanning forest over the whole network; a robot's
limits then use only the current positions of its kept neighbours, and under shadowing the
shadowing measured on those links). With ``plan = "local"`` (:mod:`netsim.mobility.local`) every
robot decides its own step from the Acks it heard, keeps the links it cannot certify a
detour for, and answers for each against the other end's largest motion since its Ack
(under shadowing by the shadowing it measured on the link's Acks, on a map clear of walls or
within the range through the walls it can cross),
or holds; no command is sent.
"""

from __future__ import annotations

import math
import warnings
from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass, replace
from enum import StrEnum
from typing import NamedTuple

import numpy as np
import pandas as pd
from netsim.mobility.bridges import plan_follow
from netsim.mobility.explored import Explored
from netsim.mobility.forces import (
    LAWS,
    SQRT3,
    Law,
    border_forces,
    component_centres,
    expansion_forces,
    pair_resultants,
)
from netsim.mobility.geodesic import (
    FreeGrid,
    expansion_to_uncovered,
    expansion_to_unexplored,
    in_sight,
    slide,
    within_reach,
)
from netsim.mobility.keep import FADE_SIGMAS, LinkRules, prefer
from netsim.mobility.local import (
    Fade,
    Heard,
    Lists,
    Memory,
    answered_by_halves,
    centre_estimates,
    cut_for_walls,
    latest_pulls,
    let_go,
    lists_bytes,
    lists_depth,
    plan_local,
    silence_of,
    silent,
    sources_heard,
    turn_takers,
    walls_of,
)
from netsim.mobility.spread import plan_spread
from netsim.mobility.steps import Plan, StepLimits, cap_length, fell_short

from netsim import metrics
from netsim.area import MAX_COORDINATE_M, Bounds, within_reach_of_doubles
from netsim.compiled import load
from netsim.config import MIN_RANGE_M, ConfigWarning
from netsim.control import ControlLoop, ControlStep
from netsim.errors import ConfigError
from netsim.geometry import SPEED_OF_LIGHT_MPS, drivable, in_motion, row_starts, speeds_mps
from netsim.groups import GroupView, in_a_group, leads_itself
from netsim.machine import gib, machine_memory_bytes
from netsim.params import Params, finite, non_negative, param, positive
from netsim.plugins import Parts, PluginSpec
from netsim.samples import ended_at
from netsim.scheduling import LAST, scheduled_event
from netsim.topology import geometric_pairs
from netsim.world.free_space import (
    free_fraction,
    obstacle_field,
    short_of_walls,
    team_region,
    wall_forces,
)

# The stopping rule's default windows (coverage.stop_hold_s = 0), s.
GLOBAL_HOLD_S = 20.0
LOCAL_HOLD_S = 60.0
# The expansion's push (the global plan's from its components' centres, the local plan's
# from the centre each robot estimates).
EXPANSION = 0.1


class Members(StrEnum):
    """How members move: spread (pushed apart, every robot) or follow (the paper's)."""

    SPREAD = "spread"
    FOLLOW = "follow"


class Knowledge(StrEnum):
    """Where the positions the forces use come from."""

    ACKS = "acks"
    GLOBAL = "global"


class PlanScope(StrEnum):
    """Who plans each step: one plan for the team from the true positions, or each robot
    its own from what it heard."""

    GLOBAL = "global"
    LOCAL = "local"


class AreaMethod(StrEnum):
    """How the covered fraction is computed over time."""

    EXACT = "exact"
    GRID = "grid"


def _gain_check(v: float) -> str | None:
    # Past it a force of a micrometre already drives a robot at its speed cap; far past it
    # the forces' sums overflow.
    return None if 0 < v <= 1e6 else "must be in (0, 1e6] (1/s)"


def _coverage_radius(v: float) -> str | None:
    # As short as the shortest range a run takes: a disk of 1e-300 m covers 0 of the area
    # and its bound 0 (covered over bound: 0 / 0).
    if math.isfinite(v) and (v == 0 or v >= MIN_RANGE_M):
        return None
    return f"must be 0 (the range) or a finite radius of at least {MIN_RANGE_M:g} m"


def _speed_cap_check(v: float) -> str | None:
    # Every robot's velocity must be drivable (netsim.geometry): far past it a step's squares overflow.
    if not math.isfinite(v):
        return "must be finite"
    if v > 0 and drivable((v, 0.0)):
        return None
    return f"must be in (0, {SPEED_OF_LIGHT_MPS:g}] (m/s, no faster than light)"


@dataclass(frozen=True)
class CoverageParams(Params):
    """The coverage controller's section, ``[coverage]`` (it also sets the control loop's
    period and first step, for every controller)."""

    section = "coverage"
    enabled: bool = param(False, None, "the team spreads out by virtual forces (needs mobility.model = 'static')")
    members: Members = param(
        Members.SPREAD,
        None,
        "'spread': every robot is pushed apart, a spanning forest kept; 'follow': members follow their leader",
    )
    law: Law = param(Law.SPRING, None, "force law between neighbouring robots (follow: between leaders)")
    knowledge: Knowledge = param(
        Knowledge.ACKS,
        None,
        "positions the forces among neighbours use: 'acks', as heard in Acks (stale; the local plan needs"
        " it), or 'global', the true ones (the global plan's expansion and limits use the true ones either"
        " way; on a map, with expansion > 0, the global plan has no such forces)",
    )
    plan: PlanScope = param(
        PlanScope.GLOBAL,
        None,
        "spread: 'global' (one plan from the true positions) or 'local' (each robot from what it heard)",
    )
    release_s: float = param(
        20.0, positive, "plan = 'local': a robot forgets a robot whose latest Ack it heard was sent this long ago, s"
    )
    band_m: float = param(
        7.5,
        positive,
        "plan = 'local': links are ordered by bands of length this wide, then by their robots' ids, m",
    )
    control_period_s: float = param(
        1.0, finite(positive), "time between control steps, s (also for control.controllers)", schedules="run"
    )
    start_s: float = param(
        10.0,
        non_negative,
        "first control step, s (after the groups have formed; at or after duration_s: none, and a warning)",
    )
    gain: float = param(
        0.1,
        _gain_check,
        "a controlled robot's velocity (follow: a leader's) is gain x resultant force, 1/s (forces in metres), "
        "in (0, 1e6]",
    )
    speed_max_mps: float = param(2.0, _speed_cap_check, "speed cap of every controlled robot, m/s")
    margin_m: float = param(
        1.0, non_negative, "kept links stay this far inside the range, m (below the smallest range)"
    )
    fade_margin_db: float = param(
        8.0,
        non_negative,
        "shadowing: kept links keep this much power margin against the change of their shadowing, dB",
    )
    detour_sigmas: float = param(
        FADE_SIGMAS,
        positive,
        "local plan under shadowing in open space (with fade_margin_db > 0; else unused): rule 1 certifies a"
        " detour's measured link up within this many standard deviations of its shadowing's change (4: as kept"
        " links are kept; fewer: more links let go, a larger chance of a split)",
    )
    expansion: float = param(
        EXPANSION,
        finite(non_negative),
        "spread: every robot is also pushed away from the centre of its component (plan = 'local': from the"
        " centre it estimates with the robots it hears) with expansion x its distance from it, at most"
        " sqrt(3) r_c / 4 (a pure number: forces in metres; 0: off); on a map the push is that cap,"
        " through free space toward the nearest free cell no robot covers (plan = 'local': none the robot"
        " knows its team to have covered), whatever the value above 0, and its only push: no pushes of"
        " robots or walls, which 0 brings back (docs/model.md 5.1, 5.3)",
    )
    stop_speed_mps: float = param(
        0.02,
        non_negative,
        "a robot (follow: a leader) whose force asks for less than this holds, m/s; on a map with"
        " expansion > 0 the team counts as still spreading (stop_gain) while its robots' mean distance to"
        " the free space their expansion seeks falls by more than this x stop_hold_s",
    )
    stop_hold_s: float = param(
        0.0,
        non_negative,
        "stopping rule's window: all leaders held (follow), or too little gain or motion (spread), s"
        " (0: 20 s, 60 s with plan = 'local', whose team creeps slower)",
    )
    stop_gain: float = param(
        0.002,
        non_negative,
        "spread: control ends once covered_of_bound_all gains less than this in stop_hold_s and, on a map"
        " with expansion > 0, the robots came no nearer the free space their expansion seeks"
        " (stop_speed_mps); 0: off",
    )
    radius_m: float = param(0.0, _coverage_radius, "radius of the coverage disks, m (0: the communication range r_c)")
    metrics_interval_s: float = param(5.0, positive, "coverage metrics sampling interval, s", schedules="run")
    area_method: AreaMethod = param(
        AreaMethod.EXACT, None, "covered fraction over time: 'exact' (polygon bracket) or 'grid' (cheap)"
    )
    grid_cells: int = param(
        200, metrics.grid_side, "area_method = 'grid': grid cells per side, at most 4,000 (error bound reported)"
    )

    @property
    def hold_s(self) -> float:
        """The stopping rule's window (``stop_hold_s``, or its default for the plan)."""
        if self.stop_hold_s > 0:
            return self.stop_hold_s
        return LOCAL_HOLD_S if self.plan is PlanScope.LOCAL else GLOBAL_HOLD_S

    def check(self) -> None:
        if self.plan is PlanScope.LOCAL and self.knowledge is Knowledge.GLOBAL:
            raise ConfigError(
                "coverage.plan", "local", "needs coverage.knowledge = 'acks' (a robot uses only what it heard)"
            )
        if self.plan is PlanScope.LOCAL and self.members is Members.FOLLOW:
            raise ConfigError("coverage.plan", "local", "needs coverage.members = 'spread', not 'follow'")
        step_m = self.speed_max_mps * self.control_period_s
        if self.enabled and within_reach_of_doubles(step_m):
            # A step past any area: its square, which the step limits form, heads for overflow.
            raise ConfigError(
                "coverage.control_period_s",
                self.control_period_s,
                f"a step at coverage.speed_max_mps = {self.speed_max_mps:g} m/s would reach {step_m:.3g} m, past "
                f"any area ({MAX_COORDINATE_M:g} m): lower either",
            )
        if self.enabled and self.members is Members.SPREAD and self.metrics_interval_s > self.hold_s:
            raise ConfigError(
                "coverage.metrics_interval_s",
                self.metrics_interval_s,
                f"must not exceed coverage.stop_hold_s = {self.hold_s} (the stopping rule compares samples)",
            )


def check(params: CoverageParams, config) -> None:
    """The rules that tie ``[coverage]`` to the other sections."""
    ch = config.channel
    lead = ch.latency_s + ch.latency_jitter_s
    if (params.enabled or config.control.controllers) and not params.control_period_s > lead:
        raise ConfigError(
            "coverage.control_period_s",
            params.control_period_s,
            f"must exceed the channel's largest delay (latency_s + latency_jitter_s = {lead})",
        )
    if not params.enabled:
        return
    if params.plan is PlanScope.LOCAL and ch.mac != "none":
        raise ConfigError(
            "coverage.plan",
            "local",
            f"needs channel.mac = 'none' (its bound on an Ack's age needs a bounded delay), not {ch.mac!r}",
        )
    if config.mobility.plugin.moves_robots:
        raise ConfigError(
            "coverage.enabled",
            True,
            f"needs mobility.model = 'static' (the controller moves the robots), not {config.mobility.model!r}",
        )
    if config.world.torus:
        raise ConfigError("coverage.enabled", True, "is for a bounded area; set world.torus = false")
    if config.events.runtime_links == "off":
        raise ConfigError(
            "events.runtime_links",
            "off",
            "coverage needs the links as the channel makes them during the run: set it to 'auto' or 'on'",
        )
    if not config.protocol.plugin.forms_groups:
        raise ConfigError(
            "coverage.enabled",
            True,
            f"needs a protocol that forms groups (protocol.model = 'clustering'), not {config.protocol.model!r}",
        )
    smallest = min(config.ranges_m())
    if not params.margin_m < smallest:
        # Kept links stay margin_m inside the range: no link could be kept, nobody moves.
        raise ConfigError(
            "coverage.margin_m",
            params.margin_m,
            f"must be below the smallest range ({smallest:g} m): kept links stay this far inside it",
        )
    if params.start_s >= config.duration_s:
        warnings.warn(
            f"coverage.start_s = {params.start_s:g}: at or after the run's end (duration_s = "
            f"{config.duration_s:g}): no control step is made",
            ConfigWarning,
            stacklevel=2,
        )


# -- what the leaders wish ----------------------------------------------------------------


def wished_velocities(
    pos_now: np.ndarray,
    leaders: np.ndarray,
    neighbours: list[np.ndarray],
    law_name: str,
    range_m: float,
    gain: float,
    area: float | Bounds,
) -> np.ndarray:
    """``gain x (resultant + border push)`` for each leader, from the neighbour positions it
    knows (:func:`spreading_forces` over the leaders)."""
    # Every law is zero from 2 r_c on, so farther leaders need no filtering here.
    rows = [np.reshape(np.asarray(nb, dtype=float), (-1, 2)) for nb in neighbours]
    target = np.repeat(np.arange(len(leaders), dtype=np.int64), [len(r) for r in rows])
    source_xy = np.concatenate(rows) if rows else np.zeros((0, 2))
    return spreading_forces(pos_now[leaders], target, source_xy, law_name, range_m, gain, area, len(pos_now))


def true_neighbours(pos: np.ndarray, leaders: np.ndarray, range_m: float) -> list[np.ndarray]:
    """For each leader, the true positions of the other leaders within ``2 r_c``, in the
    order of the leaders (the pairs in range, :func:`netsim.topology.geometric_pairs`)."""
    lp = pos[leaders]
    a, b, _ = geometric_pairs(lp, 2 * range_m, directed=True)
    bounds = row_starts(a, len(lp)).tolist()
    return [lp[b[lo:hi]] for lo, hi in zip(bounds[:-1], bounds[1:])]


def sources_true(pos: np.ndarray, range_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Pairs ``(robot, true position of another robot within 2 r_c)``: the forces'
    sources with ``knowledge = "global"``."""
    a, b, _ = geometric_pairs(pos, 2 * range_m)
    return np.r_[a, b], pos[np.r_[b, a]]


def spreading_forces(
    pos: np.ndarray,
    target: np.ndarray,
    source_xy: np.ndarray,
    law_name: str,
    range_m: float,
    gain: float,
    area,
    n_robots: int | None = None,
) -> np.ndarray:
    """``gain x (resultant + border push)`` on every robot of ``pos`` (rows of robots without
    sources are the border push alone), from the pairs ``(target, source position)``;
    ``n_robots``: the team's size (None: the rows of ``pos``)."""
    n = len(pos)
    f = pair_resultants(n, target, pos[target], source_xy, LAWS[law_name], range_m, gain, n_robots)
    return f + border_forces(pos, area, range_m, gain)


class StepRecord(NamedTuple):
    t_s: float
    leaders: int
    moving_leaders: int
    held_leaders: int
    bridges: int
    components: int
    max_wished_speed_mps: float
    moving_robots: int
    held_robots: int


class CoverageController:
    """The coverage controller of one run: proposes, then secures, each control step.

    It works with the run's robots, channel (commands), control loop (``parts.control``)
    and the protocol's view of the groups (``parts.groups``)."""

    def __init__(self, params: CoverageParams, parts: Parts):
        if parts.control is None or parts.groups is None:
            raise ValueError("the coverage controller needs the control loop and the protocol's groups")
        self.env, self.state, self.channel = parts.env, parts.state, parts.channel
        self.loop: ControlLoop = parts.control
        self.view: GroupView = parts.groups
        if parts.links is None:
            raise ValueError("the coverage controller needs the run's link state (events.runtime_links)")
        self.cfg = params
        st = parts.state
        # The links as the channel makes them (those of links.parquet), and what keeps them up.
        self.link_state = parts.links()
        self.rules = LinkRules(parts.channel.reception, st, self.link_state, params.margin_m, params.fade_margin_db)
        self.range_m = float(np.min(st.range_m))
        # Past twice the area's diagonal a disk about a robot covers the whole area, as do
        # the polygons that measure it: the same coverage, bound and wishes, where a radius
        # near the floats' limit overflows their squares.
        self.radius_m = min(self.cfg.radius_m or self.range_m, 2.0 * self.state.bounds.diagonal)
        self.limits = StepLimits(
            self.cfg.control_period_s, self.range_m, self.cfg.margin_m, self.cfg.speed_max_mps, st.side_m, st.bounds
        )
        self.quiet_since = np.full(st.n, np.nan)
        self.all_quiet_since = math.nan
        self.settled_s = math.nan
        self.got_command = np.zeros(st.n, bool)
        self.commander = np.full(st.n, -1)
        self.steps: list[StepRecord] = []
        self._pending: StepRecord | None = None
        self.samples: list[dict] = []
        # On a map, the global plan's steps: (t_s, the robots' mean distance through free
        # space to the free space not yet covered), its expansion's own progress.
        self._mean_to_uncovered_m: deque[tuple[float, float]] = deque()
        self.duration_s = float(parts.duration_s)
        self._max_wish = 0.0
        self.sample_at_start: dict | None = None
        # On a map, walls push as the area's border does (the control loop also stops any
        # step short of a wall).
        self.occupancy = parts.occupancy
        self.obstacles = obstacle_field(parts.occupancy) if parts.occupancy is not None else None
        # Distances through the map's free space, for pushes that follow it (netsim.mobility.geodesic).
        self.grid = FreeGrid(parts.occupancy, self.limits.box) if parts.occupancy is not None else None
        # On a map coverage is of the free region the team starts in, the space it can reach
        # (docs/model.md 5.3): the covered fractions and the bound are over its area.
        self.region = None
        if parts.occupancy is not None:
            self.region = team_region(parts.occupancy, self.limits.box, st.positions_at(parts.env.now))
        # The local plan: what each robot heard (netsim.mobility.local), the distance within which
        # a link is up whatever the shadowing, and the walls it must keep clear of.
        self.memory = Memory(st.n) if params.plan is PlanScope.LOCAL else None
        # What the Acks carry of their senders' memories: a list per control step, as many
        # as an Ack still remembered can date from.
        depth = lists_depth(params.release_s, parts.duration_s, params.control_period_s)
        if params.plan is PlanScope.LOCAL:
            # Of the machine that runs it, when it is built: a run's config.toml stays readable
            # on a smaller one.
            need, have = lists_bytes(st.n, depth), machine_memory_bytes()
            if have is not None and need > have:
                raise ConfigError(
                    "coverage.release_s",
                    params.release_s,
                    f"the local plan would hold {gib(need)} GiB of the lists the Acks carry (one per control "
                    f"step an Ack it remembers can date from, n_robots^2 entries each), more than this "
                    f"machine's {gib(have)} GiB of memory; lower it, or duration_s, or world.n_robots",
                )
        self.lists = Lists(st.n, depth)
        self.heard: Heard | None = None  # what each robot holds as of the step being planned
        self.local_limits = replace(self.limits, range_m=self._sure_range_m())
        # Under shadowing in open space the local plan keeps links by the shadowing each
        # robot measured on them (netsim.mobility.local.Fade), every robot at its speed cap.
        self.fade = self._local_fade() if self.memory is not None else None
        if self.fade is not None:
            speed = min(self.limits.speed_max_mps, self.fade.speed_mps)
            self.local_limits = replace(self.local_limits, speed_max_mps=speed)
        on_map = self.memory is not None and self.rules.walls is not None and parts.occupancy is not None
        self.local_walls = walls_of(
            parts.occupancy.occupied if on_map else None,
            *(() if parts.occupancy is None else (parts.occupancy.origin_m, parts.occupancy.resolution_m)),
            through_m=self._through_walls_m() if on_map else (),
        )
        # On a channel that loses no frame a missed Ack means the link was down: a robot lets
        # go of a robot it has not heard for longer than the largest gap between two Acks
        # (netsim.mobility.local.Silence). Under loss it keeps it for release_s.
        acks, ch = parts.acks, parts.channel
        self.silence = None
        if self.memory is not None and acks is not None and acks.lossless:
            self.silence = silence_of(acks.period_s, acks.jitter_s, ch.latency_s, ch.latency_jitter_s)
        self.silent: np.ndarray | None = None  # the robots each robot let go of as silent at the latest step
        self.knows: Memory | None = None  # the memory as of the step being planned
        self.halves = None  # the links each robot answered for by its half at the latest step
        self.kept: np.ndarray | None = None  # the links each robot kept at the latest step
        # How much earlier than its latest possible sending time an Ack may have left.
        self.jitter_s = float(parts.channel.latency_jitter_s)
        self.announced_mps = np.zeros((st.n, 2))
        self.announced_s = math.inf
        self.earlier_mps = np.zeros((st.n, 2))
        self.earlier_s = math.inf
        # The local plan's expansion (rule 6): each robot's estimate of its team's centre (m)
        # announced at the last two steps, with when (none before the first); on a map,
        # the cells each robot knows its team has covered.
        self.centre_announced = (np.zeros((st.n, 2)), math.inf)
        self.centre_earlier = (np.zeros((st.n, 2)), math.inf)
        self.explored = Explored(self.grid, st.n) if self.memory is not None and self.grid is not None else None
        # Rule 7 on a map: the order of the robots' turns at each step, drawn alike by all.
        self.turns = parts.streams.get("coverage.turns") if on_map else None

    def _sure_range_m(self) -> float:
        """The local plan's range: a link clear of walls is up at every transmission while
        its robots are this close (the range; under log-distance the implied range, and
        with shadowing the distance at which even the clipped worst, ``+4 sigma``, leaves
        it up)."""
        if self.rules.log is None:
            return self.range_m
        return float(self._sure_ranges_m(np.zeros(1, dtype=np.int64))[0])

    def _through_walls_m(self) -> np.ndarray:
        """The local plan's range through 1, 2, ... walls (:attr:`netsim.mobility.local.Walls.through_m`):
        under log-distance with ``wall_loss_db`` per wall, the sure range of a link that
        crosses that many, as long as it leaves more than the margin; none where a wall cuts
        every link (the unit disk)."""
        rules = self.rules
        if rules.log is None or not rules.wall_loss_db < math.inf:
            return np.empty(0)
        most = int(np.floor(rules.log.budget_db / rules.wall_loss_db)) if rules.wall_loss_db > 0 else 0
        r = self._sure_ranges_m(np.arange(1, most + 1))
        return np.ascontiguousarray(r[: int(np.sum(r > self.cfg.margin_m))])

    def _sure_ranges_m(self, walls: np.ndarray) -> np.ndarray:
        """Under log-distance, the distance within which a link crossing ``walls`` walls is up
        whatever the shadowing (its clipped worst), at most the range."""
        rules = self.rules
        worst = rules.shadow.clip_db if rules.shadow is not None else 0.0
        return np.minimum(self.range_m, rules.log.effective_range_m(worst, walls, self.state.n))

    def _local_fade(self) -> Fade | None:
        """The local plan's fade-margin rule: under shadowing (log-distance, sigma > 0) in
        open space with a budget that allows some travel; else None (the sure distance)."""
        rules = self.rules
        if rules.log is None or rules.shadow is None or rules.walls is not None or not self.cfg.fade_margin_db > 0:
            return None
        sh = rules.shadow
        return Fade(
            rules.log,
            sh.sigma_db,
            sh.decorrelation_m,
            self.cfg.fade_margin_db,
            self.local_limits.range_m,
            self.cfg.margin_m,
            self.cfg.control_period_s,
            self.state.n,
            self.cfg.detour_sigmas,
        )

    def _wall_push(self, pos: np.ndarray) -> np.ndarray:
        """``gain (m - d)`` away from the nearest wall within ``m = sqrt(3) r_c / 2``, as the border."""
        if self.occupancy is None or len(pos) == 0:
            return np.zeros((len(pos), 2))
        margin = SQRT3 * self.range_m / 2
        return wall_forces(self.occupancy, self.obstacles, pos, margin, self.cfg.gain)

    def _in_sight(self, pos: np.ndarray, target: np.ndarray, source_xy: np.ndarray):
        """On a map, the force pairs whose straight segment is free (netsim.mobility.geodesic.in_sight)."""
        if self.occupancy is None:
            return target, source_xy
        ok = in_sight(self.occupancy, pos[target], source_xy)
        return target[ok], source_xy[ok]

    def _slide(self, pos: np.ndarray, wished: np.ndarray) -> np.ndarray:
        """On a map, wishes that run into a wall slide along it (netsim.mobility.geodesic.slide)."""
        if self.occupancy is None:
            return wished
        return slide(self.occupancy, pos, wished, self.limits.period_s, self.limits.reach_m)

    # -- the two stages of a step --------------------------------------------------
    def propose(self, step: ControlStep) -> None:
        """Order 0: the wished velocities from the forces the leaders know of."""
        if self.cfg.members is Members.FOLLOW:
            self._propose_follow(step)
        else:
            self._propose_spread(step)

    def _propose_follow(self, step: ControlStep) -> None:
        now = self.env.now
        leaders = np.flatnonzero(leads_itself(step.leader))
        pos_now = self.state.positions_at(now)
        if self.cfg.knowledge is Knowledge.GLOBAL:
            neighbours = true_neighbours(pos_now, leaders, self.range_m) if len(leaders) else []
        else:
            neighbours = [self.view.heard_leaders(i, now)[1] for i in leaders.tolist()]
        wished = wished_velocities(
            pos_now, leaders, neighbours, self.cfg.law, self.range_m, self.cfg.gain, self.limits.box
        )
        wished += self._wall_push(pos_now[leaders])
        speed = speeds_mps(wished) if len(leaders) else np.zeros(0)
        quiet = speed < self.cfg.stop_speed_mps
        wished[quiet] = 0.0
        step.velocity_mps[:] = 0.0
        step.velocity_mps[leaders] = wished
        qs = self.quiet_since[leaders]
        self.quiet_since[:] = np.nan
        self.quiet_since[leaders] = np.where(quiet, np.where(np.isnan(qs), now, qs), np.nan)
        if len(leaders) and quiet.all() and now - np.nanmax(self.quiet_since[leaders]) >= self.cfg.hold_s:
            self.settled_s = now
            self.loop.stop()
        self._max_wish = float(speed.max()) if len(speed) else 0.0

    def _propose_spread(self, step: ControlStep) -> None:
        if self.memory is not None:
            self._propose_local(step)
            return
        now = self.env.now
        c = self.cfg
        pos_now = self.state.positions_at(now)
        # The leader whose decisions each robot carries out (-1: none).
        group = step.leader
        if c.expansion > 0 and self.grid is not None:
            # On a map the expansion alone moves the team (docs/model.md 5.3): the pushes
            # of the robots in sight, summed over a room's crowd, press it into the room's
            # corners, and the walls' push, felt everywhere in an office and turning about
            # at every corridor's and door's middle, throws robots from side to side of a
            # door instead of through it.
            wished, to_uncovered_m = expansion_to_uncovered(self.grid, pos_now, self.radius_m, self.range_m, c.gain)
            self._expansion_progress(to_uncovered_m)
        else:
            wished = self._pushes(pos_now)
            if c.expansion > 0:
                a, b = self.link_state.up_pairs()
                component = metrics.components_of_links(self.state.n, a, b)
                centre = component_centres(pos_now, component)
                wished += expansion_forces(pos_now, centre, c.expansion, self.range_m, c.gain)
        wished = self._slide(pos_now, wished)
        wished[group < 0] = 0.0
        speed = speeds_mps(wished)
        wished[speed < c.stop_speed_mps] = 0.0
        step.velocity_mps[:] = wished
        self._max_wish = float(speed[group >= 0].max()) if (group >= 0).any() else 0.0

    def _expansion_progress(self, to_uncovered_m: np.ndarray) -> None:
        """Keep the robots' mean distance to the free space their expansion seeks, over the
        stopping rule's window (:meth:`_nearing_uncovered`)."""
        reached = to_uncovered_m[np.isfinite(to_uncovered_m)]
        if len(reached):
            now, steps = self.env.now, self._mean_to_uncovered_m
            steps.append((now, float(reached.mean())))
            while steps[0][0] < now - self.cfg.hold_s - 1e-9:
                steps.popleft()  # before every stopping window still to come

    def _pushes(self, pos_now: np.ndarray) -> np.ndarray:
        """The global plan's pushes: of the robots each knows of (in sight, on a map) and
        of the walls."""
        c, now = self.cfg, self.env.now
        if c.knowledge is Knowledge.GLOBAL:
            target, source_xy = sources_true(pos_now, self.range_m)
        else:
            target, _, source_xy = self.view.neighbourhood(now)
        target, source_xy = self._in_sight(pos_now, target, source_xy)
        wished = spreading_forces(pos_now, target, source_xy, c.law, self.range_m, c.gain, self.limits.box)
        return wished + self._wall_push(pos_now)

    def _propose_local(self, step: ControlStep) -> None:
        """Every robot's wish from its own position and the positions it heard."""
        c, memory, st = self.cfg, self.memory, self.state
        assert memory is not None
        robot, other, xy, heard_s, power_dbm = self.view.heard_acks(self.env.now)
        speed = self.local_limits.speed_max_mps
        x_db = margin_db = None
        if self.fade is not None:
            # Each robot's own measurement: the power it received each Ack at.
            own = st.positions_at(self.env.now)[robot]
            x_db, margin_db = self.fade.measure(own, xy, power_dbm, heard_s - self.loop.lead_s, self.env.now, speed)
        memory.hear(robot, other, xy, heard_s, self.loop.lead_s, st.velocity_mps, st.t0_s, step.t_s, x_db, margin_db)
        self.knows = memory.at(step.t_s, speed, self.jitter_s)
        pos = step.positions_m
        known = memory.known(self.env.now, c.release_s)
        self.heard = self.lists.heard(known, memory.sent_s, c.release_s)
        self.lists.take(memory, self.env.now, c.release_s)
        if self.explored is not None and c.expansion > 0:
            # On a map the expansion alone moves the team, as in the global plan, toward
            # the free space each robot knows its team has not covered (rule 6).
            cells = self.explored.step(pos, self.radius_m, known, memory.sent_s, self.env.now)
            wished, to_unexplored_m = expansion_to_unexplored(self.grid, pos, cells, self.range_m, c.gain)
            if self.env.now > c.start_s:
                # At the first step each robot knows only the cells it explored itself: the
                # distance to unexplored space then rises as Acks tell of the team's, which
                # the stopping rule would read as a team coming no nearer.
                self._expansion_progress(to_unexplored_m)
        else:
            target, source_xy = sources_heard(self.knows, self.heard, step.t_s, 2 * self.range_m, pos)
            target, source_xy = self._in_sight(pos, target, source_xy)
            wished = spreading_forces(pos, target, source_xy, c.law, self.range_m, c.gain, self.limits.box)
            wished += self._wall_push(pos)
            if c.expansion > 0:
                centre = self._centre_estimates(pos, known)
                wished += expansion_forces(pos, centre, c.expansion, self.range_m, c.gain)
        wished = self._slide(pos, wished)
        speed = speeds_mps(wished)
        wished[speed < c.stop_speed_mps] = 0.0
        step.velocity_mps[:] = wished
        self._max_wish = float(speed.max(initial=0.0))

    @property
    def centre_m(self) -> np.ndarray | None:
        """Each robot's estimate of its team's centre at the latest step (rule 6; None
        before the first)."""
        centre, at_s = self.centre_announced
        return None if math.isinf(at_s) else centre

    def _centre_estimates(self, pos: np.ndarray, known: np.ndarray) -> np.ndarray:
        """Rule 6's centres at this step, each robot's from its own and those the robots it
        remembers (``known``) announced; the Acks sent from now on carry them."""
        memory = self.memory
        assert memory is not None
        own = pos if self.centre_m is None else self.centre_m
        centre = centre_estimates(own, known, memory.sent_s, self.centre_announced, self.centre_earlier)
        self.centre_earlier, self.centre_announced = self.centre_announced, (centre, self.env.now)
        return centre

    def _plan_local(self, step: ControlStep) -> Plan:
        """Each robot keeps what it cannot let go of and answers for those links itself."""
        memory, knows, heard, c = self.memory, self.knows, self.heard, self.cfg
        assert memory is not None and knows is not None and heard is not None
        limits, walls, pos = self.local_limits, self.local_walls, step.positions_m
        t0, t1, speed = step.t_s, step.t_s + limits.period_s, limits.speed_max_mps
        fade = self.fade
        if fade is not None:
            knows.keep_m, travel = fade.limits(knows, t0, t1, speed)
        # A robot lets go of a silent robot: their link was down in the window.
        quiet = silent(memory, self.env.now, self.loop.lead_s, self.silence)
        window = 0.0 if self.silence is None else self.silence.window_s
        gone = let_go(pos, knows, heard, t0, speed, c.band_m, limits.range_m, walls, fade, window, quiet)
        kept = heard.known & ~quiet & ~gone
        self.kept, self.silent = kept, quiet
        announced, earlier = (self.announced_mps, self.announced_s), (self.earlier_mps, self.earlier_s)
        wish = step.velocity_mps + latest_pulls(pos, knows, kept, announced, earlier, step.t_s, limits, memory.sent_s)
        # What each robot's next Acks announce (netsim.mobility.local, rule 4).
        self.earlier_mps, self.earlier_s = self.announced_mps, self.announced_s
        # On a map a robot announces the step it can make (capped at its reach, ended short
        # of the walls): a wish into a wall would pull every robot keeping it there too.
        if walls.on:
            announced = within_reach(self.occupancy, pos, wish, limits.period_s, limits.reach_m)
        else:
            announced = wish
        self.announced_mps, self.announced_s = announced, self.env.now
        reach, halves = None, None
        if fade is not None:
            # Rule 2 by halves: the links a robot cannot answer for alone (rule 3).
            halves = fade.halves(knows, heard, pos, t0, speed)
            used = answered_by_halves(pos, knows, kept, t0, limits, halves)
            halves = halves._replace(usable=used)
            travel = np.where(used, halves.travel_m, travel)
            reach = fade.reach(travel, kept)
        self.halves = halves
        if not walls.on:
            return plan_local(pos, wish, knows, kept, step.t_s, limits, reach, halves)
        # Rule 7: a robot moves only in its turn, so the robots it keeps hold while it moves.
        assert self.turns is not None
        turn = turn_takers(kept, self.turns.permutation(len(pos)))
        plan = plan_local(pos, wish * turn[:, None], knows, kept, t0, limits, reach, halves)
        # Rule 5: the step ends short of the walls (as the control loop would make it), then
        # keeps every kept link clear of them.
        move = short_of_walls(self.occupancy, pos, plan.velocity_mps * limits.period_s, 1.0)
        planned = move.copy()
        move = cut_for_walls(pos, move, knows, kept, t1, limits, walls, self.occupancy)
        held = plan.held | fell_short(planned, move, limits.range_m)
        return plan._replace(velocity_mps=move / limits.period_s, held=held)

    def secure(self, step: ControlStep) -> None:
        """Order 100: make the plan keep the network connected; leaders send their commands."""
        if self.cfg.members is Members.FOLLOW:
            plan = plan_follow(step.positions_m, step.leader, step.velocity_mps, self.limits)
        elif self.memory is not None:
            plan = self._plan_local(step)
        else:
            plan = self._plan_spread(step)
        step.velocity_mps[:] = plan.velocity_mps
        self.commander = plan.commander
        self.got_command[:] = False
        for leader in np.unique(plan.commander[plan.commander >= 0]).tolist():
            self.channel.broadcast(leader, step.t_s, self._deliver, kind="command")
        self._pending = self._record(step, plan)
        if self.cfg.members is Members.SPREAD:
            self._stopping_rule(plan)

    def _plan_spread(self, step: ControlStep) -> Plan:
        """Leaders move; a member moves if it can hear its leader's command now."""
        leader = step.leader
        pos_now = self.state.positions_at(self.env.now)
        is_leader = leads_itself(leader)
        member = in_a_group(leader)
        lead = np.where(member, leader, 0)
        st = self.state  # never a torus (coverage refuses one)
        reach = load("netsim._kernels", st.n).in_range(pos_now, np.arange(st.n), lead, st.range_m[lead], 0.0)
        commandable = member & is_leader[lead] & reach
        mobile = is_leader | commandable
        commander_of = np.where(commandable, leader, -1)
        pos = step.positions_m
        links = self.rules.candidates(pos, step.t_s)
        if self.rules.walls is not None and self.occupancy is not None:
            links = self._prefer_lasting(pos, np.where(mobile[:, None], step.velocity_mps, 0.0), links)
        plan = plan_spread(pos, mobile, commander_of, step.velocity_mps, self.limits, links)
        if self.rules.walls is None or plan.kept is None:
            return plan
        return self._cut_for_walls(pos, plan, commander_of >= 0, links)

    def _prefer_lasting(self, pos: np.ndarray, wish_mps: np.ndarray, links):
        """On a map: the forest prefers the links that stay up over the wished step (each
        wish capped at the reach and ended short of the walls), so that the links it keeps
        are the ones that let the robots move (netsim.mobility.keep.prefer)."""
        period = self.limits.period_s
        move = cap_length(wish_mps * period, self.limits.reach_m)
        if not (move != 0).any() or len(links.i) == 0:
            return links
        short_of_walls(self.occupancy, pos, move, 1.0)
        return prefer(links, self.rules.lasting(pos, move / period, links, period))

    def _cut_for_walls(self, pos: np.ndarray, plan: Plan, commanded: np.ndarray, links) -> Plan:
        """On a map: each step ends short of the walls (as the control loop would make it),
        then is cut before the first instant a kept link would be lost (netsim.mobility.keep)."""
        move = plan.velocity_mps * self.limits.period_s
        moving = np.flatnonzero(in_motion(move))
        if len(moving) == 0:
            return plan
        # A planned step that runs into a wall slides along it instead: the exact cut below
        # keeps every kept link up whatever the step.
        move = slide(self.occupancy, pos, move, 1.0, math.inf)
        f = free_fraction(self.occupancy, pos[moving], pos[moving] + move[moving])
        move[moving] *= f[:, None]
        scale = self.rules.cut_for_walls(pos, move, commanded, links, plan.kept, self.limits.period_s)
        move *= scale[:, None]
        velocity = move / self.limits.period_s
        held = plan.held | (in_motion(plan.velocity_mps) & (scale < 1))
        commander = np.where(in_motion(velocity), plan.commander, -1)
        return plan._replace(velocity_mps=velocity, commander=commander, held=held)

    def _stopping_rule(self, plan: Plan) -> None:
        """Control ends once no robot has moved faster than ``stop_speed_mps`` for ``stop_hold_s``."""
        now = self.env.now
        if speeds_mps(plan.velocity_mps).max(initial=0.0) >= self.cfg.stop_speed_mps:
            self.all_quiet_since = math.nan
            return
        if math.isnan(self.all_quiet_since):
            self.all_quiet_since = now
        if now - self.all_quiet_since >= self.cfg.hold_s:
            self.settled_s = now
            self.loop.stop()

    def _record(self, step: ControlStep, plan: Plan) -> StepRecord:
        """The step's row, its components counted when the step takes effect (:meth:`obey`)."""
        leaders = leads_itself(step.leader)
        moving = speeds_mps(plan.velocity_mps) > 0
        return StepRecord(
            step.t_s,
            int(leaders.sum()),
            int(moving[leaders].sum()),
            int(plan.held[leaders].sum()),
            plan.bridges,
            0,
            self._max_wish,
            int(moving.sum()),
            int(plan.held.sum()),
        )

    def _at_end_of_instant(self, fn) -> None:
        """Call ``fn`` after everything else due now (every transmission and link event of
        this instant: the links then are those links.parquet has at this instant)."""
        scheduled_event(self.env, 0.0, LAST, lambda _event: fn())

    def _count_step(self, row: int) -> None:
        self.steps[row] = self.steps[row]._replace(components=self.components_now())

    def _count_sample(self, sample: dict) -> None:
        components = self.components_now()
        sample["components"] = components
        sample["connected"] = components == 1

    def components_now(self) -> int:
        """Connected components of the network of the links up now, as the channel makes
        them (the links of links.parquet)."""
        a, b = self.link_state.up_pairs()
        return metrics.component_count(self.state.n, a, b)

    def _deliver(self, sender: int, receivers: np.ndarray, _payload) -> None:
        self.got_command[receivers[self.commander[receivers] == sender]] = True

    def obey(self, step: ControlStep) -> None:
        """At the step's start: a robot that did not hear its leader's command holds."""
        if self._pending is not None:
            self.steps.append(self._pending)
            self._pending = None
            row = len(self.steps) - 1
            self._at_end_of_instant(lambda: self._count_step(row))
        missed = (self.commander >= 0) & ~self.got_command
        step.velocity_mps[missed] = 0.0

    # -- metrics over time -----------------------------------------------------------

    def _covered(self, centres: np.ndarray) -> tuple[float, float]:
        box, region = self.limits.box, self.region
        if self.cfg.area_method is AreaMethod.GRID:
            return metrics.covered_fraction(
                centres, self.radius_m, box, self.cfg.grid_cells, region=region, n_robots=self.state.n
            )
        return metrics.covered_fraction_exact(centres, self.radius_m, box, region=region)

    def sample(self, t: float) -> dict:
        st = self.state
        pos = st.positions_at(t)
        leaders = pos[leads_itself(self.view.leader)]
        cov_l, err_l = self._covered(leaders)
        cov_a, err_a = self._covered(pos)
        free_m2 = None if self.region is None else float(self.region.area)
        bound = metrics.bound_fraction(st.n, self.radius_m, st.bounds, st.range_m, free_m2)
        components = self.components_now()
        spacing = metrics.nearest_spacing(leaders)
        travelled = st.travelled_m(t, slice(None))
        return {
            "t_s": t,
            "leaders": len(leaders),
            "covered_fraction_leaders": cov_l,
            "covered_fraction_all": cov_a,
            "covered_error_bound_leaders": err_l,
            "covered_error_bound_all": err_a,
            "coverage_bound": bound,
            "covered_of_bound_all": cov_a / bound if bound > 0 else math.nan,
            "components": components,
            "connected": components == 1,
            "spacing_median_ratio": float(np.median(spacing) / (SQRT3 * self.range_m))
            if len(leaders) > 1
            else math.nan,
            "hexagonality": metrics.hexagonality(leaders, SQRT3 * self.range_m),
            "distance_mean_m": float(travelled.mean()) if len(travelled) else 0.0,
        }

    def sampler(self):
        env = self.env
        while True:
            sample = self.sample(env.now)
            self.samples.append(sample)
            self._at_end_of_instant(lambda sample=sample: self._count_sample(sample))
            if self.cfg.members is Members.SPREAD:
                self._coverage_stopping_rule()
            yield env.timeout(self.cfg.metrics_interval_s)

    def _coverage_stopping_rule(self) -> None:
        """Spread: control ends once the covered fraction of ``min(1, U(N) / A)`` has not
        risen ``stop_gain`` above its value ``stop_hold_s`` ago (the team stopped spreading),
        nor, on a map, the robots come nearer the free space their expansion seeks
        (:meth:`_nearing_uncovered`)."""
        c, now = self.cfg, self.env.now
        loop = self.loop
        if loop.stopped or c.stop_gain <= 0 or now < c.start_s + c.hold_s - 1e-9:
            return
        window = [s["covered_of_bound_all"] for s in self.samples if s["t_s"] >= now - c.hold_s - 1e-9]
        if len(window) > 1 and max(window[1:]) - window[0] < c.stop_gain and not self._nearing_uncovered():
            self.settled_s = now
            loop.stop()

    def _nearing_uncovered(self) -> bool:
        """Whether the robots' mean distance through free space to the free space their
        expansion seeks (not yet covered; with the local plan, not known to be explored: what
        the expansion on a map descends) fell by more than ``stop_speed_mps x stop_hold_s``
        within the stopping rule's window: robots that file through a door toward it raise
        the coverage only once they are through."""
        c, now = self.cfg, self.env.now
        window = [d for t, d in self._mean_to_uncovered_m if t >= now - c.hold_s - 1e-9]
        return len(window) > 1 and window[0] - min(window[1:]) > c.stop_speed_mps * c.hold_s

    # -- outputs -----------------------------------------------------------------------
    def coverage_frame(self) -> pd.DataFrame:
        # The last sample at the run's end T, once the run has reached it: the sampler's
        # next event is due at T or after, and never processed (events due exactly at the
        # end are not). Asked for before the end, the table ends at now the same way, by a
        # sample handed out but not kept: the run goes on recording what it would have.
        end, now = self.duration_s, float(self.env.now)
        times = [s["t_s"] for s in self.samples[-1:]]
        if now >= end and not ended_at(times, end):
            self.samples.append(self.sample(end))
        if now < end and not ended_at(times, now):
            return pd.DataFrame([*self.samples, self.sample(now)])
        return pd.DataFrame(self.samples)

    def travel_frame(self) -> pd.DataFrame:
        """Distance each robot travelled over the run (the energy it spent moving)."""
        st = self.state
        return pd.DataFrame({"robot": np.arange(st.n), "distance_m": st.travelled_m(self.env.now, slice(None))})

    def control_frame(self) -> pd.DataFrame:
        return pd.DataFrame(self.steps, columns=list(StepRecord._fields))

    def summary(self, frames: Mapping[str, pd.DataFrame], duration_s: float) -> dict:
        last = self.sample(duration_s)
        steps = self.control_frame()
        start = self.sample_at_start
        travel = frames["travel"]["distance_m"] if "travel" in frames else pd.Series(dtype=float)
        return {
            "coverage_law": str(self.cfg.law),
            "coverage_knowledge": str(self.cfg.knowledge),
            "coverage_members": str(self.cfg.members),
            "leaders_final": last["leaders"],
            "covered_fraction_leaders_start": start["covered_fraction_leaders"] if start else math.nan,
            "covered_fraction_leaders_final": last["covered_fraction_leaders"],
            "covered_fraction_all_start": start["covered_fraction_all"] if start else math.nan,
            "covered_fraction_all_final": last["covered_fraction_all"],
            "covered_error_bound_all": last["covered_error_bound_all"],
            "coverage_bound": last["coverage_bound"],
            "covered_of_bound_all_start": start["covered_of_bound_all"] if start else math.nan,
            "covered_of_bound_all_final": last["covered_of_bound_all"],
            "components_start": start["components"] if start else math.nan,
            "components_final": last["components"],
            "components_max_during_control": int(steps["components"].max()) if len(steps) else math.nan,
            "connected_final": last["connected"],
            "spacing_median_ratio_final": last["spacing_median_ratio"],
            "hexagonality_final": last["hexagonality"],
            "distance_mean_m": float(travel.mean()) if len(travel) else last["distance_mean_m"],
            "distance_max_m": float(travel.max()) if len(travel) else math.nan,
            "control_steps": len(steps),
            "control_settled_s": self.settled_s,
        }

    def _mark_start(self):
        yield self.env.timeout(self.cfg.start_s)
        self.sample_at_start = start = self.sample(self.env.now)
        self._at_end_of_instant(lambda: self._count_sample(start))


def build(params: CoverageParams, parts: Parts) -> CoverageController:
    """The controller, in the control loop: it proposes first (order 0) and secures the
    plan last (order 100), user controllers run in between."""
    ctl = CoverageController(params, parts)
    ctl.loop.add(ctl.propose, order=0)
    ctl.loop.add(ctl.secure, order=100)
    ctl.loop.before_apply.append(ctl.obey)
    parts.env.process(ctl.sampler())
    parts.env.process(ctl._mark_start())
    parts.trace.add_frame("coverage", ctl.coverage_frame)
    parts.trace.add_frame("control", ctl.control_frame)
    parts.trace.add_frame("travel", ctl.travel_frame)
    return ctl


COVERAGE_SCHEMA = {
    "t_s": "float64",
    "leaders": "int64",
    "covered_fraction_leaders": "float64",
    "covered_fraction_all": "float64",
    "covered_error_bound_leaders": "float64",
    "covered_error_bound_all": "float64",
    "coverage_bound": "float64",
    "covered_of_bound_all": "float64",
    "components": "int64",
    "connected": "bool",
    "spacing_median_ratio": "float64",
    "hexagonality": "float64",
    "distance_mean_m": "float64",
}
CONTROL_SCHEMA = {
    name: ("float64" if name in ("t_s", "max_wished_speed_mps") else "int64") for name in StepRecord._fields
}

PLUGIN = PluginSpec(
    Params=CoverageParams,
    build=build,
    check=check,
    tables={
        "coverage": COVERAGE_SCHEMA,
        "control": CONTROL_SCHEMA,
        "travel": {"robot": "int64", "distance_m": "float64"},
    },
    timing=lambda params: (params.control_period_s, params.start_s),
)
