"""The controller interface (the paper's reserved interfaces) and its two shipped
examples: a collision-avoidance controller and a logging hook."""

import numpy as np
import pytest

from netsim import config
from netsim.errors import ConfigError, NetsimInputError
from netsim.params import NoParams
from netsim.plugins import PluginSpec
from netsim.run import execute


def _head_on(params, parts):
    """A user controller: every robot heads for the middle of the area at 2 m/s."""

    def controller(step):
        to_centre = step.side_m / 2 - step.positions_m
        dist = np.hypot(*to_centre.T)
        moving = dist > 1e-9
        step.velocity_mps[moving] = 2.0 * to_centre[moving] / dist[moving, None]
        step.velocity_mps[~moving] = 0.0

    return controller


HEAD_ON = PluginSpec(Params=NoParams, build=_head_on)


def _outward(params, parts):
    """A user controller: every robot heads along x away from the middle at 2 m/s (on a
    torus the two robots of ``two_robots`` meet across the seam)."""

    def controller(step):
        step.velocity_mps[:] = 0.0
        step.velocity_mps[:, 0] = np.where(step.positions_m[:, 0] < step.side_m / 2, -2.0, 2.0)

    return controller


OUTWARD = PluginSpec(Params=NoParams, build=_outward)


def two_robots(tmp_path, controllers, mobility="static", torus=False):
    csv = tmp_path / "two.csv"
    csv.write_text("x_m,y_m\n100,500\n900,500\n")
    return config.load(
        None,
        [
            "world.n_robots=2",
            f'world.placement="{csv}"',
            f'mobility.model="{mobility}"',
            *(["mobility.stationary_start=false"] if mobility == "random_waypoint" else []),
            'protocol.model="none"',
            "duration_s=300",
            "coverage.start_s=0",
            f"control.controllers={controllers!r}".replace("'", '"'),
            "control.options={min_separation_m=5.0}",
            f"world.torus={str(torus).lower()}",
        ],
    )


def test_avoid_collisions_stops_robots_short_of_the_minimum_separation(tmp_path):
    r = execute(two_robots(tmp_path, ["tests.test_controllers:HEAD_ON", "avoid_collisions", "log_separation"]))
    sep = r.frames["separation"]
    assert len(sep) >= 290
    assert sep["min_distance_m"].min() >= 5.0
    assert sep["min_distance_m"].iloc[-1] < 10.0  # they did come close
    assert (sep["pairs_closer_than_min"] == 0).all()


def test_on_a_torus_avoidance_and_separation_measure_across_the_seam(tmp_path):
    """Two robots meeting across a torus' seam: the avoidance holds them short of the
    separation and the log measures them to the nearest image (on the plane they stay
    800 m or more apart, and would pass through each other)."""
    r = execute(
        two_robots(tmp_path, ["tests.test_controllers:OUTWARD", "avoid_collisions", "log_separation"], torus=True)
    )
    sep = r.frames["separation"]
    assert sep["min_distance_m"].min() >= 5.0
    assert sep["min_distance_m"].iloc[-1] < 10.0  # they did come close, across the seam
    assert (sep["pairs_closer_than_min"] == 0).all()
    r = execute(two_robots(tmp_path, ["tests.test_controllers:OUTWARD", "log_separation"], torus=True))
    sep = r.frames["separation"]
    assert sep["min_distance_m"].min() < 5.0 and (sep["pairs_closer_than_min"] > 0).any()


def test_without_avoidance_the_same_robots_come_closer(tmp_path):
    r = execute(two_robots(tmp_path, ["tests.test_controllers:HEAD_ON", "log_separation"]))
    assert r.frames["separation"]["min_distance_m"].min() < 5.0


def test_logging_hook_observes_any_mobility_model(tmp_path):
    r = execute(two_robots(tmp_path, ["log_separation"], mobility="random_waypoint"))
    sep = r.frames["separation"]
    pos = r.frames["positions"]
    assert len(sep) >= 290
    # The logged metric is the true distance (positions sampled at the same instants).
    at = pos[pos["t_s"] == 100.0].sort_values("robot")[["x_m", "y_m"]].to_numpy()
    row = sep.iloc[(sep["t_s"] - 100.0).abs().argmin()]
    assert row["t_s"] == pytest.approx(100.001)
    assert row["min_distance_m"] == pytest.approx(np.hypot(*(at[0] - at[1])), abs=0.05)


def test_a_controller_may_not_fight_the_mobility_model(tmp_path):
    with pytest.raises(NetsimInputError, match="mobility.model = 'static'"):
        execute(two_robots(tmp_path, ["tests.test_controllers:HEAD_ON"], mobility="random_waypoint"))


def test_unknown_controller_is_a_config_error(tmp_path):
    with pytest.raises(ConfigError) as err:
        execute(two_robots(tmp_path, ["steer_by_magic"]))
    assert err.value.key == "control.controllers"


def _shrinks_the_range(params, parts):
    """A user controller that writes into the ranges it is shown."""

    def controller(step):
        step.range_m -= 5.0

    return controller


SHRINKS = PluginSpec(Params=NoParams, build=_shrinks_the_range)


def test_a_controller_cannot_write_the_robots_ranges(tmp_path):
    """``step.range_m`` was the robots' own array: a controller that subtracted from it
    shrank every robot's range during the run, and links.parquet, solved after the run
    from the final ranges, no longer matched what the channel had done."""
    with pytest.raises(ValueError, match="read-only"):
        execute(two_robots(tmp_path, ["tests.test_controllers:SHRINKS"]))


def test_control_options_changed_after_the_build_are_not_the_runs(tmp_path):
    """The run held the configuration's own ``[control.options]`` table: a script that
    changed it after ``build`` changed the run it had built."""
    from netsim.run import build

    cfg = two_robots(tmp_path, ["avoid_collisions"])
    sim = build(cfg)
    cfg.control.options["min_separation_m"] = 400.0
    seen = []
    sim.models["control"].before_apply.append(lambda step: seen.append(step.options["min_separation_m"]))
    sim.run(until_s=3.0)
    assert seen and set(seen) == {5.0}


def _loop(positions, period_s=1.0, start_s=0.5, lead_s=0.001, **loop):
    """A control loop on robots standing at ``positions`` (a core without models), its steps
    decided at start_s, start_s + period_s, ..."""
    from netsim.control import ControlLoop
    from tests.fixtures import static_core

    sim = static_core(positions, latency_s=lead_s)
    return sim, ControlLoop(sim.env, sim.state, sim.trace, period_s, start_s, lead_s, **loop)


def test_controllers_run_in_ascending_order_then_in_the_order_added():
    """At every step the controllers run by ``order`` (the coverage's proposal at 0, user
    controllers at 50, the safety at 100), those of one order as they were added."""
    sim, loop = _loop([[0.0, 0.0]])
    called = []
    for name, order in (("safety", 100), ("propose", 0), ("user a", 50), ("user b", 50)):
        loop.add(lambda step, name=name: called.append(name), order=order)
    sim.run(until_s=2.0)
    assert called == ["propose", "user a", "user b", "safety"] * 2


def test_a_loop_stopped_during_a_step_stops_every_robot_and_calls_no_controller_again():
    """A controller that stops the loop: the velocities of that step are all zero whatever
    was proposed, and no step follows."""
    sim, loop = _loop([[10.0, 10.0], [20.0, 10.0]])
    steps = []

    def controller(step):
        steps.append(step.t_s)
        step.velocity_mps[:] = [1.0, 0.5]
        if len(steps) == 2:
            loop.stop()

    loop.add(controller)
    sim.run(until_s=6.0)
    assert steps == [pytest.approx(0.501), pytest.approx(1.501)]
    assert (sim.state.velocity_mps == 0.0).all()
    # Moved at (1, 0.5) m/s from 0.501 s to 1.501 s, then stood.
    np.testing.assert_allclose(sim.positions(), [[11.0, 10.5], [21.0, 10.5]], atol=1e-9)


def test_a_control_step_without_bounds_moves_in_the_square_of_its_side():
    from netsim.area import Bounds
    from netsim.control import ControlStep

    zeros = np.zeros((1, 2))
    step = ControlStep(0.0, 1.0, zeros, zeros.copy(), np.zeros(1), np.full(1, -1), np.ones(1), 40.0, {})
    assert step.bounds == Bounds.square(40.0)


def test_a_step_shows_the_positions_at_the_instant_its_velocities_take_effect():
    """Step k is decided at t_k and takes effect at t_k + lead: its positions are those at
    t_k + lead (a robot driven at 1 m/s from the first step's effect on is 1 m further at
    the second's), not those when it is decided."""
    sim, loop = _loop([[10.0, 10.0]], lead_s=0.25)
    seen = []

    def controller(step):
        seen.append((step.t_s, step.positions_m.copy()))
        step.velocity_mps[:] = [1.0, 0.0]

    loop.add(controller)
    sim.run(until_s=2.0)
    (t1, p1), (t2, p2) = seen
    assert (t1, t2) == (0.75, 1.75)
    np.testing.assert_allclose(p1, [[10.0, 10.0]], atol=1e-12)
    np.testing.assert_allclose(p2, [[11.0, 10.0]], atol=1e-12)


def test_without_groups_a_step_shows_every_robot_undecided_and_leaderless():
    sim, loop = _loop([[0.0, 0.0], [5.0, 0.0]])
    seen = []
    loop.add(lambda step: seen.append((step.role.tolist(), step.leader.tolist(), step.role_names)))
    sim.run(until_s=1.0)
    assert seen == [([0, 0], [-1, -1], ())]


def test_a_controller_cannot_write_the_protocols_roles():
    """A step's roles and leaders are the step's own: a controller that overwrites them
    leaves the protocol's groups as they were."""

    class Groups:
        role = np.array([2, 1], dtype=np.int8)
        leader = np.array([0, 0])
        role_names = ("gamma", "beta", "alpha")

    sim, loop = _loop([[0.0, 0.0], [5.0, 0.0]], groups=Groups())

    def controller(step):
        assert step.role.tolist() == [2, 1] and step.leader.tolist() == [0, 0]
        step.role[:] = 0
        step.leader[:] = -1

    loop.add(controller)
    sim.run(until_s=2.0)
    assert Groups.role.tolist() == [2, 1] and Groups.leader.tolist() == [0, 0]


def test_a_velocity_the_mobility_model_changes_while_a_step_waits_is_not_the_controllers():
    """Robots moved by a mobility model: one that turns between a step's decision and its
    effect was not turned by the controller (which changed nothing), and nothing is refused."""
    sim, loop = _loop([[10.0, 10.0]], lead_s=0.01, moved_by="mobility.model = 'random_waypoint'")

    def turn():
        yield sim.env.timeout(0.505)  # after the first step is decided at 0.5, before it applies
        sim.state.set_leg(0, sim.env.now, (1.0, 0.0))

    sim.env.process(turn())
    seen = []
    loop.add(lambda step: seen.append(step.velocity_mps.tolist()))
    sim.run(until_s=2.0)
    assert seen == [[[0.0, 0.0]], [[1.0, 0.0]]]
    assert sim.state.velocity_mps.tolist() == [[1.0, 0.0]]


def test_a_loop_stopped_between_steps_calls_no_controller_again_and_keeps_what_was_recorded():
    """stop() from outside a step (a hook, say): the next step calls no controller and
    stops every robot, what runs before a step applies still runs for it (and the table
    it recorded is kept), and no step follows."""
    sim, loop = _loop([[10.0, 10.0]])
    calls = []

    def controller(step):
        calls.append(step.t_s)
        step.velocity_mps[:] = [1.0, 0.0]

    loop.add(controller)
    loop.before_apply.append(lambda step: step.record("applied", vx=float(step.velocity_mps[0, 0])))

    def stop():
        yield sim.env.timeout(1.0)  # between the steps of 0.5 s and 1.5 s
        loop.stop()

    sim.env.process(stop())
    sim.run(until_s=5.0)
    assert calls == [pytest.approx(0.501)]
    assert sim.trace.frame("applied")["vx"].tolist() == [1.0, 0.0]
    np.testing.assert_allclose(sim.positions(), [[11.0, 10.0]], atol=1e-9)


def test_a_table_first_recorded_before_a_step_applies_is_netsims_not_the_next_controllers():
    """A table recorded first by what runs before a step applies (the coverage's) is not
    written by the user's controller that happens to run first at the next step."""
    sim, loop = _loop([[10.0, 10.0]])
    loop.add(lambda step: None, owner="control.controllers[0] = 'mine'")
    loop.before_apply.append(lambda step: step.record("applied", t=step.t_s))
    sim.run(until_s=3.0)
    assert len(sim.trace.frame("applied")) == 3
    assert "applied" not in sim.trace.owners


def test_a_controller_fighting_the_mobility_model_is_told_the_first_robot_it_changed():
    sim, loop = _loop([[0.0, 0.0], [5.0, 0.0], [10.0, 0.0]], moved_by="mobility.model = 'random_waypoint'")

    def controller(step):
        step.velocity_mps[1:] = [0.0, 1.0]

    loop.add(controller)
    with pytest.raises(NetsimInputError) as err:
        sim.run(until_s=1.0)
    assert str(err.value).startswith(
        "a controller changed the velocity of robot 1, but robots move by mobility.model = 'random_waypoint'; "
    )


def test_on_a_map_a_controller_cannot_drive_a_robot_into_a_wall(tmp_path):
    """Robots a controller drives toward the middle of the office, through its walls, stop
    just short of them: the run goes to its end with every robot in a free cell."""
    from netsim.world.maps import cached_map

    cfg = config.load(
        None,
        [
            "world.n_robots=4",
            "world.side_m=100",
            "world.map=office",
            'mobility.model="static"',
            'protocol.model="none"',
            "duration_s=30",
            "coverage.start_s=0",
            'control.controllers=["tests.test_controllers:HEAD_ON"]',
        ],
    )
    positions = execute(cfg).frames["positions"]
    start, end = (positions[positions["t_s"] == t][["x_m", "y_m"]].to_numpy() for t in (0.0, 30.0))
    assert cached_map("office").is_free(end).all()
    # They did move toward the middle, and not all of them got there.
    before, after = (np.hypot(*(p - 50.0).T) for p in (start, end))
    assert (after < before - 1.0).any() and (after > 5.0).any()


def test_on_a_map_a_step_is_kept_off_the_walls_from_where_the_robot_is_when_it_applies():
    """A robot moved while a step waits to apply (by a hook, say) is kept off the walls from
    where it then is, not from where the step was decided: it ends its step in a free cell."""
    from netsim.world.free_space import free_fraction
    from netsim.world.maps import cached_map

    office = cached_map("office")
    xs, ys = office.cell_centres_m()
    cells = np.column_stack([a.ravel() for a in np.meshgrid(xs[40:-40:8], ys[40:-40:8])])
    east = np.array([5.0, 0.0])
    fraction = free_fraction(office, cells, cells + east)
    here = office.is_free(cells)
    clear = cells[here & (fraction == 1.0)][0]  # 5 m free to the east
    blocked = cells[here & (fraction > 0.1) & (fraction < 0.5)][0]  # a wall 0.5 m to 2.5 m to the east
    sim, loop = _loop([clear], occupancy=office, lead_s=0.01)

    def moved():
        yield sim.env.timeout(0.505)  # after the step of 0.5 s is decided, before it applies
        sim.state.set_leg(0, sim.env.now, (0.0, 0.0), start_m=blocked)

    def heads_east_once(step):
        step.velocity_mps[:] = east
        if step.t_s > 1.0:  # the second step: stand
            loop.stop()

    sim.env.process(moved())
    loop.add(heads_east_once)
    sim.run(until_s=3.0)
    end = sim.positions()
    assert office.is_free(end).all() and free_fraction(office, blocked[None], end)[0] == 1.0
    assert end[0, 0] > blocked[0]  # it did go east, up to the wall


def test_a_controller_that_only_observes_runs_beside_a_mobility_model_on_a_map():
    """Under random waypoint on the office map a controller that only looks (log_separation)
    runs to the end: the loop keeps only the robots it drives off the walls, and a random
    waypoint's leg it shortened was taken for the controller's change and refused."""
    from netsim.config import load

    config = load(
        None,
        [
            "seed=1",
            "world.n_robots=5",
            "world.side_m=100",
            "world.map=office",
            "mobility.model=random_waypoint",
            "mobility.stationary_start=false",
            "protocol.model=none",
            "duration_s=20",
            'control.controllers=["log_separation"]',
        ],
    )
    result = execute(config)
    assert result.sim.now == 20.0 and len(result.frames["separation"]) >= 10
