"""Two example controllers for the control loop (:mod:`netsim.control`), one of each kind.

A controller plugin builds a controller (``build(params, parts) -> controller``); the
controller is called once per control step with a :class:`~netsim.control.ControlStep`.
These two have no parameters of their own and read ``[control.options]``. Name them in
the configuration::

    [control]
    controllers = ["avoid_collisions", "log_separation"]   # or "mypackage.mymodule:factory"

    [control.options]
    min_separation_m = 2.0
"""

from __future__ import annotations

import numpy as np

from netsim.control import ControlStep
from netsim.geometry import in_box, in_motion
from netsim.metrics import nearest_spacing
from netsim.params import NoParams
from netsim.plugins import Parts, PluginSpec
from netsim.topology import geometric_pairs


def _min_separation_m(step: ControlStep) -> float:
    return float(step.options.get("min_separation_m", 1.0))


def avoid_collisions(params: NoParams, parts: Parts):
    """A simple collision avoidance: a robot whose planned step would end within
    ``min_separation_m`` of where another robot's step ends holds its position instead.

    Runs among the user controllers (before the coverage controller secures the plan, so
    with coverage on it stops leaders, and their members stop with them). Holding is
    always safe for connectivity."""

    def controller(step: ControlStep) -> None:
        sep, side = _min_separation_m(step), step.torus_side_m
        for _ in range(3):  # a robot that holds can stop another: settle in a few passes
            end = in_box(step.positions_m + step.velocity_mps * step.period_s, side, len(step.positions_m))
            moving = in_motion(step.velocity_mps)
            i, j, _ = geometric_pairs(end, sep, side)
            if len(i) == 0:
                return
            stop = np.unique(np.concatenate([i[moving[i]], j[moving[j]]]))
            if len(stop) == 0:
                return
            step.velocity_mps[stop] = 0.0

    return controller


def log_separation(params: NoParams, parts: Parts):
    """A logging hook: records, at every control step, the smallest distance between two
    robots and how many pairs are closer than ``min_separation_m``, in a table
    ``separation`` (``separation.parquet``)."""

    def hook(step: ControlStep) -> None:
        sep, side = _min_separation_m(step), step.torus_side_m
        # A step's positions are folded into [0, side) on a torus, as nearest_spacing takes them.
        step.record(
            "separation",
            min_distance_m=float(nearest_spacing(step.positions_m, side).min()),
            pairs_closer_than_min=len(geometric_pairs(step.positions_m, sep, side)[0]),
        )

    return hook


AVOID_COLLISIONS = PluginSpec(Params=NoParams, build=avoid_collisions)
LOG_SEPARATION = PluginSpec(
    Params=NoParams,
    build=log_separation,
    tables={"separation": {"t_s": "float64", "min_distance_m": "float64", "pairs_closer_than_min": "int64"}},
)
