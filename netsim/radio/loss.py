"""Reception loss models: small callables ``survives(sender, receivers, distances_m) -> mask``.

A model returns a boolean mask of the receptions that survive, or None when all do.
Its ``uses_distances`` says whether it reads the distances: the channel measures them only
for a model that does (or a radio), and passes None to one that does not. Each model
draws from the channel's own random stream. A model with nothing to draw (zero loss)
draws nothing, so that turning loss off does not shift other draws.

``channel.loss_model`` names one (entry points of the group ``netsim.loss``, or
``"package.module:attr"``): a :class:`~netsim.radio.models.LossModel` with its parameters
(keys of ``[channel]``) that makes the callable.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from netsim.errors import ConfigError
from netsim.params import Params, param, positive, probability
from netsim.radio.models import LossModel


class CheckedLoss:
    """A loss model from outside netsim, whose every answer is checked: None, or a boolean
    mask with one entry per receiver (an integer array would be read as indices, a
    probability as a mask of all True, a short mask would drop nothing). A wrong answer
    raises :class:`~netsim.errors.ConfigError` naming ``channel.loss_model``."""

    def __init__(self, survives: Callable, name: str):
        self.survives = survives
        self.name = name
        self.uses_distances = getattr(survives, "uses_distances", True)

    def __call__(self, sender: int, receivers: np.ndarray, distances_m: np.ndarray | None) -> np.ndarray | None:
        keep = self.survives(sender, receivers, distances_m)
        if keep is None:
            return None
        if isinstance(keep, np.ndarray) and keep.size == 0 and len(receivers) == 0:
            return keep.astype(bool)  # nobody to decide for: any empty array says so
        if not isinstance(keep, np.ndarray) or keep.dtype != np.bool_ or keep.shape != receivers.shape:
            if isinstance(keep, np.ndarray):
                got = f"an array of dtype {keep.dtype} and shape {keep.shape}"
            else:
                got = f"an object of type {type(keep).__name__}"
            raise ConfigError(
                "channel.loss_model",
                self.name,
                f"its survives(sender, receivers, distances_m) must return None or a bool array of shape "
                f"{receivers.shape} (one entry a receiver), not {got}",
            )
        return keep

    def __getattr__(self, name: str) -> Any:
        # The user's model as they wrote it (its counters, its parameters), through the check.
        survives = self.__dict__.get("survives")  # absent while a copy is being made
        if survives is None:
            raise AttributeError(name)
        return getattr(survives, name)


class BernoulliLoss:
    """Each reception is lost independently with probability ``p``."""

    uses_distances = False

    def __init__(self, p: float, rng: np.random.Generator):
        self.p = float(p)
        self.rng = rng

    def __call__(self, sender: int, receivers: np.ndarray, distances_m: np.ndarray | None) -> np.ndarray | None:
        if self.p == 0.0:
            return None
        return self.rng.random(len(receivers)) >= self.p


class DistanceLoss:
    """Reception probability ``(1 - p) (1 - (d / r)^k)`` for a sender of range ``r``.

    Certain (but for ``p``) next to the sender, falling smoothly to zero at the edge of
    the range; ``k`` sets how sharp the edge is (large ``k``: nearly a unit disk).
    """

    uses_distances = True

    def __init__(self, p: float, exponent: float, range_m: np.ndarray, rng: np.random.Generator):
        self.p = float(p)
        self.exponent = float(exponent)
        self.range_m = range_m
        self.rng = rng

    def __call__(self, sender: int, receivers: np.ndarray, distances_m: np.ndarray | None) -> np.ndarray:
        assert distances_m is not None  # uses_distances: the channel measures them
        ratio = distances_m / self.range_m[sender]
        p_receive = (1.0 - self.p) * (1.0 - ratio**self.exponent)
        return self.rng.random(len(receivers)) < p_receive


class GilbertElliottLoss:
    """Bursty loss: a two-state Markov chain per directed link (sender, receiver).

    The chain steps once per transmission on its link: first the state moves
    (good -> bad with ``p_gb``, bad -> good with ``p_bg``), then the reception is lost
    with the state's loss probability. A link's first transmission draws its state from
    the chain's stationary distribution, so there is no warm-up.
    """

    uses_distances = False

    def __init__(self, p_gb: float, p_bg: float, loss_good: float, loss_bad: float, n: int, rng: np.random.Generator):
        self.p_gb, self.p_bg = float(p_gb), float(p_bg)
        self.loss = np.array([loss_good, loss_bad], dtype=float)
        total = self.p_gb + self.p_bg
        self.p_bad_stationary = self.p_gb / total if total > 0 else 0.0
        self.n = int(n)
        self.rng = rng
        self._bad: dict[int, bool] = {}

    def __call__(self, sender: int, receivers: np.ndarray, distances_m: np.ndarray | None) -> np.ndarray:
        k = len(receivers)
        u = self.rng.random((k, 2))
        keep = np.empty(k, dtype=bool)
        bad_states = self._bad
        for j, r in enumerate(receivers.tolist()):
            key = sender * self.n + r
            bad = bad_states.get(key)
            if bad is None:
                bad = u[j, 0] < self.p_bad_stationary
            elif bad:
                bad = not (u[j, 0] < self.p_bg)
            else:
                bad = u[j, 0] < self.p_gb
            bad_states[key] = bad
            keep[j] = u[j, 1] >= self.loss[int(bad)]
        return keep


@dataclass(frozen=True)
class BernoulliParams(Params):
    section = "channel"
    loss_probability: float = param(0.0, probability, "Bernoulli loss per reception (also the floor of 'distance')")


@dataclass(frozen=True)
class DistanceParams(Params):
    section = "channel"
    loss_probability: float = param(0.0, probability, "loss per reception next to the sender")
    loss_distance_exponent: float = param(
        4.0, positive, "'distance': reception probability (1 - p)(1 - (d / r)^exponent)"
    )


@dataclass(frozen=True)
class GilbertElliottParams(Params):
    section = "channel"
    ge_p_good_to_bad: float = param(0.05, probability, "Gilbert-Elliott: P(good -> bad)")
    ge_p_bad_to_good: float = param(0.5, probability, "Gilbert-Elliott: P(bad -> good)")
    ge_loss_good: float = param(0.0, probability, "Gilbert-Elliott: loss in the good state")
    ge_loss_bad: float = param(1.0, probability, "Gilbert-Elliott: loss in the bad state")


Survives = Callable[[int, np.ndarray, "np.ndarray | None"], "np.ndarray | None"]


BERNOULLI = LossModel(
    BernoulliParams,
    lambda p, range_m, rng: BernoulliLoss(p.loss_probability, rng),
    default=True,
    lossless=lambda p: p.loss_probability == 0,
)
"""``channel.loss_model = "bernoulli"``."""


def _within_the_range(params: DistanceParams, channel: Any) -> None:
    """The law falls to no reception at the range: a radio that hears beyond it (shadowing)
    would have every such frame lost, its shadowing's links undone without a word."""
    if channel.propagation_model.shadowed(channel.radio):
        raise ConfigError(
            "channel.loss_model",
            "distance",
            "falls to no reception at the range: with channel.shadowing_sigma_db > 0 every frame heard "
            "beyond it would be lost; use 'bernoulli' or 'gilbert_elliott' beside the shadowing",
        )


DISTANCE = LossModel(
    DistanceParams,
    lambda p, range_m, rng: DistanceLoss(p.loss_probability, p.loss_distance_exponent, range_m, rng),
    check=_within_the_range,
)
"""``channel.loss_model = "distance"``."""

GILBERT_ELLIOTT = LossModel(
    GilbertElliottParams,
    lambda p, range_m, rng: GilbertElliottLoss(
        p.ge_p_good_to_bad, p.ge_p_bad_to_good, p.ge_loss_good, p.ge_loss_bad, len(range_m), rng
    ),
)
"""``channel.loss_model = "gilbert_elliott"``."""
