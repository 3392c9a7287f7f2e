"""The simulation object: the run's core (SimPy environment, robots, channel, trace,
random streams) and a record of the models built on it."""

from __future__ import annotations

from types import MappingProxyType
from typing import Any

from netsim.groups import GroupView
from netsim.plugins import Parts
from netsim.progress import progress_bar


class Simulation:
    """One run: ``env`` (SimPy), ``state`` (robots), ``channel``, ``trace``, ``streams``.

    Made by :func:`netsim.run.simulation` (the core alone) or :func:`netsim.run.build`
    (with every model). :attr:`models` records the components built, by name (read-only:
    components receive their collaborators when they are built, and never look each other
    up); :attr:`groups` is the protocol's view of the groups, if it forms any;
    :attr:`config` is the configuration it was built from.
    """

    def __init__(self, parts: Parts, config: Any = None, run: int = 0):
        self.parts = parts
        self.env = parts.env
        self.state = parts.state
        self.channel = parts.channel
        self.trace = parts.trace
        self.streams = parts.streams
        self.duration_s = float(parts.duration_s)
        self.config = config
        self.groups: GroupView | None = None
        self._models: dict[str, object] = {}

    @property
    def models(self) -> MappingProxyType:
        return MappingProxyType(self._models)

    def add_model(self, name: str, component: object) -> None:
        """Record a built component under ``name``."""
        self._models[name] = component

    @property
    def now(self) -> float:
        return self.env.now

    def run(self, until_s: float | None = None, progress: bool = False, steps: int = 200) -> None:
        """Advance to ``until_s`` (default: the configured duration).

        Events due exactly at ``until_s`` are not processed (SimPy's convention); every
        output is computed for the interval ``[0, until_s]`` from exact trajectories.
        """
        until = self.duration_s if until_s is None else float(until_s)
        start = self.env.now
        with progress_bar(
            round(until - start, 6),
            "netsim run",
            "sim s",
            enabled=progress,
            leave=False,
            bar_format="{l_bar}{bar}| {n:.0f}/{total:.0f} sim s [{elapsed}<{remaining}]",
        ) as bar:
            for k in range(1, steps + 1):
                t = start + (until - start) * k / steps
                if t > self.env.now:
                    before = self.env.now
                    self.env.run(until=t)
                    bar.update(self.env.now - before)
