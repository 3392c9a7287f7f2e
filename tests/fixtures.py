"""Test helpers (imported by the tests that use them, not by conftest.py): configurations,
the bare core of a run, and the clustering protocol on scripted static deployments, each
in one line."""

from __future__ import annotations

import importlib.util
from pathlib import Path
from types import ModuleType

import numpy as np
from netsim.protocols.stack import ClusteringParams, Stack

from netsim.config import Config, from_dict
from netsim.run import simulation
from netsim.sim import Simulation
from netsim.tools.validate import rwp_density

__all__ = ["clustering", "make_config", "rwp_density", "script", "static_core"]

ROOT = Path(__file__).resolve().parents[1]


def script(path: str) -> ModuleType:
    """A script of the repository (``"experiments/coverage_targets.py"``) as a module, its
    ``main`` not run."""
    spec = importlib.util.spec_from_file_location(Path(path).stem, ROOT / path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def make_config(**tree) -> Config:
    """A validated Config from nested keyword tables, e.g. ``world={"n_robots": 5}``."""
    return from_dict(tree)


def static_core(
    positions, range_m=10.0, latency_s=0.001, seed=1, duration_s=100.0, side_m=1e6, **channel
) -> Simulation:
    """The core of a run (kernel, robots, channel, trace, streams; no model) with the robots
    standing at ``positions``; ``channel`` adds keys of ``[channel]`` (loss, jitter);
    ``range_m=None`` for a propagation whose law implies the range."""
    positions = np.asarray(positions, dtype=float)
    ranges = {} if range_m is None else {"range_m": range_m}
    config = make_config(
        seed=seed,
        duration_s=duration_s,
        world={"n_robots": len(positions), "side_m": side_m},
        mobility={"model": "static"},
        channel={**ranges, "latency_s": latency_s, **channel},
        protocol={"model": "none"},
        output={"position_interval_s": 0.0},
    )
    sim = simulation(config)
    sim.state.place(positions)
    return sim


def clustering(positions, phases=None, start=True, core: dict | None = None, **protocol) -> tuple[Simulation, Stack]:
    """The clustering protocol on robots standing at ``positions``: a :class:`Stack` of
    ``ClusteringParams(**protocol)`` (no messages unless ``message_rate_hz`` is given) on
    :func:`static_core` (``core``: its keywords), started with the Ack ``phases`` (random
    when None) unless ``start`` is false."""
    sim = static_core(positions, **(core or {}))
    stack = Stack(ClusteringParams(**{"message_rate_hz": 0.0, **protocol}), sim.parts)
    sim.add_model("protocol", stack)
    sim.groups = stack
    if start:
        stack.start(phases)
    return sim, stack


def flow_over_trace(
    tmp_path: Path, trace: str, n: int, flow: dict, duration_s: float, seed: int, channel: dict, protocol: dict
) -> tuple[Simulation, dict]:
    """A run of ``n`` robots moving as the ns-2 text ``trace`` says, carrying one flow (a
    routing protocol's test on a scripted team): the simulation and its tables."""
    from netsim.run import build, collect

    path = tmp_path / "team.ns2"
    path.write_text(trace)
    config = make_config(
        seed=seed,
        duration_s=duration_s,
        world={"n_robots": n, "side_m": 1000.0},
        mobility={"model": "trace", "trace_file": str(path)},
        channel=channel,
        protocol=protocol,
        traffic={"flows": [flow]},
        output={"position_interval_s": 0.0},
    )
    sim = build(config)
    sim.run()
    return sim, collect(sim)


def check_refused(tmp_path, capsys, overrides: list[str], key: str, words: str) -> None:
    """``netsim run --set ...overrides`` is refused: exit 2, one line on standard error
    naming ``key`` and saying ``words``, no output directory."""
    from netsim.tools.cli import main

    out = tmp_path / "out"
    argv = ["run", "--quiet", "--out", str(out)]
    for o in overrides:
        argv += ["--set", o]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"netsim: error: {key} = "), err
    assert words in err
    assert "\n" not in err
    assert not out.exists()


def keep_figures(monkeypatch, module) -> list:
    """The figures ``module`` draws through its ``pyplot``, kept open to be read (its
    ``close`` keeps them instead); the caller closes them."""
    from netsim.tools.figures import pyplot

    plt = pyplot()
    kept: list = []

    class Keep:
        def __getattr__(self, name):
            return getattr(plt, name)

        def close(self, fig):
            kept.append(fig)

    monkeypatch.setattr(module, "pyplot", Keep)
    return kept
