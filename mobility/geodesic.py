"""Coverage pushes that follow free space on a map (docs/model.md 5.3).

Straight-line pushes know nothing of doors: a robot pushed at a wall has its step cut
there and stays. On a map the plans therefore use three rules, from the map alone (the
team's map is known to every robot):

- **Pushes in sight** (:func:`in_sight`; the local plan, and the global plan with its
  expansion off): two robots push each other only when the straight segment between them
  is free. A push through a wall could only press a robot against that wall (its step is
  cut there); robots that see each other push along the free segment between them.
- **Expansion toward free space not yet covered** (the global plan, its only push on a
  map): every robot is pushed down the distance *through free space* (:class:`FreeGrid`:
  shortest paths on the map's free cells) to the nearest free cell that no robot covers.
  It leads robots out of a room through its door and along corridors to where coverage
  can still grow, where a push away from the team's centre would press them into the
  rooms' far corners (its dead ends).
- **Sliding** (:func:`slide`): a wished step that would run into a wall is replaced by
  the longer of its two components along the grid's axes, the walls of a grid map being
  its cells' sides, when that gets farther in the wished direction: a robot pushed
  obliquely at a wall slides along it instead of stopping.
"""

from __future__ import annotations

import itertools

import numpy as np
from netsim.mobility.forces import EXPANSION_CAP
from netsim.mobility.steps import cap_length

from netsim.compiled import load
from netsim.geometry import cell_centres_m, in_motion
from netsim.world.free_space import free_fraction, legs_free, nearest_free_cells, short_of_walls

# The side of the grid the distances are computed on, m (at least one map cell): fine
# enough to keep a 1.5 m door open, coarse enough to be cheap at every step.
GRID_CELL_M = 0.5
# How far (in grid cells) a position whose own cell is not free looks for a free one: a
# robot may stand within a map cell of a wall, whose grid cell then counts as blocked.
NEAR_CELLS = 2
# How far beyond a point's nearest way out of the covered cells (in grid cells) the sources
# that can decide the distances its descent reads may lie: a knight's move, rounded up.
REACH_MARGIN_CELLS = 3.0
# Relative: a path's length summed in another order of its moves differs by less.
ROUNDING = 1e-9
# The guess of how far a point's search must look (FreeGrid.to_outside): the latest distance
# found in its block of grid cells, a little more. A guess too short costs a second search,
# one too long a wider one; robots move little between steps, so near the latest is cheapest.
# Any values give the same results.
GUESS_BLOCK_CELLS = 8
GUESS_FACTOR = 1.02
GUESS_MARGIN_M = 0.5


def _kernels(values: int):
    """The geodesic kernels for a batch of ``values`` (:func:`netsim.compiled.load`)."""
    return load("netsim.mobility._geodesic_kernels", None, values=values)


class FreeGrid:
    """The map's free space on a grid of about :data:`GRID_CELL_M`: a grid cell is free
    when every map cell it holds is free and inside the area."""

    def __init__(self, occupancy, box):
        m = occupancy
        k = max(1, int(round(GRID_CELL_M / m.resolution_m)))
        h, w = m.shape
        free = np.zeros(((h + k - 1) // k * k, (w + k - 1) // k * k), bool)
        free[:h, :w] = m.free
        xs = cell_centres_m(m.origin_m[0], m.resolution_m, np.arange(free.shape[1]))
        ys = cell_centres_m(m.origin_m[1], m.resolution_m, np.arange(free.shape[0]))
        free &= ((ys >= box.y_min) & (ys <= box.y_max))[:, None] & ((xs >= box.x_min) & (xs <= box.x_max))[None, :]
        self.h, self.w = free.shape[0] // k, free.shape[1] // k
        self.free = np.ascontiguousarray(free.reshape(self.h, k, self.w, k).all(axis=(1, 3)).ravel())
        self.cell_m = k * m.resolution_m
        self.origin_m = (float(m.origin_m[0]), float(m.origin_m[1]))
        kern = _kernels(len(self.free))
        self.moves = (kern.MOVES_X, kern.MOVES_Y)
        self.allowed = kern.allowed_moves(self.free, self.w, self.h, *self.moves)
        # What the searches toward the free space not yet covered work in, kept between them
        # (each puts back what it changed), and the latest distance found in each block of
        # cells: a guess of how far to look, which changes no result. So one grid serves
        # one search at a time.
        self.field = np.full(self.w * self.h, np.inf)
        self.work = kern.search_work(self.w * self.h)
        self.blocks_w = -(-self.w // GUESS_BLOCK_CELLS)
        self.recent_m = np.full(self.blocks_w * -(-self.h // GUESS_BLOCK_CELLS), np.inf)

    def cells(self, points_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The grid cell of each point, or the nearest free one within :data:`NEAR_CELLS`
        when its own is not free (-1, -1: none; netsim.world.free_space.nearest_free_cells)."""
        free = self.free.reshape(self.h, self.w)
        return nearest_free_cells(free, self.origin_m, self.cell_m, points_m, NEAR_CELLS)

    def covered(self, points_m: np.ndarray, radius_m: float) -> np.ndarray:
        """Whether each grid cell's centre (row-major) lies within ``radius_m`` of some
        point: the covered fraction's rule (:func:`netsim._kernels.grid_nearest_m`)."""
        cells = max(self.w, self.h)
        side = cells * self.cell_m
        x0, y0 = self.origin_m
        p = np.ascontiguousarray(points_m, dtype=float).reshape(-1, 2)
        grid = load("netsim._kernels", None, values=cells * cells)  # one batch: every cell of the grid
        near = grid.grid_nearest_m(p, float(radius_m), x0, y0, side, side, cells, 0.0, True)
        return np.ascontiguousarray(np.isfinite(near[: self.h, : self.w])).ravel()

    def to_uncovered(self, points_m: np.ndarray, radius_m: float) -> tuple[np.ndarray, np.ndarray]:
        """At each point, the unit direction of the steepest descent of the distance
        through free space to the nearest free cell that no point covers (within
        ``radius_m``), and that distance. Inf, and no direction, where none can be reached,
        where the point has no free cell near, and where the point's own cell is not
        covered (a radius under the grid's half diagonal, or a point off its cell): the
        distance is then 0, and there is nothing to descend."""
        return self.to_outside(points_m, lambda: self.covered(points_m, radius_m))

    def covered_each(self, points_m: np.ndarray, radius_m: float) -> np.ndarray:
        """``(n, cells)``: the cells each point alone covers (:meth:`covered`'s rule, asked of
        the part of the grid the point's disk can reach, whole cells from the grid's
        origin)."""
        p = np.asarray(points_m, dtype=float).reshape(-1, 2)
        out = np.zeros((len(p), self.h, self.w), bool)
        grid = load("netsim._kernels", None, values=len(p))
        x0, y0 = self.origin_m
        # One cell more on each side: the kernel, not the rounding of this bound, decides.
        lo = np.floor((p - (x0, y0) - radius_m) / self.cell_m).astype(np.int64) - 1
        hi = np.ceil((p - (x0, y0) + radius_m) / self.cell_m).astype(np.int64) + 1
        lo = np.clip(lo, 0, (self.w, self.h))
        hi = np.clip(hi, 0, (self.w, self.h))
        for k in np.flatnonzero(np.isfinite(p).all(axis=1) & (hi > lo).all(axis=1)):
            (c0, r0), (c1, r1) = lo[k], hi[k]
            side = int(max(c1 - c0, r1 - r0))
            near = grid.grid_nearest_m(
                p[k : k + 1], float(radius_m), x0 + c0 * self.cell_m, y0 + r0 * self.cell_m,
                side * self.cell_m, side * self.cell_m, side, 0.0, True,
            )  # fmt: skip
            out[k, r0:r1, c0:c1] = np.isfinite(near[: r1 - r0, : c1 - c0])
        return out.reshape(len(p), -1)

    def to_outside(self, points_m: np.ndarray, covered, cells=None) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`to_uncovered` with the cells ``covered()`` gives (row-major bools; a
        callable, asked only when some point has a free cell near) as those covered.
        ``cells``: the points' own (:meth:`cells`), when the caller has them already."""
        x, y = self.cells(points_m) if cells is None else cells
        direction, value = np.zeros((len(x), 2)), np.full(len(x), np.inf)
        ok = np.flatnonzero(x >= 0)
        if len(ok) == 0:
            # No target: the search would settle every cell for nothing.
            return direction, value
        kern = _kernels(len(ok))
        covered = np.ascontiguousarray(covered())
        cx, cy = x[ok], y[ok]
        targets = (cy * self.w + cx).astype(np.int64)
        # A path from a covered cell first leaves the covered part at a source: the search
        # keeps to the covered part, and stops once the points' own cells are settled (the
        # cells their descent reads are then final). Those cells' values come from paths no
        # longer than each point's own distance and a knight's move (REACH_MARGIN_CELLS): the
        # search takes the sources and follows the paths that can be that short, within a
        # guess of that distance (the latest found near each point), and searches again
        # for a point found farther than its guess, within what was found (an upper bound).
        block = self._block_of(cx, cy)
        reach_m = self.recent_m[block] * GUESS_FACTOR + GUESS_MARGIN_M
        for attempt in itertools.count():
            bound_m = reach_m * (1.0 + ROUNDING) + REACH_MARGIN_CELLS * self.cell_m
            sources = kern.frontier(self.free, self.w, self.h, covered, *self.moves, cx, cy, bound_m / self.cell_m)
            d, v = np.zeros((len(ok), 2)), np.empty(len(ok))
            kern.descend(
                self.free, self.allowed, self.w, self.h, sources, self.cell_m, *self.moves,
                covered, targets, cx, cy, bound_m, self.field, self.work, d, v,
            )  # fmt: skip
            short = ~(v <= reach_m)
            if not short.any():
                break
            # A point found farther than its guess: what was found bounds its distance. One
            # found nowhere within it may lie farther, or out of reach: twice as far, then anywhere.
            wider = np.where(np.isfinite(v), v, 2.0 * reach_m if attempt == 0 else np.inf)
            reach_m = np.where(short, wider, reach_m)
        direction[ok], value[ok] = d, v
        # Where none was reached, the next search near there looks everywhere at once.
        self.recent_m[block] = v
        return direction, value

    def _block_of(self, cx: np.ndarray, cy: np.ndarray) -> np.ndarray:
        """The block of :data:`GUESS_BLOCK_CELLS` cells a side each cell lies in."""
        return (cy // GUESS_BLOCK_CELLS) * self.blocks_w + cx // GUESS_BLOCK_CELLS


def in_sight(occupancy, a_m: np.ndarray, b_m: np.ndarray) -> np.ndarray:
    """Whether each straight segment ``a_m[k] -> b_m[k]`` stays in free cells: the pairs of
    robots that push each other on a map (module notes)."""
    if len(a_m) == 0:
        return np.zeros(0, bool)
    return legs_free(occupancy, a_m, b_m)


def slide(occupancy, pos: np.ndarray, wish_mps: np.ndarray, period_s: float, reach_m: float) -> np.ndarray:
    """The wishes with every step that would run into a wall within ``reach_m`` replaced by
    its component along one axis when that one, cut at the walls too, gets farther along
    the wish (module notes). Other rows are returned as they are."""
    out = wish_mps.copy()
    rows = np.flatnonzero(in_motion(wish_mps))
    if len(rows) == 0:
        return out
    p = pos[rows]
    m = cap_length(wish_mps[rows] * period_s, reach_m)
    f = free_fraction(occupancy, p, p + m)
    blocked = f < 1.0
    if not blocked.any():
        return out
    rows, p, m, f = rows[blocked], p[blocked], m[blocked], f[blocked]
    best_gain = f * np.einsum("ij,ij->i", m, m)  # progress along the wish, times its length
    choice = np.full(len(rows), -1)
    for axis in (0, 1):
        alt = np.zeros_like(m)
        alt[:, axis] = m[:, axis]
        gain = free_fraction(occupancy, p, p + alt) * m[:, axis] ** 2
        better = gain > best_gain
        best_gain = np.where(better, gain, best_gain)
        choice[better] = axis
    for axis in (0, 1):
        sel = rows[choice == axis]
        out[sel, 1 - axis] = 0.0
    return out


def expansion_to_uncovered(
    grid: FreeGrid, pos: np.ndarray, radius_m: float, range_m: float, gain: float
) -> tuple[np.ndarray, np.ndarray]:
    """The expansion on a map (module notes): for every robot ``gain x EXPANSION_CAP x
    r_c`` down the distance through free space to the nearest free cell that no robot
    covers (within ``radius_m``, :meth:`FreeGrid.to_uncovered`); none where no such cell can
    be reached (the team's free region all covered). And that distance (m; inf: none)."""
    direction, d = grid.to_uncovered(pos, radius_m)
    return _capped_push(direction, d, range_m, gain), d


def _capped_push(direction: np.ndarray, d: np.ndarray, range_m: float, gain: float) -> np.ndarray:
    """The expansion's push on a map: ``gain x EXPANSION_CAP x r_c`` along ``direction``
    where a target was reached (``d`` finite), none elsewhere."""
    return (gain * EXPANSION_CAP * range_m * np.isfinite(d))[:, None] * direction


def expansion_to_unexplored(
    grid: FreeGrid, pos: np.ndarray, explored: np.ndarray, range_m: float, gain: float
) -> tuple[np.ndarray, np.ndarray]:
    """The local plan's expansion on a map (docs/model.md 5.1, rule 6): each robot pushed as
    :func:`expansion_to_uncovered` pushes it, toward the nearest free cell outside its own
    ``explored`` cells (``(n, cells)`` bools, packed by ``np.packbits`` along the cells: what
    it knows its team has covered), and that distance (m; inf: none). Robots that know the
    same cells share one search."""
    direction, d = np.zeros((len(pos), 2)), np.full(len(pos), np.inf)
    cells = grid.w * grid.h
    groups: dict[bytes, list[int]] = {}
    for i, row in enumerate(explored):
        groups.setdefault(row.tobytes(), []).append(i)
    x, y = grid.cells(pos)
    for rows in groups.values():
        members = np.array(rows)
        own = np.unpackbits(explored[rows[0]], count=cells).astype(bool)
        direction[members], d[members] = grid.to_outside(pos[members], lambda own=own: own, (x[members], y[members]))
    return _capped_push(direction, d, range_m, gain), d


def within_reach(occupancy, pos: np.ndarray, wish_mps: np.ndarray, period_s: float, reach_m: float) -> np.ndarray:
    """Each wished velocity as the robot could carry it out over a step of ``period_s``:
    capped at ``reach_m`` and ended short of the walls (the local plan's pull on a map,
    docs/model.md 5.1, rule 4: what a robot announces)."""
    move = cap_length(np.asarray(wish_mps, float) * period_s, reach_m)
    return short_of_walls(occupancy, pos, move, 1.0) / period_s
