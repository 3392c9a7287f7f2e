"""Received power as a chain of small loss terms, the way ns-3 chains propagation loss models.

Under the log-distance model a frame from ``a`` reaches ``b`` with power

    P_r = P_t - PL(d0) - 10 n log10(d / d0) - X - W      (dBm)

and is receivable when ``P_r >= sensitivity``. ``X`` is the pair's shadowing
(:mod:`netsim.radio.shadowing`), ``W`` the loss of the walls the straight line between the
two robots crosses (:mod:`netsim.world.los`). Below the reference distance the path loss
stays ``PL(d0)``, as ns-3's ``LogDistancePropagationLossModel`` does.

Each term is a small object with ``loss_db(pairs) -> array`` over a batch of pairs
(:class:`Pairs`), vectorised, and ``lowest_db``, the least loss it can ever return. A
:class:`LossChain` sums its terms; asked only which pairs are receivable, it evaluates
the terms in order and drops a pair as soon as the loss so far plus the least the
remaining terms can add exceeds the budget ``P_t - sensitivity``. Cheap terms first, then:
walls are only traced for pairs that path loss and shadowing leave in range.

The unit disk (the paper's model) is a chain too: a range term (0 within range, infinite
beyond) and, on a map, a line-of-sight term (infinite when any occupied cell lies between
the two robots), with a budget of 0 dB.

Defaults (2.4 GHz-like): ``P_t = 20 dBm``, ``d0 = 1 m``, ``PL(d0) = 40 dB`` (free space at
2.4 GHz and 1 m: 40.05 dB), ``n = 3`` (indoors, obstructed), sensitivity ``-80 dBm``: the
implied range is exactly ``1 m * 10^(60 / 30) = 100 m``.

>>> p = LogDistanceParams()
>>> implied_range_m(p)
100.0
>>> float(path_loss_db(10.0, p))
70.0
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from netsim.errors import ConfigError
from netsim.params import Params, param

# Shadowing is used clipped to +-4 sigma (its state is not: see netsim.radio.shadowing), so
# that no pair beyond a finite distance can ever link; the link probability then follows the
# closed form exactly wherever it lies between 3.2e-5 and 1 - 3.2e-5.
TRUNCATION_SIGMAS = 4.0


def _within(low: float, high: float, low_open: bool, unit: str):
    """A check: a finite number in ``(low, high]`` (``low_open``) or ``[low, high]``."""
    bracket = "(" if low_open else "["
    allowed = f"must be a finite number in {bracket}{low:g}, {high:g}] ({unit})"

    def check(v: float) -> str | None:
        ok = math.isfinite(v) and low <= v <= high and not (low_open and v == low)
        return None if ok else allowed

    return check


@dataclass(frozen=True)
class LogDistanceParams(Params):
    """Parameters of the log-distance model (keys of ``[channel]``), with units; validated
    when made. The bounds refuse what no radio has (a 1 kW robot transmitter, a sensitivity
    above 0 dBm, a negative loss, shadowing beyond 20 dB): a typo rather than a scenario.
    """

    section = "channel"
    tx_power_dbm: float = param(20.0, _within(-60.0, 60.0, False, "dBm"), "log_distance: transmit power P_t, dBm")
    reference_distance_m: float = param(
        1.0, _within(0.0, 1e6, True, "metres, > 0"), "log_distance: reference distance d0, metres"
    )
    reference_loss_db: float = param(
        40.0,
        _within(0.0, 200.0, False, "dB"),
        "log_distance: path loss at d0, dB (free space at 2.4 GHz, 1 m: 40)",
    )
    path_loss_exponent: float = param(
        3.0, _within(0.0, 10.0, True, "> 0; 2 is free space"), "log_distance: path loss exponent n (3-4 indoors)"
    )
    sensitivity_dbm: float = param(
        -80.0, _within(-200.0, 0.0, False, "dBm"), "log_distance: a frame is received when P_r >= sensitivity, dBm"
    )
    shadowing_sigma_db: float = param(
        0.0,
        _within(0.0, 20.0, False, "dB; 0 turns shadowing off"),
        "log_distance: shadowing sigma, dB (0: off)",
    )
    shadowing_decorrelation_m: float = param(
        10.0,
        _within(0.0, 1e6, True, "metres, > 0"),
        "log_distance: Gudmundson decorrelation distance d_corr, metres of pair travel",
    )
    wall_loss_db: float = param(
        5.0, _within(0.0, 100.0, False, "dB per wall"), "log_distance: loss per wall crossed on a map, dB"
    )

    def check(self) -> None:
        budget = self.tx_power_dbm - self.reference_loss_db - self.sensitivity_dbm
        if budget <= 0:
            raise ConfigError(
                "channel.sensitivity_dbm",
                self.sensitivity_dbm,
                f"must be below tx_power_dbm - reference_loss_db = {self.tx_power_dbm - self.reference_loss_db:g} dBm "
                "(otherwise no pair links even at the reference distance)",
            )

    @property
    def budget_db(self) -> float:
        """The loss a link can afford beyond ``PL(d0)``: ``P_t - PL(d0) - sensitivity``."""
        return self.tx_power_dbm - self.reference_loss_db - self.sensitivity_dbm

    # The law's distances, asked of the parameters by the models that are handed them (the
    # mobility models plan on the radio without importing it).
    def path_loss_db(self, distance_m) -> np.ndarray:
        """:func:`path_loss_db` under these parameters."""
        return path_loss_db(distance_m, self)

    def implied_range_m(self) -> float:
        """:func:`implied_range_m` under these parameters."""
        return implied_range_m(self)

    def effective_range_m(self, shadowing_db=0.0, walls=0) -> np.ndarray:
        """:func:`effective_range_m` under these parameters."""
        return effective_range_m(self, shadowing_db, walls)


def path_loss_db(distance_m, params: LogDistanceParams) -> np.ndarray:
    """``PL(d0) + 10 n log10(d / d0)``, and ``PL(d0)`` below ``d0`` (also at ``d = 0``)."""
    d = np.maximum(np.asarray(distance_m, dtype=float), params.reference_distance_m)
    return params.reference_loss_db + 10.0 * params.path_loss_exponent * np.log10(d / params.reference_distance_m)


def implied_range_m(params: LogDistanceParams) -> float:
    """The distance at which ``P_r`` equals the sensitivity without shadowing or walls."""
    return float(params.reference_distance_m * 10.0 ** (params.budget_db / (10.0 * params.path_loss_exponent)))


def effective_range_m(params: LogDistanceParams, shadowing_db=0.0, walls=0) -> np.ndarray:
    """The range of a pair whose shadowing is ``shadowing_db`` and whose line crosses ``walls``.

    While these stay constant, the pair is linked exactly when its distance is at most this
    range: what a link solver needs to turn a shadowing value into a distance threshold.
    When even ``d0`` is too far (``X + W`` above the budget) the range is 0: the pair never
    links (robots at the very same point excepted).

    >>> p = LogDistanceParams(shadowing_sigma_db=4.0)
    >>> [round(float(r), 6) for r in effective_range_m(p, [0.0, 30.0, 61.0])]
    [100.0, 10.0, 0.0]
    """
    margin = params.budget_db - np.asarray(shadowing_db, dtype=float) - params.wall_loss_db * np.asarray(walls)
    with np.errstate(over="ignore"):
        r = params.reference_distance_m * 10.0 ** (margin / (10.0 * params.path_loss_exponent))
    return np.where(margin >= 0, r, 0.0)


def reach_m(params: LogDistanceParams) -> float:
    """No pair farther apart than this can ever link: the range with the strongest shadowing
    gain allowed (``TRUNCATION_SIGMAS`` sigma). The channel's neighbour search radius."""
    return float(effective_range_m(params, -TRUNCATION_SIGMAS * params.shadowing_sigma_db))


class Pairs(NamedTuple):
    """A batch of (sender ``a``, receiver ``b``) pairs and what loss terms may need of them.

    ``travel_m`` is the sum of the two robots' path lengths since t = 0 (the pair's own
    clock for shadowing); None for robots that never move.
    """

    a: np.ndarray
    b: np.ndarray
    pos_a: np.ndarray | None  # None: no term needs positions (no map)
    pos_b: np.ndarray | None
    distance_m: np.ndarray
    travel_m: np.ndarray | None = None

    @classmethod
    def between(cls, a, b, positions_m, travel_m=None) -> Pairs:
        """Pairs ``(a[k], b[k])`` of robots at ``positions_m`` (plane, not a torus);
        ``travel_m`` is per robot (odometers) and summed per pair."""
        a = np.asarray(a, dtype=np.int64)
        b = np.asarray(b, dtype=np.int64)
        positions_m = np.asarray(positions_m, dtype=float)
        pa, pb = positions_m[a], positions_m[b]
        d = np.hypot(pb[:, 0] - pa[:, 0], pb[:, 1] - pa[:, 1])
        travel = None if travel_m is None else np.asarray(travel_m, dtype=float)[a] + np.asarray(travel_m)[b]
        return cls(a, b, pa, pb, d, travel)

    def take(self, idx) -> Pairs:
        t = None if self.travel_m is None else self.travel_m[idx]
        pa = None if self.pos_a is None else self.pos_a[idx]
        pb = None if self.pos_b is None else self.pos_b[idx]
        return Pairs(self.a[idx], self.b[idx], pa, pb, self.distance_m[idx], t)


class LogDistanceLoss:
    """``PL(d0) + 10 n log10(d / d0)`` (``PL(d0)`` below ``d0``)."""

    def __init__(self, params: LogDistanceParams):
        self.params = params
        self.lowest_db = params.reference_loss_db

    def loss_db(self, pairs: Pairs) -> np.ndarray:
        return path_loss_db(pairs.distance_m, self.params)


class ShadowingLoss:
    """The pair's shadowing ``X`` (dB), from a :class:`~netsim.radio.shadowing.PairShadowing`."""

    def __init__(self, shadowing):
        self.shadowing = shadowing
        self.lowest_db = -TRUNCATION_SIGMAS * shadowing.sigma_db

    def loss_db(self, pairs: Pairs) -> np.ndarray:
        travel = np.zeros(len(pairs.a)) if pairs.travel_m is None else pairs.travel_m
        return self.shadowing.sample(pairs.a, pairs.b, travel)


class WallLoss:
    """``wall_loss_db`` per wall (run of occupied cells) the straight line crosses"""

    def __init__(self, occupancy, wall_loss_db: float):
        self.occupancy = occupancy
        self.wall_loss_db = float(wall_loss_db)
        self.lowest_db = 0.0

    def loss_db(self, pairs: Pairs) -> np.ndarray:
        from netsim.world.los import walls_crossed

        walls = walls_crossed(self.occupancy, pairs.pos_a, pairs.pos_b)
        return self.wall_loss_db * walls


class RangeLoss:
    """The unit disk: 0 dB within the sender's range (scalar or one per robot), infinite beyond."""

    def __init__(self, range_m):
        self.range_m = np.asarray(range_m, dtype=float)
        self.lowest_db = 0.0

    def loss_db(self, pairs: Pairs) -> np.ndarray:
        r = self.range_m if self.range_m.ndim == 0 else self.range_m[pairs.a]
        return np.where(pairs.distance_m <= r, 0.0, np.inf)


class LineOfSightLoss:
    """0 dB when no occupied cell lies between the two robots, infinite otherwise."""

    def __init__(self, occupancy):
        self.occupancy = occupancy
        self.lowest_db = 0.0

    def loss_db(self, pairs: Pairs) -> np.ndarray:
        from netsim.world.los import walls_crossed

        walls = walls_crossed(self.occupancy, pairs.pos_a, pairs.pos_b)
        return np.where(walls == 0, 0.0, np.inf)


class LossChain:
    """The sum of loss terms, evaluated in order."""

    def __init__(self, *terms):
        self.terms = tuple(terms)
        # Least loss the terms from index i onward can add (for dropping pairs early).
        floors = [t.lowest_db for t in self.terms]
        self._rest = [float(sum(floors[i:])) for i in range(len(floors))]

    def loss_db(self, pairs: Pairs) -> np.ndarray:
        """Total loss of every pair (all terms evaluated on all pairs)."""
        total = np.zeros(len(pairs.a))
        for t in self.terms:
            total = total + t.loss_db(pairs)
        return total

    def receivable(self, pairs: Pairs, tx_power_dbm: float, sensitivity_dbm: float) -> np.ndarray:
        """Mask of the pairs with ``tx_power_dbm - loss >= sensitivity_dbm``.

        A pair leaves the batch as soon as it cannot make it, so later (costlier) terms,
        and shadowing draws, are spent only on pairs still in the running.
        """
        k = len(pairs.a)
        budget = tx_power_dbm - sensitivity_dbm
        alive = np.arange(k)
        loss = np.zeros(k)
        sub = pairs
        for i, term in enumerate(self.terms):
            # A small slack: dropping here must never disagree with the exact test below.
            keep = loss + self._rest[i] <= budget + 1e-9 * (1.0 + abs(budget))
            if not keep.all():
                alive, loss = alive[keep], loss[keep]
                sub = sub.take(keep)
                if len(alive) == 0:
                    break
            loss = loss + term.loss_db(sub)
        mask = np.zeros(k, dtype=bool)
        mask[alive[tx_power_dbm - loss >= sensitivity_dbm]] = True
        return mask


@dataclass(frozen=True)
class Propagation:
    """A loss chain with its power budget: what the channel asks who hears a frame.

    ``range_m`` is the implied range (no shadowing, no walls); ``reach_m`` the distance
    beyond which no pair is ever receivable (the neighbour search radius). A chain of any
    terms works: without ``fast`` the channel evaluates it term by term.
    """

    chain: LossChain
    tx_power_dbm: float
    sensitivity_dbm: float
    range_m: float
    reach_m: float
    # The model's one-pass path, ``fast(propagation, n_robots)`` (:class:`netsim.radio.fast.CompiledChain`
    # for the chains below); None: the generic one (:class:`netsim.radio.fast.GenericChain`).
    fast: Callable[[Propagation, int], Any] | None = None

    def receivable(self, pairs: Pairs) -> np.ndarray:
        return self.chain.receivable(pairs, self.tx_power_dbm, self.sensitivity_dbm)

    def received_dbm(self, pairs: Pairs) -> np.ndarray:
        """``P_r`` of every pair (``-inf`` where a term blocks): for interference sums."""
        return self.tx_power_dbm - self.chain.loss_db(pairs)


def log_distance(params: LogDistanceParams, shadowing=None, occupancy=None) -> Propagation:
    """Log-distance path loss, then shadowing (when given and sigma > 0), then walls (on a
    map, traced as :func:`netsim.world.los.walls_crossed` does).

    >>> prop = log_distance(LogDistanceParams())
    >>> pairs = Pairs.between([0, 0], [1, 2], [[0.0, 0.0], [100.0, 0.0], [100.5, 0.0]])
    >>> prop.receivable(pairs).tolist()
    [True, False]
    """
    terms: list = [LogDistanceLoss(params)]
    if shadowing is not None and shadowing.sigma_db > 0:
        terms.append(ShadowingLoss(shadowing))
    if occupancy is not None and params.wall_loss_db > 0:
        terms.append(WallLoss(occupancy, params.wall_loss_db))
    reach = reach_m(params) if len(terms) > 1 and isinstance(terms[1], ShadowingLoss) else implied_range_m(params)
    return Propagation(
        LossChain(*terms), params.tx_power_dbm, params.sensitivity_dbm, implied_range_m(params), reach, _compiled
    )


def unit_disk(range_m, occupancy=None) -> Propagation:
    """The paper's unit disk (a receiver within the sender's range), needing line of sight
    on a map (traced as :func:`netsim.world.los.walls_crossed` does)."""
    terms: list = [RangeLoss(range_m)]
    if occupancy is not None:
        terms.append(LineOfSightLoss(occupancy))
    r = float(np.max(range_m))
    return Propagation(LossChain(*terms), 0.0, 0.0, r, r, _compiled)


def _compiled(propagation: Propagation, n_robots: int) -> Any:
    from netsim.radio.fast import CompiledChain

    return CompiledChain(propagation, n_robots)
