"""The leg log's rules: what a jump is, where and when a leg ends, a torus run folded."""

import numpy as np
import pandas as pd
import pytest

from netsim.trajectory import LegTable, folded_legs, jumped

COLUMNS = ["t_s", "robot", "x_m", "y_m", "vx_mps", "vy_mps"]


def _legs(rows):
    return pd.DataFrame(rows, columns=COLUMNS)


def test_a_jump_near_the_origin_is_a_nanometre_not_a_share_of_the_coordinates():
    """The threshold is 1e-9 times (1 m plus the coordinates' size): at the origin a
    move below a nanometre is the rounding of a leg's end, above it a jump."""
    assert jumped([[0.0, 0.0]], [[5e-10, 0.0]]).tolist() == [False]
    assert jumped([[0.0, 0.0]], [[2e-9, 0.0]]).tolist() == [True]


def test_a_jump_is_judged_on_the_size_of_both_positions_either_way():
    """Far out the threshold grows with both positions' coordinates: a millimetre and a
    half at a million metres is rounding (threshold about 2 mm), whichever way round."""
    far, moved = [[1e6, 0.0]], [[1e6 + 1.5e-3, 0.0]]
    assert jumped(far, moved).tolist() == jumped(moved, far).tolist() == [False]
    assert jumped(far, [[1e6 + 3e-3, 0.0]]).tolist() == [True]


def test_a_legs_end_joined_by_the_next_leg_is_that_legs_start_as_logged():
    """Where the next leg follows without a jump, the end the movement files write is the
    waypoint logged, not the leg's motion recomputed to that instant (which rounds)."""
    legs = _legs([(0.0, 0, 0.1, 0.0, 0.7, 0.3), (0.3, 0, 0.31 + 1e-12, 0.09, 0.0, 0.0)])
    t_end, xy, jump = LegTable(legs, 1).ends(1.0)
    assert t_end.tolist() == [0.3, 1.0] and jump.tolist() == [False, False]
    assert xy[0].tolist() == [0.31 + 1e-12, 0.09]


def test_a_jump_at_the_runs_last_instant_is_still_a_jump_at_a_legs_end():
    """A next leg that starts at the duration itself follows the leg: a jump there is
    written, and the leg ends where the robot was before it."""
    legs = _legs([(0.0, 0, 0.0, 0.0, 1.0, 0.0), (10.0, 0, 50.0, 0.0, 0.0, 0.0)])
    t_end, xy, jump = LegTable(legs, 1).ends(10.0)
    assert jump.tolist() == [True, False]
    assert xy[0].tolist() == [10.0, 0.0]


def test_a_leg_ends_at_the_duration_when_the_next_starts_after_it():
    """End times are cut at the run's duration, whether the next leg starts later or none does."""
    legs = _legs([(0.0, 0, 0.0, 0.0, 1.0, 0.0), (10.0, 0, 10.0, 0.0, 0.0, 0.0), (0.0, 1, 5.0, 5.0, 0.0, 0.0)])
    table = LegTable(legs, 2)
    assert table.end_times(4.0).tolist() == [4.0, 4.0, 4.0]
    assert table.ends(4.0)[1][0].tolist() == [4.0, 0.0]


def test_a_torus_leg_from_a_border_leaving_across_it_is_not_cut_at_its_start():
    """A leg that starts on a border and leaves across it starts on the opposite border: no
    border-and-jump pair at its first instant, only at the border it reaches later."""
    legs = pd.DataFrame(
        {"t_s": [0.0], "robot": [0], "x_m": [100.0], "y_m": [50.0], "vx_mps": [-10.0], "vy_mps": [0.0]}
        | {"cause": ["start"]}
    )
    folded = folded_legs(legs, 1, 100.0, 15.0)
    assert folded[["t_s", "x_m", "cause"]].values.tolist() == [
        [0.0, 100.0, "start"],
        [10.0, 0.0, "border"],
        [10.0, 100.0, "jump"],
    ]


def test_a_torus_runs_legs_after_the_duration_are_left_out():
    """Folding keeps the run up to its duration: a leg logged after it makes no row."""
    legs = pd.DataFrame(
        {"t_s": [0.0, 20.0], "robot": [0, 0], "x_m": [10.0, 30.0], "y_m": [10.0, 10.0]}
        | {"vx_mps": [1.0, 1.0], "vy_mps": [0.0, 0.0], "cause": ["start", "waypoint"]}
    )
    folded = folded_legs(legs, 1, 100.0, 15.0)
    assert folded.t_s.tolist() == [0.0]
    assert np.all(folded.t_s <= 15.0)


@pytest.mark.parametrize("stops", [False, True])
def test_a_torus_leg_that_reaches_a_border_at_its_end_is_folded_there(stops):
    """A border reached at the leg's last instant (the duration, or the start of a leg that
    stops there) is a border reached: the robot is put on the opposite one then."""
    rows = {"t_s": [0.0], "robot": [0], "x_m": [90.0], "y_m": [50.0], "vx_mps": [1.0], "vy_mps": [0.0]}
    legs = pd.DataFrame(rows | {"cause": ["start"]})
    if stops:
        legs = pd.concat([legs, legs.assign(t_s=10.0, x_m=100.0, vx_mps=0.0, cause="waypoint")], ignore_index=True)
    folded = folded_legs(legs, 1, 100.0, 20.0 if stops else 10.0)
    assert folded[["t_s", "x_m", "cause"]].values.tolist()[1:3] == [[10.0, 100.0, "border"], [10.0, 0.0, "jump"]]


def test_positions_sampled_on_a_torus_are_folded_into_the_square():
    """A torus run's legs run on past the borders; its sampled positions are in the square."""
    from netsim.trajectory import sample_positions

    legs = _legs([(0.0, 0, 90.0, 5.0, 4.0, -1.0)])
    got = sample_positions(legs, 1, [0.0, 5.0, 10.0], 100.0, torus=True)
    assert got[["x_m", "y_m"]].values.tolist() == [[90.0, 5.0], [10.0, 0.0], [30.0, 95.0]]
    plane = sample_positions(legs, 1, [10.0])
    assert plane[["x_m", "y_m"]].values.tolist() == [[130.0, -5.0]]
