"""The simulation object: the run's core (SimPy environment, robots, channel, trace,
random streams, event bus) and a record of the models built on it."""

from __future__ import annotations

import math
import numbers
from collections.abc import Callable
from types import MappingProxyType
from typing import TYPE_CHECKING, Any

import numpy as np

from netsim.cosim import (
    Arrival,
    CommandError,
    Driver,
    LinkQualityView,
    Messenger,
    NeighbourView,
    robot_id,
    robot_ids,
    velocities,
)
from netsim.errors import ConfigError, keyboard_interrupt_in
from netsim.events import LINK_EVENTS, EventBus
from netsim.groups import GroupView
from netsim.links.kinetic import RuntimeLinks
from netsim.links.shadowed_links import ShadowedLinks
from netsim.links.walled_links import WalledLinks
from netsim.plugins import Parts
from netsim.progress import progress_bar

if TYPE_CHECKING:  # networkx is imported only by runs that ask for the live graph
    import pandas as pd

    from netsim.live import LiveTopology


def _seconds(t: float) -> str:
    """``t`` short (``60``, not ``60.0``) where that is exact, else in full."""
    short = f"{t:g}"
    return short if float(short) == t else repr(t)


class Simulation:
    """One run: ``env`` (SimPy), ``state`` (robots), ``channel``, ``trace``, ``streams``,
    ``events`` (the bus: ``sim.events.on("link_down", fn)``, docs/events.md).

    Made by :func:`netsim.run.simulation` (the core alone) or :func:`netsim.run.build`
    (with every model). :attr:`models` records the components built, by name (read-only:
    components receive their collaborators when they are built, and never look each other
    up); :attr:`groups` is the protocol's view of the groups, if it forms any;
    :attr:`config` is the configuration it was built from.

    Driven from outside (docs/cosim.md): :meth:`drive` (with ``mobility.model =
    "external"``), :meth:`positions`, :meth:`neighbours`, :meth:`send` and :meth:`inbox`,
    through what the models handed over when they were built (:mod:`netsim.cosim`).

    Link events are solved during the run (:attr:`links`) when ``runtime_links`` is
    ``"on"``, or ``"auto"`` (the default) and something subscribed to ``link_up`` or
    ``link_down`` before the run started; otherwise after it, from the legs.
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
        self.events: EventBus = parts.events if parts.events is not None else EventBus()
        self.runtime_links = "auto"
        self.links: RuntimeLinks | ShadowedLinks | WalledLinks | None = None
        # Makes the runtime link solver when the radio needs its own (shadowing, walls), else None.
        self.link_solver: Callable[[], ShadowedLinks | WalledLinks] | None = None
        self._live: LiveTopology | None = None
        # Handed over by the models when built (netsim.cosim): who moves robots as told,
        # who keeps neighbour tables, who relays messages.
        self.driver: Driver | None = None
        self.neighbour_view: NeighbourView | None = None
        self.messenger: Messenger | None = None
        # Why the run cannot go on: an exception escaped it (a subscriber's, say) and left
        # its events half made.
        self._stopped_by: str | None = None
        self._running = False

    @property
    def models(self) -> MappingProxyType:
        return MappingProxyType(self._models)

    def add_model(self, name: str, component: object) -> None:
        """Record a built component under ``name``."""
        self._models[name] = component

    @property
    def now(self) -> float:
        return self.env.now

    # -- driven from outside (docs/cosim.md) -----------------------------------------
    def _model_name(self, section: str) -> str:
        model = getattr(getattr(self.config, section, None), "model", None)
        return f"{section}.model = {model!r}" if model is not None else f"this run's {section}"

    def drive(self, robots: Any, velocities_mps: Any) -> None:
        """From now on ``robots`` (ids) move at ``velocities_mps`` (shape ``(k, 2)``, m/s),
        the others as before; each is a new straight leg. A robot stops on the area's border
        or short of a wall (mobility/external.py). Needs ``mobility.model = "external"``."""
        if self.driver is None:
            raise CommandError(
                f"robots move by {self._model_name('mobility')}: sim.drive needs mobility.model = 'external'"
            )
        ids = robot_ids(robots, self.state.n)
        v = velocities(velocities_mps, len(ids))
        self.driver.drive(ids, v, self.env.now)

    def positions(self) -> np.ndarray:
        """The robots' positions now, ``(N, 2)`` (a new array)."""
        return self.state.positions_at(self.env.now)

    def neighbours(self, robot: int) -> np.ndarray:
        """The robots ``robot`` believes are its neighbours now: the live entries of its
        neighbour table, ascending ids."""
        i = robot_id(robot, self.state.n)
        if self.neighbour_view is None:
            raise CommandError(f"{self._model_name('protocol')} keeps no neighbour tables")
        ids = self.neighbour_view.heard(self.env.now)[0][i]
        return np.sort(ids[ids >= 0])

    def link_quality(self, robot: int) -> pd.DataFrame:
        """The live entries of ``robot``'s neighbour table now (those :meth:`neighbours`
        lists), one row each by ``neighbour`` ascending: ``rx_power_dbm``, the power at
        which ``robot`` got the neighbour's last Ack (NaN under the unit disk, or any radio
        without a log-distance law), and ``age_s``, the time since that Ack arrived."""
        import pandas as pd

        i = robot_id(robot, self.state.n)
        view = self.neighbour_view
        if view is None:
            raise CommandError(f"{self._model_name('protocol')} keeps no neighbour tables: no link quality to give")
        if not isinstance(view, LinkQualityView):
            raise CommandError(f"{self._model_name('protocol')} keeps no received power in its neighbour tables")
        now = self.env.now
        ids, power, heard_s = (np.asarray(a)[i] for a in view.link_quality(now))
        slots = np.flatnonzero(ids >= 0)
        slots = slots[np.argsort(ids[slots], kind="stable")]
        return pd.DataFrame(
            {
                "neighbour": ids[slots].astype(np.int64),
                "rx_power_dbm": power[slots].astype(float),
                "age_s": now - heard_s[slots].astype(float),
            }
        )

    def send(self, src: int, dst: int, payload: Any = None) -> int:
        """Send ``payload`` from ``src`` to ``dst`` now, relayed by the protocol as its own
        messages are (a row of the ``messages`` table); returns its ``msg_id``."""
        n = self.state.n
        s, d = robot_id(src, n, "src"), robot_id(dst, n, "dst")
        if s == d:
            raise CommandError(f"src = dst = {s}: a message goes to another robot")
        if self.messenger is None:
            raise CommandError(f"{self._model_name('protocol')} relays no messages (the clustering does)")
        return self.messenger.send_message(s, d, payload)

    def inbox(self, robot: int) -> list[Arrival]:
        """The messages sent with :meth:`send` that have reached ``robot``, in order of
        arrival: ``(t_s, src, payload, msg_id)``."""
        i = robot_id(robot, self.state.n)
        if self.messenger is None:
            return []
        return self.messenger.inbox(i)

    def link_events(self) -> RuntimeLinks | ShadowedLinks | WalledLinks:
        """The runtime link solver, started at t = 0 (call before the run starts)."""
        if self.links is None:
            if self.events.started:
                raise RuntimeError("link events during the run must be asked for before it starts")
            if self.runtime_links == "off":
                raise RuntimeError("events.runtime_links = 'off': no link events during the run")
            if self.link_solver is not None:
                self.links = self.link_solver()
            else:
                self.links = RuntimeLinks(self.env, self.state, self.events)
            self.links.start()
        return self.links

    def live_topology(self) -> LiveTopology:
        """A networkx graph of the links, kept current during the run (call before it
        starts); its time-averaged levels join the summary."""
        if self._live is None:
            from netsim.live import LiveTopology

            if self.events.started:
                # Built from the link events as they come: begun late it would lack the links up.
                raise RuntimeError("the live topology must be asked for before the run starts")
            self.link_events()
            self._live = LiveTopology(self.env, self.state, self.events, self.groups)
            self.add_model("live_topology", self._live)
        return self._live

    def _begin(self) -> None:
        wanted = any(self.events.wants(name) for name in LINK_EVENTS)
        if self.links is None and (self.runtime_links == "on" or (self.runtime_links == "auto" and wanted)):
            self.link_events()
        if self.links is None and wanted:
            raise ConfigError(
                "events.runtime_links", "off", "something subscribes to link events (a hook?): set it to 'auto' or 'on'"
            )
        self.events.link_events_on = self.links is not None
        self.events.started = True

    def _until(self, until_s: Any) -> float:
        """``until_s`` as a float, checked against the run's clock and end."""
        # Text and truth values are mistakes even where float() would take them ("20", True).
        if isinstance(until_s, (str, bytes, bool, np.bool_)):
            raise CommandError(f"until_s = {until_s!r}: must be a time in seconds (a number)")
        try:
            until = float(until_s)
        except (TypeError, ValueError, OverflowError):
            raise CommandError(f"until_s = {until_s!r}: must be a time in seconds (a number)") from None
        if math.isnan(until):
            raise CommandError(f"until_s = {until_s!r}: must be a time in seconds, not NaN")
        if until > self.duration_s:
            raise CommandError(
                f"until_s = {_seconds(until)} is after the run's end (duration_s = {_seconds(self.duration_s)}): "
                "set duration_s to run longer"
            )
        if until < self.env.now:
            now = _seconds(self.env.now)
            raise CommandError(f"until_s = {_seconds(until)} is before now ({now} s): a run only goes forward")
        return until

    def run(self, until_s: float | None = None, progress: bool | str = False, steps: int = 200) -> None:
        """Advance to ``until_s`` (default: the configured duration).

        Events due exactly at ``until_s`` are not processed (SimPy's convention); every
        output is computed for the interval ``[0, until_s]`` from exact trajectories. With
        ``progress``, the advance is made in ``steps`` parts, each reported (on a bar named
        ``progress`` if it is a string, else ``"netsim run"``).

        ``until_s`` must be a number (text such as ``"20"`` is refused) in ``[now,
        duration_s]``: anything else (later than the run's end, earlier than now, NaN)
        raises :class:`~netsim.cosim.CommandError` (a ``ValueError``) naming it, and the run
        is left as it was. An exception raised inside
        the run (by a subscriber, say, or Ctrl-C) ends it: the event it interrupted was made
        only in part, so a later ``run`` raises :class:`~netsim.cosim.CommandError`;
        :func:`netsim.run.collect` still gives the tables as they stood.
        """
        if self._stopped_by is not None:
            raise CommandError(f"the run cannot go on: {self._stopped_by}; build it again")
        if self._running:
            # From a subscriber, say: the event being made would be finished after later ones.
            raise CommandError("run was called while the run is going on (from a subscriber?): call it after")
        until = self.duration_s if until_s is None else self._until(until_s)
        if isinstance(steps, (bool, np.bool_)) or not isinstance(steps, numbers.Integral) or steps < 1:
            raise CommandError(f"steps = {steps!r}: must be a whole number >= 1")
        self._running = True
        try:
            self._advance(until, progress, int(steps))
        except BaseException as exc:
            # Ctrl-C inside a compiled loop reaches here as numba's SystemError around it:
            # raised as what it is, for an ``except KeyboardInterrupt`` to catch.
            pressed = keyboard_interrupt_in(exc)
            cause = exc if pressed is None else pressed
            self._stopped_by = f"{type(cause).__name__} was raised inside it at t = {self.env.now:g} s"
            if pressed is not None and pressed is not exc:
                raise pressed from None
            raise
        finally:
            self._running = False

    def _advance(self, until: float, progress: bool | str, steps: int) -> None:
        if not self.events.started:
            self._begin()
        start = self.env.now
        if not progress:
            # In one call: the kernel's run costs a stop event and a return per call, which
            # for a short advance (a co-simulation's step) is most of its cost.
            if until > start:
                self.env.run(until=until)
            self.state.check_until(self.env.now)
            return
        with progress_bar(
            round(until - start, 6),
            progress if isinstance(progress, str) else "netsim run",
            "sim s",
            enabled=True,
            leave=False,
            bar_format="{l_bar}{bar}| {n:.0f}/{total:.0f} sim s [{elapsed}<{remaining}]",
        ) as bar:
            for k in range(1, steps + 1):
                # The last part ends at ``until`` itself, not at a sum that rounds near it.
                t = until if k == steps else start + (until - start) * k / steps
                if t > self.env.now:
                    before = self.env.now
                    self.env.run(until=t)
                    bar.update(self.env.now - before)
        self.state.check_until(self.env.now)
