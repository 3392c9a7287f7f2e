"""The local plan (``coverage.plan = "local"``; docs/model.md section 5, "Local plan"): every
robot decides its own step from what it has heard, and the network never splits.

What a robot knows (:class:`Memory`): for each robot whose Ack it has heard, the position
that Ack carried and the earliest time it can date from (its reception less the channel's
largest delay). It keeps that after its neighbour table lets the entry expire, for
``release_s`` after the Ack was sent; then it forgets the robot. Every robot moves at most
``speed_max_mps``, so a robot last heard at ``q`` at time ``s`` is, at time ``t``, within
``v (t - s)`` of ``q``.

The rules, for robot ``i`` deciding the step that runs over ``[t0, t1]`` (``t1 = t0 +
period``), its own position ``p`` at ``t0`` exact:

1. **Witness.** ``i`` lets go of a remembered robot ``j`` only if it knows a *certified
   witness* ``w``: a robot both ``i`` and ``j`` remember and that remembers both, with
   ``|p - q_w| + e_w < |p - q_j| - e_j`` and ``|q_w - q_j| + e_w + e_j < |p - q_j| - e_j``
   (``e = v (t0 - s)``): whatever the true positions at ``t0``, ``w`` is closer to both
   ends than they are to each other. Every other remembered robot is *kept*.
2. **Leash.** ``i`` ends the step within ``r - margin - v (t1 - s_j)`` of ``q_j`` for
   every kept ``j``; as ``q_j`` is fixed, the distance is convex in time and the radius
   linear, so ``i`` is then within ``r`` of ``j`` at every instant of the step whatever
   ``j`` does.
3. **Hold.** If ``i`` is farther than that radius from some kept ``q_j`` already (its
   knowledge of ``j`` is too old for it to answer for the link), ``i`` holds.

Why the network never splits: let ``K`` be the links in range at ``t0`` whose ends
remember each other. A link of ``K`` that some end lets go of has, by rule 1, a witness
whose two links are in ``K`` and truly shorter; by induction on length (the true lengths
at ``t0``: one order for every robot), the ends of every link of ``K`` stay joined by
links neither end lets go of. Each of those is kept by both ends; over the step an end
that moves keeps it in range (rule 2) and an end that holds does not change it (rule 3),
so it is in range at every instant of the step, and at the next ``t0`` it is in ``K``
again while both ends still remember each other. So the components of ``K`` never grow,
and the network (which contains ``K``) never has more components than ``K`` had when
control started: on a loss-free channel, always; under loss, unless a robot misses every
Ack of a neighbour in range for ``release_s``.
"""

from __future__ import annotations

import numpy as np

from mobility.spread import project_into
from mobility.steps import Plan, StepLimits, box_limit, cap_length, step_limit


class Memory:
    """What each robot has heard of each other robot: ``xy[i, j]``, the position in the
    latest Ack of ``j`` that ``i`` heard, and ``sent_s[i, j]``, the earliest time that Ack
    can have been sent (``-inf``: never heard)."""

    def __init__(self, n: int):
        self.xy = np.zeros((n, n, 2))
        self.sent_s = np.full((n, n), -np.inf)

    def hear(self, robot: np.ndarray, other: np.ndarray, xy: np.ndarray, heard_s: np.ndarray, delay_s: float):
        """Take the Acks in the robots' tables (reception times ``heard_s``; an Ack left at
        most ``delay_s`` before it arrived)."""
        sent = heard_s - delay_s
        newer = sent > self.sent_s[robot, other]
        r, o = robot[newer], other[newer]
        self.sent_s[r, o] = sent[newer]
        self.xy[r, o] = xy[newer]

    def known(self, now_s: float, release_s: float) -> np.ndarray:
        """``(n, n)``: ``i`` remembers ``j`` (heard an Ack of it sent less than ``release_s`` ago)."""
        return now_s - self.sent_s < release_s


def let_go(pos: np.ndarray, memory: Memory, known: np.ndarray, t0_s: float, speed_mps: float) -> np.ndarray:
    """``(n, n)``: robot ``i`` lets go of ``j`` (rule 1: it knows a certified witness).

    ``pos``: every robot's own position at ``t0_s``; ``known``: :meth:`Memory.known`.
    """
    n = len(pos)
    out = np.zeros((n, n), dtype=bool)
    mutual = known & known.T
    for i in range(n):
        nb = np.flatnonzero(known[i])
        if len(nb) < 2:
            continue
        q = memory.xy[i, nb]
        e = speed_mps * np.maximum(t0_s - memory.sent_s[i, nb], 0.0)
        d = np.hypot(*(q - pos[i]).T)
        shortest = d - e  # the shortest the link to each can be at t0
        longest = d + e
        between = np.hypot(*(q[:, None, :] - q[None, :, :]).transpose(2, 0, 1)) + e[:, None] + e[None, :]
        # rows: the witness w; columns: the robot j let go of.
        witness = (longest[:, None] < shortest[None, :]) & (between < shortest[None, :])
        witness &= mutual[np.ix_(nb, nb)] & known[nb, i][:, None]
        np.fill_diagonal(witness, False)
        out[i, nb] = witness.any(axis=0)
    return out


def leash_radius(memory: Memory, t1_s: float, limits: StepLimits) -> np.ndarray:
    """``(n, n)``: how far from ``q_j`` robot ``i`` may end the step (rule 2)."""
    return limits.keep_m - limits.speed_max_mps * (t1_s - memory.sent_s)


def plan_local(
    pos: np.ndarray,
    desired_mps: np.ndarray,
    memory: Memory,
    kept: np.ndarray,
    t0_s: float,
    limits: StepLimits,
) -> Plan:
    """Each robot's step (module notes): its wish, cut to its leashes, its reach and the area.

    ``kept``: ``(n, n)``, robot ``i`` keeps ``j`` (remembered and not let go of).
    """
    n = len(pos)
    radius = leash_radius(memory, t0_s + limits.period_s, limits)
    robot, other = np.nonzero(kept)
    centre = memory.xy[robot, other]
    r = radius[robot, other]
    # Rule 3: a robot farther from a kept robot's last-heard position than its leash holds.
    too_far = np.zeros(n, dtype=bool)
    too_far[robot[np.hypot(*(pos[robot] - centre).T) > r]] = True
    movers = np.flatnonzero(~too_far & (np.hypot(*desired_mps.T) > 0))
    mobile = np.zeros(n, dtype=bool)
    mobile[movers] = True
    sel = mobile[robot]
    robot, centre, r = robot[sel], centre[sel], r[sel]
    # Standing still is allowed: never a leash shorter than the distance now (rounding).
    r = np.maximum(r, np.hypot(*(pos[robot] - centre).T))
    robot = np.concatenate([robot, movers])
    centre = np.concatenate([centre, pos[movers]])
    r = np.concatenate([r, np.full(len(movers), limits.reach_m)])

    wish = np.zeros((n, 2))
    wish[movers] = cap_length(desired_mps[movers] * limits.period_s, limits.reach_m)
    end = project_into(pos + wish, robot, centre, r, limits.side_m)
    move = end - pos
    move[~mobile] = 0.0
    s = np.ones(n)
    if len(robot):
        np.minimum.at(s, robot, step_limit(pos[robot] - centre, r, move[robot]))
    s = np.minimum(s, box_limit(pos, move, limits.side_m))
    move *= s[:, None]
    wished = np.hypot(*wish.T)
    held = (too_far & (np.hypot(*desired_mps.T) > 0)) | (
        mobile & (wished > 0) & (np.hypot(*(move - wish).T) > 1e-9 * limits.range_m)
    )
    both = kept & kept.T
    return Plan(move / limits.period_s, np.full(n, -1), held, int(np.triu(both, 1).sum()))


def sources_heard(memory: Memory, known: np.ndarray, reach_m: float, pos: np.ndarray):
    """Pairs ``(robot, position it last heard of another robot within reach_m)``: the
    forces' sources in the local plan."""
    robot, other = np.nonzero(known)
    xy = memory.xy[robot, other]
    near = np.hypot(*(xy - pos[robot]).T) < reach_m
    return robot[near], xy[near]
