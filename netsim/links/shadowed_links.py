"""Link events during the run under shadowing: the channel's decisions, cut where the pair
leaves the reach.

Under shadowing a link is random and its state exists only where the channel looks at it,
at transmissions; ``links.parquet`` is the record of the channel's decisions
(:func:`netsim.links.radio_links.recorded_lifetimes`, docs/radio.md "Link events"): a link is up
from the first transmission between the two robots (either way) that gets through while it
is down, down at the first that does not (or when one of them sends while the other is
beyond the reach), and at the latest at the exact instant the pair leaves the reach
interval in which it came up; after that cut it is down, and the next transmission that
gets through (a *touch* of the recorder, :class:`~netsim.radio.reception.LinkRecorder`) brings
it up again.

Both ends of that rule can be known as they happen. A decision is made at its send time,
by :class:`~netsim.radio.reception.LinkRecorder`, which tells :meth:`ShadowedLinks._decided`
its changes and touches;
the reach's exits are the link events of a unit disk of the reach, solved during the run
by a :class:`~netsim.links.kinetic.RuntimeLinks` of its own (the *envelope*, announced to nobody
but this class) with the same arithmetic as the post-hoc solver. So ``link_up`` is
announced at the send that brings a link up, and ``link_down`` at the send that brings it
down or at the instant the pair leaves the reach, whichever comes first, and the table of
these events equals the post-hoc one, bit for bit (tests/test_events.py).

Order at one instant: a reach exit is a runtime link event (before anything else due then,
docs/events.md); a decision is announced during the transmission that makes it.
"""

from __future__ import annotations

import numpy as np
import simpy

from netsim.events import EventBus, LinkDown, LinkUp, notify
from netsim.links.kinetic import RuntimeLinks, up_pairs
from netsim.radio.reception import LinkRecorder
from netsim.state import RobotState


class ShadowedLinks:
    """Exact link events of one run under shadowing, announced as the channel decides them
    (module notes). The same interface as :class:`~netsim.links.kinetic.RuntimeLinks`.

    Parameters
    ----------
    env, state : the run's kernel and robots.
    events : the run's bus (``link_up``, ``link_down``).
    recorder : the reception's :class:`~netsim.radio.reception.LinkRecorder`.
    reach_m : the radio's reach (no link beyond it).
    """

    def __init__(
        self, env: simpy.Environment, state: RobotState, events: EventBus, recorder: LinkRecorder, reach_m: float
    ):
        self.env, self.state, self.events = env, state, events
        self.n = max(state.n, 1)
        self.envelope = RuntimeLinks(env, state, None, range_m=np.full(state.n, float(reach_m)))
        self.envelope.on_up.append(self._entered_reach)
        self.envelope.on_down.append(self._left_reach)
        recorder.listeners.append(self._decided)
        # Links up now: key a n + b -> (since when, the start of the reach interval it came
        # up in; None: the pair was never within the reach by the envelope's account).
        self.up: dict[int, tuple[float, float | None]] = {}
        # Each pair's last exit from the reach.
        self._left: dict[int, float] = {}
        self._on_up = events.subscribers("link_up")
        self._on_down = events.subscribers("link_down")

    @property
    def windows(self) -> int:
        return self.envelope.windows

    @property
    def started(self) -> bool:
        return self.envelope.started

    def start(self) -> None:
        self.envelope.start()

    def finish(self, t_end: float) -> None:
        """The run's end: the envelope's events due by then are applied, not announced."""
        self.envelope.finish(t_end)

    def _end(self, key: int, t_up: float, t_down: float) -> None:
        if self._on_down:
            event = LinkDown(t_down, *divmod(key, self.n), t_up)
            notify(self._on_down, event)

    def _decided(self, t: float, sender: int, robots: list[int], now_up: list[bool], touched: list[int]) -> None:
        n, up = self.n, self.up
        for r, is_up in zip(robots, now_up):
            key = sender * n + r if sender < r else r * n + sender
            if is_up:
                self._open(key, t)
            elif key in up:
                self._end(key, up.pop(key)[0], t)
        # A touch on a link the reach has cut: the first success since, a new lifetime.
        for r in touched:
            key = sender * n + r if sender < r else r * n + sender
            if key not in up:
                self._open(key, t)

    def _open(self, key: int, t: float) -> None:
        if self._on_up:
            a, b = divmod(key, self.n)
            event = LinkUp(t, a, b)
            notify(self._on_up, event)
        since = self.envelope.up.get(key)
        if since is None and key in self._left:
            # Up while the pair is beyond the reach by the envelope's account (by rounding, at
            # the range's edge): cut at once, as the record is (radio_links.recorded_lifetimes).
            self._end(key, t, t)
        else:
            self.up[key] = (t, since)

    def _entered_reach(self, event: LinkUp) -> None:
        # The reach's state at t = 0 is set after everything else due then (the envelope
        # starts last), so a decision at t = 0 learns its reach interval here.
        key = event.a * self.n + event.b
        mine = self.up.get(key)
        if mine is not None and mine[1] is None and event.t_s <= mine[0]:
            self.up[key] = (mine[0], event.t_s)

    def _left_reach(self, event: LinkDown) -> None:
        key = event.a * self.n + event.b
        self._left[key] = event.t_s
        mine = self.up.get(key)
        if mine is not None and mine[1] == event.up_since_s:
            del self.up[key]
            self._end(key, mine[0], event.t_s)

    def up_pairs(self) -> tuple[np.ndarray, np.ndarray]:
        """The links up now: arrays ``(a, b)``, ``a < b``."""
        return up_pairs(self.up, self.n)

    @property
    def now_s(self) -> float:
        """The instant the links of :meth:`up_pairs` are up at: the run's present."""
        return float(self.env.now)
