"""The internals of SimPy's kernel that netsim reads and sets, all in this one module.

netsim runs many callbacks for one kernel event, in the kernel's exact order: the agenda
of the Ack ticks, deliveries and timers (``netsim.agenda``) and the runtime link events
(``netsim.links.kinetic``). SimPy exposes neither the key of its next event, nor its counter of
event ids, nor a way to move its clock, nor a way to give an event its outcome without
scheduling it at once (``succeed()`` does both). So this module reads and sets them as
SimPy's own ``Environment.step()`` and ``Timeout.__init__`` do: the queue ``_queue`` (a
heap of ``(time, priority, id, event)``), the counter ``_eid``, the clock ``_now``, and an
event's ``_ok`` and ``_value``.

They are SimPy 4's. Loading this module with SimPy of another major version stops with
one line naming the version installed and the one tested (:data:`TESTED_MAJOR`), rather
than running on internals that may have changed.
"""

from __future__ import annotations

from collections.abc import Iterator
from heapq import heappush

import simpy

# The SimPy major version whose internals this module was written for and tested with
# (pyproject.toml pins it).
TESTED_MAJOR = 4


class SimPyVersionError(ImportError):
    """SimPy of a major version netsim was not tested with."""


def check_version(version: str) -> None:
    """Refuse a SimPy ``version`` whose major version is not :data:`TESTED_MAJOR`."""
    major = version.split(".", 1)[0]
    if major != str(TESTED_MAJOR):
        raise SimPyVersionError(
            f"SimPy {version} is installed, but netsim reads internals of SimPy {TESTED_MAJOR} "
            f"(netsim/simpy_internals.py) and was tested with it only: "
            f"pip install 'simpy>={TESTED_MAJOR}.1,<{TESTED_MAJOR + 1}'"
        )


check_version(simpy.__version__)


def kernel_queue(env: simpy.Environment) -> list:
    """SimPy's queue of scheduled events, a heap of ``(time, priority, id, event)``, to be
    read only (the same list for the whole run). An event scheduled now at ``(t,
    priority)`` would run after its head ``(t0, p0, ...)`` when ``t0 < t``, or ``t0 == t``
    and ``p0 <= priority`` (at equal priority SimPy runs events in the order they were
    scheduled)."""
    return env._queue  # type: ignore[attr-defined, no-any-return]


def event_ids(env: simpy.Environment) -> Iterator[int]:
    """SimPy's counter of event ids: ``next()`` of it is the id that the next event
    scheduled would get, so an entry keyed with it sorts exactly where that event would."""
    return env._eid  # type: ignore[attr-defined, no-any-return]


def now(env: simpy.Environment) -> float:
    """The kernel's clock (``env.now``, without the property's cost on the hot path)."""
    return env._now  # type: ignore[attr-defined, no-any-return]


def set_now(env: simpy.Environment, t_s: float) -> None:
    """Set the kernel's clock to ``t_s``, as its ``step()`` does for an event due then;
    only valid when nothing in :func:`kernel_queue` would run before such an event."""
    env._now = t_s  # type: ignore[attr-defined]


def advance_clock(env: simpy.Environment, t_s: float) -> None:
    """Move the kernel's clock forward to ``t_s`` (never back); as :func:`set_now`."""
    if t_s > env._now:  # type: ignore[attr-defined]
        env._now = t_s  # type: ignore[attr-defined]


def give_outcome(event: simpy.Event, value: object = None) -> simpy.Event:
    """Give ``event`` a successful outcome carrying ``value`` without scheduling it (as
    ``Timeout`` does), so that it can be scheduled at a delay and priority of the caller's
    choosing; ``event.value`` reads ``value`` back."""
    event._ok = True
    event._value = value
    return event


def push(env: simpy.Environment, t_s: float, priority: int, eid: int, event: simpy.Event) -> None:
    """Queue ``event``, which has its outcome, in the kernel at the key ``(t_s, priority,
    eid)`` (an id from :func:`event_ids`), as ``env.schedule`` would with that id."""
    queue: list = env._queue
    heappush(queue, (t_s, priority, eid, event))
