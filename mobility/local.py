"""The local plan (``coverage.plan = "local"``; docs/model.md section 5, "Local plan"): every
robot decides its own step from what it has heard, and the network never splits.

What a robot knows (:class:`Memory`): for each robot whose Ack it has heard, the position
that Ack carried and the earliest time it can date from (its reception less the channel's
largest delay). It keeps that after its neighbour table lets the entry expire, for
``release_s`` after the Ack was sent; then it forgets the robot. Every robot moves at most
``speed_max_mps``, so a robot last heard at ``q`` at time ``s`` is, at time ``t``, within
``v (t - s)`` of ``q``. An Ack also carries its sender's list of the robots it remembers
(:class:`Lists`), the lists it holds of them and its records of the shadowing: from those a
robot learns which robots its neighbours remember, whom those remember, and where they
heard them.

The rules, for robot ``i`` deciding the step that runs over ``[t0, t1]`` (``t1 = t0 +
period``), its own position ``p`` at ``t0`` exact:

1. **Detour.** ``i`` lets go of a remembered robot ``j`` only if it knows a *certified
   detour*: a path from ``i`` to ``j`` through robots it remembers and robots two hops out
   (named by the lists it holds), each link of which joins two robots that remember each
   other (as the lists ``i`` holds of them, or their senders held, show) and is, whatever
   the true positions at ``t0``, shorter than the link ``(i, j)``: its longest possible
   length (``|q_a - q_b| + e_a + e_b``, ``e = v (t0 - s)``; ``|p - q_a| + e_a`` from ``i``)
   below the shortest possible length of ``(i, j)`` (``|p - q_j| - e_j``); under shadowing
   each length is taken at zero shadowing under the link's record (:class:`Lists`). Every
   other remembered robot is *kept*. (With detours of two links this is the relative neighbourhood graph; with
   any, the local minimum spanning tree.)
2. **Leash.** ``i`` ends the step within ``r - margin - v (t1 - s_j)`` of ``q_j`` for
   every kept ``j``; as ``q_j`` is fixed, the distance is convex in time and the radius
   linear, so ``i`` is then within ``r`` of ``j`` at every instant of the step whatever
   ``j`` does.
3. **Hold.** If ``i`` is farther than that radius from some kept ``q_j`` already (its
   knowledge of ``j`` is too old for it to answer for the link), ``i`` holds.
4. **Pull** (:func:`pulls`). On a map a robot announces its wish as it could carry it out
   (:func:`netsim.mobility.geodesic.within_reach`), not a wish into a wall.
5. **Walls** (on a map, :func:`cut_for_walls`). ``i`` answers for every kept ``j``: the
   convex hull of the straight step and of the disk where ``j`` stands (``e_j(t0)`` around
   ``q_j``: ``j`` holds, rule 7) keeps off the walls, so every segment between the two
   robots during the step is clear of walls; else a shorter step, else its step's part
   along either axis of the map's grid or the step turned (:data:`SLIDES`) tested alike,
   or it holds. A detour's
   link must be surely clear of walls too (:func:`clear_of_walls`). Where walls let power
   through (log-distance with ``wall_loss_db``), a link whose hull meets ``k`` of the
   walls' boxes crosses at most ``k`` walls and is certified within the range at ``k``
   walls instead (:func:`through_walls`, :attr:`Walls.through_m`).
6. **Expansion.** In open space (:func:`centre_estimates`) each robot estimates its
   team's centre as the mean of its own estimate and those the robots it heard announced
   at their latest steps (a consensus: over a connected team the estimates meet), and adds
   the global plan's push away from it to its wish. On a map (:mod:`netsim.mobility.explored`)
   each robot keeps the cells it knows its team has covered, its own and those the Acks it
   heard carried, and is pushed through free space toward the nearest free cell outside
   them, as the global plan's robots are toward the nearest no robot covers.
7. **Turns** (on a map, :func:`turn_takers`). At each step every robot draws the same
   order of the robots (a stream of the run's seed), and a robot moves only if it outranks
   every robot it keeps: of two robots that keep each other, one holds. So a robot answers
   for a kept link against the other end holding where it stands (rule 5): if that end
   keeps it too, it holds; if not, the link is none the argument below needs.

**Release** (:class:`Silence`, on a channel that loses no frame): ``i`` lets go of a robot
it has heard no Ack of for longer than the largest gap between two (``ack_period_s +
ack_jitter_s`` plus the channel's delay jitter): an Ack of it due before the step did not
arrive, so the link was down at an instant of the *window* ``[t0 - W, t0]``
(:func:`silence_of`); the robot stays a node of rule 1's graph, but that link is no
detour's link. Rule 1 then certifies a detour's links up over the whole window: on each
of its pieces (:data:`netsim.mobility._local_kernels.WINDOW_PIECES`) each end within a
disk about where its known leg puts it (the cap's travel where it knows none), a measured
link's pair travel counted from the window's start. Under loss a missed Ack says
nothing of the link: no release, ``W = 0``.

``r`` is the plan's range: the range on a disk (the implied range under log-distance;
on a map, for a link clear of walls), and under shadowing the *sure* distance, where even
the clipped worst shadowing (``+4 sigma``) leaves a link up. Under the unit disk a link
through a wall is never certified: a robot that keeps it holds, and a link whose two robots
hold does not change.

**Shadowing** (in open space, :class:`Fade`): each robot measures the pair's shadowing
``X`` on every Ack it hears, from the power it received it at, ``X = P_t - PL(d) - P_r``
(``d`` from the position the Ack carried; the shadowing is reciprocal, so what ``i``
measures on ``j``'s Ack is the pair's), and keeps a link by the global plan's fade-margin
rule (:mod:`netsim.mobility.keep`, :mod:`netsim.mobility._fade_kernels`): within the
length where its margin with that ``X`` is ``B = min(fade_margin_db, margin)`` (in place of
``r`` in rules 2 and 3), while the pair's travel since the Ack, the other end's next step
at the speed cap every robot keeps (:attr:`Fade.speed_mps`) and its own step stay within
the travel ``B`` allows; else within the sure distance. The pair's travel since a
measurement is what ``i`` knows of it (:meth:`Memory.travel_m`): its own leg, and each
robot's speed as its latest Ack carried it (with the time its leg started: velocities
change only at control steps), the cap only before that or where no velocity is known. An
Ack's list carries the shadowing its sender measured on each robot it lists, so rule 1
certifies a detour's link by a measurement too: up at ``t0`` unless the shadowing moved
beyond ``coverage.detour_sigmas`` standard deviations (default ``FADE_SIGMAS``) over the
pair's largest travel since. Both
make the guarantee below probabilistic for the links longer than the sure distance, as the
global plan's. A link whose two robots hold does not
change (the shadowing runs in the pair's travel). A robot that cannot answer for a kept
link alone (rule 3) answers for its half when both ends can compute the same limits
(:meth:`Fade.halves`): it knows where the other is at ``t0`` and reads the link's record
(:func:`link_records`); it ends within half the link's allowed length of the midpoint at
``t0`` and takes at most half of the pair's travel left, so a weak link, which would hold
both robots for good, moves a little and its shadowing changes.

Why the network never splits: let ``K`` be the links up over the window ``[t0 - W, t0]``
whose ends remember each other. No end lets go of one as silent (it carried every Ack of
the window). A link of ``K`` that some end lets go of has, by rule 1, a detour
whose links are in ``K`` and truly shorter; by induction on length (the true lengths
at ``t0``: one order for every robot), the ends of every link of ``K`` stay joined by
links neither end lets go of. Each of those is kept by both ends; over the step an end
that moves keeps it up whatever the other does (rules 2 and 5 alone), or keeps its half
while the other keeps its half, answers alone or holds (halves), or, on a map, keeps it
clear of walls (or within the range through the walls it can cross) against the other
end holding, which the other then does (rules 5 and 7: of two robots that keep each
other one holds), an end that cannot holds (rules 3 and 5),
and a link whose ends hold does not change, so it is up at every instant of the step, so
up over the next step's window, and at the next ``t0`` it is in ``K`` again while both
ends still remember each other. So the components of ``K`` never grow,
and the network (which contains ``K``) never has more components than ``K`` had when
control started: on a loss-free channel, always; under loss, unless a robot misses every
Ack of a neighbour in range for ``release_s``.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from netsim.mobility.keep import FADE_SIGMAS, fade_travel_m
from netsim.mobility.spread import add_pulls, project_into
from netsim.mobility.steps import SAFETY, Plan, StepLimits, box_limit, cap_length, fell_short, step_limit

from netsim.compiled import filled, load
from netsim.geometry import beyond, distances_m, in_motion, row_starts, speeds_mps
from netsim.trajectory import points_on_legs
from netsim.world.free_space import short_of_walls
from netsim.world.maps import OccupancyMap


class Walls(NamedTuple):
    """What a robot knows of the walls: its team's map, as a lower bound of the distance from
    a cell's points to the nearest occupied cell (:func:`walls_of`). ``on``: False where there
    is no map (then nothing is a wall)."""

    on: bool
    field: np.ndarray  # (H, W): the distance from the cell's centre to the nearest wall, less half a diagonal, m
    origin_x_m: float
    origin_y_m: float
    resolution_m: float
    clearance_m: float  # a hull clear of walls keeps more than this from every wall, m
    open: np.ndarray  # (H, W) bool: cells that are not walls (where a robot may be)
    # Where walls let some power through (log-distance, wall_loss_db): through_m[k - 1], the
    # plan's range for a link that crosses at most k walls (empty: a wall cuts every link).
    through_m: np.ndarray
    rects: np.ndarray  # (R, 4): the occupied cells as boxes x0, x1, y0, y1 (m), for counting walls


NO_WALLS = Walls(
    False, np.full((1, 1), np.inf), 0.0, 0.0, 1.0, 0.0, np.ones((1, 1), bool), np.empty(0), np.empty((0, 4))
)

# How far from every wall a hull must keep to be clear of walls, m: less than the hair by
# which the control loop stops a robot short of a wall head-on (free_space.free_fraction
# stops it that far along its leg, so a grazing approach ends nearer), so that a link from a
# robot standing there along the wall is clear; more
# than the rounding of the test, and than the tolerance within which line of sight puts a
# point on a grid line (netsim.world.los).
WALL_CLEARANCE_M = 1e-8


def walls_of(
    occupied: np.ndarray | None,
    origin_m: tuple[float, float] = (0.0, 0.0),
    resolution_m: float = 1.0,
    through_m: np.ndarray | tuple = (),
) -> Walls:
    """The walls of a map (``occupied``: ``(H, W)`` bool, row 0 at the bottom), or
    :data:`NO_WALLS` (None). A point ``x`` in the cell of centre ``c`` is at least
    ``field - |x - c|`` from every occupied cell (closed squares): a cell's points lie within
    half a diagonal of its centre. ``through_m``: the plan's range through 1, 2, ... walls
    (:attr:`Walls.through_m`)."""
    if occupied is None:
        return NO_WALLS
    through = np.ascontiguousarray(through_m, float).reshape(-1)
    from scipy.ndimage import distance_transform_edt

    half = resolution_m * math.sqrt(0.5)
    if not occupied.any():
        field = np.full(occupied.shape, np.inf)
    else:
        field = distance_transform_edt(~occupied) * resolution_m - half
    ox, oy, res = float(origin_m[0]), float(origin_m[1]), float(resolution_m)
    field = np.ascontiguousarray(field, float)
    rects = wall_boxes(occupied, (ox, oy), res) if len(through) else np.empty((0, 4))
    return Walls(True, field, ox, oy, res, WALL_CLEARANCE_M, np.ascontiguousarray(~occupied), through, rects)


def wall_boxes(occupied: np.ndarray, origin_m: tuple[float, float], resolution_m: float) -> np.ndarray:
    """The occupied cells as boxes ``x0, x1, y0, y1`` (m) that cover them exactly: each row's
    runs of occupied cells, a run grown upward while the rows above hold the same run. A
    segment meets a box in one stretch (boxes are convex), so it crosses no more walls (runs
    of occupied cells, :mod:`netsim.world.los`) than the boxes it meets.

    >>> wall_boxes(np.array([[1, 1, 0], [1, 1, 0], [0, 1, 1]], bool), (0.0, 0.0), 1.0).tolist()
    [[0.0, 2.0, 0.0, 2.0], [1.0, 3.0, 2.0, 3.0]]
    """
    h, w = occupied.shape
    growing: dict[tuple[int, int], int] = {}
    boxes = []
    for j in range(h + 1):
        row = occupied[j] if j < h else np.zeros(w, bool)
        edges = np.diff(np.r_[0, row.astype(np.int8), 0])
        runs = list(zip(np.flatnonzero(edges == 1).tolist(), np.flatnonzero(edges == -1).tolist()))
        ended = [run for run in growing if run not in set(runs)]
        for run in sorted(ended, key=lambda r: (growing[r], r)):
            boxes.append((run[0], run[1], growing.pop(run), j))
        for run in runs:
            growing.setdefault(run, j)
    cells = np.array(boxes, float).reshape(-1, 4)
    out = np.empty_like(cells)
    out[:, :2] = origin_m[0] + cells[:, :2] * resolution_m
    out[:, 2:] = origin_m[1] + cells[:, 2:] * resolution_m
    return np.ascontiguousarray(out)


def clear_of_walls(
    walls: Walls, a: np.ndarray, b: np.ndarray, e_a_m: np.ndarray, e_b_m: np.ndarray | None = None
) -> np.ndarray:
    """Whether the convex hull of the disk of radius ``e_a_m`` around ``a`` and the disk of
    radius ``e_b_m`` (default ``e_a_m``) around ``b`` (row-wise) keeps more than
    :attr:`Walls.clearance_m` from every wall cell (closed squares): then every segment between a
    point of the one and a point of the other is clear of walls. Exact, up to rounding: the
    hull is the union of the disks of radius ``(1 - f) e_a + f e_b`` around the points
    ``a + f (b - a)``, ``f`` in [0, 1]; the test walks the segment in steps of the clearance
    there (:attr:`Walls.field`, less the distance to the cell's centre, a lower bound) less
    that radius, and where that leaves less than a cell it tests the occupied cells near the
    next stretch of the hull one by one, with the separating axes of a box and the hull of
    two disks.

    >>> w = walls_of(np.eye(4, dtype=bool)[::-1], resolution_m=1.0)
    >>> clear_of_walls(w, np.array([[0.2, 0.2], [3.8, 3.5]]), np.array([[0.2, 3.5], [3.8, 0.2]]), np.zeros(2)).tolist()
    [False, False]
    >>> clear_of_walls(NO_WALLS, np.zeros((1, 2)), np.ones((1, 2)), np.ones(1)).tolist()
    [True]
    """
    a = np.asarray(a, float).reshape(-1, 2)
    b = np.asarray(b, float).reshape(-1, 2)
    ea = np.broadcast_to(np.asarray(e_a_m, float), (len(a),)).copy()
    eb = ea.copy() if e_b_m is None else np.broadcast_to(np.asarray(e_b_m, float), (len(a),)).copy()
    if not walls.on or len(a) == 0:
        return np.ones(len(a), dtype=bool)
    out = np.empty(len(a), dtype=bool)
    kernels = load("netsim.mobility._local_kernels", None, values=len(a))
    kernels.clear_many(walls, np.ascontiguousarray(a), np.ascontiguousarray(b), ea, eb, out)
    return out


def step_clear_of_walls(walls: Walls, p: np.ndarray, move: np.ndarray, q: np.ndarray, e_m: np.ndarray) -> np.ndarray:
    """Whether the convex hull of the straight step from ``p`` to ``p + move`` and the disk
    of radius ``e_m`` around ``q`` (row-wise) keeps more than :attr:`Walls.clearance_m` from
    every wall cell: then every segment between a point of the step and a point of the disk
    is clear of walls. Exact, up to rounding, as :func:`clear_of_walls`.

    >>> w = walls_of(np.eye(4, dtype=bool)[::-1], resolution_m=1.0)
    >>> p, q = np.array([[0.5, 2.5]]), np.array([[0.5, 0.5]])
    >>> step_clear_of_walls(w, p, np.array([[0.0, -1.5]]), q, np.zeros(1)).tolist()
    [True]
    >>> step_clear_of_walls(w, p, np.array([[2.0, 0.0]]), q, np.zeros(1)).tolist()
    [False]
    """
    p = np.ascontiguousarray(np.asarray(p, float).reshape(-1, 2))
    move = np.ascontiguousarray(np.asarray(move, float).reshape(-1, 2))
    q = np.ascontiguousarray(np.asarray(q, float).reshape(-1, 2))
    if not walls.on or len(p) == 0:
        return np.ones(len(p), dtype=bool)
    out = np.empty(len(p), dtype=bool)
    kernels = load("netsim.mobility._local_kernels", None, values=len(p))
    kernels.steps_clear(walls, p, move, q, filled(e_m, (len(p),)), out)
    return out


class Memory:
    """What each robot has heard of each other robot: ``xy[i, j]``, the position in the
    latest Ack of ``j`` that ``i`` heard, ``sent_s[i, j]``, the earliest time that Ack can
    have been sent (``-inf``: never heard), and ``vel[i, j]``, the velocity that Ack
    carried, which holds until ``until_s[i, j]`` (the sender's leg ends at the next control
    step; ``until_s = sent_s``: the velocity is not known to hold after the Ack)."""

    def __init__(self, n: int):
        self.xy = np.zeros((n, n, 2))
        self.sent_s = np.full((n, n), -np.inf)
        self.vel = np.zeros((n, n, 2))
        self.until_s = np.full((n, n), -np.inf)
        # Under shadowing (:class:`Fade`): the pair's shadowing ``i`` measured on that Ack
        # (dB, NaN: none), the margin it was received with (dB above the sensitivity), and
        # the earliest time the Ack can have been sent, which :meth:`at` leaves as it is.
        self.x_db = np.full((n, n), np.nan)
        self.margin_db = np.full((n, n), np.nan)
        self.measured_s = np.full((n, n), -np.inf)
        # How far from ``q_j`` robot ``i`` answers for the link (:func:`leash_radius`); None:
        # the plan's range less its margin for every link.
        self.keep_m: np.ndarray | None = None
        # The velocity with which ``i`` knows ``j`` moved from ``leg_from_s[i, j]`` until
        # ``leg_until_s[i, j]``, its next step (that of the latest Ack of ``j`` it heard, if
        # sent on a leg; ``i``'s own on the diagonal, inf: it holds until ``i`` steps again),
        # NaN: unknown. After that step ``j`` may be on a leg no Ack told of yet
        # (:func:`largest_travel_m` counts the cap; rule 1 follows ``j`` back along the leg
        # over its window, :meth:`at`'s uncertainty counting the cap after it).
        self.leg_velocity_mps = np.full((n, n, 2), np.nan)
        self.leg_from_s = np.full((n, n), np.inf)
        self.leg_until_s = np.full((n, n), np.inf)

    def hear(
        self,
        robot: np.ndarray,
        other: np.ndarray,
        xy: np.ndarray,
        heard_s: np.ndarray,
        delay_s: float,
        leg_velocity_mps: np.ndarray | None = None,
        leg_start_s: np.ndarray | None = None,
        leg_until_s: float = -np.inf,
        x_db: np.ndarray | None = None,
        margin_db: np.ndarray | None = None,
    ):
        """Take the Acks in the robots' tables (reception times ``heard_s``; an Ack left at
        most ``delay_s`` before it arrived). With ``leg_velocity_mps`` and ``leg_start_s``
        (each robot's current leg), an Ack sent during its sender's current leg carries
        that leg's velocity, which holds until ``leg_until_s`` (the next control step).
        ``x_db``, ``margin_db``: the shadowing each robot measured on each Ack and the
        margin it heard it with (:meth:`Fade.measure`; NaN: none)."""
        sent = heard_s - delay_s
        newer = sent > self.sent_s[robot, other]
        r, o, sent = robot[newer], other[newer], sent[newer]
        self.sent_s[r, o] = sent
        self.measured_s[r, o] = sent
        self.xy[r, o] = xy[newer]
        self.x_db[r, o] = np.nan if x_db is None else x_db[newer]
        self.margin_db[r, o] = np.nan if margin_db is None else margin_db[newer]
        if leg_velocity_mps is None or leg_start_s is None:
            self.vel[r, o] = 0.0
            self.until_s[r, o] = sent
            self.leg_velocity_mps[r, o] = np.nan
            self.leg_from_s[r, o] = np.inf
            self.leg_until_s[r, o] = np.inf
            return
        on_leg = sent >= leg_start_s[o]
        self.vel[r, o] = np.where(on_leg[:, None], leg_velocity_mps[o], 0.0)
        self.until_s[r, o] = np.where(on_leg, leg_until_s, sent)
        self.leg_velocity_mps[r, o] = np.where(on_leg[:, None], leg_velocity_mps[o], np.nan)
        # An Ack carries its sender's velocity and when its leg started.
        self.leg_from_s[r, o] = np.where(on_leg, leg_start_s[o], np.inf)
        self.leg_until_s[r, o] = np.where(on_leg, leg_until_s, np.inf)
        # Each robot knows its own leg: its velocity since the leg started, until it steps.
        own = np.arange(len(self.sent_s))
        self.leg_velocity_mps[own, own] = leg_velocity_mps
        self.leg_from_s[own, own] = leg_start_s
        self.leg_until_s[own, own] = np.inf

    @property
    def leg_speed_mps(self) -> np.ndarray:
        """``(n, n)``: the speed of :attr:`leg_velocity_mps` (NaN: unknown)."""
        return speeds_mps(self.leg_velocity_mps).reshape(self.leg_from_s.shape)

    def known(self, now_s: float, release_s: float) -> np.ndarray:
        """``(n, n)``: ``i`` remembers ``j`` (heard an Ack of it sent less than ``release_s`` ago)."""
        return remembered(self.sent_s, now_s, release_s)

    def at(self, t0_s: float, speed_mps: float, jitter_s: float) -> Memory:
        """What the robots know of each other at ``t0_s``, as a memory of Acks without
        velocities: each position carried along its known leg to ``t0_s``, and a sending
        time such that ``speed_mps (t - sent_s)`` bounds the distance to the true position
        at every ``t >= t0_s`` (the leg's velocity over the send time's uncertainty
        ``jitter_s``, then the speed cap from where the known leg ends)."""
        out = Memory(len(self.sent_s))
        heard = np.isfinite(self.sent_s)
        with np.errstate(invalid="ignore"):
            span = np.where(heard, np.clip(np.minimum(t0_s, self.until_s) - self.sent_s, 0.0, None), 0.0)
        # Carried along the leg by the position rule itself, a leg per pair from time 0.
        n = len(self.sent_s)
        pairs = n * n
        legs = (self.xy.reshape(pairs, 2), self.vel.reshape(pairs, 2), np.zeros(pairs))
        out.xy = points_on_legs(*legs, np.arange(pairs), span.reshape(pairs), n).reshape(self.xy.shape)
        error = speeds_mps(self.vel).reshape(self.vel.shape[:-1]) * jitter_s
        error = error + travel_at_cap_m(np.where(heard, self.until_s, -np.inf), t0_s, speed_mps)
        with np.errstate(invalid="ignore"):
            out.sent_s = np.where(heard, t0_s - error / speed_mps, -np.inf)
        out.until_s = out.sent_s.copy()
        out.x_db, out.margin_db, out.measured_s = self.x_db, self.margin_db, self.measured_s
        out.leg_velocity_mps, out.leg_from_s, out.leg_until_s = self.leg_velocity_mps, self.leg_from_s, self.leg_until_s
        return out

    def travel_m(self, since_s: np.ndarray, t0_s: float, speed_mps: float) -> np.ndarray:
        """``(n, n)``: the farthest ``i`` knows ``j`` (itself on the diagonal) can have travelled
        from ``since_s[i, j]`` to ``t0_s`` (:func:`largest_travel_m`)."""
        return largest_travel_m(self.leg_speed_mps, self.leg_from_s, self.leg_until_s, since_s, t0_s, speed_mps)


def largest_travel_m(
    leg_speed_mps: np.ndarray,
    leg_from_s: np.ndarray,
    leg_until_s: np.ndarray,
    since_s: np.ndarray,
    t0_s: float,
    speed_mps: float,
) -> np.ndarray:
    """The farthest a robot can have travelled from ``since_s`` to ``t0_s`` (``(n, m)``
    arrays, the leg's broadcast to its shape): at the speed its Ack carried (its leg's,
    which holds from ``leg_from_s`` until its next step, ``leg_until_s``) where that is
    known, at the speed cap before and after it, and at the cap all along where no speed
    is known (NaN) (:func:`netsim.mobility._local_kernels.largest_travel_m`)."""
    shape = np.shape(since_s)
    if np.size(since_s) == 0:
        return np.zeros(shape)
    since = np.ascontiguousarray(since_s, float).reshape(shape[0], -1)
    speed, start, end = (filled(v, shape).reshape(since.shape) for v in (leg_speed_mps, leg_from_s, leg_until_s))
    kernels = load("netsim.mobility._local_kernels", since.shape[0])
    return kernels.largest_travels_m(speed, start, end, since, float(t0_s), float(speed_mps)).reshape(shape)


def travel_at_cap_m(since_s: np.ndarray, t_s: float, speed_mps: float) -> np.ndarray:
    """:func:`largest_travel_m` of robots whose legs are not known: the cap all along, from
    ``since_s`` (any shape) to ``t_s``; what a robot answers for against another's motion."""
    return largest_travel_m(np.nan, np.nan, np.nan, since_s, t_s, speed_mps)


class Heard(NamedTuple):
    """What the robots heard, as rule 1 and the forces read it: each robot's own memory
    (``known``) and, from each robot it remembers, the list the latest Ack it heard of that
    robot carried (:class:`Lists`). The lists of every snapshot are stored one after the
    other, each sorted by sender, then by the robot listed."""

    known: np.ndarray  # (n, n) bool: Memory.known
    which: np.ndarray  # (n, n) int64: the snapshot whose list i holds from u; -1: none
    start: np.ndarray  # (K, n + 1) int64: snapshot k's list of u is entries start[k, u]:start[k, u + 1]
    other: np.ndarray  # (M,) int64: the robot an entry lists
    sent_s: np.ndarray  # (M,): the earliest time the sender's latest Ack of it can have been sent
    xy: np.ndarray  # (M, 2): the position that Ack carried
    release_s: float
    x_db: np.ndarray | None = None  # (M,): the shadowing the sender measured on that Ack (NaN: none)
    # held[t % R, u, w] (int32, a ring of R slots): the step of w's list that u held when it
    # made its list of step t (-1: none); empty: not known (rule 1's graph then ends at the
    # robots i remembers). netsim.mobility._local_kernels.held_list reads it.
    held: np.ndarray | None = None
    steps: np.ndarray | None = None  # (K,) int64: each snapshot's step (lists taken before it)
    records_db: np.ndarray | None = None  # (n, n): the records rule 1 orders by (NaN: none)
    records_from: int = -1  # the steps whose lists carry them: [records_from, records_to)
    records_to: int = -1


# Rule 1's order under shadowing reads records taken every RECORD_EPOCH_STEPS-th list, those
# of the epoch of the list taken RECORD_DELAY_STEPS steps before the latest (Lists): late
# enough that the lists a robot holds mostly carry them (a list carries its epoch's and the
# previous one's), early enough that they are still close to the shadowing they order by.
RECORD_EPOCH_STEPS = 3
RECORD_DELAY_STEPS = 2


def lists_depth(release_s: float, duration_s: float, control_period_s: float) -> int:
    """The lists :class:`Lists` keeps: one per control step an Ack still remembered can
    date from (none from before the run: a ``release_s`` beyond ``duration_s`` keeps no
    more)."""
    return math.ceil(min(release_s, duration_s) / control_period_s) + 2


def lists_bytes(n: int, depth: int) -> int:
    """Memory of the holdings of :class:`Lists` of ``n`` robots keeping ``depth`` lists."""
    return (depth + 1) * n * n * np.dtype(np.int32).itemsize


class Lists:
    """What an Ack carries of its sender's memory: the robots it remembers, each with the
    position, the earliest sending time and the shadowing measured (NaN: none) of the latest
    Ack of it the sender heard; the lists the sender holds of them (so a robot also learns
    whom the robots two hops out remember); and the *records* of the current and the previous
    epoch (below).

    A robot's memory changes at control steps alone (:meth:`Memory.hear`), and only
    refreshes there: an Ack sent after a step carries at least the list of that step. So
    ``i``, holding an Ack of ``u`` sent no earlier than ``s``, holds at least ``u``'s list
    as of its latest step before ``s`` (:meth:`take` keeps the last ``depth`` of them; with
    none old enough, ``i`` counts the list as empty). The lists start with control: an Ack
    sent before the first step carries none.

    Records (rule 1's order under shadowing, docs/model.md 5.1): every
    :data:`RECORD_EPOCH_STEPS`-th list starts an epoch, and each robot's records of that epoch
    are the shadowing it had measured then on each robot it remembered. A list carries its
    epoch's records and the previous epoch's, so every robot holding a list of the epoch
    being read, or of the next, reads the same numbers. At each step rule 1 reads the epoch
    of the list taken :data:`RECORD_DELAY_STEPS` steps before the latest."""

    def __init__(self, n: int, depth: int):
        self.n = n
        self.depth = int(depth)
        self._taken: list[tuple] = []
        self._steps = 0  # lists taken so far: the next list's step
        self._records: dict[int, np.ndarray] = {}
        # Each list's holdings, by step, in a ring one longer than the lists kept: the list
        # taken after a step's Heard (rule 1 reads it after) never overwrites one it names.
        self._held: np.ndarray | None = None

    def take(self, memory: Memory, now_s: float, release_s: float) -> None:
        """Every robot's list from now on: the robots it remembers (:meth:`Memory.known`)."""
        known = memory.known(now_s, release_s)
        robot, other = np.nonzero(known)
        start = row_starts(robot, self.n)
        # The step of the list each robot holds of each other one now (-1: none).
        version = self._versions(memory.sent_s)
        # An Ack carries the lists its sender holds of the robots its list names, no others.
        if self._held is None:
            self._held = np.full((self.depth + 1, self.n, self.n), -1, np.int32)
        self._held[self._steps % len(self._held)] = np.where(
            known & (version >= 0), version + (self._steps - len(self._taken)), -1
        )
        self._taken.append(
            (
                float(now_s),
                start,
                other,
                memory.sent_s[robot, other],
                memory.xy[robot, other],
                memory.x_db[robot, other],
            )
        )
        del self._taken[: -self.depth]
        if self._steps % RECORD_EPOCH_STEPS == 0:
            epoch = self._steps // RECORD_EPOCH_STEPS
            self._records[epoch] = np.where(known, memory.x_db, np.nan)
            for old in [e for e in self._records if e < epoch - 1]:
                del self._records[old]
        self._steps += 1

    def _versions(self, sent_s: np.ndarray) -> np.ndarray:
        """For Acks sent no earlier than ``sent_s``: the index, among the lists kept, of the
        latest list taken strictly before (-1: none)."""
        taken_s = np.array([t[0] for t in self._taken])
        return np.searchsorted(taken_s, sent_s, side="left") - 1

    def heard(self, known: np.ndarray, sent_s: np.ndarray, release_s: float) -> Heard:
        """What each robot holds: its own memory ``known`` and, for each robot ``u`` whose
        latest Ack it heard can have been sent no earlier than ``sent_s[i, u]``, ``u``'s list of
        its latest step strictly before then, with the lists ``u`` held then and the records
        rule 1 reads at this step."""
        which = self._versions(sent_s)
        sizes = np.array([len(t[2]) for t in self._taken], dtype=np.int64)
        offset = np.r_[0, np.cumsum(sizes)[:-1]] if len(sizes) else sizes
        start = np.array([t[1] + o for t, o in zip(self._taken, offset)], dtype=np.int64).reshape(-1, self.n + 1)
        other = np.concatenate([t[2] for t in self._taken]) if self._taken else np.empty(0, np.int64)
        sent = np.concatenate([t[3] for t in self._taken]) if self._taken else np.empty(0)
        xy = np.concatenate([t[4] for t in self._taken]) if self._taken else np.empty((0, 2))
        x = np.concatenate([t[5] for t in self._taken]) if self._taken else np.empty(0)
        first = self._steps - len(self._taken)
        steps = np.arange(first, self._steps, dtype=np.int64)
        held = self._held if self._taken and self._held is not None else np.empty((0, self.n, self.n), np.int32)
        epoch = (self._steps - 1 - RECORD_DELAY_STEPS) // RECORD_EPOCH_STEPS
        records_db = self._records.get(epoch)
        span = (epoch * RECORD_EPOCH_STEPS, (epoch + 2) * RECORD_EPOCH_STEPS) if records_db is not None else (-1, -1)
        if records_db is None:
            records_db = np.full((self.n, self.n), np.nan)
        return Heard(
            known,
            which.astype(np.int64),
            start,
            other.astype(np.int64),
            sent,
            xy,
            float(release_s),
            x,
            held,
            steps,
            records_db,
            *span,
        )


def remembered(sent_s: np.ndarray, now_s: float, release_s: float, n_robots: int | None = None) -> np.ndarray:
    """Whether each Ack sent at ``sent_s`` is still remembered at ``now_s`` (the kernel
    :func:`netsim.mobility._local_kernels.remembers`, as a team of ``n_robots`` calls it;
    None: the rows of ``sent_s``, a team's memory), in the shape of ``sent_s``."""
    sent = np.asarray(sent_s, dtype=float)
    kernels = load("netsim.mobility._local_kernels", n_robots, values=sent.shape[0])
    return kernels.remembers(sent, float(now_s), float(release_s))


def let_go(
    pos: np.ndarray,
    memory: Memory,
    heard: Heard,
    t0_s: float,
    speed_mps: float,
    band_m: float,
    range_m: float,
    walls: Walls = NO_WALLS,
    fade: Fade | None = None,
    window_s: float = 0.0,
    silent_of: np.ndarray | None = None,
) -> np.ndarray:
    """``(n, n)``: robot ``i`` lets go of ``j`` (rule 1: it knows a certified detour).

    ``pos``: every robot's own position at ``t0_s``; ``heard``: each robot's memory and the
    lists it holds (:class:`Lists`); ``band_m``: the width of the length bands of the links'
    order. Robot ``i``'s graph: itself, the robots it remembers (at the positions it heard)
    and, when ``heard`` carries the lists their senders held, the robots two hops out that
    the lists it holds name (at the freshest position they give), joined where ``i`` can
    certify that the two remember each other at ``t0_s`` (``i`` is one of them and
    remembers the other; or a list ``i`` holds of ``u``, or that a robot ``i`` remembers
    held of it, names ``v`` with an Ack sent less than ``release_s`` before ``t0_s``) and
    they are surely within ``range_m`` and (on a map) surely clear of ``walls`` or within the
    range through the walls they can cross (:attr:`Walls.through_m`)
    (:func:`clear_of_walls`, each end with its own uncertainty), each link at the
    largest rank it can have at ``t0``. Under shadowing (``fade``) a link's band is that of
    its length at zero shadowing under its record of the step's epoch (:class:`Lists`), and
    a link whose record ``i`` cannot read is neither a detour's link nor let go of. A
    detour's worst link is the bottleneck of ``i``'s path to ``j`` in a minimum spanning
    tree of that graph, computed by :func:`netsim.mobility._local_kernels.let_go`.
    ``window_s``: a detour's links are certified up over ``[t0_s - window_s, t0_s]``, not
    at ``t0_s`` alone (each end where its known leg puts it over each piece of the window,
    :func:`netsim.mobility._local_kernels.up_over_window`; :class:`Silence`).
    ``silent_of``: ``(n, n)``, the robots each robot has heard nothing of for longer than
    the largest gap between two Acks (:func:`silent`): their link was down in the window,
    so it is no detour's link, though the robot is still a node.

    Notes
    -----
    ``O(k^2 + l)`` per robot with ``k`` robots in its graph (it remembers them, or two hops
    out), whose lists hold ``l`` entries.
    """
    n = len(pos)
    out = np.zeros((n, n), dtype=bool)
    rule = DetourRule(float(t0_s), float(speed_mps), float(band_m), float(range_m), float(window_s))
    kernels = load("netsim.mobility._local_kernels", n)
    listed_x = heard.x_db if heard.x_db is not None else np.full(len(heard.other), np.nan)
    heard = heard._replace(x_db=listed_x, release_s=float(heard.release_s))
    if heard.held is None:
        # Lists without the lists their senders held: a graph of the robots i remembers.
        heard = heard._replace(held=np.empty((0, 0, 0), np.int32))
    if heard.steps is None or heard.records_db is None:
        # No records: under shadowing no link's place in the order is known.
        heard = heard._replace(
            steps=np.zeros(max(len(heard.start), 1), np.int64),
            records_db=np.full((n, n), np.nan),
            records_from=-1,
            records_to=-1,
        )
    quiet = np.zeros((n, n), dtype=bool) if silent_of is None else np.ascontiguousarray(silent_of, dtype=bool)
    memories = Remembered(
        memory.xy,
        memory.sent_s,
        heard.known,
        quiet,
        memory.x_db,
        memory.measured_s,
        memory.leg_speed_mps,
        memory.leg_from_s,
        memory.leg_velocity_mps,
        memory.leg_until_s,
    )
    kernels.let_go(pos, memories, heard, rule, walls, out, NO_FADE if fade is None else fade.rule)
    return out


class Remembered(NamedTuple):
    """What rule 1's kernel reads of the robots' memories, ``[i, j]``: robot ``i``'s of ``j``."""

    xy: np.ndarray  # (n, n, 2): the position j's latest Ack carried
    sent_s: np.ndarray  # (n, n): the earliest time it can have been sent
    known: np.ndarray  # (n, n) bool: i remembers j
    silent: np.ndarray  # (n, n) bool: their link was down in the window (Silence)
    x_db: np.ndarray  # (n, n): the shadowing i measured on it (NaN: none)
    measured_s: np.ndarray  # (n, n): the earliest time that Ack can have been sent
    leg_speed_mps: np.ndarray  # (n, n): j's speed as i knows it (its own on the diagonal)
    leg_from_s: np.ndarray  # (n, n): when that leg started (largest_travel_m)
    leg_velocity_mps: np.ndarray  # (n, n, 2): that leg's velocity (NaN: unknown)
    leg_until_s: np.ndarray  # (n, n): when that leg ends, j's next step (largest_travel_m)


class DetourRule(NamedTuple):
    """The step's constants of rule 1 (a detour's links certified over ``[t0_s - window_s, t0_s]``)."""

    t0_s: float
    speed_mps: float
    band_m: float
    range_m: float
    window_s: float


# How much longer than the largest gap between two Acks a robot waits before it counts a
# robot silent, and how much wider the window of rule 1 is for it (s): room for the
# rounding of the times compared.
SILENCE_SLACK_S = 1e-6


class Silence(NamedTuple):
    """The release of a silent robot (module notes, "Release"), on a channel that loses no
    frame: ``i`` lets go of ``j`` once it has heard no Ack of ``j`` for more than ``gap_s``
    (then the link was down at an instant of the window, :func:`silence_of`), and rule 1
    certifies a detour's links up over the ``window_s`` before ``t0``."""

    gap_s: float
    window_s: float


def silence_of(period_s: float, jitter_s: float, latency_s: float, latency_jitter_s: float) -> Silence:
    """The release's gap and window from the Acks' timing (``protocol.ack_period_s``,
    ``protocol.ack_jitter_s``) and the channel's delay (``latency_s + latency_jitter_s``,
    the largest ``lead``).

    Two Acks of ``j`` leave at most ``period_s + jitter_s`` apart, so the closed span
    ``[now - lead - period_s - jitter_s - slack, now - lead - slack]`` holds one, sent at
    ``a``; it arrived by ``a + lead < now``. Had the link been up then, ``i`` would hold it,
    heard no earlier than ``a + latency_s``: a silence of at most ``period_s + jitter_s +
    latency_jitter_s + slack`` (``gap_s``). A longer silence means the link was down at an
    instant of that span, which starts ``period_s + jitter_s + 2 lead + slack`` (``window_s``)
    before ``t0 = now + lead``.

    >>> [round(x, 9) for x in silence_of(1.0, 0.05, 0.001, 0.0)]
    [1.050001, 1.052001]
    """
    lead = latency_s + latency_jitter_s
    gap = period_s + jitter_s + latency_jitter_s + SILENCE_SLACK_S
    return Silence(gap, period_s + jitter_s + 2.0 * lead + SILENCE_SLACK_S)


def silent(memory: Memory, now_s: float, lead_s: float, silence: Silence | None) -> np.ndarray:
    """``(n, n)``: ``i`` has heard no Ack of ``j`` for more than ``silence.gap_s`` at ``now_s``
    (the latest one it heard arrived at ``memory.sent_s + lead_s``); all False without the
    release (``silence`` None: a channel that may lose frames)."""
    if silence is None:
        return np.zeros(memory.sent_s.shape, dtype=bool)
    heard = np.isfinite(memory.sent_s)
    with np.errstate(invalid="ignore"):
        return heard & (now_s - (memory.sent_s + lead_s) > silence.gap_s)


def turn_takers(kept: np.ndarray, rank: np.ndarray) -> np.ndarray:
    """Rule 7 (turns, on a map): the robots that may move at a step, those that outrank
    (``rank``, one permutation every robot draws alike) every robot they keep (``kept``): of
    two robots that keep each other, one holds."""
    return ~(kept & (rank[None, :] > rank[:, None])).any(axis=1)


def leash_radius(memory: Memory, t1_s: float, limits: StepLimits) -> np.ndarray:
    """``(n, n)``: how far from ``q_j`` robot ``i`` may end the step (rule 2): what it
    answers for (``memory.keep_m``, or the plan's range less its margin) less ``j``'s largest
    motion since its Ack."""
    keep = limits.keep_m if memory.keep_m is None else memory.keep_m
    return keep - travel_at_cap_m(memory.sent_s, t1_s, limits.speed_max_mps)


def plan_local(
    pos: np.ndarray,
    desired_mps: np.ndarray,
    memory: Memory,
    kept: np.ndarray,
    t0_s: float,
    limits: StepLimits,
    reach_m: np.ndarray | None = None,
    halves: Halves | None = None,
) -> Plan:
    """Each robot's step (module notes): its wish, brought into its leashes, its reach and
    the area.

    ``kept``: ``(n, n)``, robot ``i`` keeps ``j`` (remembered and not let go of). A robot
    inside all its leashes now goes along its projected step as far as it stays inside
    them; one already outside some (but within what it answers for now) must end inside
    them, and holds if the projection found no such end. ``reach_m``: each robot's longest
    step (default the speed cap's; under shadowing the travel its kept links allow,
    :meth:`Fade.reach`); a robot whose reach is 0 holds. ``halves``: the links each robot
    answers for by its half (``usable``, :func:`answered_by_halves`): it ends within the
    half's radius of the link's midpoint in place of its leash.
    """
    n = len(pos)
    reach = np.full(n, limits.reach_m) if reach_m is None else np.minimum(reach_m, limits.reach_m)
    robot, other = np.nonzero(kept)
    centre = memory.xy[robot, other]
    now_m = leash_radius(memory, t0_s, limits)[robot, other]
    r = leash_radius(memory, t0_s + limits.period_s, limits)[robot, other]
    if halves is not None:
        half = halves.usable[robot, other]
        centre[half] = halves.centre_m[robot[half], other[half]]
        now_m[half] = r[half] = halves.radius_m[robot[half], other[half]]
    # Rule 3: a robot that cannot answer for a kept link now holds.
    cannot = np.zeros(n, dtype=bool)
    cannot[robot[beyond(pos[robot], centre, now_m, n)]] = True
    outside = np.zeros(n, dtype=bool)
    outside[robot[beyond(pos[robot], centre, r, n)]] = True
    wants = in_motion(desired_mps)
    cannot |= reach <= 0
    movers = np.flatnonzero(~cannot & wants)
    mobile = np.zeros(n, dtype=bool)
    mobile[movers] = True
    sel = mobile[robot]
    robot, centre, r = robot[sel], centre[sel], r[sel]
    robot = np.concatenate([robot, movers])
    centre = np.concatenate([centre, pos[movers]])
    r = np.concatenate([r, reach[movers]])

    wish = np.zeros((n, 2))
    wish[movers] = cap_length(desired_mps[movers] * limits.period_s, reach[movers])
    end = project_into(pos + wish, robot, centre, r * SAFETY, limits.box)
    move = end - pos
    move[~mobile] = 0.0
    inside = ~outside[robot]
    s = np.ones(n)
    if len(robot):
        rows = robot[inside]
        np.minimum.at(s, rows, step_limit(pos[rows] - centre[inside], r[inside], move[rows], n))
        missed = beyond(pos[robot] + move[robot], centre, r, n)
        s[robot[~inside & missed]] = 0.0
    s = np.minimum(s, box_limit(pos, move, limits.box))
    s[outside & (s < 1.0)] = 0.0
    move *= s[:, None]
    held = (cannot & wants) | (mobile & fell_short(wish, move, limits.range_m))
    both = kept & kept.T
    return Plan(move / limits.period_s, np.full(n, -1), held, int(np.triu(both, 1).sum()))


# The fractions of its step a robot tries, longest first, when walls stand near its links.
WALL_TRIES = (1.0, 0.5, 0.25, 0.125, 0.0)


def cut_for_walls(
    pos: np.ndarray,
    move: np.ndarray,
    memory: Memory,
    kept: np.ndarray,
    t1_s: float,
    limits: StepLimits,
    walls: Walls,
    occupancy: OccupancyMap | None = None,
) -> np.ndarray:
    """Rule 5 (walls): each robot's step, such that every kept link is surely clear of walls
    over it while the other end holds (rule 7), or (:attr:`Walls.through_m`) within the
    range through the walls it can cross (:func:`through_walls`), and still ending within
    its leashes (rule 2). The convex hull of the step and of the disk of radius ``e_j(t0)`` around ``q_j``
    (where ``j`` stands) keeps off the walls (:func:`step_clear_of_walls`). The largest
    fraction of :data:`WALL_TRIES` with which every link passes and the leashes hold is
    taken. 0: the robot holds (then it answers for nothing: the other end, or no motion,
    keeps the link); a robot that keeps no link moves as it wished. With ``occupancy`` (the
    map), a robot that would hold tries the steps of :data:`SLIDES` in turn (its step's part
    along x, along y, then the step turned by 45 and 90 degrees either way), each ended
    short of the walls (:func:`netsim.world.free_space.short_of_walls`) and inside the area,
    and tested alike:
    along a corridor it may keep in sight a robot that its whole step would leave behind a
    door's frame."""
    out = _cut_straight(pos, move, memory, kept, t1_s, limits, walls)
    if occupancy is None or not walls.on:
        return out
    planned = np.asarray(move, float)
    for other_way in SLIDES:
        held = ~in_motion(out) & in_motion(planned)
        if not held.any():
            break
        step = np.zeros_like(planned)
        step[held] = planned[held] @ other_way
        step = short_of_walls(occupancy, pos, step, 1.0)
        step *= box_limit(pos, step, limits.box)[:, None]
        step = _cut_straight(pos, step, memory, kept, t1_s, limits, walls)
        out[held] = step[held]
    return out


def _turned(degrees: float) -> np.ndarray:
    """The matrix that turns a row vector by ``degrees`` counterclockwise."""
    c, s = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
    return np.array([[c, s], [-s, c]])


# The steps a robot that rule 5 holds tries in turn, as matrices of its planned step: its
# part along x, along y, then the step turned by 45 and 90 degrees either way.
SLIDES = (np.diag([1.0, 0.0]), np.diag([0.0, 1.0]), _turned(45), _turned(-45), _turned(90), _turned(-90))


def _cut_straight(
    pos: np.ndarray, move: np.ndarray, memory: Memory, kept: np.ndarray, t1_s: float, limits: StepLimits, walls: Walls
) -> np.ndarray:
    """:func:`cut_for_walls` along the step as given."""
    n = len(pos)
    move = np.array(move, float)
    length = np.hypot(*move.T)
    if not walls.on or not (length > 0).any():
        return move
    robot, other = np.nonzero(kept & (length > 0)[:, None])
    centre = memory.xy[robot, other]
    e = travel_at_cap_m(memory.sent_s[robot, other], t1_s - limits.period_s, limits.speed_max_mps)
    leash = leash_radius(memory, t1_s, limits)[robot, other]
    fall = travel_at_cap_m(memory.sent_s[robot, other], t1_s, limits.speed_max_mps)
    scale = np.ones(n)
    undecided = np.zeros(n, dtype=bool)
    undecided[robot] = True
    for s in WALL_TRIES:
        if s == 0.0:
            break
        rows = np.flatnonzero(undecided[robot])
        if len(rows) == 0:
            break
        r = robot[rows]
        ok = step_clear_of_walls(walls, pos[r], s * move[r], centre[rows], e[rows])
        ok &= ~beyond(pos[r] + s * move[r], centre[rows], leash[rows], n)
        if len(walls.through_m):
            late = rows[~ok]
            step = s * move[robot[late]]
            ok[~ok] = through_walls(walls, pos[robot[late]], step, centre[late], e[late], limits, fall[late])
        failed = np.zeros(n, dtype=bool)
        failed[r[~ok]] = True
        done = undecided & ~failed
        scale[done] = s
        undecided &= failed
    scale[undecided] = 0.0
    return move * scale[:, None]


def through_walls(
    walls: Walls,
    p: np.ndarray,
    move: np.ndarray,
    q: np.ndarray,
    e_m: np.ndarray,
    limits: StepLimits,
    fall_m: np.ndarray,
) -> np.ndarray:
    """Rule 5 through walls (log-distance, :attr:`Walls.through_m`): whether a link is surely
    up over the step from ``p`` to ``p + move`` against the other end standing in the disk
    ``D(q, e_m)``, though walls stand between them. The hull of the step and the disk meets
    ``k`` of the walls' boxes (:func:`netsim.mobility._local_kernels.boxes_met`), so no
    segment between the two robots crosses more than ``k`` walls; every such segment is at
    most ``max(|p - q|, |p + move - q|) + e_m`` long (the distance to a point is convex along
    the step), and each end must keep the margin within the range through ``k`` walls as
    rule 2 keeps it within the range: ``|p - q| + e_m`` and ``|p + move - q| + fall_m``
    within ``through_m[k - 1] - margin``, ``fall_m`` being the other end's largest travel by
    the step's end (``e_m`` grown to ``t1``, as rule 2's leash counts it). No wall met
    (``k = 0``) is rule 5's own test: False here."""
    out = np.zeros(len(p), bool)
    if len(p):
        rows = (np.ascontiguousarray(a, float) for a in (p, move, q))
        ends = (filled(x, (len(p),)) for x in (e_m, fall_m))
        kernels = load("netsim.mobility._local_kernels", None, values=len(p))
        kernels.steps_through(walls, *rows, *ends, float(limits.margin_m), out)
    return out


def pulls(
    pos: np.ndarray,
    memory: Memory,
    kept: np.ndarray,
    announced_mps: np.ndarray,
    announced_s: float,
    t0_s: float,
    limits: StepLimits,
    sent_s: np.ndarray | None = None,
) -> np.ndarray:
    """Rule 4, the pull: each robot's velocity toward the kept robots that announced (in an
    Ack it heard, sent after ``announced_s``) a wish to move away from it faster than the
    slack of its leash allows, by the excess. ``sent_s``: when the Acks were sent (default
    ``memory.sent_s``; give the raw times when ``memory`` is :meth:`Memory.at`'s).

    Without it a taut link only blocks: the outer robot of a chain wants out, the inner
    ones are pushed evenly from all sides and stay. A pull travels one link per step.
    """
    heard = memory.sent_s if sent_s is None else sent_s
    robot, other = np.nonzero(kept & (heard >= announced_s))
    q = memory.xy[robot, other]
    off = q - pos[robot]
    d = distances_m(pos[robot], q, None, len(pos))
    along = off / np.maximum(d, 1e-12)[:, None]
    slack = np.maximum(leash_radius(memory, t0_s + limits.period_s, limits)[robot, other] - d, 0.0) / limits.period_s
    return add_pulls(np.zeros_like(pos), robot, along, announced_mps[other], slack)


def latest_pulls(
    pos: np.ndarray,
    memory: Memory,
    kept: np.ndarray,
    announced: tuple[np.ndarray, float],
    earlier: tuple[np.ndarray, float],
    t0_s: float,
    limits: StepLimits,
    sent_s: np.ndarray,
) -> np.ndarray:
    """Rule 4 from the latest wish each robot heard: the wishes ``announced`` at the last
    step (and when), carried by the Acks sent since; for a kept robot whose latest Ack heard
    was sent before that, the wishes announced a step ``earlier``, which that Ack carried.
    ``sent_s``: when the Acks were sent."""
    latest, older = carried(kept, sent_s, announced[1], earlier[1])
    return pulls(pos, memory, latest, *announced, t0_s, limits, sent_s) + pulls(
        pos, memory, older, *earlier, t0_s, limits, sent_s
    )


def carried(
    known: np.ndarray, sent_s: np.ndarray, announced_s: float, earlier_s: float
) -> tuple[np.ndarray, np.ndarray]:
    """Which announcement the latest Ack each robot heard of each ``known`` robot carried
    (rules 4 and 6): masks ``(latest, older)``, the one made at the last step (at
    ``announced_s``) for an Ack sent at it or after (``sent_s``, its earliest sending time),
    the one made a step earlier (``earlier_s``) for an Ack sent between the two; an Ack
    sent before both carried neither."""
    latest = known & (sent_s >= announced_s)
    return latest, known & ~latest & (sent_s >= earlier_s)


def centre_estimates(
    centre_m: np.ndarray,
    known: np.ndarray,
    sent_s: np.ndarray,
    announced: tuple[np.ndarray, float],
    earlier: tuple[np.ndarray, float],
) -> np.ndarray:
    """The expansion's centre (rule 6): each robot's estimate of its team's centre, the
    mean of its own estimate ``centre_m`` and the estimates its ``known`` robots announced
    at their latest step before the Ack of theirs it heard (sent at ``sent_s``): those
    ``announced`` at the last step (and when), else those announced a step ``earlier``
    (:func:`carried`).

    Averaging with every robot it hears at each step is a consensus: the estimates of a
    connected team meet at one point, a mean of where its robots stood when control
    started, each weighted by how many robots it heard (not the team's plain mean), so the
    team spreads away from about its middle, not from a point a robot guessed alone.

    >>> known = np.array([[False, True], [True, False]])
    >>> sent = np.array([[0.0, 1.5], [0.5, 0.0]])
    >>> said = (np.array([[0.0, 0.0], [4.0, 0.0]]), 1.0), (np.array([[2.0, 0.0], [8.0, 0.0]]), 0.0)
    >>> centre_estimates(np.array([[0.0, 0.0], [4.0, 0.0]]), known, sent, *said).tolist()
    [[2.0, 0.0], [3.0, 0.0]]
    """
    latest, older = carried(known, sent_s, announced[1], earlier[1])
    total = centre_m + latest.astype(float) @ announced[0] + older.astype(float) @ earlier[0]
    count = 1.0 + latest.sum(axis=1) + older.sum(axis=1)
    return total / count[:, None]


def sources_heard(memory: Memory, heard: Heard, t0_s: float, reach_m: float, pos: np.ndarray):
    """Pairs ``(robot, position it knows of another robot within reach_m)``: the forces'
    sources in the local plan. A robot knows the robots it remembers, at the position it
    heard (``memory``), and those named in the lists it holds from them (:class:`Lists`;
    still remembered at ``t0_s``), at the position of the freshest Ack any of those lists
    reports (the first of the robots it remembers, by id, on a tie): the kernel
    :func:`netsim.mobility._local_kernels.heard_sources`."""
    n = len(pos)
    kernels = load("netsim.mobility._local_kernels", n)
    pick = np.empty((n, n), np.int64)
    kernels.heard_sources(heard._replace(release_s=float(heard.release_s)), float(t0_s), pick)
    robot, other = np.nonzero(pick != -2)
    if len(robot) == 0:
        return np.empty(0, np.int64), np.empty((0, 2))
    entry = pick[robot, other]
    xy = memory.xy[robot, other]
    listed = entry >= 0
    xy[listed] = heard.xy[entry[listed]]
    # Within reach as everywhere in the engine (the global plan's sources are the pairs in
    # range): entry k's robot (row robot[k]) against the point it heard (row n + k).
    points = np.concatenate([np.asarray(pos, float), xy])
    rows = np.arange(len(robot))
    near = load("netsim._kernels", n).in_range(points, robot, n + rows, np.full(len(robot), float(reach_m)), 0.0)
    return robot[near], xy[near]


class FadeRule(NamedTuple):
    """The shadowing's rule as the kernels read it (:func:`netsim.mobility._local_kernels.measured_range_m`)."""

    on: bool
    sigma_db: float
    decorrelation_m: float
    budget_db: float
    reference_distance_m: float
    exponent: float
    # Standard deviations of its shadowing's change within which rule 1 certifies a detour's
    # measured link up (coverage.detour_sigmas).
    detour_sigmas: float


# The fade rule switched off (:func:`netsim.mobility._local_kernels.let_go`).
NO_FADE = FadeRule(False, 0.0, 1.0, 0.0, 1.0, 1.0, FADE_SIGMAS)


class Halves(NamedTuple):
    """Where each robot ``i`` can answer for its half of its link to ``j`` (:meth:`Fade.halves`):
    ``usable[i, j]``; then it ends the step within ``radius_m[i, j]`` of ``centre_m[i, j]``
    (the midpoint of the two positions at ``t0``) and moves at most ``travel_m[i, j]``."""

    usable: np.ndarray  # (n, n) bool
    centre_m: np.ndarray  # (n, n, 2)
    radius_m: np.ndarray  # (n, n)
    travel_m: np.ndarray  # (n, n)


def link_records(heard: Heard, n: int) -> tuple[np.ndarray, np.ndarray]:
    """``(x_db, sent_s)``, ``(n, n)``: for robot ``i`` and its link to ``j``, the link's
    *record*: the shadowing the smaller id measured on the latest Ack of the larger it had
    heard as of its latest step before ``t0`` (its list of that step, the last one ``heard``
    holds) and the earliest time that Ack can have been sent, as ``i`` reads it: in its own
    list, or in the other robot's list of that step when the latest Ack of it ``i`` heard
    carried that one. NaN (``-inf``): ``i`` cannot read it. Both ends that read it read the
    same numbers."""
    x = np.full((n, n), np.nan)
    sent = np.full((n, n), -np.inf)
    prev = heard.start.shape[0] - 1
    if prev < 0:
        return x, sent
    rows = np.arange(heard.start[prev, 0], heard.start[prev, n])
    sender = np.repeat(np.arange(n), np.diff(heard.start[prev]))
    other = heard.other[rows]
    lower = sender < other
    listed_x = heard.x_db if heard.x_db is not None else np.full(len(heard.other), np.nan)
    for reader, read, ok in (
        (sender, other, lower),
        (other, sender, lower & (heard.which[other, sender] == prev)),
    ):
        x[reader[ok], read[ok]] = listed_x[rows[ok]]
        sent[reader[ok], read[ok]] = heard.sent_s[rows[ok]]
    return x, sent


def answered_by_halves(
    pos: np.ndarray, memory: Memory, kept: np.ndarray, t0_s: float, limits: StepLimits, halves: Halves
) -> np.ndarray:
    """``(n, n)``: the kept links each robot answers for by its half (rule 2, "Halves"): those
    it cannot answer for alone now (rule 3) and can by its half."""
    far = beyond(pos[:, None, :], memory.xy, leash_radius(memory, t0_s, limits), len(pos))
    return kept & halves.usable & far


class Fade:
    """The fade-margin rule by which the local plan keeps links under shadowing (module
    notes, "Shadowing"; the global plan's rule, :mod:`netsim.mobility.keep`, one
    implementation: :mod:`netsim.mobility._fade_kernels`).

    ``radio``: the log-distance law's parameters (``tx_power_dbm``, ``sensitivity_dbm``,
    ``path_loss_db``, ``budget_db``, ...); ``sigma_db``, ``decorrelation_m``: the
    shadowing's; ``fade_margin_db``: the budget a kept link keeps against the change of its
    shadowing; ``sure_m``: the plan's range without a measurement (the sure distance);
    ``margin_m``: the plan's distance margin; ``period_s``: the control period;
    ``detour_sigmas``: the standard deviations of a measured link's change of shadowing
    within which rule 1 certifies it up as a detour's link.
    """

    def __init__(
        self,
        radio,
        sigma_db: float,
        decorrelation_m: float,
        fade_margin_db: float,
        sure_m: float,
        margin_m: float,
        period_s: float,
        n_robots: int,
        detour_sigmas: float,
    ):
        self.radio = radio
        self.n_robots = int(n_robots)  # the team's size: whether the radio's laws run compiled
        self.sigma_db = float(sigma_db)
        self.decorrelation_m = float(decorrelation_m)
        self.fade_margin_db = float(fade_margin_db)
        self.sure_m = float(sure_m)
        self.margin_m = float(margin_m)
        self.rule = FadeRule(
            True,
            self.sigma_db,
            self.decorrelation_m,
            float(radio.budget_db),
            float(radio.reference_distance_m),
            float(radio.path_loss_exponent),
            float(detour_sigmas),
        )
        # The speed cap known to all: a pair's travel over two control periods, both robots
        # at the cap, stays within what a full budget allows at X = 0 (an Ack each period
        # then leaves every kept link some travel in each step).
        travel = float(
            fade_travel_m(
                np.array([self.fade_margin_db]), np.zeros(1), self.sigma_db, self.decorrelation_m, self.n_robots
            )[0]
        )
        self.speed_mps = travel / (4.0 * float(period_s))

    def measure(
        self,
        own_xy: np.ndarray,
        heard_xy: np.ndarray,
        power_dbm: np.ndarray,
        sent_s: np.ndarray,
        now_s: float,
        speed_mps: float,
    ) -> tuple[np.ndarray, np.ndarray]:
        """The shadowing each robot measured on each Ack it heard, and the margin it heard
        it with (dB; NaN where no power was measured): ``X = P_t - PL(d) - P_r``, ``d`` the
        shortest the distance can have been when the Ack was sent (the position it carried
        to the robot's own position at ``now_s``, less the robot's largest motion since
        ``sent_s``, the earliest the Ack can have been sent): an ``X`` no lower than the true
        one, which only shortens the links kept. ``margin = P_r - sensitivity``."""
        moved = travel_at_cap_m(np.asarray(sent_s, float), now_s, speed_mps)
        d = distances_m(own_xy, heard_xy, None, self.n_robots) - moved
        r = self.radio
        x = r.radio.shadowing_db(r.path_loss_db(np.maximum(d, 0.0), self.n_robots), power_dbm)
        return x, r.radio.above_sensitivity_db(power_dbm, self.n_robots)

    def limits(self, knows: Memory, t0_s: float, t1_s: float, speed_mps: float) -> tuple[np.ndarray, np.ndarray]:
        """``(keep_m, travel_m)``, ``(n, n)``: how far from ``q_j`` robot ``i`` answers for
        the link to ``j`` (rule 2, before ``j``'s motion since its Ack), and the longest step
        it may take while keeping it (inf: no bound). A link with a measurement: budget
        ``B = min(fade_margin_db, margin)``, kept up to where its margin with the measured
        ``X`` is ``B``, less ``margin_m``, while the pair's travel since the Ack (``i``'s own
        and ``j``'s as ``i`` knows them, :meth:`Memory.travel_m`), ``j``'s next step at the
        speed cap and ``i``'s step stay within the travel that ``B`` allows
        (:func:`netsim.mobility.keep.fade_travel_m`); where that gives no longer link or no
        travel, the sure distance less ``margin_m``, no bound."""
        x, margin, s = knows.x_db, knows.margin_db, knows.measured_s
        measured = np.isfinite(x) & np.isfinite(margin) & np.isfinite(s)
        x0 = np.where(measured, x, 0.0)
        _, reach, left = self._allowance(knows, np.where(measured, margin, 0.0), x0, s, t0_s, speed_mps)
        with np.errstate(invalid="ignore"):
            left = left - travel_at_cap_m(np.array([t0_s]), t1_s, speed_mps)[0]
        usable = measured & (reach > self.sure_m) & (left > 0)
        keep = np.where(usable, reach, self.sure_m) - self.margin_m
        return keep, np.where(usable, left, np.inf)

    def _allowance(
        self, knows: Memory, margin_db: np.ndarray, x0_db: np.ndarray, since_s: np.ndarray, t0_s: float, speed: float
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The fade-margin rule for links measured at ``since_s`` with shadowing ``x0_db``
        and margin ``margin_db`` (0 where there is none): ``(budget, length, left)``, the
        budget ``B = min(fade_margin_db, margin)``, the length at which the margin with that
        ``X`` is ``B``, and the pair's travel ``B`` allows
        (:func:`netsim.mobility.keep.fade_travel_m`) less what each end travelled since, as
        the robot knows it (its own leg, the other's from its Acks, :meth:`Memory.travel_m`;
        ``speed``: the cap, where no velocity is known)."""
        budget = np.minimum(self.fade_margin_db, margin_db)
        length = self.radio.effective_range_m(x0_db + budget, 0, self.n_robots)
        own = np.arange(len(since_s))
        leg = (knows.leg_speed_mps, knows.leg_from_s, knows.leg_until_s)
        own_travel = largest_travel_m(*(v[own, own][:, None] for v in leg), since_s, t0_s, speed)
        with np.errstate(invalid="ignore"):
            travel = fade_travel_m(budget, x0_db, self.sigma_db, self.decorrelation_m, self.n_robots)
            left = travel - own_travel - knows.travel_m(since_s, t0_s, speed)
        return budget, length, left

    def halves(self, knows: Memory, heard: Heard, pos: np.ndarray, t0_s: float, speed_mps: float) -> Halves:
        """Where each robot can answer for half of a link (rule 2, "Halves"): the link's record
        (:func:`link_records`) read, the other end's position at ``t0_s`` known exactly, so
        that both ends compute one midpoint ``c``, one length ``L`` and one budget: ``B =
        min(fade_margin_db, m0)``, ``m0`` the margin at the link's length now with the
        recorded ``X``, ``L`` where the margin with that ``X`` is ``B``, and the pair's
        travel ``fade_travel_m(B, X)`` from the record on, less the pair's travel since as
        the robot knows it, of which each end takes half."""
        n = len(pos)
        x, since = link_records(heard, n)
        q = knows.xy
        r = self.radio
        with np.errstate(invalid="ignore"):
            exact = knows.sent_s >= t0_s
            seen = np.isfinite(x) & np.isfinite(since) & exact
            # Only the lengths of links with a record are read.
            d0 = np.zeros((n, n))
            i, j = np.nonzero(seen)
            d0[i, j] = distances_m(pos[i], q[i, j], None, self.n_robots)
            x0 = np.where(seen, x, 0.0)
            m0 = np.where(seen, r.margin_db(np.maximum(d0, 1e-9), x0, 0, self.n_robots), 0.0)
            budget, length, left = self._allowance(knows, m0, x0, since, t0_s, speed_mps)
            # B <= m0: the margin at d0 is at least B (max: the inverse's rounding).
            length = np.maximum(length, d0)
            usable = seen & (budget > 0) & (left > 0)
        centre = 0.5 * (pos[:, None, :] + q)
        return Halves(usable, centre, np.where(usable, 0.5 * length, 0.0), np.where(usable, 0.5 * left, 0.0))

    @staticmethod
    def reach(travel_m: np.ndarray, kept: np.ndarray) -> np.ndarray:
        """Each robot's longest step: the least travel its kept links allow."""
        return np.where(kept, travel_m, np.inf).min(axis=1, initial=np.inf)
