"""Every model's motion is checked against the area and the map's walls where legs change
(netsim.state.RobotState.check_motion): a robot that leaves is one line naming it and the
time, whichever model moved it."""

import numpy as np
import pytest

from netsim import load
from netsim.errors import NetsimInputError
from netsim.params import NoParams
from netsim.plugins import Parts, PluginSpec
from netsim.run import build, execute
from netsim.state import MotionError, RobotState
from netsim.tools.cli import main


def _runaway(params, parts: Parts):
    """Robot 0 leaves (100, 500) at 2 m/s eastward and never turns: it reaches x = 1000 at 450 s."""
    parts.state.place(np.array([[100.0, 500.0]] + [[500.0, 500.0]] * (parts.state.n - 1)))
    parts.state.set_leg(0, 0.0, (2.0, 0.0))


RUNAWAY = PluginSpec(Params=NoParams, build=_runaway)


def _turns_late(params, parts: Parts):
    """Robot 0 runs east past the border, then turns back inside at 500 s."""
    st, env = parts.state, parts.env
    st.place(np.array([[100.0, 500.0]] * st.n))
    st.set_leg(0, 0.0, (2.0, 0.0))

    def back():
        yield env.timeout(500.0)
        st.set_leg(0, env.now, (-2.0, 0.0))

    env.process(back())


TURNS_LATE = PluginSpec(Params=NoParams, build=_turns_late)


def _through_a_wall(params, parts: Parts):
    """On a map: robot 0 goes from a free cell straight into the nearest cell that is not
    free, and stops there at 10 s."""
    m, st, env = parts.occupancy, parts.state, parts.env
    xs, ys = m.cell_centres_m()
    gx, gy = np.meshgrid(xs, ys)
    cells = np.column_stack([gx.ravel(), gy.ravel()])
    b = st.bounds
    inner = (cells[:, 0] > b.x_min + 20) & (cells[:, 0] < b.x_max - 20)
    inner &= (cells[:, 1] > b.y_min + 20) & (cells[:, 1] < b.y_max - 20)
    free = cells[inner & m.is_free(cells)]
    wall = cells[inner & ~m.is_free(cells)]
    start = free[len(free) // 2]
    goal = wall[np.argmin(np.hypot(*(wall - start).T))]
    st.place(np.array([start] * st.n))
    st.set_leg(0, 0.0, (goal - start) / 10.0)

    def stop():
        yield env.timeout(10.0)
        st.arrive(0, env.now, goal)

    env.process(stop())


THROUGH_A_WALL = PluginSpec(Params=NoParams, build=_through_a_wall, respects_map=True)


def _config(model, *more):
    return load(
        None, [f"mobility.model=tests.test_motion_checks:{model}", "world.n_robots=2", "protocol.model=none", *more]
    )


def test_a_plugin_robot_still_outside_at_the_end_is_refused_naming_it_and_the_time():
    """A leg that leaves the area and is never ended is caught at the end of the run."""
    with pytest.raises(MotionError, match=r"^robot 0 leaves the area \[0, 1000\] x \[0, 1000\] at t = 450 s"):
        execute(_config("RUNAWAY", "duration_s=600"))


def test_a_plugin_robot_still_outside_at_the_end_is_refused_when_the_run_reports_progress():
    """The end-of-run check holds for a run advanced in reported parts as for one in one call."""
    sim = build(_config("RUNAWAY", "duration_s=600"))
    with pytest.raises(MotionError, match=r"^robot 0 leaves the area \[0, 1000\] x \[0, 1000\] at t = 450 s"):
        sim.run(progress=True, steps=4)


def test_a_plugin_robot_that_comes_back_is_still_refused():
    """A leg that leaves the area is caught when the robot's next leg starts."""
    sim = build(_config("TURNS_LATE", "duration_s=600"))
    with pytest.raises(MotionError, match=r"^robot 0 leaves the area .* at t = 450 s, at \(1000, 500\)"):
        sim.run(until_s=520.0)
    assert sim.now == 500.0


def test_a_plugin_robot_inside_for_the_whole_run_passes():
    """The check refuses nothing that stays inside: the same runaway, stopped at 400 s."""
    execute(_config("RUNAWAY", "duration_s=400"))


def test_a_robot_leaving_the_area_is_one_line_exit_2(tmp_path, capsys):
    out = tmp_path / "out"
    code = main(
        ["run", "--quiet", "--set", "mobility.model=tests.test_motion_checks:RUNAWAY", "--set", "world.n_robots=2"]
        + ["--set", "duration_s=600", "--set", "protocol.model=none", "--out", str(out)]
    )
    err = capsys.readouterr().err.splitlines()
    assert code == 2 and len(err) == 1 and err[0].startswith("netsim: error: robot 0 leaves the area")
    assert not out.exists()


def test_a_plugin_robot_crossing_a_wall_is_refused():
    """On a map, a leg that enters a cell that is not free is refused, naming the robot."""
    config = _config("THROUGH_A_WALL", "world.map=office", "world.side_m=200", "duration_s=12")
    with pytest.raises(MotionError, match=r"^robot 0 crosses a wall of the map at t = "):
        execute(config)


def test_a_jump_out_of_the_area_is_refused():
    st = RobotState(2, 100.0, 10.0)
    st.check_motion()
    st.place(np.array([[10.0, 10.0], [20.0, 20.0]]))
    with pytest.raises(MotionError, match=r"robot 1 jumps out of the area .* at t = 3 s, to \(150, 20\)"):
        st.set_leg(1, 3.0, (0.0, 0.0), start_m=(150.0, 20.0))
    assert issubclass(MotionError, NetsimInputError)


def test_a_state_without_the_check_holds_any_position():
    """Scratch states (tests, formats) are not checked unless asked."""
    st = RobotState(1, 100.0, 10.0)
    st.place(np.array([[10.0, 10.0]]))
    st.set_leg(0, 0.0, (100.0, 0.0))
    st.set_leg(0, 5.0, (0.0, 0.0))
    st.check_until(10.0)
    assert st.positions_at(10.0).tolist() == [[510.0, 10.0]]


@pytest.mark.parametrize(
    "positions, fragment",
    [
        ([[1.0, 2.0]], r"^2 robots need positions of shape \(2, 2\), not \(1, 2\)$"),
        ([[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]], r"^2 robots need positions of shape \(2, 2\), not \(2, 3\)$"),
        ([[1.0, 2.0], [np.nan, 5.0]], r"^robot 1 is placed at \(nan, 5\): a position must be finite$"),
        ([[np.inf, 2.0], [4.0, 5.0]], r"^robot 0 is placed at \(inf, 2\): a position must be finite$"),
        ([["a", "b"], ["c", "d"]], r"^the robots are placed at positions that are not numbers"),
    ],
)
def test_a_placement_that_is_no_position_is_refused_naming_it(positions, fragment):
    """Positions of the wrong shape, not numbers, or not finite are refused where they are
    placed (MotionError, one line: a NaN was carried through the run, then reported as
    leaving the area at the run's end)."""
    st = RobotState(2, 100.0, 10.0)
    with pytest.raises(MotionError, match=fragment):
        st.place(positions)


def test_a_velocity_that_is_not_finite_or_not_two_numbers_is_refused_where_it_is_set():
    """set_leg and set_legs refuse a velocity that is not finite, or not of two components
    (a third was dropped without a word), at the time it is set."""
    st = RobotState(3, 100.0, 10.0)
    st.place(np.full((3, 2), 50.0))
    with pytest.raises(MotionError, match=r"^robot 1 is given the velocity \(nan, 0\) m/s at t = 1 s: it must be fin"):
        st.set_leg(1, 1.0, (np.nan, 0.0))
    with pytest.raises(MotionError, match=r"^robot 0 is given the velocity \(4e\+08, 0\) m/s .*slower than light"):
        st.set_leg(0, 1.0, (4e8, 0.0))
    with pytest.raises(MotionError, match=r"^robot 2 is given a velocity of 3 components at t = 1 s, not 2$"):
        st.set_leg(2, 1.0, (1.0, 0.0, 0.0))
    with pytest.raises(MotionError, match=r"^robot 2 is given the velocity \(0, inf\) m/s at t = 2 s"):
        st.set_legs(np.array([0, 2]), 2.0, np.array([[0.0, 1.0], [0.0, np.inf]]))
    with pytest.raises(MotionError, match=r"^2 robots are given velocities of shape \(3,\) at t = 2 s, not \(2, 2\)$"):
        st.set_legs(np.array([0, 2]), 2.0, np.zeros(3))
    with pytest.raises(MotionError, match=r"^robot 0 jumps to \(nan, 1\.0\) at t = 3 s: a position is two finite"):
        st.set_leg(0, 3.0, (0.0, 0.0), start_m=(np.nan, 1.0))
    assert st.legs()["cause"].tolist() == ["start"] * 3  # nothing was kept of the refused legs


def _nan_controller(params, parts: Parts):
    def control(step):
        step.velocity_mps[0] = np.nan

    return control


NAN_CONTROLLER = PluginSpec(Params=NoParams, build=_nan_controller)


def test_a_controller_setting_a_nan_velocity_is_one_line_at_that_step(tmp_path, capsys):
    out = tmp_path / "out"
    code = main(
        ["run", "--quiet", "--set", 'control.controllers=["tests.test_motion_checks:NAN_CONTROLLER"]']
        + ["--set", "world.n_robots=3", "--set", "duration_s=50", "--set", "protocol.model=none"]
        + ["--set", "mobility.model=static", "--out", str(out)]
    )
    err = capsys.readouterr().err.splitlines()
    assert code == 2 and len(err) == 1, err
    assert err[0].startswith("netsim: error: robot 0 is given the velocity (nan, nan) m/s at t = 10.001 s")
    assert not out.exists()
