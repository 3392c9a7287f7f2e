"""Random direction's own rules: headings, speeds and turns, in the open and on a torus."""

import math

import numpy as np
import pandas as pd
import pytest
import simpy
from netsim.mobility.random_direction import RandomDirectionParams, direction_robot

from netsim import load
from netsim.area import Bounds
from netsim.errors import ConfigError
from netsim.state import RobotState


def _robots(params: RandomDirectionParams, until_s: float, torus: bool = False, n: int = 40) -> pd.DataFrame:
    """``n`` robots from the middle of a square of 1 km, each on its own stream."""
    env = simpy.Environment()
    st = RobotState(n, 1000.0, 10.0, torus=torus)
    st.place(np.full((n, 2), 500.0))
    for i in range(n):
        env.process(direction_robot(env, st, params, Bounds.square(1000.0), i, np.random.default_rng(i)))
    env.run(until=until_s)
    return st.legs()


def _first_moves(legs: pd.DataFrame) -> pd.DataFrame:
    return legs[legs["t_s"] == 0.0].groupby("robot").last()


@pytest.mark.parametrize("torus", [False, True])
def test_random_direction_headings_are_uniform_on_the_whole_circle(torus):
    """From the middle of the area every heading is open: a team leaves in all four quadrants."""
    first = _first_moves(_robots(RandomDirectionParams(), 1.0, torus))
    quadrant = np.floor(np.mod(np.arctan2(first["vy_mps"], first["vx_mps"]), 2 * math.pi) / (math.pi / 2))
    assert set(quadrant.tolist()) == {0.0, 1.0, 2.0, 3.0}


def test_random_direction_speeds_are_drawn_between_the_bounds():
    first = _first_moves(_robots(RandomDirectionParams(speed_min_mps=1.0, speed_max_mps=3.0), 1.0))
    speeds = np.hypot(first["vx_mps"], first["vy_mps"]).to_numpy()
    assert speeds.min() >= 1.0 and speeds.max() <= 3.0 and speeds.max() - speeds.min() > 1.0


def test_random_direction_on_a_torus_turns_every_turn_interval():
    legs = _robots(RandomDirectionParams(turn_interval_s=10.0), 25.0, torus=True, n=1)
    moves = legs.groupby("t_s").last()
    assert moves.index.tolist() == [0.0, 10.0, 20.0]
    assert moves["cause"].tolist() == ["start", "turn", "turn"]


def test_random_direction_needs_a_top_speed_above_zero():
    with pytest.raises(ConfigError, match="must be > 0 for random direction"):
        load(None, ["mobility.model=random_direction", "mobility.speed_min_mps=0", "mobility.speed_max_mps=0"])
