"""What a protocol that organises robots into groups tells the rest of a run.

The engine defines no roles: a protocol that forms groups (the clustering stack) provides a
:class:`GroupView`, and :func:`netsim.run.build` hands it to whoever needs it (the control
loop and its controllers, :func:`netsim.topology.snapshot`). One convention makes roles
readable without the protocol's codes: every robot has a *leader*, its own id for a leader,
the leader's id for a member of a group, and -1 for a robot in no group
(:func:`leads_itself`, :func:`in_a_group`).
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np


@runtime_checkable
class GroupView(Protocol):
    """The groups of a run as its protocol knows them."""

    role_names: tuple[str, ...]  # the label of each role code, as in roles.parquet

    @property
    def role(self) -> np.ndarray:
        """``(N,)`` each robot's role code now (``role_names[code]`` is its label)."""
        ...

    @property
    def leader(self) -> np.ndarray:
        """``(N,)`` each robot's leader now: its own id for a leader, -1 for none."""
        ...

    def heard_leaders(self, leader: int, now: float) -> tuple[np.ndarray, np.ndarray]:
        """Ids and last-heard positions ``(k, 2)`` of the other leaders ``leader`` knows of
        (those it hears and those its neighbours hear)."""
        ...

    def neighbourhood(self, now: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """What every robot knows of those around it (those it hears and those they hear):
        arrays ``(robot, other, last-heard position of other (k, 2))``."""
        ...

    def heard_acks(self, now: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """What each robot itself heard: arrays ``(robot, sender, position in the sender's
        latest Ack it heard (k, 2), when it heard it, the power it heard it at (dBm, NaN
        where the channel measures none))``, entries its table no longer counts live
        included while they are kept."""
        ...


def leads_itself(leader: np.ndarray) -> np.ndarray:
    """Mask of the leaders, from an array of leaders (module notes).

    >>> leads_itself(np.array([0, 0, -1, 3])).tolist()
    [True, False, False, True]
    """
    return leader == np.arange(len(leader))


def in_a_group(leader: np.ndarray) -> np.ndarray:
    """Mask of the members of a group led by another robot.

    >>> in_a_group(np.array([0, 0, -1, 3])).tolist()
    [False, True, False, False]
    """
    return (leader >= 0) & ~leads_itself(leader)
