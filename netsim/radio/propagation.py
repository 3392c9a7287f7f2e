"""Received power as a chain of small loss terms, the way ns-3 chains propagation loss models.

Under the log-distance model a frame from ``a`` reaches ``b`` with power

    P_r = P_t - PL(d0) - 10 n log10(d / d0) - X - W      (dBm)

and is receivable when ``P_r >= sensitivity``. ``X`` is the pair's shadowing
(:mod:`netsim.radio.shadowing`), ``W`` the loss of the walls the straight line between the
two robots crosses (:mod:`netsim.world.los`). Below the reference distance the path loss
stays ``PL(d0)``, as ns-3's ``LogDistancePropagationLossModel`` does.

The chain, its terms and the :class:`~netsim.radio.chain.Radio` that hears it (transmit
power and sensitivity, the same for every model with a notion of power: their keys are
:class:`RadioParams`') are :mod:`netsim.radio.chain`'s, re-exported here; the law ``PL(d)``
is computed by one kernel, :func:`netsim.radio._kernels.path_loss_db`. This module holds
:class:`Propagation` (a chain and its radio: what the channel asks who hears a frame), the
log-distance model's parameters, its distances (implied range, effective range, reach) and
the two built-in chains.

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
from typing import Any

import numpy as np

from netsim.compiled import filled, load
from netsim.errors import ConfigError
from netsim.params import Params, param
from netsim.radio.chain import (
    NO_POWER,
    LineOfSightLoss,
    LogDistanceLoss,
    LossChain,
    Pairs,
    Radio,
    RangeLoss,
    ShadowingLoss,
    WallLoss,
    path_loss_db,
)
from netsim.radio.fast import CompiledChain, one_pass
from netsim.radio.shadowing import TRUNCATION_SIGMAS

__all__ = [
    "TRUNCATION_SIGMAS",
    "LineOfSightLoss",
    "LogDistanceLoss",
    "LogDistanceParams",
    "LossChain",
    "Pairs",
    "Propagation",
    "Radio",
    "RadioParams",
    "RangeLoss",
    "ShadowingLoss",
    "WallLoss",
    "effective_range_m",
    "implied_range_m",
    "log_distance",
    "path_loss_db",
    "reach_m",
    "unit_disk",
]


@dataclass(frozen=True)
class Propagation:
    """A loss chain and the radio it is heard with: what the channel asks who hears a frame.

    ``radio`` is the robots' :class:`Radio` (every robot sends with the same power);
    ``range_m`` is the implied range (no shadowing, no walls); ``reach_m`` the distance
    beyond which no pair is ever receivable (the neighbour search radius). A chain of any
    terms works: one of a model's own terms, with no ``fast``, is evaluated term by term.
    """

    chain: LossChain
    radio: Radio
    range_m: float
    reach_m: float
    # The model's one-pass path, ``fast(propagation, n_robots)`` (:class:`netsim.radio.fast.CompiledChain`
    # for the built-in chains); None: netsim.radio.fast.one_pass decides (the compiled pass
    # for a chain of built-in terms, else the generic one, :class:`netsim.radio.fast.GenericChain`).
    fast: Callable[[Propagation, int], Any] | None = None

    def receivable(self, pairs: Pairs) -> np.ndarray:
        """Mask of the pairs the radio hears: the one pass a run's channel takes
        (:func:`netsim.radio.fast.one_pass`: the model's ``fast``, or the compiled pass of a
        chain of built-in terms, whoever built it), else, for a model's own terms, its chain
        term by term (:meth:`LossChain.receivable`). The pairs of one batch must be distinct
        (a broadcast's receivers are): the compiled pass draws each pair's shadowing once."""
        path = one_pass(self)
        if path is None:
            return self.chain.receivable(pairs, self.radio)
        return path(self, pairs.team_size()).receivable(pairs)

    def received_dbm(self, pairs: Pairs) -> np.ndarray:
        """``P_r`` of every pair (``-inf`` where a term blocks), term by term. Like
        :meth:`receivable`, a call steps the pairs' shadowing to their travel (a draw for a
        pair not seen yet): the power of a run's frame as its channel decided it is
        :meth:`netsim.radio.reception.Reception.received_dbm`, which reads it."""
        return self.radio.received_dbm(self.chain.loss_db(pairs))


def _within(low: float, high: float, low_open: bool, unit: str):
    """A check: a finite number in ``(low, high]`` (``low_open``) or ``[low, high]``."""
    bracket = "(" if low_open else "["
    allowed = f"must be a finite number in {bracket}{low:g}, {high:g}] ({unit})"

    def check(v: float) -> str | None:
        ok = math.isfinite(v) and low <= v <= high and not (low_open and v == low)
        return None if ok else allowed

    return check


@dataclass(frozen=True)
class RadioParams(Params):
    """The radio's keys of ``[channel]``: transmit power and sensitivity, declared once for
    every propagation model with a notion of power (which extends this class with its own
    keys), and read as one :class:`~netsim.radio.chain.Radio`."""

    section = "channel"
    tx_power_dbm: float = param(20.0, _within(-60.0, 60.0, False, "dBm"), "radio: transmit power P_t, dBm")
    sensitivity_dbm: float = param(
        -80.0, _within(-200.0, 0.0, False, "dBm"), "radio: a frame is received when P_r >= sensitivity, dBm"
    )

    @property
    def radio(self) -> Radio:
        """The robots' radio under these keys."""
        return Radio(self.tx_power_dbm, self.sensitivity_dbm)


@dataclass(frozen=True)
class LogDistanceParams(RadioParams):
    """Parameters of the log-distance model (keys of ``[channel]``), with units; validated
    when made, the radio's (:class:`RadioParams`) with the law's own. The bounds refuse what
    no radio has (a 1 kW robot transmitter, a sensitivity above 0 dBm, a negative loss,
    shadowing beyond 20 dB): a typo rather than a scenario.
    """

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
    def path_loss_db(self, distance_m, n_robots: int | None = None) -> np.ndarray:
        """:func:`path_loss_db` under these parameters (``n_robots``: the team's size, which
        decides whether the law runs compiled; None: as many as the distances)."""
        return path_loss_db(distance_m, self, n_robots)

    def loss_db(self, distance_m, shadowing_db=0.0, walls=0, n_robots: int | None = None) -> np.ndarray:
        """A pair's loss as a frame's decision sums it: ``(PL(d) + X) + W``, ``W`` the loss
        of ``walls`` walls crossed."""
        loss = self.path_loss_db(distance_m, n_robots) + shadowing_db
        law = load("netsim.radio._kernels", n_robots, values=np.size(loss))
        return law.through_walls_db(loss, self.wall_loss_db, np.asarray(walls))

    def margin_db(self, distance_m, shadowing_db=0.0, walls=0, n_robots: int | None = None) -> np.ndarray:
        """The pair's power margin over the sensitivity, ``Radio.margin_db`` of :meth:`loss_db`."""
        return self.radio.margin_db(self.loss_db(distance_m, shadowing_db, walls, n_robots), n_robots)

    def implied_range_m(self) -> float:
        """:func:`implied_range_m` under these parameters."""
        return implied_range_m(self)

    def effective_range_m(self, shadowing_db=0.0, walls=0, n_robots: int | None = None) -> np.ndarray:
        """:func:`effective_range_m` under these parameters."""
        return effective_range_m(self, shadowing_db, walls, n_robots)


def implied_range_m(params: LogDistanceParams) -> float:
    """The distance at which ``P_r`` equals the sensitivity without shadowing or walls."""
    kernels = load("netsim._kernels", 1)
    return float(
        kernels.range_at_margin_m(float(params.budget_db), params.reference_distance_m, params.path_loss_exponent)
    )


def effective_range_m(params: LogDistanceParams, shadowing_db=0.0, walls=0, n_robots: int | None = None) -> np.ndarray:
    """The range of a pair whose shadowing is ``shadowing_db`` and whose line crosses ``walls``
    (``n_robots``: the team's size, which decides whether the law runs compiled; None: as
    many as the values).

    While these stay constant, the pair is linked exactly when its distance is at most this
    range: what a link solver needs to turn a shadowing value into a distance threshold.
    When even ``d0`` is too far (``X + W`` above the budget) the range is 0: the pair never
    links (robots at the very same point excepted).

    >>> p = LogDistanceParams(shadowing_sigma_db=4.0)
    >>> [round(float(r), 6) for r in effective_range_m(p, [0.0, 30.0, 61.0])]
    [100.0, 10.0, 0.0]
    """
    x_db, walls_db = np.broadcast_arrays(
        np.asarray(shadowing_db, dtype=float),
        load("netsim.radio._kernels", n_robots, values=np.size(walls)).through_walls_db(
            0.0, params.wall_loss_db, np.asarray(walls)
        ),
    )
    shape = x_db.shape
    x_flat, w_flat = (filled(a, shape).reshape(-1) for a in (x_db, walls_db))
    out = np.empty(x_flat.shape[0])
    with np.errstate(over="ignore"):
        kernels = load("netsim._kernels", n_robots, values=x_flat.shape[0])
        kernels.ranges_at_loss_m(
            x_flat, w_flat, float(params.budget_db), params.reference_distance_m, params.path_loss_exponent, out
        )
    return out.reshape(shape)


def reach_m(params: LogDistanceParams) -> float:
    """No pair farther apart than this can ever link: the range with the strongest shadowing
    gain allowed (``TRUNCATION_SIGMAS`` sigma). The channel's neighbour search radius."""
    return float(effective_range_m(params, -TRUNCATION_SIGMAS * params.shadowing_sigma_db))


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
    return Propagation(LossChain(*terms), params.radio, implied_range_m(params), reach, CompiledChain)


def unit_disk(range_m, occupancy=None) -> Propagation:
    """The paper's unit disk (a receiver within the sender's range), needing line of sight
    on a map (traced as :func:`netsim.world.los.walls_crossed` does)."""
    terms: list = [RangeLoss(range_m)]
    if occupancy is not None:
        terms.append(LineOfSightLoss(occupancy))
    r = float(np.max(range_m))
    return Propagation(LossChain(*terms), NO_POWER, r, r, CompiledChain)
