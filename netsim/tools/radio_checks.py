"""Closed-form checks of the radio models, as pure functions (for ``netsim validate``).

Each check returns records ``(item, result, theory, measured, tolerance, unit)``; a record
passes when ``|measured - theory| <= tolerance``. Statistical checks use four standard
errors.

- **Unit disk equivalence**: without shadowing or walls, log-distance links exactly the pairs
  within the implied range ``d0 10^((P_t - PL(d0) - sensitivity) / (10 n))``.
- **Link probability under shadowing**: on a static uniform deployment the fraction of pairs
  linked at distance ``d`` is ``Phi((P_t - PL(d) - sensitivity) / sigma)`` (with the
  shadowing clipped at 4 sigma: 0 and 1 beyond), in every distance bin, within four standard
  errors of the binomial (Poisson-binomial: each pair its own ``p``) count.
- **Shadowing correlation**: a moving pair's shadowing at travel separation ``delta`` has
  correlation ``exp(-delta / d_corr)``, whatever the times at which it was looked at in
  between (Fisher's z interval).
- **Walls**: across a wall two robots do not link under the unit disk; through a doorway they
  do; under log-distance each wall crossed lowers the received power by ``wall_loss_db``.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
from scipy.spatial import cKDTree
from scipy.special import ndtr

from netsim.radio.propagation import (
    TRUNCATION_SIGMAS,
    LogDistanceParams,
    Pairs,
    implied_range_m,
    log_distance,
    path_loss_db,
    reach_m,
    unit_disk,
)
from netsim.radio.shadowing import PairShadowing
from netsim.tools.check import Check
from netsim.world.maps import OccupancyMap

Z = 4.0


def correlation_row(delta_m: float, r: float, rho: float, n_pairs: int) -> dict:
    """A measured correlation ``r`` over ``n_pairs`` independent pairs beside its theory
    ``rho``, with the Fisher-z interval of :data:`Z` standard errors around ``rho``."""
    half = Z / math.sqrt(n_pairs - 3)
    return {
        "delta_m": float(delta_m),
        "correlation": r,
        "theory": rho,
        "lo": math.tanh(math.atanh(rho) - half),
        "hi": math.tanh(math.atanh(rho) + half) if rho < 1 else 1.0,
    }


def _all_pairs(pos: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray]:
    pairs = cKDTree(pos).query_pairs(radius, output_type="ndarray")
    return pairs[:, 0], pairs[:, 1]


def check_unit_disk_equivalence(params: LogDistanceParams | None = None, n: int = 600, seed: int = 1):
    """Log-distance without shadowing or walls links exactly the pairs within the implied range."""
    params = params or LogDistanceParams()
    r = implied_range_m(params)
    rng = np.random.default_rng(seed)
    pos = rng.uniform(0.0, 4.0 * r, (n, 2))
    a, b = _all_pairs(pos, 2.0 * r)
    pairs = Pairs.between(a, b, pos)
    linked = log_distance(params).receivable(pairs)
    wrong = int((linked != (pairs.distance_m <= r)).sum())
    return [Check("17", f"log-distance, no shadowing: unit disk of {r:g} m (pairs wrong of {len(a)})", 0.0, wrong, 0.0)]


def link_probability(distance_m, params: LogDistanceParams) -> np.ndarray:
    """``P(P_r >= sensitivity)`` at distance ``d`` under shadowing clipped at 4 sigma."""
    # The closed form, written out: the theory the channel's decisions are checked against.
    margin = params.tx_power_dbm - path_loss_db(distance_m, params) - params.sensitivity_dbm
    sigma = params.shadowing_sigma_db
    clip = TRUNCATION_SIGMAS * sigma
    return np.where(margin >= clip, 1.0, np.where(margin < -clip, 0.0, ndtr(margin / sigma)))


def link_fraction_table(
    params: LogDistanceParams, n_robots: int, side_m: float, seed: int = 1, n_bins: int = 12
) -> pd.DataFrame:
    """Fraction of pairs linked per distance bin on a static uniform deployment, against theory.

    Columns: ``d_lo_m, d_hi_m, pairs, linked, fraction, theory, tolerance`` (four standard
    errors of the fraction) and ``phi_at_centre`` (Phi at the bin's centre, for reading).
    """
    rng = np.random.default_rng(seed)
    pos = rng.uniform(0.0, side_m, (n_robots, 2))
    reach = reach_m(params)
    a, b = _all_pairs(pos, reach)
    pairs = Pairs.between(a, b, pos, np.zeros(n_robots))
    shadowing = PairShadowing(params.shadowing_sigma_db, params.shadowing_decorrelation_m, rng)
    linked = log_distance(params, shadowing).receivable(pairs)
    p = link_probability(pairs.distance_m, params)
    edges = np.linspace(0.0, reach, n_bins + 1)
    which = np.clip(np.digitize(pairs.distance_m, edges) - 1, 0, n_bins - 1)
    rows = []
    for k in range(n_bins):
        sel = which == k
        m = int(sel.sum())
        if m == 0:
            continue
        theory = float(p[sel].mean())
        se = math.sqrt(float((p[sel] * (1 - p[sel])).sum())) / m
        centre = 0.5 * (edges[k] + edges[k + 1])
        rows.append(
            {
                "d_lo_m": edges[k],
                "d_hi_m": edges[k + 1],
                "pairs": m,
                "linked": int(linked[sel].sum()),
                "fraction": float(linked[sel].mean()),
                "theory": theory,
                "tolerance": Z * se,
                "phi_at_centre": float(link_probability(centre, params)),
            }
        )
    return pd.DataFrame(rows)


def check_link_probability(params: LogDistanceParams | None = None, n_robots: int = 3000, seed: int = 1):
    """Every distance bin's linked fraction within four standard errors of theory."""
    params = params or LogDistanceParams(shadowing_sigma_db=6.0)
    side = 8.0 * implied_range_m(params)
    table = link_fraction_table(params, n_robots, side, seed)
    return [
        Check(
            "17",
            f"shadowing sigma {params.shadowing_sigma_db:g} dB: linked fraction, d in "
            f"[{row.d_lo_m:.0f}, {row.d_hi_m:.0f}) m ({row.pairs} pairs)",
            row.theory,
            row.fraction,
            row.tolerance,
        )
        for row in table.itertuples()
    ]


def correlation_table(
    sigma_db: float = 6.0,
    decorrelation_m: float = 10.0,
    separations_m=(1.0, 5.0, 10.0, 20.0, 40.0),
    n_pairs: int = 4000,
    seed: int = 1,
    step_m: float = 0.0,
) -> pd.DataFrame:
    """Empirical correlation of pairs' shadowing between travel 0 and travel ``delta``.

    Each pair is looked at at travel 0, then at its own random intermediate travels (0 to 3
    looks between consecutive separations, so schedules differ), then at each separation.
    Columns: ``delta_m, correlation, theory, lo, hi`` (Fisher's z, four standard errors).
    """
    rng = np.random.default_rng(seed)
    sh = PairShadowing(sigma_db, decorrelation_m, rng, step_m=step_m)
    a, b = 2 * np.arange(n_pairs), 2 * np.arange(n_pairs) + 1
    x0 = sh.sample(a, b, np.zeros(n_pairs))
    last = np.zeros(n_pairs)
    rows = []
    for delta in separations_m:
        for _ in range(3):
            look = rng.random(n_pairs) < 0.5
            mid = last + rng.random(n_pairs) * (delta - last)
            sh.sample(a[look], b[look], mid[look])
            last[look] = mid[look]
        x = sh.sample(a, b, np.full(n_pairs, float(delta)))
        last[:] = delta
        rows.append(
            correlation_row(delta, float(np.corrcoef(x0, x)[0, 1]), math.exp(-delta / decorrelation_m), n_pairs)
        )
    return pd.DataFrame(rows)


def check_shadowing_correlation(sigma_db: float = 6.0, decorrelation_m: float = 10.0, seed: int = 1):
    table = correlation_table(sigma_db, decorrelation_m, seed=seed)
    return [
        Check(
            "17",
            f"shadowing correlation at {row.delta_m:g} m of pair travel (d_corr {decorrelation_m:g} m)",
            row.theory,
            row.correlation,
            max(row.hi - row.theory, row.theory - row.lo),
        )
        for row in table.itertuples()
    ]


def pair_travel_correlation(
    separations_m=(5.0, 10.0, 20.0),
    n_pairs: int = 2000,
    speed_mps: float = 1.0,
    distance_m: float = 100.0,
    seed: int = 1,
) -> pd.DataFrame:
    """The channel's shadowing of pairs whose two robots both move, against Gudmundson's law
    in the pair's travel, the *sum* of the two path lengths.

    A run with log-distance shadowing (default radio, sigma 6 dB, d_corr 10 m): ``n_pairs``
    pairs ``distance_m`` apart, both robots of a pair moving side by side at ``speed_mps``
    from t = 0 (the distance stays the same, each robot travels ``v t``, the pair ``2 v t``).
    The channel decides each pair's frame at t = 0 and at the instants the pair's travel
    reaches each separation, the sender drawn at random each time, and its reception gives
    the received power: the shadowing is the power's departure from the mean. Columns:
    ``delta_m, correlation, theory, lo, hi`` (correlation with t = 0 against ``exp(-delta /
    d_corr)``, Fisher's z, four standard errors). Counting one robot's travel only would
    give ``exp(-delta / (2 d_corr))``.
    """
    from netsim.config import from_dict
    from netsim.run import build

    n = 2 * n_pairs
    cfg = from_dict(
        {
            "seed": seed,
            "world": {"n_robots": n, "side_m": 10_000.0},
            "mobility": {"model": "static"},
            "channel": {"propagation": "log_distance", "shadowing_sigma_db": 6.0},
            "protocol": {"model": "none"},
            "output": {"position_interval_s": 0.0},
        }
    )
    sim = build(cfg)
    d_corr = cfg.channel.radio.shadowing_decorrelation_m
    pos = np.zeros((n, 2))
    pos[0::2, 1] = pos[1::2, 1] = np.arange(n_pairs) * 4.0
    pos[1::2, 0] = distance_m
    sim.state.place(pos)
    for i in range(n):
        sim.state.set_leg(i, 0.0, (0.0, speed_mps))
    rec = sim.channel.reception
    rng = np.random.default_rng(seed)
    one = np.array([distance_m])

    def powers(t: float) -> np.ndarray:
        out = np.empty(n_pairs)
        flip = rng.random(n_pairs) < 0.5
        for k in range(n_pairs):
            a, b = (2 * k + 1, 2 * k) if flip[k] else (2 * k, 2 * k + 1)
            rec.decide(t, a, np.array([b]), one)
            out[k] = rec.received_dbm(t, a, np.array([b]), one)[0]
        return out

    first = powers(0.0)
    rows = []
    for delta in separations_m:
        r = float(np.corrcoef(first, powers(delta / (2.0 * speed_mps)))[0, 1])
        rows.append(correlation_row(delta, r, math.exp(-delta / d_corr), n_pairs))
    return pd.DataFrame(rows)


def wall_test_map(resolution_m: float = 0.25) -> OccupancyMap:
    """A 40 m x 40 m room cut by three walls at x = 10, 20, 30 m (0.5 m thick); the wall at
    x = 20 m has a doorway for y in [2, 4) m."""
    w, h = int(round(40 / resolution_m)), int(round(40 / resolution_m))
    occ = np.zeros((h, w), dtype=bool)
    for x in (10.0, 20.0, 30.0):
        c = int(round(x / resolution_m))
        occ[:, c : c + int(round(0.5 / resolution_m))] = True
    c = int(round(20 / resolution_m))
    occ[int(round(2 / resolution_m)) : int(round(4 / resolution_m)), c : c + int(round(0.5 / resolution_m))] = False
    return OccupancyMap(occ, ~occ, resolution_m, (0.0, 0.0), "wall test map")


def check_walls(params: LogDistanceParams | None = None):
    """Walls block the unit disk and cost ``wall_loss_db`` each under log-distance."""
    params = params or LogDistanceParams()
    m = wall_test_map()
    disk = unit_disk(50.0, m)

    def pair(p, q):
        p, q = np.atleast_2d(p).astype(float), np.atleast_2d(q).astype(float)
        k = len(p)
        return Pairs.between(np.arange(k), np.arange(k) + k, np.vstack([p, q]))

    across = disk.receivable(pair([15.0, 15.0], [25.0, 15.0]))[0]
    door = disk.receivable(pair([15.0, 3.0], [25.0, 3.0]))[0]
    # Pairs 10 to 30 m apart crossing 0, 1, 2 and 3 walls.
    pairs = pair(
        [[12.0, 15.0], [15.0, 15.0], [5.0, 15.0], [5.0, 15.0]], [[18.0, 15.0], [25.0, 15.0], [25.0, 15.0], [35.0, 15.0]]
    )
    drop = log_distance(params).received_dbm(pairs) - log_distance(params, occupancy=m).received_dbm(pairs)
    error = float(np.max(np.abs(drop - params.wall_loss_db * np.arange(4))))
    return [
        Check("W1", "unit disk: robots across a wall (10 m apart, range 50 m) linked", 0.0, float(across), 0.0),
        Check("W2", "unit disk: robots through a doorway (10 m apart) linked", 1.0, float(door), 0.0),
        Check(
            "W3",
            f"log-distance: power drop = {params.wall_loss_db:g} dB per wall, 0-3 walls (largest error)",
            0.0,
            error,
            1e-9,
            "dB",
        ),
    ]


def run_all() -> list[Check]:
    """Every radio check, at its default size (a few seconds)."""
    return check_unit_disk_equivalence() + check_link_probability() + check_shadowing_correlation() + check_walls()
