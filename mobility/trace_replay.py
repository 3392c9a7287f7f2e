"""Replay of an ns-2 movement file (ns-2 ``setdest``, BonnMotion's ns-2 export, or
``netsim scenario generate``), with the semantics of ns-3's ``Ns2MobilityHelper``."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import simpy

from netsim import ns2
from netsim.errors import ConfigError, NetsimInputError
from netsim.params import Params, param
from netsim.plugins import Parts, PluginSpec
from netsim.state import RobotState


@dataclass(frozen=True)
class TraceParams(Params):
    """The trace replay's keys of ``[mobility]``."""

    section = "mobility"
    trace_file: str = param("", None, "ns-2 movement file replayed by model = 'trace'")

    def check(self) -> None:
        if not self.trace_file:
            raise ConfigError("mobility.trace_file", self.trace_file, "must name a file when model = 'trace'")


def load(params: TraceParams, world) -> ns2.Scenario:
    """The scenario of ``params.trace_file``, checked against the world's size."""
    try:
        scen = ns2.read(params.trace_file, world.n_robots)
    except NetsimInputError as exc:
        raise NetsimInputError(f"mobility.trace_file: {exc}") from None
    if scen.n_robots != world.n_robots:
        raise ConfigError(
            "world.n_robots", world.n_robots, f"must equal the {scen.n_robots} nodes of {params.trace_file}"
        )
    side = world.side_m
    xy = np.concatenate([scen.initial_m.ravel(), scen.commands[["x_m", "y_m"]].to_numpy(float).ravel()])
    xy = xy[~np.isnan(xy)]
    if len(xy) and (xy.min() < 0 or xy.max() > side):
        raise ConfigError(
            "world.side_m",
            side,
            f"is smaller than the area of {params.trace_file} (coordinates up to {xy.max():g})",
        )
    return scen


def replay(env: simpy.Environment, st: RobotState, scen: ns2.Scenario):
    """One process walks the commands in time order; arrivals are timed per robot."""
    generation = np.zeros(st.n, dtype=np.int64)

    def stop_on_arrival(i, gen, dest):
        def stop(_event):
            if generation[i] == gen:
                st.arrive(i, env.now, dest)

        return stop

    for t, i, kind, x, y, speed in scen.commands.itertuples(index=False):
        if t > env.now:
            yield env.timeout(t - env.now)
        generation[i] += 1
        if kind == "setdest":
            dest = np.array([x, y])
            travel = st.head_to(i, env.now, dest, speed, "trace")
            if travel > 0:
                env.timeout(travel).callbacks.append(stop_on_arrival(i, int(generation[i]), dest))
        else:
            here = st.positions_at(env.now, [i])[0]
            new = np.array([here[0] if math.isnan(x) else x, here[1] if math.isnan(y) else y])
            st.set_leg(i, env.now, (0.0, 0.0), start_m=new, cause="jump")


def build(params: TraceParams, parts: Parts) -> None:
    scen = load(params, parts.world)
    parts.state.place(scen.initial_m)
    parts.env.process(replay(parts.env, parts.state, scen))


PLUGIN = PluginSpec(Params=TraceParams, build=build)
