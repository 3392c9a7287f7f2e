"""Timed positions per robot, followed in straight lines: what BonnMotion files and
recorded poses describe, and the legs they make.

A robot is at its first waypoint from t = 0 until that waypoint's time (a robot whose log
starts later waits there), moves in a straight line at constant speed from each waypoint to
the next, and stays at its last one. Two waypoints at one instant are a jump.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from netsim.errors import NetsimInputError
from netsim.geometry import row_starts
from netsim.trajectory import LegTable


@dataclass(frozen=True)
class Waypoints:
    """Rows ``(robot, t_s, x_m, y_m)``, sorted by robot then time (stable), every robot
    from 0 to ``n_robots - 1`` with at least one row."""

    robot: np.ndarray
    t_s: np.ndarray
    x_m: np.ndarray
    y_m: np.ndarray

    @property
    def n_robots(self) -> int:
        return int(self.robot.max()) + 1 if len(self.robot) else 0

    @classmethod
    def of(cls, robot: Any, t_s: Any, x_m: Any, y_m: Any, source: str) -> Waypoints:
        """Sorted rows; every robot 0..max named at least once, else one line naming ``source``."""
        robot = np.asarray(robot, dtype=np.int64)
        t_s, x_m, y_m = (np.asarray(a, dtype=float) for a in (t_s, x_m, y_m))
        if len(robot) == 0:
            raise NetsimInputError(f"{source}: no positions")
        order = np.lexsort((t_s, robot))
        robot, t_s, x_m, y_m = robot[order], t_s[order], x_m[order], y_m[order]
        missing = np.setdiff1d(np.arange(robot.max() + 1), robot)
        if len(missing):
            raise NetsimInputError(f"{source}: robot(s) {missing[:10].tolist()} have no position")
        return cls(robot, t_s, x_m, y_m)

    def initial_m(self) -> np.ndarray:
        """Each robot's first position, (n, 2)."""
        first = row_starts(self.robot, self.n_robots)[:-1]
        return np.column_stack([self.x_m[first], self.y_m[first]])

    def commands(self) -> list[tuple[float, int, float, float, float, float]]:
        """Time-ordered ``(t_s, robot, x_m, y_m, vx_mps, vy_mps)``: at ``t_s`` the robot is at
        ``(x_m, y_m)`` and moves on at that velocity (0: it stops there)."""
        out = []
        same = self.robot[1:] == self.robot[:-1]
        for k in range(len(self.robot)):
            nxt = k + 1 if k + 1 < len(self.robot) and same[k] else -1
            vx = vy = 0.0
            if nxt >= 0:
                dt = self.t_s[nxt] - self.t_s[k]
                if dt == 0.0:
                    continue  # a jump: the next row starts from its own position
                vx = (self.x_m[nxt] - self.x_m[k]) / dt
                vy = (self.y_m[nxt] - self.y_m[k]) / dt
            out.append((float(self.t_s[k]), int(self.robot[k]), float(self.x_m[k]), float(self.y_m[k]), vx, vy))
        out.sort(key=lambda c: (c[0], c[1]))
        return out

    def positions_at(self, t_s: float) -> np.ndarray:
        """Every robot's position at ``t_s``, (n, 2) (for tests and checks)."""
        out = np.empty((self.n_robots, 2))
        for i in range(self.n_robots):
            rows = self.robot == i
            t, x, y = self.t_s[rows], self.x_m[rows], self.y_m[rows]
            k = np.searchsorted(t, t_s, side="right")
            if k == 0:
                out[i] = x[0], y[0]
            elif k == len(t):
                out[i] = x[-1], y[-1]
            else:
                f = (t_s - t[k - 1]) / (t[k] - t[k - 1])
                out[i] = x[k - 1] + f * (x[k] - x[k - 1]), y[k - 1] + f * (y[k] - y[k - 1])
        return out


def from_legs(legs: pd.DataFrame, n_robots: int, duration_s: float) -> Waypoints:
    """The waypoints of a run's legs (``legs.parquet``): each leg's start, where each robot
    is at ``duration_s``, and where a leg that ends in a jump put its robot at the jump's
    instant (two waypoints at one instant)."""
    table = LegTable(legs[legs["t_s"] <= duration_s], n_robots)
    t_end, end, jump = table.ends(duration_s)
    last = np.zeros(len(table.t), bool)
    last[table.end - 1] = True
    # Each leg's start, then its end where that is a waypoint of its own (not a leg of no
    # duration's, its start already); a stable sort by robot and time keeps a jump's two
    # waypoints in that order.
    instant = (t_end == table.t) & (end == table.p).all(axis=1)
    keep = np.column_stack([np.ones(len(last), bool), (jump | last) & ~instant]).ravel()
    robot = np.repeat(table.robot, 2)[keep]
    t = np.column_stack([table.t, t_end]).ravel()[keep]
    xy = np.stack([table.p, end], axis=1).reshape(-1, 2)[keep]
    return Waypoints.of(robot, t, xy[:, 0], xy[:, 1], "legs")
