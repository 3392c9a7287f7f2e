"""A user's own propagation model: two-ray ground reflection (ns-3's
``TwoRayGroundPropagationLossModel``), the example of docs/plugins.md, tested end to end by
tests/test_channel_plugins.py.

Free space (Friis) up to the crossover distance ``d_c = 4 pi h^2 / lambda``, beyond it the
ground-reflected ray's ``40 log10(d) - 20 log10(h_t h_r)``. Its chain has one term of its
own, so the channel evaluates it on the generic (numpy) path.
"""

import math
from dataclasses import dataclass

import numpy as np

from netsim.params import finite, param, positive
from netsim.radio.models import PropagationModel
from netsim.radio.propagation import LossChain, Propagation, RadioParams

SPEED_OF_LIGHT_MPS = 299_792_458.0


@dataclass(frozen=True)
class TwoRayParams(RadioParams):
    """Two-ray's own keys; transmit power and sensitivity are the radio's."""

    antenna_height_m: float = param(1.5, finite(positive), "two_ray: height of every antenna above the ground, m")
    frequency_hz: float = param(2.4e9, finite(positive), "two_ray: carrier frequency, Hz")


def loss_db(distance_m, params: TwoRayParams) -> np.ndarray:
    """Path loss at ``distance_m`` (at least 1 m)."""
    d = np.maximum(np.asarray(distance_m, dtype=float), 1.0)
    wavelength_m = SPEED_OF_LIGHT_MPS / params.frequency_hz
    h = params.antenna_height_m
    crossover_m = 4.0 * math.pi * h * h / wavelength_m
    friis = 20.0 * np.log10(4.0 * math.pi * d / wavelength_m)
    ground = 40.0 * np.log10(d) - 40.0 * math.log10(h)
    return np.where(d < crossover_m, friis, ground)


def implied_range_m(params: TwoRayParams) -> float:
    """Where the received power falls to the sensitivity (the loss grows with distance)."""
    budget = params.radio.budget_db
    lo, hi = 1.0, 1e7
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if loss_db(mid, params) <= budget else (lo, mid)
    return lo


class TwoRayLoss:
    """The chain's one term: ``loss_db(pairs)`` over a batch of pairs, and the least loss."""

    def __init__(self, params: TwoRayParams):
        self.params = params
        self.lowest_db = float(loss_db(1.0, params))

    def loss_db(self, pairs) -> np.ndarray:
        return loss_db(pairs.distance_m, self.params)


def make(params: TwoRayParams, range_m, occupancy, rng) -> Propagation:
    r = implied_range_m(params)
    return Propagation(LossChain(TwoRayLoss(params)), params.radio, r, r)


# A deterministic model of distance alone: its links are the unit disk of its implied
# range (ranges), solved exactly as the unit disk's are.
PLUGIN = PropagationModel(TwoRayParams, make, ranges=implied_range_m, reach=implied_range_m)
