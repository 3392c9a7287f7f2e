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
