"""The speed keys that random waypoint and random direction share."""

from __future__ import annotations

from dataclasses import dataclass

from netsim.errors import ConfigError
from netsim.params import Params, finite, non_negative, param, speed


@dataclass(frozen=True)
class SpeedParams(Params):
    """Speeds drawn uniformly on ``[speed_min_mps, speed_max_mps]``, and a pause."""

    section = "mobility"
    speed_min_mps: float = param(0.5, speed, "minimum speed, m/s")
    speed_max_mps: float = param(5.0, speed, "maximum speed, m/s")
    pause_s: float = param(2.0, finite(non_negative), "pause at each waypoint, or at the border, s")

    def check(self) -> None:
        if self.speed_min_mps > self.speed_max_mps:
            raise ConfigError(
                "mobility.speed_min_mps",
                self.speed_min_mps,
                f"must not exceed mobility.speed_max_mps = {self.speed_max_mps}",
            )
