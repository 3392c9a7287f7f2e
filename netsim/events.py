"""The run's event bus: users' functions called as things happen.

:class:`EventBus` (``sim.events``) calls users' functions as things happen:
``sim.events.on("link_down", fn)``. Event names and their payloads (named tuples):

- ``course_change``: :class:`CourseChange` (a leg starts; a row of legs.parquet);
- ``link_up``: :class:`LinkUp`; ``link_down``: :class:`LinkDown`;
- ``role_change``: the protocol's record (the clustering protocol's ``RoleChange``:
  ``t_s, robot, role, leader, cause``, a row of roles.parquet);
- ``delivery``: :class:`Delivery` (a transmission reaches its receivers);
- ``drop``: :class:`Drop` (receptions the channel dropped, with the cause);
- ``message_delivered``: :class:`MessageDelivered` (a relayed message reaches its
  destination, end to end); ``message_dropped``: :class:`MessageDropped` (one no copy of
  which can reach it any more, with the cause).

A component emits an event only when someone listens (:meth:`EventBus.wants`), so an
unwatched run pays nothing. docs/events.md describes the order of events at one instant.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import numpy as np

__all__ = [
    "EVENT_NAMES",
    "CourseChange",
    "Delivery",
    "Drop",
    "EventBus",
    "LinkDown",
    "LinkUp",
    "MessageDelivered",
    "MessageDropped",
]


class CourseChange(NamedTuple):
    """A robot starts a new straight leg: from ``(x_m, y_m)`` at ``t_s`` with velocity
    ``(vx_mps, vy_mps)`` (positions unwrapped on a torus); ``cause`` as legs.parquet."""

    t_s: float
    robot: int
    x_m: float
    y_m: float
    vx_mps: float
    vy_mps: float
    cause: str


class LinkUp(NamedTuple):
    """Robots ``a < b`` come within range of each other (``min(r_a, r_b)``) at ``t_s``."""

    t_s: float
    a: int
    b: int


class LinkDown(NamedTuple):
    """The link ``a < b``, up since ``up_since_s``, breaks at ``t_s``."""

    t_s: float
    a: int
    b: int
    up_since_s: float


class Delivery(NamedTuple):
    """A transmission of ``kind`` ("ack", "data", ...) from ``sender`` reaches ``receivers``
    (ids ascending, read only) at ``t_s``; ``payload`` is what was sent."""

    t_s: float
    kind: str
    sender: int
    receivers: np.ndarray
    payload: object


class Drop(NamedTuple):
    """Receptions of a transmission of ``kind`` from ``sender`` that the channel dropped:
    ``receivers`` lost it for ``cause`` ("loss", "not_alive", "out_of_range" at send time;
    under a medium "collision", "half_duplex" at the frame's end), or, with ``receivers``
    empty, a frame the medium dropped at its sender ("queue_full", "retry_limit";
    docs/events.md)."""

    t_s: float
    kind: str
    sender: int
    receivers: np.ndarray
    cause: str


class MessageDelivered(NamedTuple):
    """Message ``msg_id`` from ``src`` reaches ``dst`` at ``t_s`` (its first copy to arrive),
    ``hops`` transmissions from the source, ``latency_s`` after it was sent: the row of
    messages.parquet with ``delivered`` true."""

    t_s: float
    msg_id: int
    src: int
    dst: int
    hops: int
    latency_s: float


class MessageDropped(NamedTuple):
    """Message ``msg_id`` from ``src`` to ``dst`` can no longer be delivered, known at ``t_s``.
    ``cause``: ``"no_route"`` (shortest-path routing found no neighbour leading to ``dst``),
    ``"lost"`` (the transmission carrying it was not received), ``"ttl"`` (its last copy
    reached the hop limit), ``"died_out"`` (flooding: the last copy in flight arrived and no
    robot that got it relays it, or nobody received the source's broadcast). ``hops``:
    transmissions on the path of the copy that ended it. A message still in flight when the
    run ends has neither event."""

    t_s: float
    msg_id: int
    src: int
    dst: int
    hops: int
    cause: str


EVENT_NAMES = (
    "course_change",
    "link_up",
    "link_down",
    "role_change",
    "delivery",
    "drop",
    "message_delivered",
    "message_dropped",
)
LINK_EVENTS = ("link_up", "link_down")


def read_only(array: np.ndarray) -> np.ndarray:
    """A view of ``array`` that cannot be written: what user code is handed of the run's
    own arrays (a subscriber or controller that wrote into one would change the run)."""
    view = array.view()
    view.flags.writeable = False
    return view


def notify(subscribers: list[Callable], event: object) -> None:
    """Call each of ``subscribers`` with ``event``. The list is read before the first call,
    so a subscriber that unsubscribes itself (or another) while called makes none of the
    others miss the event."""
    for fn in tuple(subscribers):
        fn(event)


class UnknownEvent(ValueError):
    """A subscription to an event name that no component emits."""


class NotASubscriber(TypeError):
    """A subscription of something that cannot be called."""


class EventBus:
    """Subscribers by event name; components emit, subscribers are called in the order
    they subscribed, at the simulated instant of the event (``sim.now``)."""

    def __init__(self) -> None:
        self._subscribers: dict[str, list[Callable]] = {name: [] for name in EVENT_NAMES}
        # Set by the run once it has started: link events must be asked for before.
        self.started = False
        self.link_events_on = False

    def on(self, name: str, fn: Callable) -> Callable:
        """Call ``fn(event)`` on every event ``name``; returns ``fn``."""
        if name not in self._subscribers:
            raise UnknownEvent(f"unknown event {name!r}; events are " + ", ".join(EVENT_NAMES))
        if not callable(fn):
            raise NotASubscriber(f"a subscriber to {name!r} must be callable, not {type(fn).__name__}")
        if name in LINK_EVENTS and self.started and not self.link_events_on:
            raise RuntimeError(
                f"subscribe to {name!r} before the run starts (or set events.runtime_links = 'on'): "
                "link events are solved during the run only when asked for from the start"
            )
        self._subscribers[name].append(fn)
        return fn

    def off(self, name: str, fn: Callable) -> None:
        """Stop calling ``fn`` on ``name`` (also from inside a subscriber: :func:`notify`)."""
        if name not in self._subscribers:
            raise ValueError(f"unknown event {name!r}; events are " + ", ".join(EVENT_NAMES))
        if fn not in self._subscribers[name]:
            raise ValueError(f"{getattr(fn, '__name__', fn)!r} is not subscribed to {name!r}")
        self._subscribers[name].remove(fn)

    def wants(self, name: str) -> bool:
        """Whether anybody listens to ``name`` (components build payloads only then)."""
        return bool(self._subscribers[name])

    def subscribers(self, name: str) -> list[Callable]:
        """The functions called on ``name``, in order (the list itself: it follows later
        subscriptions; for hot loops that call them directly)."""
        return self._subscribers[name]

    def emit(self, name: str, event: object) -> None:
        notify(self._subscribers[name], event)
