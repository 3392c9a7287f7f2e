"""A frame of an environment's team, drawn as the figures draw a deployment (roles, groups'
colours, links, coverage disks, the area's border: netsim.tools.figures and style)."""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from netsim.sim import Simulation

if TYPE_CHECKING:
    from matplotlib.figure import Figure
    from matplotlib.image import AxesImage


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


def matplotlib_backend() -> str:
    """The name of the backend matplotlib draws with (chosen now if not yet: pyplot starts
    it, and falls back to one that draws no window where the one asked for cannot start)."""
    import matplotlib
    import matplotlib.pyplot  # noqa: F401

    return str(matplotlib.get_backend())


def shows_windows() -> bool:
    """Whether matplotlib's backend draws to a window (an interactive one: not Agg, PDF, ...,
    nor Jupyter's inline backend, which would print a picture a frame)."""
    try:
        from matplotlib.backends import BackendFilter, backend_registry

        drawn_only = backend_registry.list_builtin(BackendFilter.NON_INTERACTIVE)
    except ImportError:  # matplotlib before 3.9
        from matplotlib.rcsetup import non_interactive_bk as drawn_only  # type: ignore[attr-defined,no-redef]
    backend = matplotlib_backend().lower()
    return backend not in drawn_only and "inline" not in backend


def no_window_said() -> str:
    """Why render_mode = "human" shows nothing here, and what to do: the backend draws no
    window, or the one MPLBACKEND asks for could not start (no display) and matplotlib fell
    back to one that draws none."""
    backend = matplotlib_backend()
    asked = os.environ.get("MPLBACKEND", "")
    if asked and asked.lower() != backend.lower():
        display = os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
        why = f", with DISPLAY = {display!r}" if display else ": this machine has no display (DISPLAY is not set)"
        return (
            f"render_mode='human' shows a window, and matplotlib could not start the backend MPLBACKEND asks for"
            f" ({asked}){why}; it fell back to {backend}, which draws none: nothing is shown (use"
            " render_mode='rgb_array', or run where a display is)"
        )
    return (
        f"render_mode='human' shows a window, and matplotlib's backend ({backend}) draws none: nothing is shown"
        " (set MPLBACKEND to a window's backend, e.g. TkAgg or QtAgg, or use render_mode='rgb_array')"
    )


class Window:
    """The window of ``render_mode = "human"``: one per environment, opened at the first
    frame, and again if the user closed it; each frame replaces the last, no sooner than
    ``1 / fps`` after it was shown (``clock``: seconds, monotonic)."""

    TITLE = "netsim coverage_v0"

    def __init__(self, clock: Callable[[], float] = time.monotonic) -> None:
        self._figure: Figure | None = None
        self._image: AxesImage | None = None
        self._clock = clock
        self._shown_s: float | None = None

    def show(self, image: np.ndarray, fps: float) -> None:
        import matplotlib.pyplot as plt

        figure, shown = self._figure, self._image
        is_open = figure is not None and shown is not None and plt.fignum_exists(figure.number)
        # A render_fps of 0 or less (or NaN): frames as they come.
        if figure is not None and is_open and self._shown_s is not None and fps > 0:
            left = self._shown_s + 1.0 / fps - self._clock()
            if left > 0:
                # The last frame stays its time; the window answers meanwhile.
                figure.canvas.start_event_loop(left)
        if figure is None or shown is None or not is_open:
            height, width = image.shape[:2]
            # A figure of its own (a label would give another environment's window back).
            figure = self._figure = plt.figure(figsize=(width / 100, height / 100), dpi=100)
            if figure.canvas.manager is not None:
                figure.canvas.manager.set_window_title(self.TITLE)
            axes = figure.add_axes((0.0, 0.0, 1.0, 1.0))
            axes.set_axis_off()
            self._image = axes.imshow(image)
            plt.show(block=False)
        else:
            shown.set_data(image)
        # This figure's canvas, not pyplot's current figure (plt.pause's), which the user may
        # have changed; its event loop runs a moment so that the window draws and answers.
        figure.canvas.draw_idle()
        figure.canvas.start_event_loop(1e-3)
        self._shown_s = self._clock()

    def close(self) -> None:
        if self._figure is not None:
            import matplotlib.pyplot as plt

            plt.close(self._figure)
            self._figure = self._image = None
