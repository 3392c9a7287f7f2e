"""A user's own controller plugin with its own configuration section, ``[separation]``:
the kind of plugin docs/plugins.md shows, tested end to end by
tests/test_user_plugin.py."""

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from netsim.control import ControlStep
from netsim.params import Params, param, positive
from netsim.plugins import Parts, PluginSpec


@dataclass(frozen=True)
class SeparationParams(Params):
    section = "separation"
    min_distance_m: float = param(2.0, positive, "closest approach counted as too close, metres")


def build(params: SeparationParams, parts: Parts):
    def hook(step: ControlStep) -> None:
        pairs = cKDTree(step.positions_m).query_pairs(params.min_distance_m, output_type="ndarray")
        too_close = np.unique(pairs) if len(pairs) else np.empty(0, dtype=int)
        step.record("too_close", robots=int(len(too_close)), pairs=int(len(pairs)))

    return hook


PLUGIN = PluginSpec(
    Params=SeparationParams,
    build=build,
    tables={"too_close": {"t_s": "float64", "robots": "int64", "pairs": "int64"}},
)
