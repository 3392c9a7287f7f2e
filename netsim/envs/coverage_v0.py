"""Connected coverage as a multi-agent environment (PettingZoo's parallel API; docs/cosim.md).

``parallel_env(n_robots=20, ...)`` returns a :class:`CoverageEnv`. Each robot is an agent
(``robot_0``, ...); a step is one control period (``step_s``): every agent's action is the
velocity it holds over the period, and the network runs meanwhile (Acks, clustering, exact
links), its robots moving as told (``mobility.model = "external"``: they stop on the
border). Agents observe what they know (their own state and their neighbours as the Acks
told them), never the true positions of the others; the team is rewarded for the covered
fraction it gains, and penalised for every component of the true network beyond one.

Everything is measured on the network and area the run really has, the keywords' values
or what ``netsim`` sets instead (``world.side_m``, ``world.bounds_m``, ``channel.*``,
``protocol.tau_s``, ...): an override the environment cannot honour is refused when it
is made (:func:`refused`).

Observation of an agent (float32, ``4 + R + 4K`` values, R roles, K = ``max_neighbours``):
its position ``x, y`` (m), its velocity ``vx, vy`` (m/s; 0 once stopped on the border), its
role one-hot (``role_names``), then up to K neighbours of its table, nearest first by
the positions their Acks told: ``dx, dy`` (m, told position minus own position), the age
of that Ack (s) and 1 (present); missing neighbours are all zeros. With ``link_quality``
(a log-distance radio), ``3K`` more: up to K live entries, strongest first by the power it
got their last Acks at: that power (dBm), the Ack's age (s) and 1; a missing one is the
radio's sensitivity (the floor: nothing heard), 0 and 0. Its
bounds are the run's: the area, the speed bound, the protocol's ``tau``, the radio's
sensitivity and strongest possible power (:func:`power_bounds_dbm`).

Reward (the same for every agent): ``C(t) - C(t - step) - component_penalty x
(components(t) - 1)``, ``C`` the fraction of the run's area within ``radius_m`` (0: the
run's smallest range, as the coverage table) of some robot, on a grid of ``grid_cells^2``
cell centres; ``components`` those of the links the channel makes (those of
``links.parquet``, as the coverage table counts them).
"""

from __future__ import annotations

import dataclasses
import numbers
import warnings
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, cast

import numpy as np

from netsim.errors import needs_extra  # before the extra's imports, whose absence it words

try:
    from gymnasium import spaces
    from pettingzoo import ParallelEnv
    from pettingzoo.utils.conversions import parallel_to_aec_wrapper
    from pettingzoo.utils.wrappers import OrderEnforcingWrapper
except ModuleNotFoundError as missing:  # the optional extra `rl` (pyproject.toml): say how to get it
    raise ModuleNotFoundError(needs_extra("netsim.envs", [str(missing.name)], "rl"), name=missing.name) from None

from netsim import config as cfgmod
from netsim import metrics
from netsim.area import Bounds
from netsim.compiled import load
from netsim.cosim import CommandError, LinkQualityView, as_numbers
from netsim.envs.drawing import Window, frame, no_window_said, shows_windows
from netsim.errors import ConfigError
from netsim.params import Params, finite, non_negative, param, positive
from netsim.placement import check_placement
from netsim.radio.propagation import TRUNCATION_SIGMAS, LogDistanceParams
from netsim.run import build
from netsim.sim import Simulation
from netsim.topology import geometric_pairs

FIELDS_PER_NEIGHBOUR = 4  # dx, dy, age, present
FIELDS_PER_LINK = 3  # rx_power_dbm, age, present (link_quality)
RENDER_MODES = ("human", "rgb_array")  # a window; frames returned


@dataclass(frozen=True)
class CoverageEnvParams(Params):
    """The environment's parameters (the keywords of :func:`parallel_env`)."""

    section = "coverage_v0"
    n_robots: int = param(20, positive, "number of robots (agents)")
    side_m: float = param(400.0, finite(positive), "side of the square area, m")
    range_m: float = param(50.0, finite(positive), "communication range (unit disk), m")
    radius_m: float = param(0.0, finite(non_negative), "radius of the coverage disks, m (0: the run's smallest range)")
    placement: str = param("centre", None, "world.placement of the robots at reset")
    centre_side_m: float = param(100.0, finite(positive), 'placement = "centre": side of the central square, m')
    speed_max_mps: float = param(2.0, finite(positive), "bound of each velocity component of an action, m/s")
    step_s: float = param(1.0, finite(positive), "one step: the control period, s")
    ack_period_s: float = param(1.0, finite(positive), "Ack period, s")
    max_neighbours: int = param(6, non_negative, "neighbours K in an observation")
    link_quality: bool = param(
        False, None, "append the K strongest live neighbours' received power and age (a log-distance radio)"
    )
    max_cycles: int = param(200, positive, "steps before the episode is truncated")
    component_penalty: float = param(0.01, finite(non_negative), "reward lost per component beyond one")
    grid_cells: int = param(100, metrics.grid_side, "the covered fraction's grid: cells per side, at most 4,000")
    seed: int = param(0, non_negative, "seed of the first episode when reset() is given none")


class CoverageEnv(ParallelEnv):
    """The environment (module notes). ``sim`` is the current episode's
    :class:`~netsim.sim.Simulation`, to read anything else the network did; ``netsim``
    adds keys to its configuration (``{"channel": {"loss_model": ...}}``)."""

    metadata: dict[str, Any] = {"name": "coverage_v0", "render_modes": list(RENDER_MODES), "is_parallelizable": True}

    def __init__(self, params: CoverageEnvParams, netsim: Mapping | None = None, render_mode: str | None = None):
        if render_mode not in (None, *RENDER_MODES):
            raise ConfigError("render_mode", render_mode, "must be None, 'human' or 'rgb_array'")
        self.params = p = params
        self.render_mode = render_mode
        # A window shows the team in real time, a step per step_s (as Gymnasium's physics
        # environments do); set env.metadata["render_fps"] to watch faster or slower.
        self.metadata = {**CoverageEnv.metadata, "render_fps": 1.0 / p.step_s}
        self._window: Window | None = None  # render_mode = "human": opened at the first frame
        if netsim is not None and not isinstance(netsim, Mapping):
            raise ConfigError("netsim", netsim, "must be a table of configuration keys (a dict)")
        if netsim is not None and "seed" in netsim:
            # The episodes' seeds are the environment's: reset(seed=...) would not hold.
            raise ConfigError("seed", netsim["seed"], "the environment's: give it as seed= or reset(seed=...)")
        self.netsim = dict(netsim or {})
        self.possible_agents = [f"robot_{i}" for i in range(p.n_robots)]
        self.agents: list[str] = []
        self._live: set[str] = set()
        self._index = {a: i for i, a in enumerate(self.possible_agents)}
        self._seed = int(p.seed)
        # Steps before truncation, for the next episodes (PettingZoo's tests set it).
        self.max_cycles = p.max_cycles
        # Whether the channel's law implies the ranges: the same for every episode.
        self._ranges_implied: bool | None = None
        self._shorter_side: float | None = None
        # A bad key of ``netsim``, or one the environment cannot honour, is refused now,
        # not at the first reset.
        # What the configuration warns of (keys ignored) is said once a setting is known to
        # be good, and once for the environment's life, not again at every reset.
        self._told: set[str] = set()
        config, said = self._config_told(self._seed)
        problem = refused(config, p)
        if problem is not None:
            raise ConfigError(*problem)
        check_placement(config.world)
        self._hold_paths(config.world)
        self._tell(said)
        if self._ranges_implied and p.range_m != type(p)().range_m:
            # A range the user gave, that the radio's law overrides: said, as netsim says it of
            # channel.range_m.
            warnings.warn(
                f"range_m = {p.range_m:g}: not used by netsim's channel.propagation = "
                f"{config.channel.propagation!r} (its law implies the range); ignored",
                cfgmod.ConfigWarning,
                stacklevel=2,
            )
        # The run's area, ranges and tau, whatever set them (the keywords or ``netsim``).
        self.area: Bounds = cfgmod.world_bounds(config.world)
        self.range_m = float(min(config.ranges_m()))
        self.radius_m = p.radius_m or self.range_m
        self.tau_s = float(getattr(config.protocol.params, "tau_s", np.inf))
        self.role_names: tuple[str, ...] = ("gamma", "beta", "alpha")
        # Where the link quality starts in an observation; its power's bounds (None: off).
        self.link_quality_start = 4 + len(self.role_names) + FIELDS_PER_NEIGHBOUR * p.max_neighbours
        self.power_bounds_dbm = power_bounds_dbm(config) if p.link_quality else None
        self._obs_size = self.link_quality_start + (FIELDS_PER_LINK * p.max_neighbours if p.link_quality else 0)
        self._episode = -1
        self.sim: Simulation | None = None
        self.cycles = 0
        self.covered = 0.0
        self.components = 0
        v = np.float32(p.speed_max_mps)
        self._action_space = spaces.Box(-v, v, shape=(2,), dtype=np.float32)
        self._observation_space = observation_space(
            self.area, p.speed_max_mps, len(self.role_names), p.max_neighbours, self.tau_s, self.power_bounds_dbm
        )
        # The team's true state for a centralised critic (state()): each robot's own part of
        # its observation (position, velocity, role), robot after robot.
        own = observation_space(self.area, p.speed_max_mps, len(self.role_names), 0, self.tau_s)
        self.state_space = spaces.Box(np.tile(own.low, p.n_robots), np.tile(own.high, p.n_robots), dtype=np.float32)
        # An action may reach the bound as either precision gives it: speed_max_mps, or the
        # action space's float32 bound (rounded up or down); it is then held to the former.
        self._high = np.maximum(self._action_space.high.astype(float), p.speed_max_mps)
        # The measures' kernels, compiled or plain as the run's own loops (netsim.compiled.load).
        self._measures: Any = load("netsim.envs._kernels", p.n_robots)

    # -- spaces: one object per agent for the whole life of the environment ---------------

    def observation_space(self, agent: str) -> spaces.Box:
        return self._observation_space

    def action_space(self, agent: str) -> spaces.Box:
        return self._action_space

    # -- episodes -------------------------------------------------------------------------
    def _hold_paths(self, world: Any) -> None:
        """The files the setting names, as the configuration made them absolute: every
        episode finds them, whatever the working directory is when it starts."""
        given = dict(self.netsim.get("world", {}))
        for key in ("placement", "map"):
            if key in given:
                given[key] = getattr(world, key)
        if given:
            self.netsim["world"] = given
        if "placement" not in given:
            self.params = dataclasses.replace(self.params, placement=world.placement)

    def _shorter_side_m(self, raw: dict) -> float:
        """The shorter side of the run's area (the same for every episode)."""
        if self._shorter_side is None:
            probe = cfgmod.merge(raw, self.netsim)
            # Any placement and square will do to learn the area.
            probe["world"] = {**probe["world"], "placement": "uniform"}
            probe["world"].pop("centre_side_m", None)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", cfgmod.ConfigWarning)
                area = cfgmod.world_bounds(cfgmod.from_dict(probe).world)
            self._shorter_side = min(area.width, area.height)
        return self._shorter_side

    def _config(self, seed: int) -> cfgmod.Config:
        p = self.params
        world: dict[str, Any] = {"n_robots": p.n_robots, "side_m": p.side_m, "placement": p.placement}
        raw: dict[str, Any] = {
            "seed": seed,
            "duration_s": self.max_cycles * p.step_s,
            "world": world,
            "channel": {"range_m": p.range_m},
            "mobility": {"model": "external"},
            "protocol": {"model": "clustering", "ack_period_s": p.ack_period_s, "message_rate_hz": 0.0},
            # The protocol's tables are sampled at this interval: once an episode is enough.
            "output": {"position_interval_s": self.max_cycles * p.step_s},
        }
        # The keyword's central square, held within the run's area, whatever set it (side_m,
        # netsim's side_m or bounds_m, a map's extent); netsim's own centre_side_m wins.
        world["centre_side_m"] = min(p.centre_side_m, self._shorter_side_m(raw))
        if self._ranges_implied is None:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", cfgmod.ConfigWarning)
                channel = cfgmod.from_dict(cfgmod.merge(raw, self.netsim)).channel
            self._ranges_implied = channel.propagation_model.ranges(channel.radio) is not None
        if self._ranges_implied:
            # A model whose law implies the ranges (log-distance) takes no range_m: passing
            # the unit disk's would only warn of a key the user never set.
            raw["channel"] = {}
        return cfgmod.from_dict(cfgmod.merge(raw, self.netsim))

    def _config_told(self, seed: int) -> tuple[cfgmod.Config, list[warnings.WarningMessage]]:
        """:meth:`_config`, and the configuration's warnings it gave (keys ignored), held
        back; any other warning goes on as it came."""
        with warnings.catch_warnings(record=True) as said:
            warnings.simplefilter("always")
            config = self._config(seed)
        held = [w for w in said if issubclass(w.category, cfgmod.ConfigWarning)]
        for w in said:
            if not issubclass(w.category, cfgmod.ConfigWarning):
                warnings.warn_explicit(w.message, w.category, w.filename, w.lineno, source=w.source)
        return config, held

    def _tell(self, said: list[warnings.WarningMessage]) -> None:
        for w in said:
            if str(w.message) not in self._told:
                self._told.add(str(w.message))
                warnings.warn(w.message, w.category, stacklevel=3)

    def reset(self, seed: int | None = None, options: dict | None = None) -> tuple[dict, dict]:
        """A new episode: the run of ``(seed, episode)``, ``episode`` counting the resets
        since the last seed given (so ``reset()`` after ``reset(seed=s)`` is a new episode,
        the same on every replay)."""
        # Nothing changes until the new episode is known to be good: a refused reset leaves
        # the environment as it was.
        if seed is not None and (isinstance(seed, bool) or not isinstance(seed, (int, np.integer))):
            raise ConfigError("seed", seed, "must be a whole number >= 0")
        seed_, episode = (int(seed), 0) if seed is not None else (self._seed, self._episode + 1)
        config, said = self._config_told(seed_)
        # max_cycles may have changed since the environment was made: checked again.
        problem = refused(config, dataclasses.replace(self.params, max_cycles=self.max_cycles))
        if problem is not None:
            raise ConfigError(*problem)
        self._tell(said)
        self.sim = sim = build(config, run=episode)
        self._seed, self._episode = seed_, episode
        if sim.groups is not None:
            self.role_names = tuple(sim.groups.role_names)
        if sim.link_solver is not None:
            sim.link_events()  # links decided by the channel (shadowing, walls), tracked as it makes them
        sim.run(until_s=0.0)
        self._finish_instant()
        self.agents = list(self.possible_agents)
        self._live = set(self.agents)
        self.cycles = 0
        pos = sim.positions()
        self.covered = self._covered(pos)
        self.components = self._components(pos)
        obs = self._observations(pos)
        if self.render_mode == "human":
            self._draw(stacklevel=3)  # the warnings point at the caller's reset or step
        return obs, self._infos(pos)

    def _finish_instant(self) -> None:
        """Process everything else due now (placements and the first links at t = 0; any
        transmission or link event at a step's end), so that the measures see the links
        as the coverage table does: after every event of the instant."""
        env = self.sim.env  # type: ignore[union-attr]
        while env.peek() <= env.now:
            env.step()

    def _covered(self, pos: np.ndarray) -> float:
        a = self.area
        cells = self.params.grid_cells
        return float(
            self._measures.covered_fraction_grid(pos, self.radius_m, a.x_min, a.y_min, a.width, a.height, cells)
        )

    def _links_up(self, pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The links the channel has up now, as pairs ``(a, b)``: on the unit disk the pairs
        within both robots' ranges (the rule of its link solver), else those its link solver
        holds."""
        sim = self.sim
        assert sim is not None
        if sim.links is None:
            a, b, _ = geometric_pairs(pos, sim.state.range_m)
            return a, b
        return sim.links.up_pairs()

    def _components(self, pos: np.ndarray) -> int:
        """Components of the network of the links the channel has up now."""
        assert self.sim is not None
        return metrics.component_count(self.sim.state.n, *self._links_up(pos))

    def step(self, actions: Mapping[str, Any]) -> tuple[dict, dict, dict, dict, dict]:
        if self.sim is None or not self.agents:
            raise RuntimeError("the episode is over (or not begun): call reset()")
        robots, velocities = self.checked_actions(actions)
        sim, p = self.sim, self.params
        if len(robots):
            sim.drive(robots, velocities)
        sim.run(until_s=(self.cycles + 1) * p.step_s, steps=1)
        self._finish_instant()
        self.cycles += 1
        pos = sim.positions()
        covered = self._covered(pos)
        self.components = self._components(pos)
        reward = covered - self.covered - p.component_penalty * (self.components - 1)
        self.covered = covered
        obs = self._observations(pos)
        infos = self._infos(pos)
        done = self.cycles >= self.max_cycles
        agents = self.agents
        rewards = dict.fromkeys(agents, reward)
        terminations = dict.fromkeys(agents, False)
        truncations = dict.fromkeys(agents, done)
        if done:
            self.agents = []
            self._live = set()
        if self.render_mode == "human":
            self._draw(stacklevel=3)  # the warnings point at the caller's reset or step
        return obs, rewards, terminations, truncations, infos

    def checked_actions(self, actions: Mapping[str, Any] | None) -> tuple[np.ndarray, np.ndarray]:
        """The robots and velocities of ``actions``, all checked before any is applied."""
        if actions is not None and not isinstance(actions, Mapping):
            raise CommandError(
                f"actions must be a dict from agent name to velocity (vx, vy), as {{'robot_0': (1.0, 0.0)}}; "
                f"got {type(actions).__name__}"
            )
        if not actions:  # a step without actions: every robot keeps its velocity
            return np.empty(0, np.int64), np.empty((0, 2))
        live = self._live
        if not live.issuperset(actions):
            agent = next(a for a in actions if a not in live)
            raise CommandError(f"action for {agent!r}: no such agent in this episode ({len(live)} agents)")
        index = self._index
        robots = [index[agent] for agent in actions]
        try:
            v = as_numbers(list(actions.values()))
        except (TypeError, ValueError):
            v = np.empty(0)
        if v.shape != (len(robots), 2):
            for agent, action in actions.items():  # which one is wrong
                try:
                    shape = as_numbers(action).shape
                except (TypeError, ValueError):
                    shape = None
                if shape != (2,):
                    raise CommandError(
                        f"action of {agent} = {action!r}: must be a velocity (vx, vy) of numbers, shape (2,)"
                    )
        bad = ~(np.isfinite(v) & (np.abs(v) <= self._high)).all(axis=1)
        if bad.any():
            agent = list(actions)[int(np.flatnonzero(bad)[0])]
            vmax = self.params.speed_max_mps
            raise CommandError(
                f"action of {agent} = {v[bad][0].tolist()}: each component must be finite and within "
                f"[-{vmax:g}, {vmax:g}] m/s"
            )
        v = np.clip(v, -self.params.speed_max_mps, self.params.speed_max_mps)
        return np.array(robots, dtype=np.int64), v.reshape(-1, 2)

    # -- what agents see ------------------------------------------------------------------
    def state(self) -> np.ndarray:
        """The team's true state (``state_space``), for a critic trained with what no agent
        sees: every robot's own part of its observation (position, velocity, role one-hot),
        robot after robot, now."""
        if self.sim is None:
            raise RuntimeError("no episode yet: call reset()")
        return self._own(self.sim.positions()).ravel()

    def _own(self, pos: np.ndarray, width: int | None = None) -> np.ndarray:
        """Each robot's own part of its observation, in the first columns of a zeroed
        ``(n, width)`` array (``width`` None: that part alone)."""
        sim = self.sim
        assert sim is not None
        n, roles = self.params.n_robots, len(self.role_names)
        out = np.zeros((n, width or 4 + roles), dtype=np.float32)
        out[:, 0:2] = pos
        out[:, 2:4] = sim.state.velocity_mps
        if sim.groups is not None:
            out[np.arange(n), 4 + sim.groups.role] = 1.0
        return out

    def _observations(self, pos: np.ndarray) -> dict[str, np.ndarray]:
        sim, p = self.sim, self.params
        assert sim is not None
        k = p.max_neighbours
        out = self._own(pos, self._obs_size)
        roles = len(self.role_names)
        if k and sim.neighbour_view is not None:
            ids, told, heard_s = sim.neighbour_view.heard(sim.now)
            self._measures.nearest_told(out, 4 + roles, pos, ids, told, heard_s, sim.now, k, self.tau_s)
        bounds = self.power_bounds_dbm
        if k and bounds is not None and isinstance(sim.neighbour_view, LinkQualityView):
            ids, power, heard_s = sim.neighbour_view.link_quality(sim.now)
            start = self.link_quality_start
            self._measures.strongest_heard(out, start, ids, power, heard_s, sim.now, k, *bounds, self.tau_s)
        return {a: out[i] for i, a in enumerate(self.agents)}

    def _infos(self, pos: np.ndarray) -> dict[str, dict]:
        info = {"positions_m": pos, "covered_fraction": self.covered, "components": self.components}
        # One dict each: an agent's info changed by a training loop is not another's.
        return {a: dict(info) for a in self.agents}

    # -- drawing --------------------------------------------------------------------------
    def render(self) -> np.ndarray | None:
        """The team now, as the figures draw a deployment (netsim.tools.figures): with
        ``render_mode = "rgb_array"`` returned as an ``(H, W, 3)`` uint8 array; with
        ``"human"`` shown in a window (which ``reset()`` and ``step()`` also update), None
        returned."""
        return self._draw(stacklevel=3)

    def _draw(self, stacklevel: int) -> np.ndarray | None:
        """render(), its warnings given ``stacklevel`` frames up (the user's call)."""
        if self.render_mode is None:
            warnings.warn(
                "render() draws only in render_mode 'rgb_array' or 'human': make the environment with"
                " render_mode='rgb_array' (frames returned) or render_mode='human' (a window)",
                stacklevel=stacklevel,
            )
            return None
        if self.sim is None:
            return None
        if self.render_mode == "human" and not shows_windows():
            if "no window" not in self._told:
                self._told.add("no window")
                warnings.warn(no_window_said(), stacklevel=stacklevel)
            return None
        image = frame(self.sim, self._links_up(self.sim.positions()), self.radius_m, self.range_m, self.covered)
        if self.render_mode == "rgb_array":
            return image
        if self._window is None:
            self._window = Window()
        fps = self.metadata.get("render_fps")
        # None (Gymnasium's "not declared") or anything but a number: frames as they come.
        self._window.show(image, float(fps) if isinstance(fps, numbers.Real) else 0.0)
        return None

    def close(self) -> None:
        self.sim = None
        if self._window is not None:
            self._window.close()
            self._window = None


def observation_space(
    area: Bounds,
    speed_max_mps: float,
    roles: int,
    k: int,
    tau_s: float,
    power_bounds_dbm: tuple[float, float] | None = None,
) -> spaces.Box:
    """The box of an agent's observation (module notes) in the run's ``area``, with
    ``roles`` roles, ``k`` neighbours and Acks' ages at most ``tau_s``; with the link
    quality of ``k`` neighbours when ``power_bounds_dbm`` (their power's) are given."""
    v, w, h = speed_max_mps, area.width, area.height
    low = [area.x_min, area.y_min, -v, -v] + [0.0] * roles + [-w, -h, 0.0, 0.0] * k
    high = [area.x_max, area.y_max, v, v] + [1.0] * roles + [w, h, tau_s, 1.0] * k
    if power_bounds_dbm is not None:
        low += [power_bounds_dbm[0], 0.0, 0.0] * k
        high += [power_bounds_dbm[1], tau_s, 1.0] * k
    return spaces.Box(np.array(low, np.float32), np.array(high, np.float32), dtype=np.float32)


def power_bounds_dbm(config: cfgmod.Config) -> tuple[float, float]:
    """The power (dBm) an Ack can be received at under the run's log-distance radio: at
    least the sensitivity (a frame below it is not received), at most the transmit power
    less the path loss at the reference distance (the least there is: nearer, the loss
    stays PL(d0)) plus the strongest shadowing (clipped at 4 sigma); walls only take."""
    radio: Any = config.channel.radio  # LogDistanceParams (refused otherwise)
    strongest = radio.radio.received_dbm(radio.reference_loss_db - TRUNCATION_SIGMAS * radio.shadowing_sigma_db)
    return float(radio.sensitivity_dbm), float(strongest)


def refused(config: cfgmod.Config, params: CoverageEnvParams) -> tuple[str, object, str] | None:
    """The key, value and reason of a setting of the runs' ``config`` that the environment
    cannot honour (its agents drive every robot over ``max_cycles`` steps, and it measures
    coverage of a bounded area on the links the channel makes during the run), or None."""
    world = config.world
    if world.n_robots != params.n_robots:
        return (
            "world.n_robots",
            world.n_robots,
            f"the environment has n_robots = {params.n_robots} agents: set n_robots",
        )
    if config.mobility.model != "external":
        return (
            "mobility.model",
            config.mobility.model,
            "the environment's agents move the robots: it must be 'external'",
        )
    if config.protocol.model != "clustering":
        return (
            "protocol.model",
            config.protocol.model,
            "the environment's observations are the clustering's roles and neighbour table: it must be 'clustering'",
        )
    for name, *_ in cfgmod.controllers(config):
        key, value = ("control.controllers", name) if name in config.control.controllers else (f"{name}.enabled", True)
        return key, value, "the environment's agents move the robots: no controller may"
    if config.duration_s != params.max_cycles * params.step_s:
        return "duration_s", config.duration_s, "is max_cycles x step_s in the environment: set those"
    channel = config.channel
    if config.radio_decides_links() and config.events.runtime_links == "off":
        return (
            "events.runtime_links",
            "off",
            "the environment counts the links the channel makes under shadowing or walls during the run",
        )
    if world.torus:
        return "world.torus", True, "the environment measures coverage of a bounded area"
    if params.link_quality and not isinstance(channel.radio, LogDistanceParams):
        return (
            "link_quality",
            True,
            "needs a received power: a log-distance radio, as channel.propagation = 'log_distance'"
            f" (set it in netsim), not {channel.propagation!r}",
        )
    return None


def parallel_env(render_mode: str | None = None, netsim: Mapping | None = None, **params: Any) -> CoverageEnv:
    """The environment, from the keys of :class:`CoverageEnvParams` (a bad value raises
    :class:`~netsim.errors.ConfigError` naming it); ``netsim`` adds keys to the runs'
    configuration; ``render_mode``: None, ``"human"`` (a window) or ``"rgb_array"``."""
    allowed = [f.name for f in dataclasses.fields(CoverageEnvParams)]
    for key, value in params.items():
        if key not in allowed:
            keywords = sorted([*allowed, "netsim", "render_mode"])
            raise ConfigError(
                key, value, f"unknown key{cfgmod.did_you_mean(key, keywords)}; allowed: " + ", ".join(keywords)
            )
    return CoverageEnv(CoverageEnvParams(**params), netsim, render_mode)


class CoverageTurns(parallel_to_aec_wrapper):
    """PettingZoo's conversion of the environment to turns, each action checked when it is
    given: a bad one (None included, for an agent still in the episode) raises there and is
    not kept, so the agent can give another. (The conversion alone keeps it and fails at the
    turn's last agent, at every step after.)"""

    def __init__(self, parallel_env: CoverageEnv) -> None:
        super().__init__(parallel_env)
        # The environment's own table, not the conversion's copy of it: a render_fps set
        # here paces its window too.
        self.metadata = parallel_env.metadata

    def step(self, action: Any) -> None:
        agent = self.agent_selection
        if not (self.terminations[agent] or self.truncations[agent]):
            cast(CoverageEnv, self.env).checked_actions({agent: action})
        super().step(action)


def env(**params: Any) -> Any:
    """The environment in PettingZoo's AEC API (turns), converted from the parallel one."""
    return OrderEnforcingWrapper(CoverageTurns(parallel_env(**params)))
