"""The kernel's priorities and scheduled events: the SimPy helpers the engine's processes use.

SimPy orders events of the same instant by priority (URGENT before NORMAL), then
by the order they were scheduled. ``env.timeout(delay)`` always has NORMAL priority;
transmissions and deliveries must come before the deadlines of their instant
(docs/model.md, order of simultaneous events), which only ``env.schedule(event, URGENT,
delay)`` gives. ``schedule`` wants an event that has already been given its outcome, which
SimPy has no public way to give without scheduling it at once: :func:`scheduled_event`
gives it through :mod:`netsim.simpy_internals`, the one module that touches SimPy's
internals. Runtime link events use :data:`FIRST`, a priority ahead of URGENT: they are
delivered before anything else due at their instant. :func:`kernel_queue` and
:func:`advance_clock` (from :mod:`netsim.simpy_internals`) let one kernel event stand for
several consecutive instants of the runtime link events (``netsim.links.kinetic``) or several
entries of an agenda (``netsim.agenda``: the Ack ticks and deliveries).
"""

from __future__ import annotations

from collections.abc import Callable

import simpy
from simpy.events import NORMAL, URGENT

from netsim.simpy_internals import advance_clock, give_outcome, kernel_queue

__all__ = ["FIRST", "LAST", "NORMAL", "URGENT", "advance_clock", "kernel_queue", "scheduled_event"]

# Ahead of URGENT (0) at the same instant: runtime link events and their bookkeeping.
FIRST = -1
# After everything else of an instant (NORMAL is 1): the runtime links' start at t = 0.
LAST = 2


def scheduled_event(
    env: simpy.Environment,
    delay_s: float,
    priority: int = NORMAL,
    callback: Callable[[simpy.Event], None] | None = None,
    value: object = None,
) -> simpy.Event:
    """An event that occurs ``delay_s`` from now at ``priority`` (``URGENT`` or ``NORMAL``),
    calling ``callback(event)`` if given, with ``event.value`` the ``value`` given; a process
    may also ``yield`` it, as a timeout."""
    ev = give_outcome(simpy.Event(env), value)
    if callback is not None:
        ev.callbacks.append(callback)
    env.schedule(ev, priority, delay_s)  # type: ignore[arg-type]  # SimPy types priorities as an IntEnum
    return ev
