"""Colours and role symbols shared by the figures and the browser replay.

One group, one colour: groups are coloured by the rank of their leader's id among every
robot that was ever a leader in the run (ids themselves would make neighbouring groups
collide), cycling through :data:`GROUP_COLOURS` (matplotlib's ``tab20``). Robots with no
leader are :data:`NO_GROUP`. Colours are hex strings, usable by matplotlib and by a
browser alike.
"""

from __future__ import annotations

import numpy as np

# matplotlib's "tab20", spelled out so that the replay needs no matplotlib.
GROUP_COLOURS = (
    "#1f77b4",
    "#aec7e8",
    "#ff7f0e",
    "#ffbb78",
    "#2ca02c",
    "#98df8a",
    "#d62728",
    "#ff9896",
    "#9467bd",
    "#c5b0d5",
    "#8c564b",
    "#c49c94",
    "#e377c2",
    "#f7b6d2",
    "#7f7f7f",
    "#c7c7c7",
    "#bcbd22",
    "#dbdb8d",
    "#17becf",
    "#9edae5",
)
NO_GROUP = "#808080"  # matplotlib "0.5"
LINK = "#cccccc"  # "0.8"
UNDECIDED = "#666666"  # "0.4"
OUTLINE = "#000000"
WALL = "#333333"
DISK_ALPHA = 0.15

# Role symbols as matplotlib markers; the replay draws the same shapes.
MARKERS = {
    "alpha": "^",  # leader: a triangle in its group's colour, outlined
    "beta": "o",  # member: a dot in its group's colour
    "gateway": "s",  # member linked to another group's leader: an open square, outlined
    "gamma": "x",  # undecided: a grey cross
}
LABELS = {
    "alpha": "leader (alpha)",
    "beta": "member (beta)",
    "gateway": "gateway",
    "gamma": "undecided (gamma)",
}


def group_ranks(leader_ids) -> dict[int, int]:
    """Colour index of each group, keyed by its leader's id: the rank of that id among
    ``leader_ids`` (every robot that was ever a leader), modulo the palette's length.

    >>> group_ranks([7, 3, 3, 12])
    {3: 0, 7: 1, 12: 2}
    """
    ids = np.unique(np.asarray(leader_ids, dtype=np.int64))
    return {int(j): k % len(GROUP_COLOURS) for k, j in enumerate(ids.tolist())}


def as_dict() -> dict:
    """Everything above, for the replay's page."""
    return {
        "groups": list(GROUP_COLOURS),
        "no_group": NO_GROUP,
        "link": LINK,
        "undecided": UNDECIDED,
        "outline": OUTLINE,
        "wall": WALL,
        "disk_alpha": DISK_ALPHA,
        "markers": dict(MARKERS),
        "labels": dict(LABELS),
    }
