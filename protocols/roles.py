"""The clustering's roles (paper section 1.3.1) and the table of role changes.

The protocol writes every robot's role and leader in :class:`Roles`; the rest of a run
reads them through the stack's :class:`~netsim.groups.GroupView`, and tools reading
``roles.parquet`` get the labels from the protocol plugin (:data:`LABELS`).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from netsim.plugins import RoleLabels
from netsim.trace import Trace

# Roles, in the paper's terms: gamma (undecided), beta (member), alpha (leader).
UNDECIDED, MEMBER, LEADER = 0, 1, 2
ROLE_NAMES = ("gamma", "beta", "alpha")
# The cause recorded when a member's leader times out (rule 3).
LEADER_LOST = "rule3_leader_lost"
LABELS = RoleLabels(ROLE_NAMES[LEADER], ROLE_NAMES[MEMBER], ROLE_NAMES[UNDECIDED], LEADER_LOST)

NO_LEADER = -1


class RoleChange(NamedTuple):
    t_s: float
    robot: int
    role: str
    leader: int
    cause: str


ROLES_SCHEMA = {"t_s": "float64", "robot": "int64", "role": "object", "leader": "int64", "cause": "object"}


class Roles:
    """Every robot's role and leader (a leader leads itself; ``NO_LEADER`` for none)."""

    def __init__(self, n: int):
        self.role = np.full(n, UNDECIDED, dtype=np.int8)
        self.leader = np.full(n, NO_LEADER, dtype=np.int64)


def declare_roles(trace: Trace) -> None:
    """The ``roles`` table exists in every run of these protocols, empty if nobody changes."""
    trace.declare("roles", RoleChange)
