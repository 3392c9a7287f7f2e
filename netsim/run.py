"""Build a run from a configuration, execute it, and collect its results.

:func:`build` is the only reader of the configuration: it makes the run's core (kernel,
robots, channel with its loss model, trace, random streams), then each model from its own
section, handing it what it works with (:class:`~netsim.plugins.Parts`): the mobility
model, the protocol, and the controllers, which also get the control loop and the
protocol's view of the groups. Models are plugins known by name, so ``netsim/`` imports
neither ``mobility/`` nor ``protocols/``.
"""

from __future__ import annotations

import copy
import dataclasses
import math
import numbers
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd
import simpy
from pandas.api.types import pandas_dtype

from netsim import config as cfgmod
from netsim import plugins
from netsim.config import Config, world_bounds
from netsim.control import ControlLoop
from netsim.cosim import AckSchedule, Driver, Messenger, NeighbourView
from netsim.errors import ConfigError, NetsimInputError, setting
from netsim.events import EventBus, NotASubscriber, UnknownEvent
from netsim.groups import GroupView
from netsim.links.radio_links import radio_link_lifetimes
from netsim.links.shadowed_links import ShadowedLinks
from netsim.links.walled_links import WalledLinks
from netsim.params import Params
from netsim.plugins import AckTiming, Parts, Reports, Schema
from netsim.radio.channel import Channel
from netsim.radio.loss import CheckedLoss
from netsim.radio.reception import Reception
from netsim.radio.receptions import RECEPTIONS_SCHEMA, ReceptionLog
from netsim.rng import KindStreams, Streams
from netsim.samples import sample_times
from netsim.sim import Simulation
from netsim.state import RobotState
from netsim.survival import lifetime_summary
from netsim.trace import Trace, as_read_back, conform, empty_table
from netsim.traffic import Traffic
from netsim.trajectory import sample_positions

# The tables every run writes, whatever its models (theirs are declared by their plugins).
ENGINE_TABLES: dict[str, Schema] = {
    "positions": {"t_s": "float64", "robot": "int64", "x_m": "float64", "y_m": "float64"},
    "links": {
        "a": "int64",
        "b": "int64",
        "t_up_s": "float64",
        "t_down_s": "float64",
        "censored": "bool",
        "censored_start": "bool",
        "censored_end": "bool",
    },
    "legs": {
        "t_s": "float64",
        "robot": "int64",
        "x_m": "float64",
        "y_m": "float64",
        "vx_mps": "float64",
        "vy_mps": "float64",
        "cause": "object",
    },
}


def simulation(config: Config, run: int = 0) -> Simulation:
    """The core of a run with no model yet: kernel, robots (none placed), the channel and
    its loss model (``[channel]``), the trace, the random streams of ``(seed, run)`` and
    the event bus."""
    # Time is a float from the start: rows and figures at t = 0 are 0.0, as every later one.
    if isinstance(run, (bool, np.bool_)) or not isinstance(run, numbers.Integral) or run < 0:
        raise ValueError(f"run = {run!r}: must be a whole number >= 0 (a sweep point's replication)")
    env = simpy.Environment(initial_time=0.0)
    streams = Streams(config.seed, run)
    w = config.world
    events = EventBus()
    state = RobotState(w.n_robots, w.side_m, config.ranges_m(), w.torus, world_bounds(w))
    state.events = events
    ch = config.channel
    # The built-in loss models draw each kind of frame from its own stream; a plugin's model
    # is handed a plain generator, one stream for every frame (docs/plugins.md).
    loss_rng = KindStreams(streams, "channel.loss") if ch.loss_plugin.make.__module__.startswith("netsim.") else None
    survives = ch.loss_plugin.make(ch.loss, state.range_m, loss_rng or streams.get("channel.loss"))
    if not type(survives).__module__.startswith("netsim."):
        survives = CheckedLoss(survives, ch.loss_model)
    occupancy = world_map(config)
    radio = ch.propagation_model
    propagation = radio.make(ch.radio, state.range_m, occupancy, streams.get("channel.shadowing"))
    reception = None
    if propagation is not None:
        # Random links have no solvable events: the links table records the decisions.
        reception = Reception(propagation, state, record=radio.shadowed(ch.radio))
    channel = Channel(
        env,
        state,
        survives,
        ch.latency_s,
        ch.latency_jitter_s,
        KindStreams(streams, "channel.latency"),
        reception,
        events=events,
        loss_rng=loss_rng,
    )
    mac = ch.mac_model
    if mac.build is not None:
        radio_params = ch.radio

        def power(noise_floor_dbm: float, capture_threshold_db: float) -> Any:
            return radio.power(radio_params, noise_floor_dbm, capture_threshold_db)

        channel.attach_mac(mac.build(ch.medium, channel, streams.get("channel.mac"), power))
    if config.output.receptions:
        channel.receptions = ReceptionLog(channel)
    flows = config.traffic.flow_list()
    traffic = Traffic(tuple(flows), config.channel.max_frame_bytes) if flows else None
    parts = Parts(
        env,
        state,
        channel,
        Trace(),
        streams,
        w,
        config.duration_s,
        config.output,
        events=events,
        occupancy=occupancy,
        traffic=traffic,
        max_frame_bytes=config.channel.max_frame_bytes,
    )
    sim = Simulation(parts, config, run)
    # Log-distance path loss without shadowing or walls is the unit disk of the implied range
    # (the robots' range_m): its link events are solved during the run as the unit disk's.
    # Under shadowing they are the channel's decisions, cut at the reach (netsim.links.shadowed_links);
    # on a map without shadowing, sampled along stretches (netsim.links.walled_links).
    sim.runtime_links = config.events.runtime_links
    if reception is not None and reception.recorder is not None:
        recorder, reach_m = reception.recorder, reception.reach_m
        sim.link_solver = lambda: ShadowedLinks(env, state, events, recorder, reach_m)
    elif reception is not None and reception.map is not None:
        walled = reception
        sim.link_solver = lambda: WalledLinks(env, state, events, walled)
    return sim


def world_map(config: Config) -> Any:
    """The run's occupancy map (``world.map``), None in open space."""
    if not config.world.map:
        return None
    from netsim.world.maps import cached_map

    return cached_map(config.world.map)


def ack_timing(protocol: object, channel: Any) -> AckTiming | None:
    """The Ack beacon's timing for the controllers (:attr:`Parts.acks`), as the run's
    ``protocol`` declares it (:class:`~netsim.cosim.AckSchedule`; None for a protocol
    without Acks), and whether the ``channel`` (its configuration) loses frames: lossless
    when its loss model declares it drops none under its keys
    (:attr:`~netsim.radio.models.LossModel.lossless`: the Bernoulli model at
    ``loss_probability = 0``) and there is no shared medium."""
    if not isinstance(protocol, AckSchedule):
        return None
    lossless = channel.loss_plugin.lossless(channel.loss) and channel.mac_model.build is None
    return AckTiming(float(protocol.ack_period_s), float(protocol.ack_jitter_s), bool(lossless))


def _build_model(sim: Simulation, name: str, plugin: Any, params: Params, parts: Parts, key: str, value: Any) -> object:
    """``plugin`` built; a subscription it makes to an event that does not exist, or of
    something that cannot be called, is refused naming its configuration ``key = value``.
    A user's model writes through a trace that records its tables as its own."""
    if _users(plugin):
        parts = dataclasses.replace(parts, trace=parts.trace.written_by(setting(key, value)))
    try:
        component = plugin.build(params, parts)
    except (UnknownEvent, NotASubscriber) as exc:
        raise ConfigError(key, value, f"subscribes wrongly: {exc}") from None
    sim.add_model(name, component)
    return component


def control_timing(config: Config) -> tuple[float, float]:
    """The control loop's period and first step, from the section that sets them."""
    for name, plugin in cfgmod.section_owners(config.control).items():
        if plugin.timing is not None:
            return plugin.timing(config.sections[name])
    raise ConfigError(
        "control.controllers", list(config.control.controllers), "no installed plugin sets the control loop's period"
    )


def _model_label(config: Config, name: str) -> str:
    """How a built component ``name`` is named in messages: the key that chose it."""
    if name in ("mobility", "protocol"):
        return f"{name}.model = {getattr(config, name).model!r}"
    return name


def _users(plugin: Any) -> bool:
    """Whether ``plugin`` is a user's, not one shipped with netsim: its tables are held to
    its declaration as the run is collected (netsim's own are, by the tests)."""
    return not getattr(plugin.build, "__module__", "").startswith("netsim.")


def _controller_key(config: Config, name: str) -> tuple[str, Any]:
    """The configuration key and value that switch controller ``name`` on: its place in
    ``control.controllers``, or its section's ``enabled``."""
    if name in config.control.controllers:
        return "control.controllers", name
    return f"{name}.enabled", True


# Tables netsim writes itself: no model may declare or write one of these names.
RESERVED_TABLES = frozenset(ENGINE_TABLES) | {"medium", "receptions"}


def _declaring(config: Config) -> list[tuple[str, Any, Any]]:
    """``(key, value, plugin)`` of every model of ``config`` that may declare tables: the
    mobility model, the protocol, the controllers and the hooks, each with the key that
    chose it."""
    named = [("mobility.model", config.mobility.model, config.mobility.plugin)]
    named.append(("protocol.model", config.protocol.model, config.protocol.plugin))
    named += [(*_controller_key(config, name), plugin) for name, plugin, _ in cfgmod.controllers(config)]
    for k, name in enumerate(config.events.hooks):
        named.append((f"events.hooks[{k}]", name, plugins.resolve(plugins.HOOKS, name, f"events.hooks[{k}]")))
    return named


def check_declared_tables(config: Config) -> None:
    """No model of ``config`` declares a table named like one netsim writes itself, or a
    column of a type that is not one: refused naming its key, before the run (a table
    written so is refused after it, :func:`collect`)."""
    for key, value, plugin in _declaring(config):
        clash = sorted(set(plugin.tables) & RESERVED_TABLES)
        if clash:
            raise ConfigError(key, value, f"declares {', '.join(clash)}, a table netsim writes itself: rename it")
        for table, schema in plugin.tables.items():
            for column, dtype in schema.items():
                if not _is_dtype(dtype):
                    why = f"declares {table}.{column} as {dtype!r}, not a dtype (as 'float64', 'int64', 'object')"
                    raise ConfigError(key, value, why)


def _is_dtype(name: str) -> bool:
    try:
        pandas_dtype(name)
    except TypeError:
        return False
    return True


def _users_tables(config: Config) -> dict[str, set[str]]:
    """The tables each user's model of ``config`` declares, by the key that chose it."""
    return {setting(key, value): set(plugin.tables) for key, value, plugin in _declaring(config) if _users(plugin)}


def check_owned_tables(sim: Simulation) -> None:
    """Every table a user's model has registered so far is one its plugin declares, and not
    one netsim writes itself: otherwise refused in one line naming its key and the table
    (as the run is built, or after it for a table first written during the run)."""
    declared = _users_tables(sim.config)
    for name, who in sim.trace.owners.items():
        if name in RESERVED_TABLES:
            raise NetsimInputError(f"{who}: writes table {name!r}, a table netsim writes itself: rename it")
        if name not in declared.get(who, ()):
            raise NetsimInputError(
                f"{who}: writes table {name!r}, which its plugin does not declare: declare it, with its columns"
            )


def build(config: Config, run: int = 0) -> Simulation:
    """A :class:`Simulation` with every model of ``config`` built from its own section:
    the mobility model, the protocol, then the controllers (module notes)."""
    check_declared_tables(config)
    sim = simulation(config, run)
    parts = sim.parts
    # The models' motion is checked (a bare core's scripted robots go where a test sends them).
    walls = None
    if parts.occupancy is not None:
        from netsim.world.free_space import Walls

        walls = Walls(parts.occupancy)
    sim.state.check_motion(walls)
    m, p = config.mobility, config.protocol
    mobility = _build_model(sim, "mobility", m.plugin, m.params, parts, "mobility.model", m.model)
    sim.driver = mobility if isinstance(mobility, Driver) else None
    # The links as the channel makes them, solved during the run, for the protocol, the
    # controllers and the hooks that ask (None: events.runtime_links = "off").
    links = sim.link_events if sim.runtime_links != "off" else None
    with_links = dataclasses.replace(parts, links=links)
    protocol = _build_model(sim, "protocol", p.plugin, p.params, with_links, "protocol.model", p.model)
    sim.groups = protocol if isinstance(protocol, GroupView) else None
    sim.neighbour_view = protocol if isinstance(protocol, NeighbourView) else None
    sim.messenger = protocol if isinstance(protocol, Messenger) else None
    chosen = cfgmod.controllers(config)
    if chosen:
        period_s, start_s = control_timing(config)
        moved = config.mobility
        loop = ControlLoop(
            sim.env,
            sim.state,
            sim.trace,
            period_s,
            start_s,
            lead_s=sim.channel.latency_s + sim.channel.latency_jitter_s,
            moved_by=f"mobility.model = {moved.model!r}" if moved.plugin.moves_robots else None,
            groups=sim.groups,
            # The run's own copy: the configuration a script changes after the build is not the run's.
            options=copy.deepcopy(config.control.options),
            occupancy=parts.occupancy,
        )
        sim.add_model("control", loop)
        acks = ack_timing(protocol, config.channel)
        with_loop = dataclasses.replace(parts, control=loop, groups=sim.groups, links=links, acks=acks)
        for name, plugin, params in chosen:
            key = _controller_key(config, name)
            component = _build_model(sim, name, plugin, params, with_loop, *key)
            if callable(component):
                loop.add(component, owner=setting(*key) if _users(plugin) else None)
    events = config.events
    if events.live_topology:
        sim.live_topology()
    for k, name in enumerate(events.hooks):
        hook = plugins.resolve(plugins.HOOKS, name, f"events.hooks[{k}]")
        with_groups = dataclasses.replace(
            sim.parts,
            groups=sim.groups,
            control=sim.models.get("control"),
            links=links,
        )
        _build_model(sim, name, hook, hook.Params(), with_groups, f"events.hooks[{k}]", name)
    check_owned_tables(sim)
    # Link events are solved during the run if asked for now (a hook subscribed) or later,
    # before the run starts (Simulation.run).
    return sim


def tables(config: Config) -> dict[str, Schema]:
    """Every table a run of ``config`` writes, with its columns: the engine's, and those its
    models declare."""
    out = dict(ENGINE_TABLES)
    for _, _, plugin in _declaring(config):
        out.update(plugin.tables)
    if config.output.receptions:
        out["receptions"] = dict(RECEPTIONS_SCHEMA)
    return config.channel.mac_model.tables(out)


@dataclass
class RunResult:
    sim: Simulation
    frames: dict[str, pd.DataFrame]
    summary: dict
    wall_s: float


def collect(
    sim: Simulation, emit: Callable[[str, pd.DataFrame], object] | None = None, progress: bool = False
) -> dict[str, pd.DataFrame]:
    """Every output table of the run so far; each is also passed to ``emit(name, table)``
    as soon as it is made (a writer starts on it while the next is made).

    The tables end at ``sim.now``, whether or not the run has reached ``duration_s``:
    positions are sampled up to now, links still up are censored at now, as the end of a
    finished run censors them (docs/python.md).

    A user's model's tables are held to its declaration (:func:`netsim.trace.conform`); one it
    declares and never wrote is written empty. ``progress``: a bar while a long solve runs
    (a map's links for a large team)."""
    frames: dict[str, pd.DataFrame] = {}
    declared = tables(sim.config)
    users = {name: who for who, names in _users_tables(sim.config).items() for name in names}

    def add(name: str, frame: pd.DataFrame) -> None:
        if name in declared:
            # A table without rows takes its columns' declared types, not pandas' object for
            # all: one table of two runs has one schema whether or not either wrote a row;
            # and its text is held as its file read back holds it.
            frame = as_read_back(frame, declared[name])
        if name in users:
            frame = conform(frame, declared[name], users[name], name)
        frames[name] = frame
        if emit is not None:
            emit(name, frame)

    check_owned_tables(sim)
    clash = sorted(set(sim.trace.names()) & RESERVED_TABLES)
    if clash:
        raise NetsimInputError(
            f"a model's table is named like one netsim writes itself ({', '.join(clash)}): rename it in its plugin"
        )
    legs = sim.state.legs()
    side, torus = sim.state.side_m, sim.state.torus
    for name in sim.trace.names():
        add(name, sim.trace.frame(name))
    for name in sorted(set(users) - set(frames)):
        # Declared and never written: a script reading it finds it, with no rows.
        add(name, empty_table(declared[name]))
    times = sample_times(sim.parts.output.position_interval_s, sim.env.now)
    add("positions", sample_positions(legs, sim.state.n, times, side, torus))
    if sim.links is not None and sim.env.now >= sim.duration_s:
        # The changes due at the run's end, which the kernel does not process, are applied
        # to the live links at the end alone (mid-run they are the run's to announce when it
        # goes on): after the run they are those the table leaves up.
        sim.links.finish(sim.env.now)
    # Solved from the legs, whether or not link events were announced during the run: the
    # runtime solvers are the live feed, and their events are this table's rows.
    add(
        "links",
        radio_link_lifetimes(sim.channel.reception, legs, sim.state.range_m, sim.env.now, side, torus, progress),
    )
    # Every course change: trajectories are exact from these (positions unwrapped on a torus).
    add("legs", legs)
    if sim.channel.mac is not None:
        add("medium", sim.channel.mac.frame())
    if sim.channel.receptions is not None:
        add("receptions", sim.channel.receptions.frame(legs, sim.state.n, side, torus))
    return frames


def summarize(sim: Simulation, frames: dict[str, pd.DataFrame], wall_s: float) -> dict:
    """The run's figures: the engine's (motion and links), then each model's own."""
    n, duration = sim.state.n, sim.env.now
    links = frames["links"]
    life = links["t_down_s"] - links["t_up_s"]
    done = ~links["censored"]
    # Path length: the travel less what jumps (a trace's set X_) made of it.
    distance = sim.state.travelled_m(duration, slice(None)) - sim.state.jumped_m
    km = lifetime_summary(links)
    config = sim.config
    summary = {
        "robots": n,
        "duration_s": duration,
        "seed": sim.streams.seed,
        "mobility": config.mobility.model if config is not None else "",
        "protocol": config.protocol.model if config is not None else "",
        "wall_s": round(wall_s, 3),
        "link_lifetimes": len(links),
        "link_lifetimes_complete": int(done.sum()),
        # The mean lifetime with the links still up at the end counted (Kaplan-Meier); the
        # mean of the complete ones alone leaves the longest links out.
        "link_duration_km_mean_s": km["mean_s"],
        "link_duration_km_ci_low_s": km["mean_ci_low_s"],
        "link_duration_km_ci_high_s": km["mean_ci_high_s"],
        "mean_link_duration_s": float(life[done].mean()) if done.any() else math.nan,
        # Time-average degree, exact from the link lifetimes.
        "mean_degree": float(2 * life.sum() / (n * duration)) if duration > 0 else math.nan,
        "mean_speed_mps": float(distance.sum() / (n * duration)) if duration > 0 else math.nan,
    }
    if config is not None and config.channel.propagation_model.ranges(config.channel.radio) is not None:
        summary["propagation"] = config.channel.propagation
        summary["implied_range_m"] = float(sim.state.range_m[0]) if n else math.nan
    if sim.channel.reception is not None:
        summary["radio_reach_m"] = sim.channel.reception.reach_m
    if sim.channel.mac is not None:
        summary.update(sim.channel.mac.summary(duration))
    if config is not None and config.world.map:
        summary["map"] = config.world.map
    for name, component in sim.models.items():
        if isinstance(component, Reports):
            told = component.summary(frames, duration)
            who = _model_label(sim.config, name)
            if not isinstance(told, dict):
                raise NetsimInputError(f"{who}: its summary() must return a dict, not {type(told).__name__}")
            taken = sorted(set(told) & set(summary))
            if taken:
                raise NetsimInputError(
                    f"{who}: its summary() gives {', '.join(taken)}, already in the summary: rename them in its plugin"
                )
            summary.update(told)
    return summary


def execute(
    config: Config,
    run: int = 0,
    progress: bool | str = False,
    emit: Callable[[str, pd.DataFrame], object] | None = None,
    built: Callable[[Simulation], object] | None = None,
) -> RunResult:
    """Build, run and collect (each table passed to ``emit`` as it is made: :func:`collect`),
    timing the whole; ``built(sim)`` is called between the build and the run. ``progress``:
    as :meth:`Simulation.run`'s."""
    start = time.perf_counter()
    sim = build(config, run)
    if built is not None:
        built(sim)
    sim.run(progress=progress)
    frames = collect(sim, emit, progress=bool(progress))
    wall = time.perf_counter() - start
    return RunResult(sim, frames, summarize(sim, frames, wall), wall)
