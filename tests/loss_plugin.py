"""A user's own loss model, the example of docs/plugins.md: every reception farther from
the sender than ``edge_fraction`` of its range is lost (a sharp edge inside the range)."""

from dataclasses import dataclass

import numpy as np

from netsim.params import Params, param, probability
from netsim.radio.models import LossModel


@dataclass(frozen=True)
class EdgeParams(Params):
    section = "channel"
    edge_fraction: float = param(0.5, probability, "edge: receptions beyond this fraction of the range are lost")


class EdgeLoss:
    uses_distances = True  # the channel measures the receivers' distances for it

    def __init__(self, fraction: float, range_m: np.ndarray):
        self.fraction = fraction
        self.range_m = range_m

    def __call__(self, sender: int, receivers: np.ndarray, distances_m: np.ndarray) -> np.ndarray:
        return distances_m <= self.fraction * self.range_m[sender]


PLUGIN = LossModel(EdgeParams, lambda params, range_m, rng: EdgeLoss(params.edge_fraction, range_m))


class CoinLoss:
    """Each reception lost with probability one half, drawn as a library would draw it:
    from the numpy ``Generator`` the model is handed."""

    uses_distances = False

    def __init__(self, rng: np.random.Generator):
        if not isinstance(rng, np.random.Generator):
            raise TypeError(f"a loss model's rng is a numpy Generator, not {type(rng).__name__}")
        self.random = rng.random  # bound once: every frame draws from this one stream

    def __call__(self, sender: int, receivers: np.ndarray, distances_m: np.ndarray | None) -> np.ndarray:
        return self.random(len(receivers)) >= 0.5


COIN = LossModel(EdgeParams, lambda params, range_m, rng: CoinLoss(rng))
