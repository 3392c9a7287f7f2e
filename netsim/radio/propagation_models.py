"""Propagation models: who can hear a frame, the built-in models ``channel.propagation`` names.

- ``"unit_disk"`` (the default, the paper's model): a frame from ``i`` reaches the robots
  within ``i``'s range (``channel.range_m``); on a map (``world.map``) a link also needs line
  of sight (no occupied cell on the straight line between the two robots).
- ``"log_distance"``: received power ``P_r = P_t - PL(d0) - 10 n log10(d / d0) - X - W``
  (:mod:`netsim.radio.propagation`), receivable when ``P_r >= sensitivity``; ``X`` is the
  pair's log-normal shadowing (:mod:`netsim.radio.shadowing`), ``W`` the loss of the walls
  crossed on a map. ``channel.range_m`` does not apply: every robot's range is the implied
  range, where ``P_r`` equals the sensitivity without shadowing or walls.

Each is a :class:`~netsim.radio.models.PropagationModel` (entry points of the group
``netsim.propagation``): its parameters (keys of ``[channel]``), the robots' link ranges,
and the reception decision it makes (a :class:`~netsim.radio.propagation.Propagation`, or
None for a plain unit disk, which the channel decides by distance alone). The channel's
reception is then a chain: propagation (range or path loss), walls, shadowing, and the
loss model last (:mod:`netsim.radio.loss`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from netsim.params import Params
from netsim.radio.models import PropagationModel
from netsim.radio.propagation import (
    LogDistanceParams,
    Propagation,
    implied_range_m,
    log_distance,
    reach_m,
    unit_disk,
)


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


def _power(params: LogDistanceParams, noise_floor_dbm: float, capture_threshold_db: float) -> Any:
    from netsim.radio.mac import PowerModel

    return PowerModel(params, noise_floor_dbm, capture_threshold_db)


UNIT_DISK = PropagationModel(UnitDiskParams, _unit_disk, default=True)
"""``channel.propagation = "unit_disk"``: the paper's model."""

LOG_DISTANCE = PropagationModel(
    LogDistanceParams,
    _log_distance,
    ranges=implied_range_m,
    reach=reach_m,
    shadowed=lambda p: p.shadowing_sigma_db > 0,
    power=_power,
)
"""``channel.propagation = "log_distance"``: path loss, shadowing and walls."""
