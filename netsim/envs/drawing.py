"""A frame of an environment's team, drawn as the figures draw a deployment (roles, groups'
colours, links, coverage disks, the area's border: netsim.tools.figures and style)."""

from __future__ import annotations

import numpy as np

from netsim.sim import Simulation


def frame(
    sim: Simulation,
    links: tuple[np.ndarray, np.ndarray],
    radius_m: float,
    range_m: float,
    covered: float,
    size_px: int = 480,
) -> np.ndarray:
    """The team at ``sim.now``, its links up then ``links`` (pairs ``(a, b)``), as an
    ``(size_px, size_px, 3)`` uint8 image."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from netsim.tools import style
    from netsim.tools.figures import Snapshot, draw_deployment

    n, area = sim.state.n, sim.state.bounds
    pos = sim.positions()
    groups = sim.groups
    if groups is not None:
        names = np.array(groups.role_names, dtype=object)
        role, leader = names[groups.role], groups.leader.copy()
        leaders = np.flatnonzero(leader == np.arange(n))
        colours = style.group_colours(leaders, pos[leaders], range_m)
    else:
        role, leader, colours = np.full(n, "none", dtype=object), np.full(n, -1), {}
    snap = Snapshot(sim.now, pos, role, leader, np.full(n, -1))
    dpi = 100
    fig = Figure(figsize=(size_px / dpi, size_px / dpi), dpi=dpi)
    ax = fig.add_axes((0.13, 0.1, 0.84, 0.84))
    draw_deployment(ax, snap, colours, links, disks_m=radius_m)
    x0, y0, x1, y1 = area.x_min, area.y_min, area.x_max, area.y_max
    ax.plot([x0, x1, x1, x0, x0], [y0, y0, y1, y1, y0], color=style.BORDER, lw=0.8, zorder=0)
    margin = 0.02 * max(area.width, area.height)
    ax.set_xlim(x0 - margin, x1 + margin)
    ax.set_ylim(y0 - margin, y1 + margin)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(f"t = {sim.now:g} s, covered {covered:.1%}", fontsize=9)
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    rgba = np.asarray(canvas.buffer_rgba())
    return rgba[:, :, :3].copy()
