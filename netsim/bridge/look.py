"""How the team looks in the live views: the Foxglove scene (``--live``) and the bridge's
RViz markers (``/network/links``), so that a leader is the same colour in both. Colours
are RGBA in 0-1, as both message types take them."""

from __future__ import annotations

from typing import Any

import numpy as np

from netsim.area import Bounds
from netsim.geometry import link_segments_m

GREY = (0.6, 0.6, 0.6, 1.0)
# Keyed by the clustering protocol's role labels: leader (alpha), member (beta), undecided
# (gamma); a protocol with other labels gets grey robots.
ROLE_RGBA = {"alpha": (0.85, 0.2, 0.2, 1.0), "beta": (0.2, 0.45, 0.85, 1.0), "gamma": GREY}
LINK_RGBA = (0.1, 0.6, 0.1, 0.8)


def robot_rgba(groups: Any, n: int) -> list[tuple[float, float, float, float]]:
    """Each robot's colour now: by its role (``ROLE_RGBA``), grey without roles."""
    if groups is None:
        return [GREY] * n
    names = groups.role_names
    return [ROLE_RGBA.get(names[int(c)], GREY) for c in groups.role]


def robot_diameter_m(bounds: Bounds) -> float:
    """A robot's sphere: 1/100 of the area's longer side, so that the team shows when the
    whole area is in view, whatever its size."""
    return max(bounds.width, bounds.height) / 100.0


def link_line_list(pos_m: np.ndarray, pairs: list[tuple[int, int]], side_m: float | None) -> list[tuple[float, float]]:
    """The points of the links ``pairs`` of robots at ``pos_m`` as a line list (two points
    a segment): on a torus of side ``side_m`` (None: the plane) a link across the border is
    drawn from both ends toward it (:func:`netsim.geometry.link_segments_m`), not across
    the area. The viewers do not clip: each half runs past the border by the rest of the
    link."""
    if not pairs:
        return []
    a, b = np.array(pairs, np.int64).T
    segments = link_segments_m(pos_m[a], pos_m[b], side_m)
    return [(float(x), float(y)) for x, y in segments.reshape(-1, 2).tolist()]
