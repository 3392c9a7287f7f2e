"""The paper's figures, drawn from a run's output directory (``netsim figures``).

- ``fig6_initial_deployment.png``: robots when control starts (after group formation):
  leaders, members coloured by group, gateways, undecided robots, and the links;
- ``fig7_leader_paths.png``: the leaders' force-driven paths, start to end;
- ``fig8_final_deployment.png``: the final deployment with the leaders' coverage disks.

Only the run's files are read (``config.toml``, ``positions.parquet``, ``roles.parquet``,
``groups.parquet`` when there), so figures can be redrawn from old results.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pandas as pd

from netsim import config as cfgmod
from netsim.errors import NetsimInputError
from netsim.topology import geometric_pairs

# The built-in coverage scenario: a dense random start in the middle of the area, as the
# paper's Fig. 6, then the leaders spread out.
COVERAGE_SCENARIO = [
    "world.n_robots=60",
    "world.side_m=1000",
    'world.placement="centre"',
    "world.centre_side_m=300",
    'mobility.model="static"',
    "channel.range_m=100",
    "coverage.enabled=true",
    "duration_s=300",
]


def _read(run_dir: Path):
    needed = ["config.toml", "positions.parquet", "roles.parquet"]
    missing = [f for f in needed if not (run_dir / f).is_file()]
    if missing:
        raise NetsimInputError(f"{run_dir}: not a run directory with positions (missing {', '.join(missing)})")
    config = cfgmod.from_dict(tomllib.loads((run_dir / "config.toml").read_text()))
    positions = pd.read_parquet(run_dir / "positions.parquet")
    if positions.empty:
        raise NetsimInputError(f"{run_dir}: positions were not sampled (output.position_interval_s = 0)")
    roles = pd.read_parquet(run_dir / "roles.parquet")
    groups = pd.read_parquet(run_dir / "groups.parquet") if (run_dir / "groups.parquet").is_file() else None
    return config, positions, roles, groups


def _sample_time(frame: pd.DataFrame, t: float) -> float:
    """The sampling instant of ``frame`` at or just after ``t`` (the last one if none)."""
    times = np.sort(frame["t_s"].unique())
    return float(times[min(int(np.searchsorted(times, t - 1e-9)), len(times) - 1)])


def _at(positions: pd.DataFrame, t: float) -> tuple[float, np.ndarray]:
    """The positions sample at or just after ``t``: its time and (N, 2) positions."""
    when = _sample_time(positions, t)
    snap = positions[positions["t_s"] == when].sort_values("robot")
    return when, snap[["x_m", "y_m"]].to_numpy()


def _roles_at(roles: pd.DataFrame, n: int, t: float) -> tuple[np.ndarray, np.ndarray]:
    r = roles[roles["t_s"] <= t + 1e-9].reset_index(drop=True)
    r["order"] = np.arange(len(r))
    last = r.sort_values(["robot", "t_s", "order"]).groupby("robot").tail(1)
    role = np.full(n, "gamma", dtype=object)
    leader = np.full(n, -1)
    role[last["robot"].to_numpy()] = last["role"].to_numpy()
    leader[last["robot"].to_numpy()] = last["leader"].to_numpy()
    return role, leader


def _gateways_at(groups: pd.DataFrame | None, n: int, t: float) -> np.ndarray:
    out = np.zeros(n, bool)
    if groups is None or groups.empty:
        return out
    g = groups[groups["t_s"] == _sample_time(groups, t)]
    counts = g.groupby("robot").size()
    out[counts[counts > 1].index.to_numpy()] = True
    return out


def _deployment(ax, pos, role, leader, gateway, range_m, side_m, colours, disks_m=0.0):
    import matplotlib.patches as mpatches

    a, b, _ = geometric_pairs(pos, range_m)
    for i, j in zip(a.tolist(), b.tolist()):
        ax.plot(*pos[[i, j]].T, color="0.8", lw=0.5, zorder=1)
    is_leader = role == "alpha"
    if disks_m > 0:
        for i in np.flatnonzero(is_leader).tolist():
            ax.add_patch(mpatches.Circle(pos[i], disks_m, color=colours(i), alpha=0.15, lw=0, zorder=0))
    members = np.flatnonzero((role == "beta") & ~gateway)
    ax.scatter(*pos[members].T, s=12, c=[colours(int(leader[m])) for m in members], zorder=2, label="member (beta)")
    gw = np.flatnonzero((role == "beta") & gateway)
    if len(gw):
        ax.scatter(*pos[gw].T, s=30, marker="s", facecolors="none", edgecolors="k", lw=0.8, zorder=3, label="gateway")
    und = np.flatnonzero(role == "gamma")
    if len(und):
        ax.scatter(*pos[und].T, s=14, marker="x", c="0.4", zorder=2, label="undecided (gamma)")
    lead = np.flatnonzero(is_leader)
    ax.scatter(
        *pos[lead].T, s=90, marker="^", c=[colours(i) for i in lead], edgecolors="k", zorder=4, label="leader (alpha)"
    )
    ax.set_xlim(0, side_m)
    ax.set_ylim(0, side_m)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")


def draw(run_dir: str | Path, out_dir: str | Path | None = None) -> list[Path]:
    """Draw Figs. 6-8 of the paper from the run in ``run_dir``; returns the PNG paths."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    run_dir = Path(run_dir)
    out = Path(out_dir) if out_dir else run_dir
    out.mkdir(parents=True, exist_ok=True)
    config, positions, roles, groups = _read(run_dir)
    n = config.world.n_robots
    range_m = float(min(config.ranges_m()))
    side = config.world.side_m
    cmap = plt.get_cmap("tab20")
    # One colour per group, in order of the leaders' ids (ids themselves would collide).
    rank = {int(j): k for k, j in enumerate(np.unique(roles.loc[roles["role"] == "alpha", "robot"]))}
    colours = lambda i: cmap(rank.get(int(i), 0) % 20) if i >= 0 else "0.5"
    start_s = config.coverage.start_s if config.coverage.enabled else float(positions["t_s"].min())
    t0, pos0 = _at(positions, start_s)
    role0, leader0 = _roles_at(roles, n, t0)
    t1, pos1 = _at(positions, float(positions["t_s"].max()))
    role1, leader1 = _roles_at(roles, n, t1)
    written = []

    fig, ax = plt.subplots(figsize=(7, 7))
    _deployment(ax, pos0, role0, leader0, _gateways_at(groups, n, t0), range_m, side, colours)
    groups_n = int((role0 == "alpha").sum())
    ax.set_title(f"Fig. 6  Initial deployment at t = {t0:g} s: {n} robots, {groups_n} groups")
    ax.legend(loc="upper right", fontsize=8)
    written.append(out / "fig6_initial_deployment.png")
    fig.savefig(written[-1], dpi=120, bbox_inches="tight")
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(7, 7))
    path = positions[positions["t_s"] >= t0].sort_values(["robot", "t_s"])
    for i in np.flatnonzero(role0 == "alpha").tolist():
        p = path[path["robot"] == i]
        ax.plot(p["x_m"], p["y_m"], color=colours(i), lw=1.5)
        ax.scatter(p["x_m"].iloc[0], p["y_m"].iloc[0], s=25, color=colours(i), marker="o", edgecolors="k", zorder=3)
        ax.scatter(p["x_m"].iloc[-1], p["y_m"].iloc[-1], s=80, color=colours(i), marker="^", edgecolors="k", zorder=3)
    ax.set_xlim(0, side)
    ax.set_ylim(0, side)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(f"Fig. 7  Leaders' paths under the virtual forces, {t0:g} s to {t1:g} s (o start, ^ end)")
    written.append(out / "fig7_leader_paths.png")
    fig.savefig(written[-1], dpi=120, bbox_inches="tight")
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(7, 7))
    radius = config.coverage.radius_m or range_m
    _deployment(ax, pos1, role1, leader1, _gateways_at(groups, n, t1), range_m, side, colours, disks_m=radius)
    ax.set_title(f"Fig. 8  Final deployment at t = {t1:g} s with coverage disks (r = {radius:g} m)")
    ax.legend(loc="upper right", fontsize=8)
    written.append(out / "fig8_final_deployment.png")
    fig.savefig(written[-1], dpi=120, bbox_inches="tight")
    plt.close(fig)
    return written
