"""The paper's figures, drawn from a run's output directory (``netsim figures``).

- ``fig6_initial_deployment.png``: the deployment at one instant (by default when
  coverage control starts, after the groups have formed; without coverage, the first
  sample with every robot in a group, or else with the fewest undecided, a note giving
  the time; any time with ``--at``):
  leaders, members in their group's colour, gateways (filled with their own group's
  colour, edged with the other group's), undecided robots, and the links;
- ``fig7_leader_paths.png``: every robot's path from that instant to the end, framed to
  the team's extent; the paths of the robots that lead a group at the end are drawn
  thick (any mobility model: for random waypoint these are the waypoint legs);
- ``fig8_final_deployment.png``: the final deployment with every robot's coverage disk,
  and the covered fraction of the area (exact) beside the most a connected team can
  cover, ``min(1, U(N) / A)``.
- ``fig_packets.png``, when the run wrote ``packets.parquet`` (flows, or a routing
  protocol's messages): how routing carried them (:mod:`netsim.tools.packet_figure`).

Colours and markers come from :mod:`netsim.tools.style`, as in the replay (``netsim view``):
each group has one colour for the whole run, and groups that could touch never share one.
Legends sit outside the axes. When a figure cannot show something (no groups yet, no
coverage disks, nobody moved) :func:`draw` says so in a note beside the file, and the
figure shows what there is.

Only the run's files are read (``config.toml``, ``positions.parquet``, ``roles.parquet``,
``groups.parquet`` when there), so figures can be redrawn from old results.
"""

from __future__ import annotations

import math
import tempfile
from pathlib import Path
from typing import NamedTuple

import numpy as np
import pandas as pd

from netsim import config as cfgmod
from netsim import metrics
from netsim.area import Bounds
from netsim.config import Config, world_bounds
from netsim.errors import NetsimInputError
from netsim.geometry import crosses_border, distances_m, link_segments_m
from netsim.tools import style
from netsim.tools.output import TMP_PREFIX, load_run_config, read_run_table, run_map
from netsim.topology import geometric_pairs

# The built-in coverage scenario: a dense random start in the middle of the area, as the
# paper's Fig. 6, then the team spreads out.
COVERAGE_SCENARIO = [
    "world.n_robots=60",
    "world.side_m=1000",
    'world.placement="centre"',
    "world.centre_side_m=300",
    'mobility.model="static"',
    "channel.range_m=100",
    "coverage.enabled=true",
    "duration_s=400",
]


class Run(NamedTuple):
    config: cfgmod.Config
    positions: pd.DataFrame
    roles: pd.DataFrame
    groups: pd.DataFrame | None
    links: pd.DataFrame | None = None  # links.parquet, where the run wrote it


class Snapshot(NamedTuple):
    t_s: float
    pos: np.ndarray  # (N, 2)
    role: np.ndarray  # "alpha" | "beta" | "gamma"; "none" in a run without roles
    leader: np.ndarray
    other_group: np.ndarray  # a gateway's other group (-1: not a gateway)


class Drawn(NamedTuple):
    path: Path
    note: str  # what the figure could not show ("" if nothing)


def read_run(run_dir: Path) -> Run:
    needed = ["config.toml", "positions.parquet", "roles.parquet"]
    missing = [f for f in needed if not (run_dir / f).is_file()]
    if missing:
        raise NetsimInputError(f"{run_dir}: not a run directory with positions (missing {', '.join(missing)})")
    config = load_run_config(run_dir)
    n = config.world.n_robots
    positions = read_run_table(run_dir, "positions", n)
    roles = read_run_table(run_dir, "roles", n)
    assert positions is not None and roles is not None  # checked above
    if positions.empty:
        positions = _positions_from_legs(run_dir, config)
    return Run(config, positions, roles, read_run_table(run_dir, "groups", n), read_run_table(run_dir, "links", n))


def _positions_from_legs(run_dir: Path, config: Config) -> pd.DataFrame:
    """A run that sampled no positions (``output.position_interval_s = 0``): its robots'
    exact motion (``legs.parquet``) sampled at the default interval, as a run would have."""
    from netsim.config import OutputParams
    from netsim.samples import sample_times
    from netsim.trajectory import sample_positions

    n = config.world.n_robots
    legs = read_run_table(run_dir, "legs", n)
    if legs is None or legs.empty:
        raise NetsimInputError(
            f"{run_dir}: positions were not sampled (output.position_interval_s = 0) and legs.parquet is missing"
        )
    times = sample_times(OutputParams().position_interval_s, config.duration_s)
    return sample_positions(legs, n, times, config.world.side_m, config.world.torus)


def _sample_time(frame: pd.DataFrame, t: float) -> float:
    """The sampling instant of ``frame`` at or just after ``t`` (the last one if none)."""
    times = np.sort(frame["t_s"].unique())
    return float(times[min(int(np.searchsorted(times, t - 1e-9)), len(times) - 1)])


def snapshot(run: Run, t: float) -> Snapshot:
    """Positions, roles and gateways at the positions sample at or just after ``t``."""
    n = run.config.world.n_robots
    when = _sample_time(run.positions, t)
    snap = run.positions[run.positions["t_s"] == when].sort_values("robot")
    r = run.roles[run.roles["t_s"] <= when + 1e-9].reset_index(drop=True)
    r["order"] = np.arange(len(r))
    last = r.sort_values(["robot", "t_s", "order"]).groupby("robot").tail(1)
    role = np.full(n, "gamma" if run.config.protocol.plugin.role_labels else "none", dtype=object)
    leader = np.full(n, -1)
    # (An empty roles table reads back with float columns.)
    robots = last["robot"].to_numpy(np.int64)
    role[robots] = last["role"].to_numpy()
    leader[robots] = last["leader"].to_numpy(np.int64)
    other = np.full(n, -1)
    if run.groups is not None and not run.groups.empty:
        g = style.other_group(run.groups[run.groups["t_s"] == _sample_time(run.groups, when)])
        other[g.index.to_numpy()] = g.to_numpy()
    return Snapshot(when, snap[["x_m", "y_m"]].to_numpy(), role, leader, other)


def links_at(run: Run, snap: Snapshot) -> tuple[np.ndarray, np.ndarray]:
    """The pairs ``(a, b)`` linked at ``snap``'s instant: the run's own links
    (``links.parquet``: the channel's, under shadowing or walls too); without that table,
    the pairs within both ends' ranges at its positions on the unit disk, and none where
    walls or shadowing decided the links (no range would say which)."""
    if run.links is None and run.config.radio_decides_links():
        return np.empty(0, np.int64), np.empty(0, np.int64)
    if run.links is not None:
        lk = run.links
        open_end = lk["censored_end"].to_numpy(bool) if "censored_end" in lk else np.zeros(len(lk), bool)
        up = metrics.links_up_at(lk["t_up_s"].to_numpy(float), lk["t_down_s"].to_numpy(float), open_end, snap.t_s)
        return lk["a"].to_numpy(np.int64)[up], lk["b"].to_numpy(np.int64)[up]
    config = run.config
    a, b, _ = geometric_pairs(snap.pos, np.asarray(config.ranges_m(), float), config.world.torus_side_m)
    return a, b


def undecided_at(run: Run, times: np.ndarray) -> np.ndarray:
    """How many robots are undecided (in no group) at each of ``times``, as :func:`snapshot`
    reads the roles: a robot's last record at or before the instant, undecided before its
    first."""
    labels = run.config.protocol.plugin.role_labels
    n = run.config.world.n_robots
    if labels is None or run.roles.empty:
        return np.full(len(times), n)
    r = run.roles.reset_index(drop=True)
    order = np.lexsort((np.arange(len(r)), r["t_s"].to_numpy(float)))
    t = r["t_s"].to_numpy(float)[order]
    robot = r["robot"].to_numpy(np.int64)[order]
    now = (r["role"].to_numpy()[order] == labels.undecided).astype(np.int64)
    # Each record changes its robot's state from its previous record's (undecided before
    # the first): the count after each record is n plus the running sum of the changes.
    before = np.ones(len(now), dtype=np.int64)
    by_robot = np.lexsort((np.arange(len(robot)), robot))
    same = robot[by_robot][1:] == robot[by_robot][:-1]
    before[by_robot[1:][same]] = now[by_robot[:-1][same]]
    count = n + np.cumsum(now - before)
    k = np.searchsorted(t, np.asarray(times, float) + 1e-9, side="right")
    return np.where(k > 0, count[np.maximum(k - 1, 0)], n)


def groups_formed_s(run: Run) -> tuple[float, int]:
    """The first positions sample at which every robot is in a group, or failing that the
    first with the fewest undecided, and how many are undecided then."""
    times = np.sort(run.positions["t_s"].unique())
    undecided = undecided_at(run, times)
    k = int(np.argmin(undecided))
    return float(times[k]), int(undecided[k])


def run_colours(run: Run) -> dict[int, str]:
    """The colour of every group of the run (one for the whole run, as in the replay)."""
    config = run.config
    labels = config.protocol.plugin.role_labels
    if labels is None:
        return {}
    side = config.world.torus_side_m
    slots = style.run_group_slots(run.roles, run.positions, labels.leader, float(min(config.ranges_m())), side)
    return {leader: style.GROUP_PALETTE[s] for leader, s in slots.items()}


def _colour(colours: dict[int, str], leader: int) -> str:
    return colours.get(int(leader), style.NO_GROUP)


def _clipped_to_torus(ax, artist, side_m: float | None):
    """``artist`` clipped at the border of a torus of side ``side_m`` (None: the plane, as it is)."""
    if side_m is not None:
        import matplotlib.patches as mpatches

        artist.set_clip_path(mpatches.Rectangle((0.0, 0.0), side_m, side_m, transform=ax.transData))
    return artist


def draw_deployment(
    ax,
    snap: Snapshot,
    colours: dict[int, str],
    pairs: tuple[np.ndarray, np.ndarray],
    disks_m: float = 0.0,
    side_m: float | None = None,
) -> None:
    """The links ``pairs`` (:func:`links_at`), (disks,) members, gateways, undecided robots
    and leaders, with a legend. ``side_m``: a torus of that side (None: the plane), whose
    links across the border are drawn to it from both ends."""
    import matplotlib.patches as mpatches
    from matplotlib.collections import LineCollection, PatchCollection

    pos, role = snap.pos, snap.role
    a, b = pairs
    links = LineCollection(link_segments_m(pos[a], pos[b], side_m), colors=style.LINK, lw=0.5, zorder=1)
    ax.add_collection(_clipped_to_torus(ax, links, side_m))
    group_of = np.where(role == "alpha", np.arange(len(pos)), snap.leader)
    if disks_m > 0:
        disks = [mpatches.Circle(p, disks_m) for p in pos]
        face = [_colour(colours, g) for g in group_of]
        ax.add_collection(PatchCollection(disks, facecolors=face, edgecolors="none", alpha=style.DISK_ALPHA, zorder=0))
    s = style.ROLE_STYLE
    gateway = (role == "beta") & (snap.other_group >= 0)
    members = np.flatnonzero((role == "beta") & ~gateway)
    if len(members):
        ax.scatter(
            *pos[members].T,
            s=s["beta"]["size"],
            marker=s["beta"]["marker"],
            c=[_colour(colours, snap.leader[m]) for m in members],
            zorder=2,
            label=s["beta"]["label"],
        )
    gw = np.flatnonzero(gateway)
    if len(gw):
        ax.scatter(
            *pos[gw].T,
            s=s["gateway"]["size"],
            marker=s["gateway"]["marker"],
            c=[_colour(colours, snap.leader[g]) for g in gw],
            edgecolors=[_colour(colours, snap.other_group[g]) for g in gw],
            linewidths=1.8,
            zorder=3,
            label=s["gateway"]["label"],
        )
    for plain in ("gamma", "none"):
        some = np.flatnonzero(role == plain)
        if len(some):
            ax.scatter(
                *pos[some].T,
                s=s[plain]["size"],
                marker=s[plain]["marker"],
                c=s[plain]["colour"],
                zorder=2,
                label=s[plain]["label"],
            )
    lead = np.flatnonzero(role == "alpha")
    if len(lead):
        ax.scatter(
            *pos[lead].T,
            s=s["alpha"]["size"],
            marker=s["alpha"]["marker"],
            c=[_colour(colours, i) for i in lead],
            edgecolors=s["alpha"]["edge"],
            zorder=4,
            label=s["alpha"]["label"],
        )


def _axes(ax, xlim, ylim, area: Bounds) -> None:
    ax.set_xlim(*xlim)
    ax.set_ylim(*ylim)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    # The border of the area, where it is in view.
    x0, y0, x1, y1 = area.as_list()
    ax.plot([x0, x1, x1, x0, x0], [y0, y0, y1, y1, y0], color=style.BORDER, lw=0.8, zorder=0)


def _legend_outside(ax, **kw) -> None:
    handles, labels = ax.get_legend_handles_labels()
    if handles:
        ax.legend(handles, labels, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0, fontsize=8, **kw)


def _extent(xy: np.ndarray, margin_m: float, area: Bounds):
    lo = np.maximum(xy.min(axis=0) - margin_m, area.lo - 0.02 * area.size)
    hi = np.minimum(xy.max(axis=0) + margin_m, area.hi + 0.02 * area.size)
    # A square frame: the same scale on both axes.
    half = max(hi - lo) / 2
    mid = (lo + hi) / 2
    return (mid[0] - half, mid[0] + half), (mid[1] - half, mid[1] + half)


def _path_pieces(xy: np.ndarray, colours: list[str], side_m: float | None) -> tuple[list[np.ndarray], list[str]]:
    """The polylines that draw the paths ``xy`` (robots x samples x 2), each in its robot's
    colour: on a torus each path is cut where it crosses the border, and the step across
    is drawn to the border from both sides (:func:`netsim.geometry.link_segments_m`)."""
    if side_m is None:
        return list(xy), list(colours)
    pieces: list[np.ndarray] = []
    out: list[str] = []
    for path, colour in zip(xy, colours):
        across = np.flatnonzero(crosses_border(path[:-1], path[1:], side_m))
        cuts = np.r_[0, across + 1, len(path)]
        for lo, hi in zip(cuts[:-1], cuts[1:]):
            pieces.append(path[lo:hi])
        pieces.extend(link_segments_m(path[across], path[across + 1], side_m))
        out += [colour] * (len(cuts) - 1 + 2 * len(across))
    return pieces, out


def draw_paths(ax, run: Run, t0: float, t1: float, end: Snapshot, colours: dict[int, str], range_m: float) -> str:
    """Every robot's path over ``[t0, t1]``, in its final group's colour; the final
    leaders' paths thick. Returns a note if nobody moved."""
    from matplotlib.collections import LineCollection

    p = run.positions[(run.positions["t_s"] >= t0 - 1e-9) & (run.positions["t_s"] <= t1 + 1e-9)]
    p = p.sort_values(["robot", "t_s"])
    n = run.config.world.n_robots
    side = run.config.world.torus_side_m
    xy = p[["x_m", "y_m"]].to_numpy().reshape(n, -1, 2)
    group_of = np.where(end.role == "alpha", np.arange(n), end.leader)
    colour = [_colour(colours, g) for g in group_of]
    lead = end.role == "alpha"
    s = style.ROLE_STYLE
    # Each layer only if it has someone (an empty one breaks the legend).
    for group, width, what in ((~lead, 0.8, "path of a robot"), (lead, 2.2, "path of a robot leading at the end")):
        if group.any():
            pieces, piece_colours = _path_pieces(xy[group], [c for c, g in zip(colour, group) if g], side)
            paths = LineCollection(
                pieces,
                colors=piece_colours,
                lw=width,
                alpha=0.7 if width < 1 else 1.0,
                zorder=1 if width < 1 else 2,
                label=what,
            )
            ax.add_collection(_clipped_to_torus(ax, paths, side))
    ax.scatter(*xy[:, 0].T, s=10, facecolors="none", edgecolors=style.NO_GROUP, lw=0.6, zorder=3, label=f"at {t0:g} s")
    if (~lead).any():
        ax.scatter(
            *xy[~lead, -1].T,
            s=s["beta"]["size"],
            c=[c for c, ld in zip(colour, lead) if not ld],
            zorder=4,
            label=f"at {t1:g} s",
        )
    if lead.any():
        ax.scatter(
            *xy[lead, -1].T,
            s=s["alpha"]["size"],
            marker=s["alpha"]["marker"],
            c=[c for c, ld in zip(colour, lead) if ld],
            edgecolors=s["alpha"]["edge"],
            zorder=5,
            label=f"leader at {t1:g} s",
        )
    steps_m = distances_m(xy[:, :-1].reshape(-1, 2), xy[:, 1:].reshape(-1, 2), side, n)
    travelled = steps_m.reshape(n, -1).sum(axis=1)
    area = world_bounds(run.config.world)
    xlim, ylim = _extent(xy.reshape(-1, 2), range_m, area)
    _axes(ax, xlim, ylim, area)
    if travelled.max(initial=0.0) == 0.0:
        return f"nobody moved between {t0:g} s and {t1:g} s"
    return ""


def draw_map(ax, occupancy) -> None:
    """The map under the robots: walls dark grey, unknown cells light grey, free cells blank."""
    if occupancy is None:
        return
    shade = np.zeros((*occupancy.shape, 4))
    shade[~occupancy.free & ~occupancy.occupied] = (0.85, 0.85, 0.85, 1.0)
    shade[occupancy.occupied] = (0.35, 0.35, 0.35, 1.0)
    x0, x1, y0, y1 = occupancy.extent_m
    # Row 0 of the grid is its bottom: origin="lower".
    ax.imshow(shade, extent=(x0, x1, y0, y1), origin="lower", interpolation="nearest", zorder=-1)


def pyplot():
    """matplotlib's pyplot drawing to files (the Agg backend), imported when a figure is
    drawn rather than when a command starts: importing it costs more than a small run."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def draw(run_dir: str | Path, out_dir: str | Path | None = None, at_s: float | None = None) -> list[Drawn]:
    """Draw Figs. 6-8 of the paper from the run in ``run_dir``; ``at_s``: the instant of
    Fig. 6 (default: when coverage control starts, or without coverage
    :func:`groups_formed_s`). Returns each PNG written with a note on what it could not
    show, or on the instant chosen for it."""
    plt = pyplot()
    run_dir = Path(run_dir)
    out = Path(out_dir) if out_dir else run_dir
    run = read_run(run_dir)
    config = run.config
    n, area = config.world.n_robots, world_bounds(config.world)
    whole = ((area.x_min, area.x_max), (area.y_min, area.y_max))
    torus_side_m = config.world.torus_side_m
    range_m = float(min(config.ranges_m()))
    occupancy = run_map(run_dir, config)
    # Keys of the run's models, where they have them.
    tree = cfgmod.to_dict(config)
    protocol, cover = tree["protocol"], tree.get("coverage", {})
    first, last = float(run.positions["t_s"].min()), float(run.positions["t_s"].max())
    chosen = ""
    if at_s is None and cover.get("enabled"):
        at_s = cover["start_s"]
    elif at_s is None:
        # No control to start from: the first instant the groups have formed.
        at_s, undecided = groups_formed_s(run)
        if undecided == 0:
            chosen = f"drawn at t = {at_s:g} s, the first sample with every robot in a group; see --at"
        elif undecided < n:
            chosen = (
                f"drawn at t = {at_s:g} s, the first sample with the fewest robots undecided ({undecided}); see --at"
            )
    elif not (first - 1e-9 <= at_s <= last + 1e-9 and math.isfinite(at_s)):
        raise NetsimInputError(
            f"--at = {at_s:g}: must be a time between {first:g} and {last:g} s (the positions sampled)"
        )
    out.mkdir(parents=True, exist_ok=True)
    # Drawn beside the results, moved into place together once all are: a figure that
    # cannot be made or written leaves none of them.
    with tempfile.TemporaryDirectory(prefix=TMP_PREFIX, dir=out) as staging:
        staged = Path(staging)
        start, end = snapshot(run, at_s), snapshot(run, last)
        drawn = []

        fig, ax = plt.subplots(figsize=(8.6, 7))
        colours = run_colours(run)
        draw_deployment(ax, start, colours, links_at(run, start), side_m=torus_side_m)
        _axes(ax, *whole, area)
        draw_map(ax, occupancy)
        groups_n = int((start.role == "alpha").sum())
        ax.set_title(f"Fig. 6  Deployment at t = {start.t_s:g} s: {n} robots, {groups_n} groups")
        _legend_outside(ax)
        note = chosen
        if config.protocol.plugin.role_labels is None:
            note = f"no roles: the run had protocol.model = {config.protocol.model!r}"
        elif groups_n == 0:
            tau = protocol["tau_s"]
            note = (
                f"no groups yet at t = {start.t_s:g} s: every robot is undecided "
                f"(groups form after tau = {tau:g} s; see --at)"
            )
        drawn.append(_save(fig, staged / "fig6_initial_deployment.png", note))

        fig, ax = plt.subplots(figsize=(8.6, 7))
        note = draw_paths(ax, run, start.t_s, end.t_s, end, colours, range_m)
        draw_map(ax, occupancy)
        ax.set_title(f"Fig. 7  Paths of all {n} robots, {start.t_s:g} s to {end.t_s:g} s")
        _legend_outside(ax)
        drawn.append(_save(fig, staged / "fig7_leader_paths.png", note))

        fig, ax = plt.subplots(figsize=(8.6, 7))
        radius = (cover["radius_m"] or range_m) if cover.get("enabled") else 0.0
        draw_deployment(ax, end, colours, links_at(run, end), disks_m=radius, side_m=torus_side_m)
        _axes(ax, *whole, area)
        draw_map(ax, occupancy)
        if radius > 0:
            # On a map, of the free region the team started in, as the run's coverage table.
            region = None
            if occupancy is not None:
                from netsim.world.free_space import team_region

                region = team_region(occupancy, area, snapshot(run, first).pos)
            covered, err = metrics.covered_fraction_exact(end.pos, radius, area, region=region)
            free_m2 = None if region is None else float(region.area)
            bound = metrics.bound_fraction(n, radius, area, config.ranges_m(), free_area_m2=free_m2)
            of = "the area" if region is None else "the free region"
            ax.set_title(
                f"Fig. 8  Deployment at t = {end.t_s:g} s with every robot's disk (r = {radius:g} m):\n"
                f"{100 * covered:.1f} % of {of} covered; a connected team covers at most {100 * bound:.0f} %"
            )
            note = ""
        else:
            ax.set_title(f"Fig. 8  Deployment at t = {end.t_s:g} s")
            note = "no coverage disks: the run had coverage.enabled = false"
        _legend_outside(ax)
        drawn.append(_save(fig, staged / "fig8_final_deployment.png", note))
        packets = read_run_table(run_dir, "packets", n)
        if packets is not None and len(packets):
            from netsim.tools.packet_figure import draw_packets

            fig, axes = plt.subplots(1, 4, figsize=(18, 4.4), constrained_layout=True)
            draw_packets(axes, packets)
            fig.suptitle(f"Packets of {n} robots under protocol.model = {config.protocol.model!r}")
            drawn.append(_save(fig, staged / "fig_packets.png", ""))
        return _placed(drawn, out)


def _placed(drawn: list[Drawn], out: Path) -> list[Drawn]:
    """``drawn`` moved into ``out``, each under its name; a name a directory holds is one
    line, before any is moved."""
    for d in drawn:
        if (out / d.path.name).is_dir():
            raise NetsimInputError(f"--out {out}: {d.path.name} is a directory; the figure cannot be written there")
    placed = []
    for d in drawn:
        try:
            d.path.replace(out / d.path.name)
        except OSError as exc:
            raise NetsimInputError(f"--out {out}: {d.path.name} cannot be written ({exc.strerror})") from None
        placed.append(Drawn(out / d.path.name, d.note))
    return placed


def _save(fig, path: Path, note: str) -> Drawn:
    import matplotlib.pyplot as plt

    fig.savefig(path, dpi=120, bbox_inches="tight")
    plt.close(fig)
    return Drawn(path, note)
