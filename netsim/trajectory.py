"""Trajectories from the leg log: where every robot was at any time, exactly."""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
import pandas as pd

from netsim.compiled import filled, load
from netsim.geometry import distances_m, in_box, row_starts

# A robot put farther than this, times 1 m plus the size of both positions' coordinates, from where
# it was has jumped (a placement, a trace's repeated instant, a border of a folded torus run):
# closer, it is the rounding of a leg's end. The link solvers judge a jump's links afresh,
# and the writers of movement files must say where it jumped: one rule for both.
JUMP_M = 1e-9


def jumped(
    was_m: npt.ArrayLike, now_m: npt.ArrayLike, side_m: float | None = None, n_robots: int | None = None
) -> np.ndarray:
    """Whether a robot at ``was_m`` put at ``now_m`` (``(k, 2)`` each) jumped; on a torus of
    side ``side_m`` (None: the plane) a move by whole sides is none, in a run of ``n_robots``."""
    was_m, now_m = np.asarray(was_m, float).reshape(-1, 2), np.asarray(now_m, float).reshape(-1, 2)
    scale = 1.0 + np.abs(was_m).max(axis=-1, initial=0.0) + np.abs(now_m).max(axis=-1, initial=0.0)
    return distances_m(was_m, now_m, side_m, n_robots) > JUMP_M * scale


def points_on_legs(
    origin_m: np.ndarray,
    velocity_mps: np.ndarray,
    t0_s: np.ndarray,
    rows: npt.ArrayLike,
    times_s: npt.ArrayLike,
    n_robots: int | None,
) -> np.ndarray:
    """Where leg ``rows[k]`` of the legs ``(origin_m, velocity_mps, t0_s)`` puts its robot
    at ``times_s[k]`` (one time for all, or one per row), unfolded, shape ``(k, 2)``: the
    position rule the state and the compiled loops use (:func:`netsim._kernels.points_on_legs`)."""
    rows = np.ascontiguousarray(rows, np.int64).reshape(-1)
    times = filled(times_s, rows.shape)
    out = np.empty((rows.size, 2))
    load("netsim._kernels", n_robots).points_on_legs(
        np.ascontiguousarray(origin_m, float),
        np.ascontiguousarray(velocity_mps, float),
        np.ascontiguousarray(t0_s, float),
        rows,
        times,
        out,
    )
    return out


class LegTable:
    """The leg log as flat arrays, with each robot's legs contiguous and time-ordered."""

    def __init__(self, legs: pd.DataFrame, n: int):
        legs = legs.sort_values(["robot", "t_s"], kind="stable")
        # Writable and row-major, as the kernels take them: a frame's columns come out
        # column-major or read-only, each a type numba compiles a kernel for again (and each
        # call would copy the whole log).
        k = len(legs)
        self.t = filled(legs["t_s"].to_numpy(float), (k,))
        self.p = filled(legs[["x_m", "y_m"]].to_numpy(float), (k, 2))
        self.v = filled(legs[["vx_mps", "vy_mps"]].to_numpy(float), (k, 2))
        robots = legs["robot"].to_numpy(np.int64)
        self.robot = robots
        # Legs logged as a jump (a placement: netsim.state.RobotState.set_leg's start_m): a
        # jump however short, as the run took it; a table without causes has none.
        self.logged_jump = legs["cause"].to_numpy() == "jump" if "cause" in legs.columns else np.zeros(k, bool)
        self.n = n
        starts = row_starts(robots, n)
        self.first, self.end = starts[:-1], starts[1:]
        if np.any(self.end == self.first):
            raise ValueError("every robot needs at least one leg (its initial position)")
        self.cur = self.first.copy()

    def legs_at(self, robots: npt.ArrayLike, times_s: npt.ArrayLike) -> np.ndarray:
        """The leg of ``robots[k]`` current at ``times_s[k]`` (one time for all, or one per
        robot): its last leg that starts at or before it, its first when none does
        (:func:`netsim._kernels.legs_at`)."""
        robots = np.asarray(robots).reshape(-1)
        robots = filled(robots, robots.shape, np.int64)
        leg = np.empty(robots.shape[0], np.int64)
        times = filled(times_s, robots.shape)
        load("netsim._kernels", self.n).legs_at(self.first, self.end, self.t, robots, times, leg)
        return leg

    def advance(self, t: float) -> None:
        """Make ``cur`` the leg of each robot that is current at time ``t``."""
        self.cur = self.legs_at(np.arange(self.n), t)

    def at(self, legs: np.ndarray, t: npt.ArrayLike) -> np.ndarray:
        """Where legs ``legs`` put their robots at ``t`` (one time, or one per leg)."""
        return points_on_legs(self.p, self.v, self.t, legs, t, self.n)

    def jumps(self, side_m: float | None = None) -> np.ndarray:
        """Whether each leg starts with a jump: logged as one, or away from where the robot's
        previous leg had it then (:func:`jumped`; on a torus of side ``side_m`` by the
        nearest image). A robot's first leg never does."""
        k = np.flatnonzero(np.r_[False, self.robot[1:] == self.robot[:-1]])
        out = np.zeros(len(self.t), bool)
        out[k] = self.logged_jump[k] | jumped(self.at(k - 1, self.t[k]), self.p[k], side_m, self.n)
        return out

    def ends(self, duration_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Each leg's end, in the table's order: its time (:meth:`end_times`), where the leg
        puts its robot then, and whether the robot's next leg, by ``duration_s``, starts
        elsewhere (a jump; never on a robot's last leg). Where the next leg follows by then
        without a jump, the end is that leg's start as logged (a waypoint, a wall the robot
        turned at), not the leg's motion recomputed to that instant."""
        last, nxt = self._next()
        t_end = self.end_times(duration_s)
        xy = self.at(np.arange(len(self.t)), t_end)
        follows = ~last & (self.t[nxt] <= duration_s)
        jump = follows & self.jumps()[nxt]
        joined = follows & ~jump
        xy[joined] = self.p[nxt[joined]]
        return t_end, xy, jump

    def end_times(self, duration_s: float) -> np.ndarray:
        """When each leg ends: the robot's next leg's start, or ``duration_s``, whichever is first."""
        last, nxt = self._next()
        return np.minimum(np.where(last, duration_s, self.t[nxt]), duration_s)

    def _next(self) -> tuple[np.ndarray, np.ndarray]:
        """Whether each leg is its robot's last, and the row of the leg after it (itself if last)."""
        k = np.arange(len(self.t))
        last = np.zeros(len(k), bool)
        last[self.end - 1] = True
        return last, np.where(last, k, k + 1)


def folded_legs(legs: pd.DataFrame, n: int, side_m: float, duration_s: float) -> pd.DataFrame:
    """A torus run's legs (each runs on past the borders, unfolded) as legs inside the square
    ``[0, side]^2``, up to ``duration_s``: each cut where it reaches a border, the robot put
    on that border (a leg of no duration) and, at the same instant, on the opposite one, from
    where the rest of the leg goes on: a jump, which the movement files' writers write."""
    legs = legs[legs["t_s"] <= duration_s]
    table = LegTable(legs, n)
    t_end = table.end_times(duration_s)
    side = float(side_m)
    legs_k = np.arange(len(table.t))
    reached = table.at(legs_k, t_end)  # each leg's unfolded end
    starts = in_box(table.p, side)
    rows: list[tuple[float, int, float, float, float, float, str]] = []
    # LegTable's order: by robot, then time, stable.
    causes = legs.sort_values(["robot", "t_s"], kind="stable")["cause"].tolist()
    for k in legs_k.tolist():
        t0, t1, robot = float(table.t[k]), float(t_end[k]), int(table.robot[k])
        p0, v = table.p[k], table.v[k]
        # A robot on a border, leaving the square across it, starts on the opposite one.
        here = np.where((starts[k] == 0.0) & (v < 0.0), side, starts[k])
        rows.append((t0, robot, *here.tolist(), *v.tolist(), causes[k]))
        cuts = []
        for a in (0, 1):
            if v[a] != 0.0:
                lo, hi = sorted((p0[a], reached[k, a]))
                for m in range(math.floor(lo / side) + 1, math.ceil(hi / side) + 1):
                    tc = t0 + (m * side - p0[a]) / v[a]
                    if t0 < tc <= t1:
                        cuts.append((tc, a))
        # Each piece from where the one before it jumped to: at a corner both axes are cut at
        # one instant, the second from where the first put the robot.
        ts = t0
        for tc, a in sorted(cuts):
            border = points_on_legs(here[None], v[None], np.array([ts]), [0], tc, 1)[0]
            border[a] = side if v[a] > 0 else 0.0
            here = border.copy()
            here[a] = 0.0 if v[a] > 0 else side
            ts = tc
            rows.append((tc, robot, *border.tolist(), 0.0, 0.0, "border"))
            rows.append((tc, robot, *here.tolist(), *v.tolist(), "jump"))
    return pd.DataFrame(rows, columns=["t_s", "robot", "x_m", "y_m", "vx_mps", "vy_mps", "cause"])


def sample_positions(
    legs: pd.DataFrame, n: int, times_s: npt.ArrayLike, side_m: float | None = None, torus: bool = False
) -> pd.DataFrame:
    """Positions of every robot at each of ``times_s`` (ascending): ``t_s, robot, x_m, y_m``."""
    table = LegTable(legs, n)
    times_s = np.asarray(times_s, dtype=float)
    xy = np.empty((len(times_s), n, 2))
    # Every robot at every instant in one query per block of instants (a block of about a
    # million positions): a call per instant cost more than the positions themselves on a
    # long run sampled finely.
    block = max(1, (1 << 20) // max(n, 1))
    robots = np.arange(n, dtype=np.int64)
    for k in range(0, len(times_s), block):
        t = np.repeat(times_s[k : k + block], n)
        who = np.tile(robots, len(t) // n) if n else robots
        xy[k : k + block] = table.at(table.legs_at(who, t), t).reshape(-1, n, 2)
    if torus:
        xy = in_box(xy, side_m, n)
    return pd.DataFrame(
        {
            "t_s": np.repeat(times_s, n),
            "robot": np.tile(np.arange(n, dtype=np.int64), len(times_s)),
            "x_m": xy[:, :, 0].ravel(),
            "y_m": xy[:, :, 1].ravel(),
        }
    )
