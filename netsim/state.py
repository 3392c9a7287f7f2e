"""The global robot state (paper section 1.2), held as numpy arrays, one row per robot.

Motion is piecewise linear: each robot is on a *leg* that started at ``t0_s[i]`` from
``origin_m[i]`` with velocity ``velocity_mps[i]``, so its position at any time ``t`` on
that leg is ``origin + velocity * (t - t0)``, exactly, without stepping (as ns-3's
constant-velocity helper). Models change course with :meth:`RobotState.set_leg`; every
leg is logged with its cause (:data:`CAUSES`), which is what exact link events and ns-2
export are computed from. Every change of a robot's leg is also told to the run's
``watchers`` (the runtime link solver) and, as a ``course_change`` event, to the
subscribers of the run's event bus.

A run's state checks the motion (:meth:`RobotState.check_motion`): every leg a robot ends,
every jump and, at the end of the run, every leg it is on must stay in the area and, on a
map, off the walls, whichever model moved it. The check sits where legs change, so it
covers every mobility model, controller and trace without their own code; as the area is
convex, a straight leg stays inside when its two ends do, so it costs two comparisons per
leg (and one traversal of the grid per leg on a map).
"""

from __future__ import annotations

import types
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import pandas as pd

from netsim.area import Bounds, OnTorus
from netsim.compiled import load
from netsim.errors import NetsimInputError
from netsim.events import CourseChange, EventBus
from netsim.geometry import distances_m, drivable, speeds_mps, wrap

# Why a leg starts (the ``cause`` column of legs.parquet): the initial placement, a
# waypoint (or a trace's destination) reached, the end of a pause, the border reached
# (random direction), a turn (random direction on a torus), a control command, a trace's
# ``setdest``, a jump (a leg that starts away from where the robot was).
CAUSES = ("start", "waypoint", "pause_end", "border", "turn", "command", "trace", "jump")
LEG_COLUMNS = ["t_s", "robot", "x_m", "y_m", "vx_mps", "vy_mps", "cause"]
# How far past the border (a fraction of the area's size) a leg's end may round.
BORDER_TOLERANCE = 1e-9


def border_tolerance_m(bounds: Bounds) -> float:
    """How far past ``bounds``' border a position computed on a leg may lie and count as on
    it: the rounding of a leg's end, relative to the area's size (at least 1 m)."""
    return BORDER_TOLERANCE * max(1.0, bounds.width, bounds.height)


class MotionError(NetsimInputError):
    """A robot left the area or crossed a wall: the model or the trace that moved it is wrong."""


class RobotState(OnTorus):
    """Positions, velocities and ranges of ``n`` robots (roles are the protocol's).

    Parameters
    ----------
    n : number of robots.
    side_m : side of the square area (the torus's, and the default area ``[0, side_m]^2``).
    range_m : communication range of each robot (scalar or one per robot).
    torus : when true, positions wrap around the borders and distances are taken on the
        torus (minimum image).
    bounds : the area robots move in, in the world frame (``world.bounds_m``); default the
        square ``[0, side_m]^2``.
    """

    def __init__(
        self,
        n: int,
        side_m: float,
        range_m: float | Sequence[float] | np.ndarray,
        torus: bool = False,
        bounds: Bounds | None = None,
    ):
        self.n = int(n)
        self.side_m = float(side_m)
        self.bounds = bounds if bounds is not None else Bounds.square(self.side_m)
        self.torus = bool(torus)
        self.range_m = np.broadcast_to(np.asarray(range_m, dtype=float), (self.n,)).copy()
        self.origin_m = np.zeros((self.n, 2))
        self.velocity_mps = np.zeros((self.n, 2))
        self.t0_s = np.zeros(self.n)
        # The same memory seen as complex numbers x + iy (a view: always in step).
        self.origin_c = self.origin_m.view(np.complex128)[:, 0]
        self.velocity_c = self.velocity_mps.view(np.complex128)[:, 0]
        self.alive = np.ones(self.n, dtype=bool)
        # Highest speed any robot has had in the run (raised by legs and by the spatial
        # indexes, never lowered): bounds how far anyone can have moved in any interval.
        self.speed_high_water_mps = 0.0
        # Bumped when a robot jumps (a trace's "set X_" at t > 0): the index must rebuild.
        self.jumps = 0
        # Travel of each robot up to the start of its current leg, a jump counted as the
        # straight line it jumped (a robot put elsewhere stands among other obstacles), and
        # its speed on the leg (numpy's abs of its velocity): the robot's travel
        # (travelled_m), the clock of the radio's shadowing (a pair's travel).
        self.odometer_m = np.zeros(self.n)
        # The part of it that jumps made: the path length is the travel less this.
        self.jumped_m = np.zeros(self.n)
        self.speed_mps = np.zeros(self.n)
        self._legs: list[tuple] = []
        # Told of every change of a robot's leg as fn(robot, t, jump), logged or not.
        self.watchers: list[Callable[[int, float, bool], None]] = []
        # The run's event bus (netsim.events.EventBus), if any: course_change events.
        self.events: EventBus | None = None
        # Off until check_motion: a scratch state (a test's, a format's) holds any position.
        self.checked = False
        self._tolerance_m = 0.0
        self._walls: Any = None
        # Where each robot's current leg comes from, for the message of a failed check
        # (a trace's file and line), when the model that moves it says.
        self.leg_notes: dict[int, str] = {}
        # The core kernels as this team's size calls them (netsim.compiled.load), looked up
        # at the first position asked: a leg change asks one, and the lookup reads the
        # environment.
        self._core: types.ModuleType | None = None
        self._every_robot = np.arange(self.n)

    # -- positions -------------------------------------------------------------------
    def positions_at(
        self, t: float, idx: int | Sequence[int] | np.ndarray | None = None, fold: bool = True
    ) -> np.ndarray:
        """Positions at time ``t`` (all robots, or rows ``idx``), shape ``(k, 2)`` (``(2,)``
        for one int): :func:`netsim._kernels.positions`, the rule the compiled loops place
        a robot by. ``fold=False``: on a torus, the point on the robot's unfolded leg.

        ``t`` must not be before the start of a robot's current leg.
        """
        rows, one = self._rows(idx)
        out = np.empty((rows.size, 2))
        kernels = self._core or self._load_core()
        bad = kernels.positions(
            self.origin_m,
            self.velocity_mps,
            self.t0_s,
            rows.reshape(-1),
            float(t),
            self.torus and fold,
            self.side_m,
            out,
        )
        if bad >= 0:
            raise IndexError(f"robot index {rows.reshape(-1)[bad]} out of range for {self.n} robots")
        return out[0] if one else out

    def _rows(self, idx: int | Sequence[int] | np.ndarray | slice | None) -> tuple[np.ndarray, bool]:
        """Robot ids as a kernel takes them (contiguous int64), and whether one was asked."""
        if idx is None:
            return self._every_robot, False
        if isinstance(idx, slice):
            return self._every_robot[idx], False
        rows = np.asarray(idx)
        one = rows.ndim == 0
        if rows.dtype != np.int64:
            if rows.size and rows.dtype.kind not in "iu":
                hint = " (a mask: np.flatnonzero(mask))" if rows.dtype == bool else ""
                raise TypeError(f"robot indices must be integers, got {rows.dtype}{hint}")
            rows = rows.astype(np.int64)
        # numba compiles a kernel again for each new array layout it is handed.
        rows = np.ascontiguousarray(rows)
        if rows.ndim > 1:
            raise ValueError(f"robot indices must be one number or a 1-d sequence, got shape {rows.shape}")
        return rows, one

    def position(self, i: int, t: float) -> tuple[float, float]:
        """Position of robot ``i`` at ``t`` as two floats (:func:`netsim._kernels.position`,
        the rule the compiled loops place a robot by)."""
        kernels = self._core or self._load_core()
        x, y = kernels.position(self.origin_m, self.velocity_mps, self.t0_s, int(i), float(t), self.torus, self.side_m)
        return float(x), float(y)

    def _load_core(self) -> types.ModuleType:
        self._core = load("netsim._kernels", self.n)
        return self._core

    def travelled_m(self, t: float, idx: np.ndarray | Sequence[int] | slice) -> np.ndarray:
        """Travel of robots ``idx`` (ids, or a slice: ``slice(None)``, every robot) from t =
        0 to ``t`` (``t`` on their current leg), a jump counted as the straight line it
        jumped (``jumped_m`` holds those): :func:`netsim._kernels.travel`, the law the
        shadowing's clock runs on."""
        rows, _ = self._rows(idx)
        out = np.empty(rows.size)
        kernels = self._core or self._load_core()
        bad = kernels.travels(self.odometer_m, self.speed_mps, self.t0_s, rows.reshape(-1), float(t), out)
        if bad >= 0:
            raise IndexError(f"robot index {rows.reshape(-1)[bad]} out of range for {self.n} robots")
        return out

    def pair_travelled_m(self, t: float, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Each pair's travel at ``t`` (``t`` on the robots' current legs): the two robots'
        :meth:`travelled_m` summed (:func:`netsim._kernels.pair_travel`), the clock a pair's
        shadowing runs on."""
        (a, _), (b, _) = self._rows(a), self._rows(b)
        if a.shape != b.shape:
            raise ValueError(f"pairs need as many first robots as second ones, got {a.shape} and {b.shape}")
        out = np.empty(a.size)
        kernels = self._core or self._load_core()
        bad = kernels.pair_travels(
            self.odometer_m, self.speed_mps, self.t0_s, a.reshape(-1), b.reshape(-1), float(t), out
        )
        if bad >= 0:
            pair = (int(a.reshape(-1)[bad]), int(b.reshape(-1)[bad]))
            raise IndexError(f"robot pair {pair} out of range for {self.n} robots")
        return out

    def _log_travel(self, i: int, t: float) -> None:
        kernels = self._core or self._load_core()
        self.odometer_m[i] = kernels.travel(self.odometer_m, self.speed_mps, self.t0_s, i, float(t))

    def _set_speeds(self, idx: int | np.ndarray) -> None:
        speeds = speeds_mps(self.velocity_mps[idx])
        self.speed_mps[idx] = speeds if np.ndim(idx) else speeds[0]
        high = float(speeds.max(initial=0.0))
        if high > self.speed_high_water_mps:
            self.speed_high_water_mps = high

    def displacement(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Vectors from positions ``b`` to ``a``; the shortest image on a torus
        (:func:`netsim.geometry.wrap`)."""
        return wrap(a - b, self.torus_side_m, self.n)

    # -- motion ----------------------------------------------------------------------
    def place(self, positions_m: np.ndarray) -> None:
        """Initial positions at t = 0, everyone at rest (cause ``"start"``)."""
        try:
            positions_m = np.asarray(positions_m, dtype=float)
        except (TypeError, ValueError):
            raise MotionError(f"the robots are placed at positions that are not numbers: {positions_m!r:.80}") from None
        if positions_m.shape != (self.n, 2):
            raise MotionError(f"{self.n} robots need positions of shape ({self.n}, 2), not {positions_m.shape}")
        bad = ~np.isfinite(positions_m).all(axis=1)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            x, y = positions_m[i]
            raise MotionError(f"robot {i} is placed at ({x:g}, {y:g}): a position must be finite")
        self.origin_m[:] = positions_m
        self.velocity_mps[:] = 0.0
        self.speed_mps[:] = 0.0
        self.t0_s[:] = 0.0
        self.odometer_m[:] = 0.0
        self.jumped_m[:] = 0.0
        self._legs = [(0.0, i, x, y, 0.0, 0.0, "start") for i, (x, y) in enumerate(positions_m.tolist())]
        for w in self.watchers:
            for i in range(self.n):
                w(i, 0.0, True)

    def _changed(self, i: int, t: float, jump: bool, cause: str | None) -> None:
        """Tell the watchers, and the subscribers when the leg is logged (``cause``)."""
        for w in self.watchers:
            w(i, t, jump)
        ev = self.events
        if cause is not None and ev is not None and ev.wants("course_change"):
            leg = self._legs[-1]
            ev.emit("course_change", CourseChange(*leg))

    def set_leg(
        self,
        i: int,
        t: float,
        velocity_mps: Sequence[float] | np.ndarray,
        start_m: Sequence[float] | np.ndarray | None = None,
        cause: str | None = None,
    ) -> None:
        """Robot ``i`` starts a new straight leg at time ``t`` with ``velocity_mps``.

        The leg starts where the robot is (continuous motion) unless ``start_m`` is given,
        which is a jump. ``cause`` (one of :data:`CAUSES`) defaults to ``"jump"`` for a jump
        and ``"command"`` otherwise.
        """
        if start_m is None:
            start = self.positions_at(t, i, fold=False)
            if self.checked:
                self._check_end(i, t, start)
        else:
            start = np.asarray(start_m, dtype=float)
            if start.shape != (2,) or not np.isfinite(start).all():
                where = f"{start_m!r:.60}"
                raise MotionError(f"robot {i} jumps to {where} at t = {t:.9g} s: a position is two finite numbers")
            self.jumps += 1
            here = self.positions_at(t, i, fold=False)
            if self.checked:
                self._check_end(i, t, here)
                self._check_jump(i, t, start)
            jumped_m = float(distances_m(here.reshape(1, 2), start.reshape(1, 2), self.torus_side_m, self.n)[0])
        if cause is None:
            cause = "command" if start_m is None else "jump"
        if len(velocity_mps) != 2:
            k = len(velocity_mps)
            raise MotionError(f"robot {i} is given a velocity of {k} components at t = {t:.9g} s, not 2")
        vx, vy = float(velocity_mps[0]), float(velocity_mps[1])
        if not drivable((vx, vy))[0]:
            raise MotionError(
                f"robot {i} is given the velocity ({vx:g}, {vy:g}) m/s at t = {t:.9g} s: it must be finite, "
                "and slower than light"
            )
        self._log_travel(i, t)
        if start_m is not None:
            self.odometer_m[i] += jumped_m
            self.jumped_m[i] += jumped_m
        self.origin_m[i] = start
        self.velocity_mps[i] = (vx, vy)
        self.t0_s[i] = t
        self._set_speeds(i)
        self._legs.append((float(t), int(i), float(start[0]), float(start[1]), vx, vy, cause))
        self._changed(i, t, start_m is not None, cause)

    def set_legs(
        self, idx: np.ndarray, t: float, velocities_mps: np.ndarray, cause: str | Sequence[str] = "command"
    ) -> None:
        """Robots ``idx`` (distinct) each start a new straight leg at ``t`` from where they
        are, with the rows of ``velocities_mps``: what :meth:`set_leg` does for each, in
        order, computed for all at once. ``cause``: one for all, or one per robot."""
        idx = np.asarray(idx, dtype=np.int64)
        v = np.asarray(velocities_mps, dtype=float)
        if v.shape != (len(idx), 2):
            n = len(idx)
            raise MotionError(f"{n} robots are given velocities of shape {v.shape} at t = {t:.9g} s, not ({n}, 2)")
        if len(idx) == 0:
            return
        ok = drivable(v)
        if not ok.all():
            k = int(np.flatnonzero(~ok)[0])
            vx, vy = v[k]
            raise MotionError(
                f"robot {int(idx[k])} is given the velocity ({vx:g}, {vy:g}) m/s at t = {t:.9g} s: it must be "
                "finite, and slower than light"
            )
        start = self.positions_at(t, idx, fold=False)
        if self.checked:
            self._check_ends(idx, t, start)
        self.odometer_m[idx] = self.travelled_m(t, idx)
        self.origin_m[idx] = start
        self.velocity_mps[idx] = v
        self.t0_s[idx] = t
        self._set_speeds(idx)
        t = float(t)
        causes = [cause] * len(idx) if isinstance(cause, str) else list(cause)
        new = [
            (t, i, x, y, vx, vy, c) for i, (x, y), (vx, vy), c in zip(idx.tolist(), start.tolist(), v.tolist(), causes)
        ]
        self._legs.extend(new)
        ev = self.events
        tell = ev is not None and ev.wants("course_change")
        if self.watchers or tell:
            for leg in new:
                for w in self.watchers:
                    w(leg[1], t, False)
                if tell:
                    assert ev is not None
                    ev.emit("course_change", CourseChange(*leg))

    def head_to(
        self, i: int, t: float, dest_m: Sequence[float] | np.ndarray, speed_mps: float, cause: str = "command"
    ) -> float:
        """Move ``i`` in a straight line toward ``dest_m`` at ``speed_mps``.

        Returns the travel time (0 when already there or when the speed is 0, in which
        case the robot stops).
        """
        here = self.positions_at(t, i, fold=False)
        dest = np.asarray(dest_m, dtype=float)
        delta = dest - here
        dist = float(distances_m(here, dest, None, self.n)[0])
        if dist == 0.0 or speed_mps <= 0.0:
            self.set_leg(i, t, (0.0, 0.0), cause=cause)
            return 0.0
        self.set_leg(i, t, delta * (speed_mps / dist), cause=cause)
        return dist / speed_mps

    def arrive(
        self, i: int, t: float, dest_m: Sequence[float] | np.ndarray, log: bool = True, cause: str = "waypoint"
    ) -> None:
        """Stop ``i`` exactly at ``dest_m`` (removes rounding from the leg's end).

        ``log=False`` when the robot leaves again at the same instant: the stop would be
        a leg of zero length (the watchers are still told: the leg changed).
        """
        if self.checked:
            self._check_end(i, t, np.asarray(dest_m, dtype=float))
        self._log_travel(i, t)
        self.origin_m[i] = dest_m
        self.velocity_mps[i] = 0.0
        self.speed_mps[i] = 0.0
        self.t0_s[i] = t
        if log:
            self._legs.append((float(t), int(i), float(dest_m[0]), float(dest_m[1]), 0.0, 0.0, cause))
        self._changed(i, t, False, cause if log else None)

    # -- the area and the walls -------------------------------------------------------
    def check_motion(self, walls: Any = None) -> None:
        """From now on, refuse motion that leaves the area (``bounds``) or, with ``walls``
        (a map's, :class:`netsim.world.free_space.Walls`), enters a cell that is not free:
        :class:`MotionError` naming the robot and the time. Not on a torus, where every
        position is inside."""
        self.checked = not self.torus
        b = self.bounds
        self._tolerance_m = border_tolerance_m(b)
        self._walls = walls

    def check_until(self, t: float) -> None:
        """The legs robots are on, up to ``t`` (the end of a run): :meth:`check_motion`'s
        rule for motion that no leg change has ended yet."""
        if not self.checked:
            return
        self._check_ends(np.arange(self.n), t, self.positions_at(t))

    def _inside(self, x: float, y: float) -> bool:
        b, tol = self.bounds, self._tolerance_m
        return b.x_min - tol <= x <= b.x_max + tol and b.y_min - tol <= y <= b.y_max + tol

    def _check_end(self, i: int, t: float, end: np.ndarray) -> None:
        """:meth:`_check_ends` for robot ``i`` alone, with a fast path for the common case (a
        leg ending inside the area, no map)."""
        moving = self.velocity_mps[i, 0] != 0 or self.velocity_mps[i, 1] != 0
        if not self._inside(float(end[0]), float(end[1])) or (self._walls is not None and moving):
            self._check_ends(np.array([i]), t, np.asarray(end, dtype=float)[None])

    def _check_ends(self, idx: np.ndarray, t: float, ends: np.ndarray) -> None:
        """Robots ``idx``'s current legs, ending at ``ends`` at ``t``, stay in the area and (on a
        map) in free cells: as the area is convex, their ends tell."""
        out = ~self.bounds.contains(ends, self._tolerance_m)
        if out.any():
            k = int(np.flatnonzero(out)[0])
            self._refuse_leg(int(idx[k]), t, ends[k], "leaves the area")
        if self._walls is not None:
            v = self.velocity_mps[idx]
            moving = np.flatnonzero((v[:, 0] != 0) | (v[:, 1] != 0))
            if len(moving):
                free = self._walls.legs_free(self.origin_m[idx[moving]], ends[moving])
                if not free.all():
                    k = int(moving[np.flatnonzero(~free)[0]])
                    self._refuse_leg(int(idx[k]), t, ends[k], "crosses a wall of the map")

    def _check_jump(self, i: int, t: float, to: np.ndarray) -> None:
        """A jump lands in the area and (on a map) in a free cell."""
        where = f"({float(to[0]):g}, {float(to[1]):g})"
        if not self._inside(float(to[0]), float(to[1])):
            raise MotionError(
                f"robot {i} jumps out of the area{self._area()} at t = {t:.9g} s, to {where}{self._note(i)}"
            )
        if self._walls is not None and not bool(self._walls.is_free(np.asarray(to, dtype=float)[None])[0]):
            raise MotionError(f"robot {i} jumps into a wall of the map at t = {t:.9g} s, to {where}{self._note(i)}")

    def _refuse_leg(self, i: int, t: float, end: np.ndarray, what: str) -> None:
        """Raise :class:`MotionError` for robot ``i``'s leg, naming when it leaves."""
        start, t0 = self.origin_m[i].copy(), float(self.t0_s[i])
        if what == "leaves the area":
            frac = self._exit_fraction(start, np.asarray(end, dtype=float))
            where = self._area()
        else:
            f = float(self._walls.first_blocked(start[None], np.asarray(end, dtype=float)[None])[0])
            frac, where = (min(f, 1.0) if np.isfinite(f) else 1.0), ""
        t_out = t0 + frac * (t - t0)
        p = start + frac * (np.asarray(end, dtype=float) - start)
        raise MotionError(f"robot {i} {what}{where} at t = {t_out:.9g} s, at ({p[0]:g}, {p[1]:g}){self._note(i)}")

    def _exit_fraction(self, start: np.ndarray, end: np.ndarray) -> float:
        """The fraction of the leg ``start -> end`` at which it leaves the area."""
        b, tol = self.bounds, self._tolerance_m
        frac = 1.0
        for axis, (lo, hi) in enumerate(((b.x_min, b.x_max), (b.y_min, b.y_max))):
            a, e = float(start[axis]), float(end[axis])
            if (e > hi + tol or e < lo - tol) and e == a:
                return 0.0  # the leg is outside from its start
            if e > hi + tol:
                frac = min(frac, (hi - a) / (e - a))
            elif e < lo - tol:
                frac = min(frac, (lo - a) / (e - a))
        return max(frac, 0.0)

    def _area(self) -> str:
        b = self.bounds
        return f" [{b.x_min:g}, {b.x_max:g}] x [{b.y_min:g}, {b.y_max:g}]"

    def _note(self, i: int) -> str:
        note = self.leg_notes.get(i)
        return f" ({note})" if note else ""

    # -- log -------------------------------------------------------------------------
    def legs(self) -> pd.DataFrame:
        """Every leg: ``t_s, robot, x_m, y_m, vx_mps, vy_mps, cause`` (unwrapped positions;
        ``cause`` one of :data:`CAUSES`)."""
        df = pd.DataFrame(self._legs, columns=LEG_COLUMNS)
        return df.sort_values(["robot", "t_s"], kind="stable").reset_index(drop=True)
