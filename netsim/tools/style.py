"""How a run looks in every drawing of it: the figures (``netsim figures``) and the browser
replay (``netsim view``, which reads :func:`as_json`), so that a leader, a group, a link
or a message looks the same everywhere. Nothing else in the package names a colour.

Groups get colours from a palette of 19 colours of high mutual contrast (Kelly's,
without white, black and the grey kept for robots in no group). Colours are given by a
greedy colouring of the graph of neighbouring groups (leaders closer than
:data:`NEIGHBOUR_RANGES` ranges), so groups that could touch never share one, however
many groups there are; far-apart groups may. A drawing of a whole run colours each
group once for the run (:func:`run_group_slots`): two leaders are neighbours if they
were, both leading, that close at any sampled instant, so that a group keeps its colour
all along and the figures and the replay of a run agree.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from netsim.geometry import in_box

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
OUTLINE = "#000000"  # leaders' edges, the hovered robot's ring and links
BORDER = "#4d4d4d"  # the border of the area
WALL = "#333333"  # occupied cells of a map
MESSAGE = "#e6007e"  # relayed messages, their sources and destinations
DISK_ALPHA = 0.12  # opacity of coverage disks
# Groups whose leaders are closer than this many ranges may touch (member to member).
NEIGHBOUR_RANGES = 3.0

# Markers (matplotlib names; a browser maps them to shapes), sizes (points^2), fill
# ("group": the robot's group's colour) and edge ("group": a gateway's other group's).
ROLE_STYLE = {
    "alpha": {"marker": "^", "size": 90, "label": "leader (alpha)", "colour": "group", "edge": OUTLINE},
    "beta": {"marker": "o", "size": 14, "label": "member (beta)", "colour": "group", "edge": "none"},
    "gateway": {
        "marker": "s",
        "size": 34,
        "label": "gateway (edge: its other group)",
        "colour": "group",
        "edge": "group",
    },
    "gamma": {"marker": "x", "size": 16, "label": "undecided (gamma)", "colour": NO_GROUP, "edge": "none"},
    # Robots of a run whose protocol gives no roles.
    "none": {"marker": "o", "size": 14, "label": "robot (no roles)", "colour": NO_GROUP, "edge": "none"},
}

# Time series (the replay's strip chart), by name: the same quantity, the same colour.
SERIES = {
    "leaders": "#0067A5",
    "components": "#2B3D26",
    "covered_leaders": "#008856",
    "covered_all": "#8DB600",
    "ack_delivery": "#BE0032",
    "delivered": "#F38400",
}
OTHER_SERIES = "#875692"
# The strip chart's own lines and text.
CHART = {"background": "#ffffff", "grid": "#eeeeee", "text": "#888888", "cursor": "#000000"}


def _greedy(ids: np.ndarray, pairs: np.ndarray) -> np.ndarray:
    """Palette slots of ``ids`` (ascending): each takes the first slot none of its
    already-coloured neighbours (``pairs``: index pairs into ``ids``) has."""
    near: list[set[int]] = [set() for _ in range(len(ids))]
    for a, b in pairs.tolist():
        near[a].add(b)
        near[b].add(a)
    slot = np.full(len(ids), -1)
    for k in range(len(ids)):
        used = {int(slot[j]) for j in near[k] if slot[j] >= 0}
        free = [c for c in range(len(GROUP_PALETTE)) if c not in used]
        # More neighbours than colours: colours repeat.
        slot[k] = free[0] if free else k % len(GROUP_PALETTE)
    return slot


def _near_pairs(xy: np.ndarray, range_m: float, side_m: float | None) -> np.ndarray:
    """Index pairs of ``xy`` within ``NEIGHBOUR_RANGES x range_m`` (on a torus of side
    ``side_m``), by the engine's rule of in range."""
    from netsim.topology import geometric_pairs

    if side_m is not None:
        xy = in_box(xy, side_m)
    i, j, _ = geometric_pairs(np.ascontiguousarray(xy, float), NEIGHBOUR_RANGES * range_m, side_m)
    return np.column_stack([i, j])


def group_colours(leaders, leader_positions_m, range_m: float) -> dict[int, str]:
    """A colour for each leader's group at one instant: neighbouring groups (leaders
    closer than ``NEIGHBOUR_RANGES x range_m``) get different colours; leaders in
    ascending id order pick the first colour free among their neighbours (the same input
    gives the same colours).

    >>> c = group_colours([3, 7, 9], [[0.0, 0.0], [50.0, 0.0], [1000.0, 0.0]], 100.0)
    >>> c[3] != c[7], c[9] == c[3]
    (True, True)
    """
    ids = np.asarray(leaders, dtype=np.int64).reshape(-1)
    if len(ids) == 0:
        return {}
    xy = np.asarray(leader_positions_m, dtype=float).reshape(-1, 2)
    order = np.argsort(ids, kind="stable")
    ids, xy = ids[order], xy[order]
    slot = _greedy(ids, _near_pairs(xy, range_m, None))
    return {int(i): GROUP_PALETTE[int(s)] for i, s in zip(ids, slot)}


def run_group_slots(
    roles: pd.DataFrame, positions: pd.DataFrame, leader_label: str, range_m: float, side_m: float | None = None
) -> dict[int, int]:
    """The palette slot of every group of a run, keyed by its leader's id (every robot
    that was ever a leader in ``roles``): a greedy colouring, in ascending id order, of
    the leaders that were both leading and closer than ``NEIGHBOUR_RANGES x range_m`` at
    some instant of ``positions`` (a robot leads at ``t`` if its last role change at or
    before ``t`` made it a leader). ``side_m``: distances wrap on a torus of that side.
    """
    r = roles.sort_values("t_s", kind="stable")
    ids = np.unique(r.loc[r["role"] == leader_label, "robot"].to_numpy(np.int64))
    if len(ids) == 0:
        return {}
    t_role = r["t_s"].to_numpy(float)
    robot = r["robot"].to_numpy(np.int64)
    is_leader = (r["role"] == leader_label).to_numpy()
    pos = positions.sort_values(["t_s", "robot"], kind="stable")
    times = np.unique(pos["t_s"].to_numpy(float))
    n = len(pos) // len(times) if len(times) else int(robot.max()) + 1
    xy = pos[["x_m", "y_m"]].to_numpy().reshape(len(times), n, 2)
    leading = np.zeros(n, dtype=bool)
    index = np.full(n, -1)
    index[ids] = np.arange(len(ids))
    pairs = []
    p = 0
    for k, t in enumerate(times.tolist()):
        while p < len(t_role) and t_role[p] <= t:
            leading[robot[p]] = is_leader[p]
            p += 1
        now = np.flatnonzero(leading)
        if len(now) > 1:
            near = _near_pairs(xy[k, now], range_m, side_m)
            pairs.append(index[now[near]])
    pairs_all = np.unique(np.sort(np.concatenate(pairs), axis=1), axis=0) if pairs else np.empty((0, 2), int)
    slot = _greedy(ids, pairs_all)
    return {int(i): int(s) for i, s in zip(ids, slot)}


def other_group(groups: pd.DataFrame) -> pd.Series:
    """A gateway's other group, by robot, in one ``groups`` sample: the lowest id among
    the groups it belongs to besides its own leader's (its edge colour in a drawing)."""
    return groups.loc[~groups["primary"]].groupby("robot")["group"].min()


def as_json() -> dict:
    """Every colour, marker and size above as plain values, for a viewer outside Python."""
    return {
        "group_palette": list(GROUP_PALETTE),
        "no_group": NO_GROUP,
        "link": LINK,
        "outline": OUTLINE,
        "border": BORDER,
        "wall": WALL,
        "message": MESSAGE,
        "disk_alpha": DISK_ALPHA,
        "neighbour_ranges": NEIGHBOUR_RANGES,
        "roles": ROLE_STYLE,
        "series": SERIES,
        "other_series": OTHER_SERIES,
        "chart": CHART,
    }
