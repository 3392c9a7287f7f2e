"""Which links a coverage plan may keep under the run's radio, and what keeps each one up
over a whole control step (docs/model.md section 5, "Staying connected").

A plan keeps a spanning forest of links that are up when the step starts, the same links
as ``links.parquet``, and limits every robot's step so that each kept link stays up at
every instant of the step, or, under shadowing, stays up unless the shadowing changes by
more than it plausibly can. What "up" means, and how it is kept, depends on the radio:

- **Disk** (the unit disk, or log-distance path loss alone, in open space): a link is up
  while ``d <= min(r_a, r_b)`` (under log-distance ``r`` is the implied range). A kept link
  ends the step at most ``max(r - margin_m, d)`` long; the distance between two robots
  moving in straight lines is convex in time, so it is up throughout. Exact.
- **Shadowing** (log-distance, ``shadowing_sigma_db > 0``): a link is up at a transmission
  when ``P_t - PL(d) - X - W >= sensitivity``; ``X``, the pair's shadowing, changes as the
  two robots travel (an Ornstein-Uhlenbeck process in the pair's travel, correlation
  ``exp(-delta / d_corr)``, clipped at ``4 sigma``). The plan uses ``X`` as the robots last
  measured it (the value of the pair's last transmission, which its received power
  tells). A link's margin is ``m = P_t - PL(d) - X - W - sensitivity`` (dB); its budget
  ``B = min(fade_margin_db, m)``. The link ends the step no longer than the distance at
  which the margin, with that ``X``, would be ``B`` (``B = m``: no longer than now); and
  the pair's travel since ``X`` was measured is bounded so that the plausible change of
  ``X``, ``(1 - rho) max(-X, 0) + FADE_SIGMAS sigma sqrt(1 - rho^2)`` with ``rho =
  exp(-travel / d_corr)`` (the drift of the process back to 0 from a favourable ``X``,
  and ``FADE_SIGMAS`` of its spread), stays within ``B`` (:func:`fade_travel_m`). So at
  every look of the channel during the step the link fails only if ``X`` moved by more
  than ``FADE_SIGMAS`` standard deviations beyond its drift: probabilistic. A link within
  the *sure* distance, where even the worst clipped shadowing (``+4 sigma``) leaves it up,
  is kept like a disk link, with no bound on travel: guaranteed. A pair that does not move
  keeps its ``X`` (the process runs in travel): holding never breaks a link. The forest
  ranks a link by the margin left after the plausible change of ``X`` over the pair's
  travel since ``X`` was measured: a link not kept while its robots moved on may be
  weaker than its measurement says.
- **Walls** (a map: the unit disk with line of sight, or log-distance with
  ``wall_loss_db``): besides the limits above (the range or the power with the walls
  crossed when the step starts), the walls crossed by the segment between two moving
  robots are computed exactly over the whole step (:func:`netsim.world.sweep.sweep_walls`),
  also for a commanded robot that misses its command and holds while its partner moves;
  a robot's step is cut just before the first instant a kept link would be lost
  (:meth:`LinkRules.cut_for_walls`). The plan's forest prefers the links that would stay
  up over the wished step (:meth:`LinkRules.lasting`, :func:`prefer`): those that would
  be lost hold their robots back at corners and doors.
"""

from __future__ import annotations

import numpy as np
from netsim.mobility._fade_kernels import FADE_SIGMAS as FADE_SIGMAS
from netsim.mobility.steps import Candidates

from netsim.compiled import load
from netsim.geometry import distances_m, in_motion, link_ranges_m, speeds_mps
from netsim.topology import geometric_pairs
from netsim.trajectory import points_on_legs

# Rounds of shortening steps on a map before robots whose links still fail are held.
CUT_ROUNDS = 8
# A step cut before a kept link's loss ends this far (of the faster robot's path) before it.
CUT_BACKOFF_M = 0.05


def plausible_change_db(
    travel_m: np.ndarray, x_db: np.ndarray, sigma_db: float, decorrelation_m: float, n_robots: int | None = None
) -> np.ndarray:
    """How far the shadowing measured at ``x_db`` plausibly moved (against the link) over a
    pair travel ``travel_m``: ``(1 - rho) max(-x, 0) + FADE_SIGMAS sigma sqrt(1 - rho^2)``
    at ``rho = exp(-travel / d_corr)``, the drift of the shadowing back to 0 from a
    favourable ``x`` and :data:`FADE_SIGMAS` of its spread (the rule both plans use,
    :func:`netsim.mobility._fade_kernels.plausible_change_db`, run as a team of
    ``n_robots`` runs it; None: as many as the values).

    >>> plausible_change_db(np.array([0.0, 1.438]), np.zeros(2), 4.0, 10.0).round(2).tolist()
    [0.0, 8.0]
    """
    travel, x = np.broadcast_arrays(np.asarray(travel_m, float), np.asarray(x_db, float))
    shape = travel.shape
    travel, x = np.ascontiguousarray(travel.ravel()), np.ascontiguousarray(x.ravel())
    out = np.empty(len(travel))
    kernels = load("netsim.mobility._fade_kernels", n_robots, values=len(out))
    kernels.plausible_change_many(travel, x, float(sigma_db), float(decorrelation_m), out)
    return out.reshape(shape)


def fade_travel_m(
    budget_db: np.ndarray, x_db: np.ndarray, sigma_db: float, decorrelation_m: float, n_robots: int | None = None
) -> np.ndarray:
    """The largest pair travel ``delta`` over which the shadowing's plausible change stays
    within ``budget_db``: ``(1 - rho) max(-x, 0) + FADE_SIGMAS sigma sqrt(1 - rho^2) <=
    budget``, ``rho = exp(-delta / d_corr)`` (0 for a budget <= 0; inf when even complete
    decorrelation stays within it; :func:`netsim.mobility._fade_kernels.fade_travel_m`, run
    as a team of ``n_robots`` runs it; None: as many as the values).

    >>> fade_travel_m(np.array([0.0, 8.0, 100.0]), np.zeros(3), 4.0, 10.0).round(3).tolist()
    [0.0, 1.438, inf]
    """
    budget, x = np.broadcast_arrays(np.asarray(budget_db, float), np.asarray(x_db, float))
    shape = budget.shape
    budget, x = np.ascontiguousarray(budget.ravel()), np.ascontiguousarray(x.ravel())
    out = np.empty(len(budget))
    kernels = load("netsim.mobility._fade_kernels", n_robots, values=len(out))
    kernels.fade_travel_many(budget, x, float(sigma_db), float(decorrelation_m), out)
    return out.reshape(shape)


def prefer(links: Candidates, lasting: np.ndarray) -> Candidates:
    """``links`` with the weight of every link not ``lasting`` raised above that of every
    link, so that a minimum spanning forest takes a link that does not last only where no
    lasting one joins the same parts (the forest has as many components either way).

    >>> rows = ([0, 0], [1, 2], [5.0, 9.0], [1.0, 2.0], [9.0, 9.0], [np.inf] * 2, [9.0] * 2)
    >>> c = Candidates(*(np.array(v) for v in rows))
    >>> prefer(c, np.array([False, True])).weight.tolist()
    [4.0, 2.0]
    """
    raise_by = np.where(lasting, 0.0, float(links.weight.max(initial=0.0)) + 1.0)
    return links._replace(weight=links.weight + raise_by)


class LinkRules:
    """The link rules of one run (module notes): built from the channel's reception (None:
    the plain unit disk), the robots, the run's link state (the links up now, as
    ``links.parquet`` has them) and the plan's margins."""

    def __init__(self, reception, state, link_state, margin_m: float, fade_margin_db: float):
        self.state = state
        self.link_state = link_state
        self.margin_m = float(margin_m)
        self.fade_margin_db = float(fade_margin_db)
        compiled = reception.compiled if reception is not None else None
        self.log = compiled.log.params if compiled is not None and compiled.log is not None else None
        self.shadow = compiled.shadow if compiled is not None else None
        if self.shadow is not None and not self.shadow.sigma_db > 0:
            self.shadow = None
        self.walls = reception.map if reception is not None else None
        self.wall_loss_db = compiled.walls.wall_loss_db if compiled is not None and compiled.walls is not None else 0.0

    @property
    def disk(self) -> bool:
        """Links are the disk of the robots' ranges: solved from positions alone."""
        return self.shadow is None and self.walls is None

    # -- the candidates -------------------------------------------------------------------
    def candidates(self, pos: np.ndarray, t_s: float) -> Candidates:
        """The links a plan may keep in a step starting at ``t_s`` with robots at ``pos``,
        with their limits (module notes)."""
        if self.disk:
            ranges = self.state.range_m
            i, j, d = geometric_pairs(pos, ranges)
            r = link_ranges_m(ranges, i, j)
            # The forest prefers short links; the shift keeps zero lengths (robots at one
            # spot) in the graph.
            return Candidates(i, j, d, d + float(ranges.min()), r - self.margin_m, np.full(len(i), np.inf), r)
        if self.shadow is None:
            # On a map without shadowing a link is a function of the two positions: the
            # pairs the channel would link at t_s, exactly (links.parquet samples the same
            # rule along the legs, docs/radio.md).
            i, j, d = geometric_pairs(pos, self._largest_range())
        else:
            i, j = self.link_state.up_pairs()
            d = distances_m(pos[i], pos[j], None, len(pos))
        walls = self._walls_now(pos, i, j)
        if self.log is None:
            # The unit disk with line of sight.
            r = link_ranges_m(self.state.range_m, i, j)
            ok = load("netsim._kernels", len(pos)).in_range(pos, i, j, r, 0.0) & (walls == 0)
            i, j, d, r = i[ok], j[ok], d[ok], r[ok]
            return Candidates(i, j, d, d + float(r.max(initial=0.0)), r - self.margin_m, np.full(len(i), np.inf), r)
        return self._power_candidates(pos, t_s, i, j, d, walls)

    def _largest_range(self) -> float:
        """No pair farther apart links (the range, or the implied range without walls)."""
        if self.log is None:
            return float(self.state.range_m.max())
        return self.log.implied_range_m()

    def _walls_now(self, pos: np.ndarray, i: np.ndarray, j: np.ndarray) -> np.ndarray:
        if self.walls is None or len(i) == 0:
            return np.zeros(len(i), np.int64)
        from netsim.world.los import walls_crossed

        return np.asarray(walls_crossed(self.walls, pos[i], pos[j]), np.int64)

    def _power_candidates(self, pos, t_s, i, j, d, walls) -> Candidates:
        p, n = self.log, self.state.n
        x = np.zeros(len(i))
        travel = np.full(len(i), np.inf)
        if self.shadow is not None:
            raw, _ = self.shadow.state(i, j)
            x = self.shadow.loss_terms(np.nan_to_num(raw, nan=np.inf))
            seen = ~np.isnan(raw)
        else:
            seen = np.ones(len(i), bool)
        # Summed as a frame's loss is, so that a link is a candidate exactly when the radio
        # would hear a frame across it.
        loss = p.loss_db(d, x, walls, n)
        ok = seen & p.radio.hears(loss, n)
        margin = np.maximum(p.radio.margin_db(loss, n), 0.0)
        i, j, d, walls, x, margin = i[ok], j[ok], d[ok], walls[ok], x[ok], margin[ok]
        travel = travel[ok]
        if self.shadow is None:
            r = p.effective_range_m(0.0, walls, n)
            reserve = np.zeros(len(i))
            keep = r - self.margin_m
        else:
            sh = self.shadow
            budget = np.minimum(self.fade_margin_db, margin)
            keep = np.maximum(p.effective_range_m(x + budget, walls, n), d)
            pair_travel = self.state.pair_travelled_m(t_s, i, j)
            _, anchor = sh.state(i, j)
            # The raw travel since the look, not the channel's clock (which steps it down to
            # a multiple of its step, radio._kernels.anchored): never less, so the change
            # the plan allows for is never less than the channel's next look can draw.
            since = np.maximum(pair_travel - anchor, 0.0)
            travel = np.maximum(fade_travel_m(budget, x, sh.sigma_db, sh.decorrelation_m, n) - since, 0.0)
            # What is left of the margin after the plausible change since X was measured: a
            # link the pair has moved on from since (not kept then) is weaker than it looks.
            left = margin - plausible_change_db(since, x, sh.sigma_db, sh.decorrelation_m, n)
            reserve = x + budget
            # Within the sure distance even the worst shadowing leaves the link up.
            sure_r = p.effective_range_m(sh.clip_db, walls, n)
            near = load("netsim._kernels", n).in_range(pos, i, j, np.ascontiguousarray(sure_r, float), 0.0)
            sure = near & (sure_r - self.margin_m >= keep)
            keep = np.where(sure, sure_r - self.margin_m, keep)
            travel = np.where(sure, np.inf, travel)
            reserve = np.where(sure, sh.clip_db, reserve)
            r = p.effective_range_m(reserve, walls, n)
            margin = np.where(sure, margin, left)
        # The forest prefers the links with the largest margin (left).
        weight = float(margin.max(initial=0.0)) + 1.0 - margin
        return Candidates(i, j, d, weight, keep, travel, r, reserve)

    # -- walls over the step ----------------------------------------------------------------
    def _range_with(self, links: Candidates, k: np.ndarray, walls: np.ndarray) -> np.ndarray:
        """The longest each link ``k`` may be while its segment crosses ``walls`` walls (-1:
        not up at any length)."""
        if self.log is None:
            return np.where(walls == 0, links.range_m[k], -1.0)
        # The law's range is d0 or more wherever the margin at d0 is not negative, else 0.
        r = self.log.effective_range_m(links.reserve_db[k], walls, self.state.n)
        return np.where(r > 0.0, r, -1.0)

    def cut_for_walls(
        self,
        pos: np.ndarray,
        move: np.ndarray,
        commanded: np.ndarray,
        links: Candidates,
        kept: np.ndarray,
        period_s: float,
    ) -> np.ndarray:
        """The fraction of its planned ``move`` each robot may make so that every kept link
        (rows ``kept`` of ``links``) stays up over the whole step, walls included: also when
        a ``commanded`` robot misses its command and holds while its partner moves. A
        shortened step is the same path stopped earlier, so a link that failed at ``t``
        holds up to just before ``t``; after :data:`CUT_ROUNDS` rounds the robots of the
        links that still fail hold."""
        n = len(pos)
        scale = np.ones(n)
        if self.walls is None or len(kept) == 0:
            return scale
        i, j = links.i[kept], links.j[kept]
        for round_ in range(CUT_ROUNDS + n + 1):
            v = move * (scale / period_s)[:, None]
            moving = in_motion(v)
            # Scenarios: both move; i holds (missed command); j holds.
            rows_k = [np.arange(len(i))] * 3
            hold_a = [np.zeros(len(i), bool), commanded[i] & moving[i], np.zeros(len(i), bool)]
            hold_b = [np.zeros(len(i), bool), np.zeros(len(i), bool), commanded[j] & moving[j]]
            sel = [moving[i] | moving[j], hold_a[1] & moving[j], hold_b[2] & moving[i]]
            k = np.concatenate([r[s] for r, s in zip(rows_k, sel)])
            if len(k) == 0:
                return scale
            ha = np.concatenate([h[s] for h, s in zip(hold_a, sel)])
            hb = np.concatenate([h[s] for h, s in zip(hold_b, sel)])
            a, b = i[k], j[k]
            va = np.where(ha[:, None], 0.0, v[a])
            vb = np.where(hb[:, None], 0.0, v[b])
            t_bad = self._first_loss(pos[a], va, pos[b], vb, kept[k], links, period_s)
            bad = np.flatnonzero(t_bad < np.inf)
            if len(bad) == 0:
                return scale
            # Stopped short of the loss by CUT_BACKOFF_M of the faster robot's path: a step
            # ending on the very instant of a loss would lose the link by rounding.
            fast = np.maximum(speeds_mps(va[bad]), speeds_mps(vb[bad]))
            early = t_bad[bad] - CUT_BACKOFF_M / np.maximum(fast, 1e-12)
            cut = np.clip(early / period_s, 0.0, 1.0) if round_ < CUT_ROUNDS else np.zeros(len(bad))
            for robots, held in ((a[bad], ha[bad]), (b[bad], hb[bad])):
                mover = ~held & moving[robots]
                np.minimum.at(scale, robots[mover], scale[robots[mover]] * cut[mover])
        return scale

    def lasting(self, pos: np.ndarray, velocity_mps: np.ndarray, links: Candidates, period_s: float) -> np.ndarray:
        """Whether each candidate link stays up over a step of ``period_s`` with the robots
        moving at ``velocity_mps`` from ``pos`` (walls swept exactly, as for a kept link)."""
        k = np.arange(len(links.i))
        if self.walls is None or len(k) == 0:
            return np.ones(len(k), bool)
        va, vb = velocity_mps[links.i], velocity_mps[links.j]
        return ~np.isfinite(self._first_loss(pos[links.i], va, pos[links.j], vb, k, links, period_s))

    def _first_loss(self, pa, va, pb, vb, k, links: Candidates, period_s: float) -> np.ndarray:
        """For each scenario (two robots from ``pa``, ``pb`` at ``va``, ``vb``), the start of
        the first stretch of constant walls in which its link ``k`` is lost (inf: none)."""
        from netsim.world.sweep import sweep_walls

        # Counts beyond what any link survives are all alike.
        limit = 0 if self.log is None else int(np.ceil(self.log.budget_db / max(self.wall_loss_db, 1e-9)))
        duration = np.full(len(pa), float(period_s))
        table = sweep_walls(self.walls, pa, va, pb, vb, duration, limit=limit)
        pair, t0, t1, walls = (np.asarray(c) for c in (table.pair, table.t0_s, table.t1_s, table.walls))
        # Distance is convex in time: its largest value on a stretch is at an end. The legs
        # start at the step's start (time 0).
        start, n = np.zeros(len(pa)), len(pa)
        r = np.ascontiguousarray(self._range_with(links, k[pair], walls), dtype=float)
        rows, in_range = np.arange(len(pair)), load("netsim._kernels", n).in_range

        def within(t: np.ndarray) -> np.ndarray:
            ends = np.r_[points_on_legs(pa, va, start, pair, t, n), points_on_legs(pb, vb, start, pair, t, n)]
            return in_range(ends, rows, rows + len(pair), r, 0.0)

        # -1 (never up) is tested apart: "in range" squares the range.
        lost = (r < 0.0) | ~(within(t0) & within(t1))
        first = np.full(len(pa), np.inf)
        np.minimum.at(first, pair[lost], t0[lost])
        return first
