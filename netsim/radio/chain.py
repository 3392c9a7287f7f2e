"""The loss chain: received power as a sum of small loss terms, and the radio that hears it.

Each term is a small object with ``loss_db(pairs) -> array`` over a batch of pairs
(:class:`Pairs`), vectorised, and ``lowest_db``, the least loss it can ever return. A
:class:`LossChain` sums its terms; asked only which pairs a :class:`Radio` hears, it
evaluates the terms in order and drops a pair as soon as the loss so far plus the least the
remaining terms can add exceeds the radio's budget ``P_t - sensitivity``. Cheap terms
first, then: walls are only traced for pairs that path loss and shadowing leave in range.

The log-distance law itself is computed in one place, the kernel
:func:`netsim.radio._kernels.path_loss_db`: the chain's term (:func:`path_loss_db`), the
compiled pass of a frame, the shared medium's interference and the receptions' power all
call it. The models that build chains are :mod:`netsim.radio.propagation`'s.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from netsim.compiled import load
from netsim.errors import NetsimInputError
from netsim.geometry import distances_m, pair_travels_m
from netsim.radio.shadowing import TRUNCATION_SIGMAS


def laws(values: int, n_robots: int | None = None) -> Any:
    """The radio's laws (:mod:`netsim.radio._kernels`), each one expression for a number or
    an array, for a batch of ``values`` of them in a run of ``n_robots`` (None: not known):
    compiled or plain as :func:`netsim.compiled.load` decides for any kernel."""
    return load("netsim.radio._kernels", n_robots, values=values)


def linear(db):
    """``10^(dB / 10)``: a power in dBm as mW, or a ratio in dB as a factor (the shared
    medium's powers and thresholds; no kernel needs it)."""
    return 10.0 ** (db / 10.0)


def in_db(factor):
    """``10 log10(factor)``: :func:`linear`'s inverse (a receiver's SINR, dB)."""
    return 10.0 * np.log10(factor)


class Radio(NamedTuple):
    """A robot's radio: the power it sends with and the weakest power it hears, dBm. The
    same for every propagation model that has a notion of power (the keys
    ``channel.tx_power_dbm`` and ``channel.sensitivity_dbm``, :class:`netsim.radio.propagation.RadioParams`).

    >>> Radio(20.0, -80.0).hears(np.array([99.0, 100.0, 101.0])).tolist()
    [True, True, False]
    """

    tx_power_dbm: float
    sensitivity_dbm: float

    @property
    def budget_db(self) -> float:
        """The most loss a frame can take and still be heard, ``P_t - sensitivity``, up to
        its rounding (the decision itself is the margin's sign, :meth:`margin_db`)."""
        return self.tx_power_dbm - self.sensitivity_dbm

    def received_dbm(self, loss_db):
        """``P_r = P_t - loss`` (:func:`netsim.radio._kernels.received_dbm`)."""
        return laws(np.size(loss_db)).received_dbm(self.tx_power_dbm, loss_db)

    def shadowing_db(self, path_loss_db, received_dbm):
        """The shadowing of a frame received at ``received_dbm`` after ``path_loss_db``:
        ``P_t - PL - P_r`` (:func:`netsim.radio._kernels.shadowing_of`).

        >>> Radio(20.0, -80.0).shadowing_db(np.array([90.0]), np.array([-72.0])).tolist()
        [2.0]
        """
        return laws(np.size(received_dbm)).shadowing_of(self.tx_power_dbm, path_loss_db, received_dbm)

    def hears(self, loss_db, n_robots: int | None = None):
        """Whether a frame after ``loss_db`` arrives at or above the sensitivity: the decision
        of a frame's compiled pass (:func:`netsim.radio._kernels.heard`), in a run of
        ``n_robots``."""
        return laws(np.size(loss_db), n_robots).heard(self.tx_power_dbm, loss_db, self.sensitivity_dbm)

    def margin_db(self, loss_db, n_robots: int | None = None):
        """How far above the sensitivity a frame after ``loss_db`` arrives: ``(P_t - loss) -
        sensitivity`` (:func:`netsim.radio._kernels.margin_db`; negative: not heard, and
        only then).

        >>> Radio(20.0, -80.0).margin_db(np.array([99.0, 100.0, 101.0])).tolist()
        [1.0, 0.0, -1.0]
        """
        return laws(np.size(loss_db), n_robots).margin_db(self.tx_power_dbm, loss_db, self.sensitivity_dbm)

    def above_sensitivity_db(self, received_dbm, n_robots: int | None = None):
        """How far above the sensitivity a frame received at ``received_dbm`` arrived
        (:func:`netsim.radio._kernels.above_sensitivity_db`), in a run of ``n_robots``."""
        return laws(np.size(received_dbm), n_robots).above_sensitivity_db(received_dbm, self.sensitivity_dbm)


# The unit disk has no power: its chain adds 0 dB within range and infinity beyond, heard
# with a budget of 0 dB.
NO_POWER = Radio(0.0, 0.0)


def path_loss_db(distance_m, params: Any, n_robots: int | None = None) -> np.ndarray:
    """``PL(d0) + 10 n log10(d / d0)``, and ``PL(d0)`` below ``d0`` (also at ``d = 0``), of
    every distance, under ``params`` (``reference_distance_m``, ``reference_loss_db``,
    ``path_loss_exponent``): the kernel :func:`netsim.radio._kernels.path_loss_db`, as a run
    of ``n_robots`` calls it (None: as many as the distances)."""
    d = np.asarray(distance_m, dtype=float)
    flat = d.reshape(-1)
    out = np.empty(flat.shape[0])
    kernels = load("netsim.radio._kernels", n_robots, values=flat.shape[0])
    n10 = 10.0 * params.path_loss_exponent
    kernels.path_losses_db(flat, params.reference_distance_m, params.reference_loss_db, n10, out)
    return out.reshape(d.shape)


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
    n_robots: int | None = None  # the team's size (None: the robots up to the largest id named)

    @classmethod
    def between(cls, a, b, positions_m, travel_m=None) -> Pairs:
        """Pairs ``(a[k], b[k])`` of the team whose robots are at ``positions_m`` (plane, not
        a torus); ``travel_m`` is per robot (odometers) and summed per pair."""
        a = np.asarray(a, dtype=np.int64)
        b = np.asarray(b, dtype=np.int64)
        positions_m = np.asarray(positions_m, dtype=float)
        pa, pb = positions_m[a], positions_m[b]
        d = distances_m(pa, pb, None, len(positions_m))
        travel = None if travel_m is None else pair_travels_m(travel_m, a, b)
        return cls(a, b, pa, pb, d, travel, len(positions_m))

    def team_size(self) -> int:
        """The team's size, which decides whether the laws run compiled: ``n_robots``, else
        the robots up to the largest id the pairs name."""
        if self.n_robots is not None:
            return self.n_robots
        return int(max(np.max(self.a), np.max(self.b))) + 1 if len(self.a) else 0

    def take(self, idx) -> Pairs:
        t = None if self.travel_m is None else self.travel_m[idx]
        pa = None if self.pos_a is None else self.pos_a[idx]
        pb = None if self.pos_b is None else self.pos_b[idx]
        return Pairs(self.a[idx], self.b[idx], pa, pb, self.distance_m[idx], t, self.n_robots)


class LogDistanceLoss:
    """``PL(d0) + 10 n log10(d / d0)`` (``PL(d0)`` below ``d0``): :func:`path_loss_db`."""

    def __init__(self, params: Any):
        self.params = params
        self.lowest_db = params.reference_loss_db

    def loss_db(self, pairs: Pairs) -> np.ndarray:
        return path_loss_db(pairs.distance_m, self.params, pairs.team_size())


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
        return laws(len(walls)).through_walls_db(0.0, self.wall_loss_db, walls)


class RangeLoss:
    """The unit disk: 0 dB within the sender's range (scalar or one per robot), infinite beyond."""

    def __init__(self, range_m):
        self.range_m = np.asarray(range_m, dtype=float)
        self.lowest_db = 0.0

    def loss_db(self, pairs: Pairs) -> np.ndarray:
        """The kernel :func:`netsim.radio._kernels.disk_losses`, the compiled pass's rule."""
        d = np.asarray(pairs.distance_m, dtype=float)
        out = np.empty(d.shape[0])
        load("netsim.radio._kernels", pairs.team_size()).disk_losses(d, pairs.a, np.atleast_1d(self.range_m), out)
        return out


class LineOfSightLoss:
    """0 dB when no occupied cell lies between the two robots, infinite otherwise."""

    def __init__(self, occupancy):
        self.occupancy = occupancy
        self.lowest_db = 0.0

    def loss_db(self, pairs: Pairs) -> np.ndarray:
        """The compiled pass's rule (:func:`netsim.radio._kernels.disk_pass`): the trace
        stops at the first wall."""
        from netsim.world.los import line_of_sight

        return np.where(line_of_sight(self.occupancy, pairs.pos_a, pairs.pos_b), 0.0, np.inf)


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

    def receivable(self, pairs: Pairs, radio: Radio) -> np.ndarray:
        """Mask of the pairs that ``radio`` hears: ``tx_power_dbm - loss >= sensitivity_dbm``.

        A pair leaves the batch as soon as it cannot make it, so later (costlier) terms,
        and shadowing draws, are spent only on pairs still in the running.
        """
        k = len(pairs.a)
        law = laws(k)
        slack_budget = law.with_slack(radio.budget_db)
        alive = np.arange(k)
        loss = np.zeros(k)
        sub = pairs
        for i, term in enumerate(self.terms):
            keep = law.may_be_heard(loss, self._rest[i], slack_budget)
            if not keep.all():
                alive, loss = alive[keep], loss[keep]
                sub = sub.take(keep)
                if len(alive) == 0:
                    break
            loss = loss + _checked_loss_db(term, sub)
        mask = np.zeros(k, dtype=bool)
        mask[alive[radio.hears(loss)]] = True
        return mask


def _checked_loss_db(term: Any, pairs: Pairs) -> np.ndarray:
    """``term.loss_db(pairs)``, refused in one line unless it is a loss a pair (or one for
    all) that is a number: a NaN would make the pair unheard without a word (``inf``, not
    NaN, blocks a pair)."""
    loss = np.asarray(term.loss_db(pairs), dtype=float)
    k = len(pairs.a)
    if loss.shape not in ((), (k,)):
        raise NetsimInputError(
            f"channel.propagation: {type(term).__name__}.loss_db gave shape {loss.shape} for {k} pairs, not ({k},)"
        )
    if np.isnan(loss).any():
        raise NetsimInputError(
            f"channel.propagation: {type(term).__name__}.loss_db gave NaN (a pair it blocks takes inf, dB)"
        )
    return loss
