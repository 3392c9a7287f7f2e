"""How roles and groups look in every drawing of a run: the figures here, and any other
view (a browser replay reads :func:`as_json`), so that a leader or a group looks the
same everywhere.

Groups get colours from a palette of 19 colours of high mutual contrast (Kelly's,
without white, black and the grey kept for robots in no group). Colours are given by a
greedy colouring of the graph of neighbouring groups (leaders closer than
:data:`NEIGHBOUR_RANGES` ranges), so groups that could touch never share one, however
many groups there are; far-apart groups may.
"""

from __future__ import annotations

import numpy as np

# Kelly (1965), colours of maximum contrast, in his order (grey, white, black left out).
GROUP_PALETTE = (
    "#BE0032",  # vivid red
    "#0067A5",  # strong blue
    "#F38400",  # vivid orange
    "#008856",  # vivid green
    "#875692",  # strong purple
    "#F3C300",  # vivid yellow
    "#A1CAF1",  # very light blue
    "#882D17",  # strong reddish brown
    "#8DB600",  # vivid yellowish green
    "#E68FAC",  # strong purplish pink
    "#604E97",  # strong violet
    "#F6A600",  # vivid orange yellow
    "#B3446C",  # strong purplish red
    "#DCD300",  # vivid greenish yellow
    "#654522",  # deep yellowish brown
    "#E25822",  # vivid reddish orange
    "#2B3D26",  # dark olive green
    "#C2B280",  # greyish yellow
    "#F99379",  # strong yellowish pink
)
NO_GROUP = "#848482"  # undecided robots, and members whose leader is unknown
LINK = "#cccccc"
# Groups whose leaders are closer than this many ranges may touch (member to member).
NEIGHBOUR_RANGES = 3.0

# Markers (matplotlib names; a browser maps them to shapes) and sizes (points^2).
ROLE_STYLE = {
    "alpha": {"marker": "^", "size": 90, "label": "leader (alpha)", "edge": "#000000"},
    "beta": {"marker": "o", "size": 14, "label": "member (beta)", "edge": "none"},
    "gateway": {"marker": "s", "size": 34, "label": "gateway (edge: its other group)", "edge": "group"},
    "gamma": {"marker": "x", "size": 16, "label": "undecided (gamma)", "edge": "none"},
}


def group_colours(leaders, leader_positions_m, range_m: float) -> dict[int, str]:
    """A colour for each leader's group: neighbouring groups (leaders closer than
    ``NEIGHBOUR_RANGES x range_m``) get different colours; leaders in ascending id order
    pick the first colour free among their neighbours (the same input gives the same
    colours).

    >>> c = group_colours([3, 7, 9], [[0.0, 0.0], [50.0, 0.0], [1000.0, 0.0]], 100.0)
    >>> c[3] != c[7], c[9] == c[3]
    (True, True)
    """
    from scipy.spatial import cKDTree

    ids = np.asarray(leaders, dtype=np.int64).reshape(-1)
    if len(ids) == 0:
        return {}
    xy = np.asarray(leader_positions_m, dtype=float).reshape(-1, 2)
    order = np.argsort(ids, kind="stable")
    ids, xy = ids[order], xy[order]
    near = cKDTree(xy).query_ball_point(xy, NEIGHBOUR_RANGES * range_m)
    slot = np.full(len(ids), -1)
    for k in range(len(ids)):
        used = {int(slot[j]) for j in near[k] if slot[j] >= 0}
        free = [c for c in range(len(GROUP_PALETTE)) if c not in used]
        # More neighbours than colours (not seen in practice): colours repeat.
        slot[k] = free[0] if free else k % len(GROUP_PALETTE)
    return {int(i): GROUP_PALETTE[int(s)] for i, s in zip(ids, slot)}


def as_json() -> dict:
    """The palette and role styles as plain values, for a viewer outside Python."""
    return {
        "group_palette": list(GROUP_PALETTE),
        "no_group": NO_GROUP,
        "link": LINK,
        "neighbour_ranges": NEIGHBOUR_RANGES,
        "roles": ROLE_STYLE,
    }
