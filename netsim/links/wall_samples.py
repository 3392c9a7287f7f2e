"""How a link on a map is sampled: the arithmetic that the post-hoc solver
(:func:`netsim.links.radio_links.walled_lifetimes`) and the runtime one
(:class:`netsim.links.walled_links.WalledLinks`) share, so that both take the same samples and
find the same floats.

On a map (walls, no shadowing) a link can only be up while the two robots are within the
radio's largest range (the *envelope*, solved exactly). Within it the link's state is
sampled along *stretches*: a stretch starts where the pair enters the envelope and at
every course change of either robot, and lasts while both keep their legs. A stretch's
samples depend only on what is known at its start, its two legs:

- the step is ``h = SAMPLE_M / max(|v_a|, |v_b|)`` (no robot moves more than ``SAMPLE_M``
  between two samples; ``h`` infinite when both are at rest: the state cannot change);
- the samples are ``u + k h`` from the stretch's start ``u``, the first taken just inside
  it, at ``u + min(TOLERANCE_S, h / 2)`` (at an envelope's start the distance is the range
  itself, which rounding may put on either side);
- a change between samples ``k`` and ``k + 1`` is located by bisection to within
  ``TOLERANCE_S``, each interval on its own (the result does not depend on which other
  intervals are bisected with it);
- samples stop before ``x``, where the pair leaves the envelope on these legs (solved from
  the later leg start, as every crossing is): between the last sample and ``x`` the state
  holds, and the link goes down exactly at the envelope's edge.

A stretch that ends (a course change at ``e``) keeps the changes found at or before ``e``;
those after it are dropped, and the next stretch starts from the new legs. The samples
beyond ``e`` of the interval that straddles it are taken on the old legs, extrapolated:
the runtime solver took them before the course change was known.

Why the step comes from the pair's own speeds, not their relative speed: walls lie along
the line between the two robots, which sweeps across the map as they move even when they
keep their distance (the same velocity: no relative motion); and not from a speed bound
of the whole run: controllers set speeds as the run goes, and a pair at rest would be
sampled for nothing.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from netsim.links.crossings import crossing_times
from netsim.radio.propagation import Pairs

if TYPE_CHECKING:
    from netsim.radio.reception import Reception

SAMPLE_M = 1.0
TOLERANCE_S = 1e-6


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
    and the walls crossed (with unequal ranges both must hear each other)."""
    d = np.hypot(pb[:, 0] - pa[:, 0], pb[:, 1] - pa[:, 1])
    chain = reception.compiled
    up = chain.receivable(Pairs(a, b, pa, pb, d))
    if not equal_ranges:
        up &= chain.receivable(Pairs(b, a, pb, pa, d))
    return up


class Stretches:
    """Stretches as columns: pair ``a, b``, start ``u``, the two legs (``pa, va, ta``: a
    leg's start position, velocity and start time; ``pb, vb, tb``), step ``h``, the
    envelope's exit ``x`` on these legs and ``jx``: how many samples after the first fall
    before it."""

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
    ):
        self.a, self.b = np.asarray(a, np.int64), np.asarray(b, np.int64)
        self.u = np.asarray(u, float)
        self.pa, self.va, self.ta = pa, va, np.asarray(ta, float)
        self.pb, self.vb, self.tb = pb, vb, np.asarray(tb, float)
        speed = np.maximum(np.hypot(va[:, 0], va[:, 1]), np.hypot(vb[:, 0], vb[:, 1]))
        with np.errstate(divide="ignore"):
            self.h = np.where(speed > 0, SAMPLE_M / np.where(speed > 0, speed, 1.0), np.inf)
        origin = np.maximum(self.ta, self.tb)
        qa = pa + va * (origin - self.ta)[:, None]
        qb = pb + vb * (origin - self.tb)[:, None]
        _, out = crossing_times(qa - qb, va - vb, np.asarray(radius, float), origin)
        self.x = np.where(np.isnan(out), np.inf, out)
        self.jx = np.maximum(count_below(self.u, self.h, self.x) - 1, 0)

    COLUMNS = ("a", "b", "u", "pa", "va", "ta", "pb", "vb", "tb", "h", "x", "jx")

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

    def sample_time(self, rows: np.ndarray, k: np.ndarray) -> np.ndarray:
        """The instant sample ``k`` of stretches ``rows`` is evaluated at."""
        u, h = self.u[rows], self.h[rows]
        with np.errstate(invalid="ignore"):
            t = u + k * h
        return np.where(k == 0, u + np.minimum(TOLERANCE_S, 0.5 * h), t)

    def state(self, reception: Reception, equal_ranges: bool, rows: np.ndarray, t: np.ndarray) -> np.ndarray:
        """The link's state of stretches ``rows`` at ``t``, on their legs (extrapolated)."""
        pa = self.pa[rows] + self.va[rows] * (t - self.ta[rows])[:, None]
        pb = self.pb[rows] + self.vb[rows] * (t - self.tb[rows])[:, None]
        return linked(reception, equal_ranges, self.a[rows], self.b[rows], pa, pb)

    def first_state(self, reception: Reception, equal_ranges: bool, rows: np.ndarray) -> np.ndarray:
        return self.state(reception, equal_ranges, rows, self.sample_time(rows, np.zeros(len(rows), np.int64)))

    def changes(
        self, reception: Reception, equal_ranges: bool, rows: np.ndarray, k0: np.ndarray, k1: np.ndarray, s0: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The changes between samples ``k`` and ``k + 1`` for ``k0 <= k < k1`` of stretches
        ``rows``, whose state at sample ``k0`` is ``s0``: ``(row, t, now_up)`` of each change
        (in order within a row: by ``k``), and each row's state at sample ``k1``."""
        count = np.maximum(k1 - k0, 0).astype(np.int64)
        total = int(count.sum())
        if total == 0:
            return np.empty(0, np.int64), np.empty(0), np.empty(0, bool), s0.copy()
        starts = np.cumsum(count) - count
        r = np.repeat(rows, count)
        k = np.repeat(k0.astype(np.int64), count) + (np.arange(total) - np.repeat(starts, count))
        lo = self.sample_time(r, k)
        hi = self.sample_time(r, k + 1)
        after = self.state(reception, equal_ranges, r, hi)
        # The state at sample k: the given one for each row's first, else the one before.
        before = np.r_[False, after[:-1]]
        first = starts[count > 0]
        before[first] = s0[count > 0]
        chg = np.flatnonzero(before != after)
        t = bisect(lambda sel, tm: self.state(reception, equal_ranges, r[chg[sel]], tm), lo[chg], hi[chg], before[chg])
        last = s0.copy()
        has = count > 0
        last[has] = after[starts[has] + count[has] - 1]
        return r[chg], t, after[chg], last


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
        # Rounding may put the estimate one off either way: settle it on the samples.
        while True:
            up = uu + k * hh < tt
            if not up.any():
                break
            k[up] += 1.0
        while True:
            down = (k > 1) & (uu + (k - 1.0) * hh >= tt)
            if not down.any():
                break
            k[down] -= 1.0
        out[fin] = k
    return out


def bisect(
    state_at: Callable[[np.ndarray, np.ndarray], np.ndarray], lo: np.ndarray, hi: np.ndarray, before: np.ndarray
) -> np.ndarray:
    """The instant each change in ``(lo, hi]`` happens, to within ``TOLERANCE_S``: the ``hi``
    of an interval halved until no wider than it, each on its own. ``state_at(sel, t)``: the
    state of changes ``sel`` at ``t``; ``before``: the state at ``lo``."""
    lo, hi = lo.copy(), hi.copy()

    def wide(i: np.ndarray) -> np.ndarray:
        # Far out (a sample of a robot that barely moves), floats are coarser than the
        # tolerance: stop where no float lies between.
        mid = 0.5 * (lo[i] + hi[i])
        return i[(hi[i] - lo[i] > TOLERANCE_S) & (mid > lo[i]) & (mid < hi[i])]

    active = wide(np.arange(len(lo)))
    while len(active):
        mid = 0.5 * (lo[active] + hi[active])
        same = state_at(active, mid) == before[active]
        lo[active] = np.where(same, mid, lo[active])
        hi[active] = np.where(same, hi[active], mid)
        active = wide(active)
    return hi
