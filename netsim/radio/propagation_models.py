"""Propagation models: who can hear a frame, the table ``channel.propagation`` chooses from.

- ``"unit_disk"`` (the default, the paper's model): a frame from ``i`` reaches the robots
  within ``i``'s range (``channel.range_m``); on a map (``world.map``) a link also needs line
  of sight (no occupied cell on the straight line between the two robots).
- ``"log_distance"``: received power ``P_r = P_t - PL(d0) - 10 n log10(d / d0) - X - W``
  (:mod:`netsim.radio.propagation`), receivable when ``P_r >= sensitivity``; ``X`` is the
  pair's log-normal shadowing (:mod:`netsim.radio.shadowing`), ``W`` the loss of the walls
  crossed on a map. ``channel.range_m`` does not apply: every robot's range is the implied
  range, where ``P_r`` equals the sensitivity without shadowing or walls.

Each entry of :data:`PROPAGATION_MODELS` has its parameters (keys of ``[channel]``), the
robots' link ranges, and makes the reception decision (a
:class:`~netsim.radio.propagation.Propagation`, or None for a plain unit disk, which the
channel decides by distance alone, as before). The channel's reception is then a chain:
propagation (range or path loss), walls, shadowing, and the loss model last
(:mod:`netsim.radio.loss`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from netsim.errors import ConfigError
from netsim.params import Params
from netsim.radio.propagation import LogDistanceParams, Propagation, implied_range_m, log_distance, unit_disk


@dataclass(frozen=True)
class UnitDiskParams(Params):
    """The unit disk has no keys of its own (its range is ``channel.range_m``)."""

    section = "channel"


def _unit_disk(params, range_m: np.ndarray, occupancy, rng) -> Propagation | None:
    return None if occupancy is None else unit_disk(range_m, occupancy)


def _log_distance(params: LogDistanceParams, range_m: np.ndarray, occupancy, rng) -> Propagation:
    from netsim.radio.shadowing import PairShadowing

    shadowing = None
    if params.shadowing_sigma_db > 0:
        shadowing = PairShadowing(
            params.shadowing_sigma_db, params.shadowing_decorrelation_m, rng, n_robots=len(range_m)
        )
    return log_distance(params, shadowing, occupancy)


class PropagationModel(NamedTuple):
    """A propagation model: its parameters; ``ranges(params, range_m)``, the robots' link
    ranges (None: ``channel.range_m``); ``make(params, range_m, occupancy, rng)``, the
    reception decision (None: a unit disk by distance alone); ``shadowed(params)``, whether
    links are random (link events are then the channel's decisions, not solved)."""

    Params: type[Params]
    ranges: Callable[[Any], float | None]
    make: Callable[[Any, np.ndarray, Any, np.random.Generator], Propagation | None]
    shadowed: Callable[[Any], bool]
    walled: Callable[[Any], bool]


PROPAGATION_MODELS: dict[str, PropagationModel] = {
    "unit_disk": PropagationModel(UnitDiskParams, lambda p: None, _unit_disk, lambda p: False, lambda p: True),
    "log_distance": PropagationModel(
        LogDistanceParams,
        implied_range_m,
        _log_distance,
        lambda p: p.shadowing_sigma_db > 0,
        lambda p: p.wall_loss_db > 0,
    ),
}


def propagation_name(key: str, value: Any) -> str:
    if not isinstance(value, str) or value not in PROPAGATION_MODELS:
        raise ConfigError(key, value, "must be one of " + ", ".join(repr(n) for n in PROPAGATION_MODELS))
    return value
