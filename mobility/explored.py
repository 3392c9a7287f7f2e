"""What each robot of the local plan knows its team has covered on a map, passed on with
the Acks (docs/model.md 5.1, rule 6 on a map).

A robot's *explored* cells are the free grid's cells (:class:`netsim.mobility.geodesic.FreeGrid`)
that it has covered itself at a control step, or that a robot it heard had among its own
when it sent the Ack: each Ack carries its sender's explored cells as of its latest step
before it (:func:`netsim.mobility.local.carried`, as for the wish and the centre). The cells
only accumulate, so what a robot knows spreads over the team an Ack period a hop, and
whatever an Ack is late with, a later one brings. The plan pushes each robot toward the
nearest free cell outside its own explored cells
(:func:`netsim.mobility.geodesic.expansion_to_unexplored`): where
its team has not been, as far as it knows, where the global plan's push goes where no
robot stands now.

The cells are kept packed eight to a byte (``np.packbits``) so that passing them on costs
a byte per eight cells and robot heard.
"""

from __future__ import annotations

import math

import numpy as np
from netsim.mobility.geodesic import FreeGrid
from netsim.mobility.local import carried


class Explored:
    """Each robot's explored cells, and those it announced at its last two steps."""

    def __init__(self, grid: FreeGrid, n: int):
        self.grid = grid
        size = (n, math.ceil(grid.w * grid.h / 8))
        self.announced = (np.zeros(size, np.uint8), math.inf)
        self.earlier = (np.zeros(size, np.uint8), math.inf)

    def step(self, pos: np.ndarray, radius_m: float, known: np.ndarray, sent_s: np.ndarray, now_s: float) -> np.ndarray:
        """Every robot's explored cells at the step decided at ``now_s`` (packed, ``(n,
        bytes)``): its own of the last step, those it covers from ``pos`` (within
        ``radius_m``), and those each robot it remembers (``known``) announced at its latest
        step before the Ack of it heard last (sent no earlier than ``sent_s``). The Acks
        sent from now on carry them."""
        own = np.packbits(self.grid.covered_each(pos, radius_m), axis=1)
        cells = own | self.announced[0]
        latest, older = carried(known, sent_s, self.announced[1], self.earlier[1])
        for said, heard in ((self.announced[0], latest), (self.earlier[0], older)):
            for i in np.flatnonzero(heard.any(axis=1)):
                cells[i] |= np.bitwise_or.reduce(said[heard[i]], axis=0)
        self.earlier, self.announced = self.announced, (cells, float(now_s))
        return cells
