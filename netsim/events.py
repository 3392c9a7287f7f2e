"""Kernel events at a chosen priority: the one place that uses SimPy's event internals.

SimPy orders events of the same instant by priority (URGENT before NORMAL), then by the
order they were scheduled. ``env.timeout(delay)`` always has NORMAL priority; transmissions
and deliveries must come before the deadlines of their instant (docs/model.md, order of
simultaneous events), which only ``env.schedule(event, URGENT, delay)`` gives. ``schedule``
wants an event that has already been given its outcome, and SimPy has no public way to give
one without scheduling it at once (``succeed()`` does both); so :func:`scheduled_event` sets
the two attributes ``_ok`` and ``_value`` itself, as SimPy's own ``Timeout.__init__`` does.
"""

from __future__ import annotations

from collections.abc import Callable

import simpy
from simpy.events import NORMAL, URGENT

__all__ = ["NORMAL", "URGENT", "scheduled_event"]


def scheduled_event(
    env: simpy.Environment,
    delay_s: float,
    priority: int = NORMAL,
    callback: Callable[[simpy.Event], None] | None = None,
) -> simpy.Event:
    """An event that occurs ``delay_s`` from now at ``priority`` (``URGENT`` or ``NORMAL``),
    calling ``callback(event)`` if given; a process may also ``yield`` it, as a timeout."""
    ev = simpy.Event(env)
    ev._ok = True
    ev._value = None
    if callback is not None:
        ev.callbacks.append(callback)
    env.schedule(ev, priority, delay_s)  # type: ignore[arg-type]  # SimPy types priorities as an IntEnum
    return ev
