"""``netsim bridge`` and ``netsim run --live``: the commands' bodies (netsim.tools.cli
parses their flags and calls these; the bridge itself is :mod:`netsim.bridge`).

Unlike ``netsim run``, a bridge is a live session: Ctrl-C (or SIGTERM) ends it where it is,
and every table is written up to that instant, with the summary; the exit status is 0.
"""

from __future__ import annotations

import gc
import importlib.util
import signal
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import tomli_w

from netsim.bridge.loop import Pacer
from netsim.bridge.settings import BridgeSettings
from netsim.errors import ConfigError, NetsimInputError, needs_extra

# Wall-clock steps of `netsim run --live`, s of simulated time.
LIVE_STEP_S = 0.1
# The libraries of the optional extra `ros` (pyproject.toml) that each live command loads.
DDS, LIVE_VIEW = "cyclonedds", "foxglove"


def check_extra(command: str, modules: tuple[str, ...]) -> None:
    """Refuse ``command`` in one line, before anything is written, when a library of the
    optional extra ``ros`` it needs is not installed."""
    missing = [m for m in modules if importlib.util.find_spec(m) is None]
    if missing:
        raise NetsimInputError(needs_extra(command, missing, "ros"))


def check_links_on(config: Any, command: str) -> None:
    """Refuse ``command``, which draws the links as they change (the live view, the
    bridge's ``/network/links``), when the run solves no link during the run."""
    if config.events.runtime_links == "off":
        why = f"{command} draws the links as they change: set 'auto' or 'on'"
        raise ConfigError("events.runtime_links", "off", why)


@contextmanager
def _stop_on_signals(pacer: Pacer) -> Iterator[None]:
    """Ctrl-C and SIGTERM stop ``pacer`` at its next step instead of raising."""

    def stop(signum: int, frame: object) -> None:
        pacer.stop = True

    old = {s: signal.signal(s, stop) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for s, handler in old.items():
            signal.signal(s, handler)


def bridge(args: Any, config: Any, settings: BridgeSettings, rate: float) -> tuple[dict, Path, list[Path]]:
    """Run the bridge of ``config`` (checked input); returns the summary, the run's
    directory and the files written."""
    from netsim.run import build, collect, summarize
    from netsim.tools.output import RunWriter, claim_dir, manifest

    with claim_dir(args.out, "--out", kind="run") as out, RunWriter(out, config) as writer:
        from netsim.bridge.bridge import RosBridge  # loads Cyclone DDS

        start = time.perf_counter()
        sim = build(config)
        ros = RosBridge(sim, settings)
        live = _live_view(sim, args.live)
        pacer = Pacer(sim, 1.0 / settings.odom_hz, rate)

        def step_end(t_s: float, publish: Any = ros.publish) -> None:
            publish(t_s)
            if live is not None:
                live.publish(t_s)

        if not args.quiet:
            print(
                f"netsim bridge: {config.world.n_robots} robots on DDS domain {settings.domain_id}, "
                f"{rate:g} simulated s per wall s, until {config.duration_s:g} s (Ctrl-C ends it, tables kept)",
                flush=True,
            )
        # The session is saved whole once it ends: a second Ctrl-C while its tables are
        # written, or while DDS shuts down, is taken as the first was (stop), not as an
        # interrupt that would lose the session.
        with _stop_on_signals(pacer):
            pacer.run(step_end, ros.take)
            frames = collect(sim, writer.table)
            writer.table("relay", ros.relay.frame())
            wall = time.perf_counter() - start
            summary = summarize(sim, frames, wall)
            summary.update({f"bridge_{k}": v for k, v in pacer.lag.summary().items()})
            summary["bridge_rate"] = rate
            summary["bridge_commands"] = ros.commands
            summary["bridge_commands_refused"] = ros.refused
            summary["bridge_relayed_sent"] = ros.relay.sent
            (writer._start() / "bridge.toml").write_text(tomli_w.dumps(settings.as_dict()))
            written = writer.finish(summary, manifest(config, 0, wall, occupancy=sim.parts.occupancy))
            if live is not None:
                live.close()
            del ros, step_end  # its DDS entities go now, not once the command has its handlers back
            gc.collect()
    lag = pacer.lag.summary()
    print(
        f"netsim bridge: {sim.now:g} s simulated in {wall:.2f} s wall; lag behind --rate {rate:g}: "
        f"max {lag['lag_max_s']:.3f} s, mean {lag['lag_mean_s']:.3f} s of wall time "
        f"(control period {1 / settings.odom_hz / rate:.3g} s of wall time)",
        flush=True,
    )
    return summary, out, written


def _live_view(sim: Any, port: int | None) -> Any:
    if port is None:
        return None
    from netsim.bridge.live_view import LiveView

    view = LiveView(sim, port)
    print(f"live view: Foxglove WebSocket on ws://127.0.0.1:{view.port}", file=sys.stderr, flush=True)
    return view


def run_live(config: Any, port: int, writer: Any) -> Any:
    """``netsim run --live``: the run at real time, streamed to Foxglove; returns the
    ``execute``-like result (sim, frames, summary, wall)."""
    from netsim.run import RunResult, build, collect, summarize

    start = time.perf_counter()
    sim = build(config)
    live = _live_view(sim, port)
    pacer = Pacer(sim, LIVE_STEP_S, 1.0)
    try:
        pacer.run(live.publish, lambda t_s: None)
        frames = collect(sim, writer.table)
    finally:
        live.close()
    wall = time.perf_counter() - start
    return RunResult(sim, frames, summarize(sim, frames, wall), wall)
