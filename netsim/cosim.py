"""Driving a run from outside (co-simulation): what the models hand the simulation when they
are built, so that :class:`~netsim.sim.Simulation` can offer ``drive``, ``neighbours``,
``send`` and ``inbox`` (docs/cosim.md) without the engine importing a model.

- a mobility model that moves robots as told (``mobility.model = "external"``) is a
  :class:`Driver`;
- a protocol that keeps neighbour tables (the Ack beacon, the clustering) is a
  :class:`NeighbourView`, and a :class:`LinkQualityView` when its tables keep each entry's
  last received power (theirs do);
- a protocol that relays messages between any two robots (the clustering) is a
  :class:`Messenger`.

:func:`netsim.run.build` hands each to the simulation when the component is one, as it
hands the protocol's :class:`~netsim.groups.GroupView`. The checks of a caller's input live
here (:func:`robot_ids`, :func:`velocities`): they run before anything changes, so a refused
call leaves the run as it was.
"""

from __future__ import annotations

from typing import Any, NamedTuple, Protocol, runtime_checkable

import numpy as np

from netsim.errors import NetsimInputError
from netsim.geometry import SPEED_OF_LIGHT_MPS, drivable


class CommandError(NetsimInputError, ValueError):
    """A call from outside that cannot be carried out (an unknown robot, a velocity that is
    not finite, ...): the message names the value; nothing in the run has changed."""


class Arrival(NamedTuple):
    """A message that reached its destination: when, from whom, what it carried, its id
    (the ``msg_id`` of the ``messages`` and ``hops`` tables)."""

    t_s: float
    src: int
    payload: Any
    msg_id: int


@runtime_checkable
class Driver(Protocol):
    """A mobility model that moves robots only as told."""

    def drive(self, robots: np.ndarray, velocities_mps: np.ndarray, now: float) -> None:
        """From ``now`` on, ``robots[k]`` moves at ``velocities_mps[k]`` (checked input)."""
        ...


@runtime_checkable
class AckSchedule(Protocol):
    """A protocol whose robots beacon Acks: a robot's next Ack leaves at most
    ``ack_period_s + ack_jitter_s`` after its previous one."""

    @property
    def ack_period_s(self) -> float: ...

    @property
    def ack_jitter_s(self) -> float: ...


@runtime_checkable
class NeighbourView(Protocol):
    """What each robot's neighbour table holds."""

    def heard(self, now: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Every robot's live table entries now, as dense arrays with one row per robot and
        a column per slot: ids ``(N, S)`` (-1 in a slot with no live entry), the positions
        the entries' last Acks told ``(N, S, 2)``, and when those Acks arrived ``(N, S)``."""
        ...


@runtime_checkable
class LinkQualityView(Protocol):
    """Neighbour tables that keep each entry's last received power."""

    def link_quality(self, now: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Every robot's live table entries now, as :meth:`NeighbourView.heard`'s dense
        arrays: ids ``(N, S)`` (-1 in a slot with no live entry), the power (dBm) at which
        the robot got each entry's last Ack (NaN where the channel measures no power) and
        when that Ack arrived ``(N, S)``."""
        ...


@runtime_checkable
class Messenger(Protocol):
    """A protocol that carries messages between any two robots."""

    def send_message(self, src: int, dst: int, payload: Any) -> int:
        """Send ``payload`` from ``src`` to ``dst`` now (checked input); returns its id."""
        ...

    def inbox(self, robot: int) -> list[Arrival]:
        """The messages that have reached ``robot``, in order of arrival."""
        ...


def robot_id(robot: Any, n: int, what: str = "robot") -> int:
    """``robot`` as an index in ``[0, n)``, or :class:`CommandError` naming it."""
    if isinstance(robot, bool) or not isinstance(robot, int | np.integer):
        raise CommandError(f"{what} = {robot!r}: must be an integer robot id in [0, {n})")
    if not 0 <= int(robot) < n:
        raise CommandError(f"{what} = {int(robot)}: no such robot; ids are 0 to {n - 1}")
    return int(robot)


def robot_ids(robots: Any, n: int) -> np.ndarray:
    """``robots`` (an id or a sequence of ids) as an int64 array of distinct ids in ``[0, n)``."""
    arr = np.atleast_1d(np.asarray(robots))
    if arr.ndim != 1 or (arr.size and arr.dtype.kind not in "iu"):
        raise CommandError(f"robots = {robots!r}: must be integer robot ids in [0, {n})")
    ids = arr.astype(np.int64)
    bad = (ids < 0) | (ids >= n)
    if bad.any():
        raise CommandError(f"robots: {int(ids[bad][0])} is no robot; ids are 0 to {n - 1}")
    if len(ids) > 1 and np.bincount(ids, minlength=n).max() > 1:
        raise CommandError(f"robots = {ids.tolist()}: each robot may be named once")
    return ids


def as_numbers(value: Any) -> np.ndarray:
    """``value`` as a float array, if it holds numbers: text that reads as a number ("1")
    and truth values are not velocities (ValueError), whether alone or beside numbers (each
    row of a list is looked at)."""
    a = np.asarray(value)
    rows = value if isinstance(value, list | tuple) else (value,)
    if a.dtype.kind not in "iuf" or any(np.asarray(row).dtype.kind not in "iuf" for row in rows):
        raise ValueError(f"not numbers: {value!r:.60}")
    return a.astype(float)


def velocities(velocities_mps: Any, k: int) -> np.ndarray:
    """``velocities_mps`` as a float ``(k, 2)`` array of finite values (one row may be given
    as a pair when ``k == 1``)."""
    try:
        v = as_numbers(velocities_mps)
    except (TypeError, ValueError):
        raise CommandError(f"velocities_mps = {velocities_mps!r}: must be numbers, shape ({k}, 2)") from None
    if k == 1 and v.shape == (2,):
        v = v.reshape(1, 2)
    if v.shape != (k, 2):
        raise CommandError(f"velocities_mps has shape {v.shape}: one row (vx, vy) per robot is ({k}, 2)")
    if not np.isfinite(v).all():
        row = int(np.flatnonzero(~np.isfinite(v).all(axis=1))[0])
        raise CommandError(f"velocities_mps[{row}] = {v[row].tolist()}: must be finite, m/s")
    fast = ~drivable(v)
    if fast.any():
        row = int(np.flatnonzero(fast)[0])
        raise CommandError(f"velocities_mps[{row}] = {v[row].tolist()}: faster than light ({SPEED_OF_LIGHT_MPS:g} m/s)")
    return v
