"""Build a run from a configuration, execute it, and collect its results.

The builder knows models only by name (plugins), so ``netsim/`` imports neither
``mobility/`` nor ``protocols/``.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
import pandas as pd

from netsim import plugins
from netsim.config import Config
from netsim.control import control_loop
from netsim.lifetimes import link_lifetimes
from netsim.sim import Simulation
from netsim.trace import RoleChange
from netsim.trajectory import distance_travelled, sample_positions


def build(config: Config, run: int = 0) -> Simulation:
    """A :class:`Simulation` with the configured mobility model and protocol installed."""
    sim = Simulation(config, run)
    sim.trace.declare("roles", RoleChange)
    mobility = plugins.resolve(plugins.MOBILITY, config.mobility.model, "mobility.model")
    sim.models["mobility"] = mobility(sim)
    if config.protocol.model != "none":
        protocol = plugins.resolve(plugins.PROTOCOLS, config.protocol.model, "protocol.model")
        sim.models["protocol"] = protocol(sim)
    if config.coverage.enabled:
        coverage = plugins.resolve(plugins.CONTROLLERS, "coverage", "coverage.enabled")
        sim.models["coverage"] = coverage(sim)
    for name in config.control.controllers:
        factory = plugins.resolve(plugins.CONTROLLERS, name, "control.controllers")
        controller = factory(sim)
        if callable(controller):
            control_loop(sim).add(controller)
    return sim


@dataclass
class RunResult:
    sim: Simulation
    frames: dict[str, pd.DataFrame]
    summary: dict
    wall_s: float


def position_times(config: Config) -> np.ndarray:
    dt = config.output.position_interval_s
    if dt <= 0:
        return np.empty(0)
    # The small tolerance keeps the last sample when duration is a multiple of dt.
    k = int(math.floor(config.duration_s / dt + 1e-9))
    return np.arange(k + 1) * dt


def collect(sim: Simulation) -> dict[str, pd.DataFrame]:
    """Every output table of a finished run."""
    cfg = sim.config
    legs = sim.state.legs()
    side, torus = cfg.world.side_m, cfg.world.torus
    frames = sim.trace.frames()
    frames["positions"] = sample_positions(legs, sim.state.n, position_times(cfg), side, torus)
    frames["links"] = link_lifetimes(legs, sim.state.range_m, sim.env.now, side, torus)
    # Every course change: trajectories are exact from these (positions unwrapped on a torus).
    frames["legs"] = legs
    if "acks" not in frames:
        frames["acks"] = sim.channel.frame("ack")
    return frames


def summarize(sim: Simulation, frames: dict[str, pd.DataFrame], wall_s: float) -> dict:
    cfg = sim.config
    n, duration = sim.state.n, sim.env.now
    links = frames["links"]
    acks = frames["acks"]
    life = links["t_down_s"] - links["t_up_s"]
    done = ~links["censored"]
    received, lost = int(acks["received"].sum()), int(acks["dropped_loss"].sum())
    legs = sim.state.legs()
    distance = distance_travelled(legs, duration)
    summary = {
        "robots": n,
        "duration_s": duration,
        "seed": cfg.seed,
        "mobility": cfg.mobility.model,
        "protocol": cfg.protocol.model,
        "wall_s": round(wall_s, 3),
        "acks_sent": int(acks["sent"].sum()),
        "acks_received": received,
        "acks_dropped_loss": lost,
        "ack_delivery_ratio": received / (received + lost) if received + lost else math.nan,
        "link_lifetimes": len(links),
        "link_lifetimes_complete": int(done.sum()),
        "mean_link_duration_s": float(life[done].mean()) if done.any() else math.nan,
        # Time-average degree, exact from the link lifetimes.
        "mean_degree": float(2 * life.sum() / (n * duration)) if duration > 0 else math.nan,
        "mean_speed_mps": float(distance.sum() / (n * duration)) if duration > 0 else math.nan,
    }
    for model in sim.models.values():
        # A model may add its own figures: summary(frames, duration_s) -> dict.
        extra = getattr(model, "summary", None)
        if callable(extra):
            summary.update(extra(frames, duration))
    return summary


def execute(config: Config, run: int = 0, progress: bool = False) -> RunResult:
    """Build, run and collect, timing the whole."""
    start = time.perf_counter()
    sim = build(config, run)
    sim.run(progress=progress)
    frames = collect(sim)
    wall = time.perf_counter() - start
    return RunResult(sim, frames, summarize(sim, frames, wall), wall)
