"""How a link on a map is solved: the arithmetic that the post-hoc solver
(:func:`netsim.links.radio_links.walled_lifetimes`) and the runtime one
(:class:`netsim.links.walled_links.WalledLinks`) share, so that both find the same floats.

On a map (walls, no shadowing) a link can only be up while the two robots are within the
radio's largest range (the *envelope*, solved exactly). Within it the link's state is
solved along *stretches*: a stretch starts where the pair enters the envelope and at every
course change of either robot, and lasts while both keep their legs. On a stretch the walls
crossed by the segment between the two robots change only at instants solved in closed form
(:func:`netsim.world.sweep.sweep_walls`), and between them the link is up while the
distance is within the range those walls leave (the unit disk: no wall at all; log-distance:
``PL(d) + wall_loss_db * walls`` within the budget, a distance threshold per count, whose
crossings are the roots of a quadratic). So every change of state is found, at its instant.

A stretch is solved a *chunk* at a time, chunks depending only on the stretch's legs:

- chunk ``k`` runs from ``u + k h`` (``u`` for the first) to ``u + (k + 1) h``, with
  ``h = CHUNK_M / max(|v_a|, |v_b|)`` (no robot moves more than ``CHUNK_M`` in a chunk;
  ``h`` infinite when both are at rest: the state cannot change);
- the last chunk ends at ``x``, where the pair leaves the envelope on these legs (solved
  from the later leg start, as every crossing is), where the link goes down exactly;
- each chunk is solved on its own (its start positions from the legs, times from its start),
  so the result does not depend on which chunks are solved together; a state at a chunk's
  start that differs from the previous chunk's last is a change at that instant.

A stretch that ends (a course change at ``e``) keeps the changes found at or before ``e``;
those after it are dropped, and the next stretch starts from the new legs. The runtime
solver solves a chunk before it starts, when the course changes to come are not known: the
chunk that straddles ``e`` is solved on the old legs, extrapolated, by both.

Why the chunk comes from the pair's own speeds, not their relative speed: walls lie along
the line between the two robots, which sweeps across the map as they move even when they
keep their distance; and not from a speed bound of the whole run: controllers set speeds as
the run goes, and a pair at rest would be solved for nothing.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from netsim.compiled import load
from netsim.geometry import distances_m, speeds_mps
from netsim.radio.propagation import Pairs, effective_range_m
from netsim.trajectory import points_on_legs
from netsim.world.los import VERTEX_TOLERANCE_CELLS
from netsim.world.sweep import MapGrid, PairMotion, map_grid

if TYPE_CHECKING:
    from netsim.radio.reception import Reception

CHUNK_M = 4.0


def envelope_radii(reception: Reception, ranges_m: np.ndarray) -> tuple[np.ndarray, bool]:
    """Each robot's envelope range (the radio's largest range; with unequal unit disk
    ranges, each robot's own: a pair's envelope is ``min(r_a, r_b)``), and whether the
    ranges are equal."""
    ranges = np.asarray(ranges_m, float)
    n = len(ranges)
    equal = bool(np.all(ranges == ranges[0])) if n else True
    if not equal:
        return ranges, False
    outer = float(reception.propagation.range_m) if not np.isfinite(reception.reach_m) else reception.reach_m
    return np.full(n, outer), True


def linked(
    reception: Reception, equal_ranges: bool, a: np.ndarray, b: np.ndarray, pa: np.ndarray, pb: np.ndarray
) -> np.ndarray:
    """The link's state of pairs ``a, b`` at positions ``pa, pb``: range or received power,
    and the walls crossed (with unequal ranges both must hear each other); on a torus over
    the nearest image."""
    chain = reception.compiled
    st = reception.state
    d = distances_m(pa, pb, st.torus_side_m, st.n)
    n = st.n
    up = chain.receivable(Pairs(a, b, pa, pb, d, None, n))
    if not equal_ranges:
        up &= chain.receivable(Pairs(b, a, pb, pa, d, None, n))
    return up


class MapRadio(NamedTuple):
    """What a chunk's solution needs of the radio: the map's walls (``grid``) and, per count
    of walls crossed, the distance within which the link is up (``inf``: anywhere
    in the envelope; counts beyond the table: never); ``kernels``: the sweep's loops for
    the run (:mod:`netsim.world._sweep_kernels`, as :func:`netsim.compiled.load` gives them)."""

    grid: MapGrid
    radii_m: np.ndarray
    kernels: Any


def map_radio(reception: Reception) -> MapRadio:
    """The :class:`MapRadio` of a channel on a map without shadowing: the unit disk with line
    of sight (no wall at all), or log-distance with ``wall_loss_db`` per wall."""
    chain = reception.compiled
    occupancy = reception.map
    if occupancy is None:
        raise ValueError("the channel has no map")
    if chain.walls is not None:
        params = chain.log.params  # type: ignore[union-attr]  # walls come after a log-distance term
        # A pair's segment crosses at most as many walls as the map has rows and columns of
        # cells: a count past that never happens, however many a small loss per wall affords.
        affordable = params.budget_db / chain.walls.wall_loss_db
        most = int(min(np.floor(affordable) + 1, sum(occupancy.shape) + 1))
        walls = np.arange(1, most + 1)
        r = effective_range_m(params, 0.0, walls, reception.state.n)
        # Within the envelope (the range without walls) no wall: up.
        radii = np.r_[np.inf, np.where(r > 0, r, -1.0)]
        radii = radii[: int(np.flatnonzero(radii >= 0).max()) + 1]
    else:
        radii = np.array([np.inf])
    kernels = load("netsim.world._sweep_kernels", reception.state.n)
    return MapRadio(map_grid(occupancy), radii, kernels)


class Stretches:
    """Stretches as columns: pair ``a, b``, start ``u``, the two legs (``pa, va, ta``: a
    leg's start position, velocity and start time; ``pb, vb, tb``), chunk length ``h``, the
    envelope's exit ``x`` on these legs, ``nc``: how many chunks start before it (at least
    one), and ``out``: 1 where the pair is out of the envelope at the start."""

    def __init__(
        self,
        a: np.ndarray,
        b: np.ndarray,
        u: np.ndarray,
        pa: np.ndarray,
        va: np.ndarray,
        ta: np.ndarray,
        pb: np.ndarray,
        vb: np.ndarray,
        tb: np.ndarray,
        radius: np.ndarray,
        n_robots: int,
    ):
        self.a, self.b = np.asarray(a, np.int64), np.asarray(b, np.int64)
        self.u = np.asarray(u, float)
        self.pa, self.va, self.ta = pa, va, np.asarray(ta, float)
        self.pb, self.vb, self.tb = pb, vb, np.asarray(tb, float)
        speed = np.maximum(speeds_mps(va), speeds_mps(vb))
        self.h = np.where(speed > 0, CHUNK_M / np.where(speed > 0, speed, 1.0), np.inf)
        m = len(self.u)
        legs = np.arange(m)
        _, out = load("netsim.links._kernels", n_robots).crossing_times(
            np.r_[self.ta, self.tb], np.r_[pa, pb], np.r_[va, vb], legs, legs + m, np.asarray(radius, float)
        )
        self.x = np.where(np.isnan(out), np.inf, out)
        # Out of the envelope at the start (a jump out of range, the envelope's own event due
        # at the same instant): down until the envelope says otherwise. At the envelope's
        # edge the distance is the radius itself, which rounding may put on either side.
        ua = points_on_legs(pa, va, self.ta, legs, self.u, n_robots)
        ub = points_on_legs(pb, vb, self.tb, legs, self.u, n_robots)
        edge = np.ascontiguousarray(np.broadcast_to(np.asarray(radius, float) * (1.0 + 1e-9), (m,)))
        far = ~load("netsim._kernels", n_robots).in_range(np.r_[ua, ub], legs, legs + m, edge, 0.0)
        self.out = far.astype(float)
        self.nc = np.maximum(count_below(self.u, self.h, self.x), 1.0)

    COLUMNS = ("a", "b", "u", "pa", "va", "ta", "pb", "vb", "tb", "h", "x", "nc", "out")

    def __len__(self) -> int:
        return len(self.u)

    @classmethod
    def blank(cls, size: int) -> Stretches:
        """Room for ``size`` stretches, filled later with :meth:`put` (the runtime solver's
        store, one row per pair in the envelope)."""
        out = cls.__new__(cls)
        for name in cls.COLUMNS:
            shape = (size, 2) if name[0] in "pv" else (size,)
            setattr(out, name, np.zeros(shape, np.int64 if name in ("a", "b") else float))
        return out

    def grown(self, size: int) -> Stretches:
        out = Stretches.blank(size)
        out.put(np.arange(len(self)), self)
        return out

    def put(self, rows: np.ndarray, other: Stretches) -> None:
        """Rows ``rows`` become ``other``'s stretches, in order."""
        for name in self.COLUMNS:
            getattr(self, name)[rows] = getattr(other, name)

    def chunk_start(self, rows: np.ndarray, k: np.ndarray) -> np.ndarray:
        """The instant chunk ``k`` of stretches ``rows`` starts."""
        u, h = self.u[rows], self.h[rows]
        t = u.copy()
        later = k > 0
        t[later] += k[later] * h[later]
        return t

    def take(
        self, radio: MapRadio, rows: np.ndarray, k0: np.ndarray, k1: np.ndarray, s0: np.ndarray | None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Chunks ``k0 <= k < k1`` of stretches ``rows``, solved: ``(row, t, now_up)`` of each
        change (in order within a row), each row's state just after the start of chunk
        ``k0`` and at the end of chunk ``k1 - 1``. ``s0``: each row's state at the end of
        chunk ``k0 - 1`` (a different state at chunk ``k0``'s start is a change then); None
        when ``k0`` is the stretch's first chunk."""
        assemble, link_chunks = radio.kernels.assemble, radio.kernels.link_chunks

        rows = np.asarray(rows, np.int64)
        count = np.maximum(np.asarray(k1) - np.asarray(k0), 0).astype(np.int64)
        total = int(count.sum())
        before = np.zeros(len(rows), bool) if s0 is None else np.asarray(s0, bool)
        if total == 0:
            return np.empty(0, np.int64), np.empty(0), np.empty(0, bool), before.copy(), before.copy()
        starts = np.cumsum(count) - count
        r = np.repeat(rows, count)
        k = np.repeat(np.asarray(k0, float), count) + (np.arange(total) - np.repeat(starts, count))
        lo = self.chunk_start(r, k)
        hi = np.minimum(self.chunk_start(r, k + 1), self.x[r])
        # Both robots at rest: one chunk, the state of its start throughout.
        span = np.where(np.isfinite(hi), np.maximum(hi - lo, 0.0), 0.0)
        dead = (self.out[r] > 0) | (np.isfinite(hi) & (hi <= lo))
        span[dead] = 0.0
        # A map's links walk its cells compiled at any team size: so do their points.
        p0 = points_on_legs(self.pa, self.va, self.ta, r, lo, None)
        q0 = points_on_legs(self.pb, self.vb, self.tb, r, lo, None)
        motion = PairMotion(p0, np.ascontiguousarray(self.va[r]), q0, np.ascontiguousarray(self.vb[r]))
        first, c_chunk, c_t, c_up = link_chunks(radio.grid, motion, span, VERTEX_TOLERANCE_CELLS, radio.radii_m)
        first[dead] = False
        chunk, t, up, start_state, end_state = assemble(first, c_chunk, c_t, c_up, lo, count, before, s0 is not None)
        return r[chunk], t, up, start_state, end_state


# Steps of one sample that settle count_below's estimate (one is the most rounding needs).
SETTLE_STEPS = 8


def count_below(u: np.ndarray, h: np.ndarray, t_end: float | np.ndarray) -> np.ndarray:
    """How many samples ``u + k h`` (``k >= 0``) fall before ``t_end``, as floats (inf when
    all do); computed on the very floats of the samples."""
    u, h = np.asarray(u, float), np.asarray(h, float)
    t_end = np.broadcast_to(np.asarray(t_end, float), u.shape)
    out = np.where(u < t_end, 1.0, 0.0)
    fin = np.flatnonzero(np.isfinite(h) & np.isfinite(t_end) & (u < t_end))
    out[np.isfinite(h) & ~np.isfinite(t_end)] = np.inf
    if len(fin):
        uu, hh, tt = u[fin], h[fin], t_end[fin]
        k = np.maximum(np.ceil((tt - uu) / hh), 1.0)
        # Rounding may put the estimate one off either way: settle it on the samples. Where
        # the samples are too fine for their floats to step with k (a nearly parallel pair
        # leaves the envelope after ages, or k beyond 2**52), a few steps do not settle it
        # and the estimate stands.
        exact = k < 2.0**52
        for _ in range(SETTLE_STEPS):
            up = exact & (uu + k * hh < tt)
            if not up.any():
                break
            k[up] += 1.0
        for _ in range(SETTLE_STEPS):
            down = exact & (k > 1) & (uu + (k - 1.0) * hh >= tt)
            if not down.any():
                break
            k[down] -= 1.0
        out[fin] = k
    return out
