"""Random waypoint against closed forms (docs/validation.md items 1-4)."""

import math
import warnings

import numpy as np
import pytest
from netsim.mobility.random_waypoint import paused_fraction, stationary_start

from netsim.errors import ConfigError
from netsim.metrics import MEAN_LEG_UNIT_SQUARE
from netsim.run import build
from netsim.tools.validate import completed_leg_lengths
from netsim.trajectory import sample_positions
from tests.fixtures import make_config, rwp_density


def test_mean_leg_constant():
    """E[L] = a (2 + sqrt 2 + 5 ln(1 + sqrt 2)) / 15 = 0.521405 a."""
    assert MEAN_LEG_UNIT_SQUARE == pytest.approx(0.521405, abs=1e-6)


def test_stationary_speed_is_harmonic_mean():
    """Item 1: at t = 0 the speed averages (v_max - v_min) / ln(v_max / v_min), not the mean.

    [0.01, 0.05] gives 0.02485 (the arithmetic mean would be 0.03).
    """
    s = stationary_start(np.random.default_rng(1), 200_000, 1.0, 0.01, 0.05, 0.0)
    theory = 0.04 / math.log(5)
    assert theory == pytest.approx(0.02485, abs=1e-5)
    se = s.speed_mps.std() / math.sqrt(len(s.speed_mps))
    assert abs(s.speed_mps.mean() - theory) < 4 * se


def test_stationary_speed_density():
    """Item 1: the stationary speed density is 1 / (v ln(v_max / v_min)): P(V < v) = ln(v / v_min) / ln(ratio)."""
    s = stationary_start(np.random.default_rng(2), 100_000, 1.0, 0.5, 5.0, 0.0)
    for v in (0.8, 1.5, 3.0):
        p = math.log(v / 0.5) / math.log(10)
        assert (s.speed_mps < v).mean() == pytest.approx(p, abs=4 * math.sqrt(p * (1 - p) / 1e5))


@pytest.mark.parametrize("pt", [(0.5, 0.5), (0.25, 0.5), (0.25, 0.25), (0.1, 0.1)])
def test_stationary_start_spatial_density(pt):
    """Items 3 and 4: positions at t = 0 follow the exact stationary density of Hyytiä et al.

    Counts in a 0.05 x 0.05 box around each point are compared with the density integrated
    over the box (5 x 5 midpoints), within 4 Poisson standard deviations.
    """
    n, h = 400_000, 0.05
    s = stationary_start(np.random.default_rng(3), n, 1.0, 0.01, 0.05, 0.0)
    offsets = (np.arange(5) + 0.5) / 5 * h - h / 2
    mass = np.mean([rwp_density(pt[0] + dx, pt[1] + dy) for dx in offsets for dy in offsets]) * h * h
    p = s.position_m
    count = int(((np.abs(p[:, 0] - pt[0]) < h / 2) & (np.abs(p[:, 1] - pt[1]) < h / 2)).sum())
    assert abs(count - n * mass) < 4 * math.sqrt(n * mass)


def test_reference_density_values():
    """The density formula itself reproduces the published values on the unit square."""
    for pt, f in [((0.5, 0.5), 2.2013), ((0.25, 0.5), 1.5816), ((0.25, 0.25), 1.2853), ((0.1, 0.1), 0.4762)]:
        assert rwp_density(*pt) == pytest.approx(f, abs=1e-4)


def test_paused_fraction_at_start():
    """Item 4: a fraction p_p = E[T_p] / (E[T_p] + E[L] E[1/V]) of robots start paused."""
    n = 100_000
    s = stationary_start(np.random.default_rng(4), n, 100.0, 1.0, 2.0, 30.0)
    p = paused_fraction(100.0, 1.0, 2.0, 30.0)
    assert 0.2 < p < 0.8
    assert (s.speed_mps == 0).mean() == pytest.approx(p, abs=4 * math.sqrt(p * (1 - p) / n))
    left = s.pause_left_s[s.speed_mps == 0]
    assert left.min() >= 0 and left.max() <= 30.0
    assert left.mean() == pytest.approx(15.0, abs=0.3)


def test_the_paused_fraction_is_the_closed_form():
    """p_p = E[T_p] / (E[T_p] + E[L] E[1/V]), with E[L] on a square of side a the known
    (2 + sqrt 2 + 5 ln(1 + sqrt 2)) a / 15 and E[1/V] = ln(v_max / v_min) / (v_max - v_min)."""
    mean_leg = (2 + math.sqrt(2) + 5 * math.log(1 + math.sqrt(2))) * 100.0 / 15
    want = 30.0 / (30.0 + mean_leg * math.log(2.0) / 1.0)
    assert paused_fraction(100.0, 1.0, 2.0, 30.0) == pytest.approx(want, rel=1e-12)


def test_a_stationary_start_stays_stationary():
    """As many robots end their legs in the first seconds as end their pauses: a mover is
    anywhere along its leg (uniformly), so its distance left is as long as a stationary
    regime has it. Checked at t = 0 alone, a start with movers too near their ends keeps
    the positions' law and drifts at once (most with slow robots and long pauses)."""
    n, pause_s, t_s = 200_000, 20.0, 5.0
    s = stationary_start(np.random.default_rng(7), n, 1.0, 0.01, 0.05, pause_s)
    paused = s.speed_mps == 0
    # Pauses of 20 s end before 5 s at the rate 1/20 a second; a leg started after one
    # cannot end by then (at most 0.25 m at 0.05 m/s).
    leaving = paused & (s.pause_left_s < t_s)
    left_m = np.hypot(*(s.destination_m - s.position_m).T)
    arriving = ~paused & (left_m < s.speed_mps * t_s)
    sd = math.sqrt((leaving.mean() + arriving.mean()) / n)
    assert arriving.mean() == pytest.approx(leaving.mean(), abs=4 * sd)


@pytest.mark.parametrize("pause_s", [0.0, 20.0])
def test_time_average_speed_over_a_run(pause_s):
    """Item 1 over a run: total distance / (N T) = E[L] / (E[L] E[1/V] + E[T_p]), and the
    average speed does not drift (first half equals second half within noise)."""
    side, vmin, vmax, n, T = 200.0, 1.0, 4.0, 400, 600.0
    cfg = make_config(
        seed=5,
        duration_s=T,
        world={"n_robots": n, "side_m": side},
        mobility={"speed_min_mps": vmin, "speed_max_mps": vmax, "pause_s": pause_s},
        protocol={"model": "none"},
    )
    sim = build(cfg)
    sim.run()
    EL = MEAN_LEG_UNIT_SQUARE * side
    EinvV = math.log(vmax / vmin) / (vmax - vmin)
    theory = EL / (EL * EinvV + pause_s)
    pos = sample_positions(sim.state.legs(), n, np.arange(0, T + 1e-9, 1.0))
    xy = pos[["x_m", "y_m"]].to_numpy().reshape(-1, n, 2)
    step = np.hypot(*np.diff(xy, axis=0).transpose(2, 0, 1))  # (T, n) distance per second
    per_robot = step.mean(axis=0)
    se = per_robot.std() / math.sqrt(n)
    assert abs(per_robot.mean() - theory) < 4 * se
    first, second = step[: int(T / 2)].mean(axis=0), step[int(T / 2) :].mean(axis=0)
    assert abs(first.mean() - second.mean()) < 4 * math.sqrt(2) * se


@pytest.mark.slow
def test_mean_leg_length_in_a_run():
    """Item 2: legs drawn during a run average 0.521405 a."""
    side, n = 100.0, 300
    cfg = make_config(
        seed=6,
        duration_s=2000.0,
        world={"n_robots": n, "side_m": side},
        mobility={"speed_min_mps": 2.0, "speed_max_mps": 5.0, "pause_s": 0.0},
        protocol={"model": "none"},
    )
    sim = build(cfg)
    sim.run()
    lengths = completed_leg_lengths(sim.state.legs())
    assert len(lengths) > 2000
    se = lengths.std() / math.sqrt(len(lengths))
    assert abs(lengths.mean() - MEAN_LEG_UNIT_SQUARE * side) < 4 * se


@pytest.mark.slow
def test_positions_stay_stationary_during_a_run():
    """Item 3 over time: the spatial density at t = 300 s equals the stationary one."""
    n, side = 8_000, 1.0
    cfg = make_config(
        seed=7,
        duration_s=301.0,
        world={"n_robots": n, "side_m": side},
        mobility={"speed_min_mps": 0.01, "speed_max_mps": 0.05, "pause_s": 0.0},
        protocol={"model": "none"},
    )
    sim = build(cfg)
    sim.run()
    p = sim.state.positions_at(300.0)
    h = 0.1
    for pt in [(0.5, 0.5), (0.15, 0.15)]:
        offsets = (np.arange(5) + 0.5) / 5 * h - h / 2
        mass = np.mean([rwp_density(pt[0] + dx, pt[1] + dy) for dx in offsets for dy in offsets]) * h * h
        count = int(((np.abs(p[:, 0] - pt[0]) < h / 2) & (np.abs(p[:, 1] - pt[1]) < h / 2)).sum())
        assert abs(count - n * mass) < 4 * math.sqrt(n * mass)


def test_zero_min_speed_without_stationary_start_warns():
    cfg = make_config(mobility={"speed_min_mps": 0.0, "stationary_start": False}, world={"n_robots": 3})
    with pytest.warns(UserWarning, match="decays"):
        build(cfg)


def test_zero_min_speed_with_stationary_start_is_an_error():
    with pytest.raises(ConfigError, match="speed_min_mps"):
        make_config(mobility={"speed_min_mps": 0.0, "stationary_start": True}, world={"n_robots": 3})


def test_robots_stay_in_the_area():
    cfg = make_config(seed=3, duration_s=500.0, world={"n_robots": 50, "side_m": 100.0}, protocol={"model": "none"})
    sim = build(cfg)
    sim.run()
    pos = sample_positions(sim.state.legs(), 50, np.linspace(0, 500, 2001))
    assert pos["x_m"].between(0, 100).all() and pos["y_m"].between(0, 100).all()


def test_no_warning_by_default():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        build(make_config(world={"n_robots": 5}))


@pytest.mark.parametrize(
    "settings, stationary",
    [
        ([], True),
        (["world.map=office", "world.side_m=200"], False),
        (["world.placement=grid"], False),
        (["mobility.speed_min_mps=0"], False),
        (["mobility.stationary_start=false"], False),
    ],
)
def test_stationary_start_auto_starts_stationary_wherever_its_law_is_known(settings, stationary):
    """``stationary_start = "auto"`` (the default) draws the stationary start in an open
    square with uniform placement and a least speed above 0, and starts at rest elsewhere
    (a map, another placement, speed_min_mps = 0) instead of refusing the run."""
    from netsim.mobility.random_waypoint import starts_stationary

    from netsim import load

    config = load(None, settings)
    assert starts_stationary(config.mobility, config.world) is stationary


def test_default_random_waypoint_runs_on_a_map():
    """The default configuration on a map is accepted and moves the robots in free cells."""
    from netsim import load
    from netsim.run import build

    sim = build(load(None, ["world.map=office", "world.side_m=200", "world.n_robots=5", "duration_s=20"]))
    sim.run()
    assert sim.state.legs()["vx_mps"].abs().max() > 0


# -- rules the mutation audit found unguarded ------------------------------------------------


def test_mean_inverse_speed_of_one_speed_is_its_inverse():
    from netsim.mobility.random_waypoint import mean_inverse_speed

    assert mean_inverse_speed(2.0, 2.0) == 0.5
    assert mean_inverse_speed(1.0, math.e) == pytest.approx(1.0 / (math.e - 1.0), rel=1e-12)


def test_the_paused_fraction_on_a_rectangle_takes_the_rectangles_mean_leg():
    from netsim.area import Bounds
    from netsim.metrics import mean_distance_rectangle

    leg = mean_distance_rectangle(200.0, 100.0)
    assert paused_fraction(Bounds(0.0, 0.0, 200.0, 100.0), 2.0, 2.0, 10.0) == pytest.approx(10.0 / (10.0 + leg / 2.0))


def test_a_robot_paused_at_the_start_leaves_at_its_pause_end():
    """A stationary start's paused robot waits out its residual pause; its first leg is a pause end."""
    import simpy
    from netsim.mobility.random_waypoint import RandomWaypointParams, Start, waypoint_robot

    from netsim.area import Bounds
    from netsim.state import RobotState

    env = simpy.Environment()
    st = RobotState(1, 100.0, 10.0)
    here = np.array([[50.0, 50.0]])
    st.place(here)
    start = Start(here, here.copy(), np.zeros(1), np.array([3.0]))
    m = RandomWaypointParams(pause_s=5.0)
    env.process(waypoint_robot(env, st, m, Bounds.square(100.0), 0, start, np.random.default_rng(0)))
    env.run(until=3.5)
    legs = st.legs()
    moving = legs[legs["t_s"] > 0]
    assert moving["t_s"].tolist() == [3.0] and moving["cause"].tolist() == ["pause_end"]


@pytest.mark.parametrize(
    "settings, key",
    [
        (
            ["mobility.speed_min_mps=0", "mobility.speed_max_mps=0", "mobility.stationary_start=false"],
            "mobility.speed_max_mps",
        ),
        (["mobility.stationary_start=true", "world.placement='grid'"], "world.placement"),
    ],
)
def test_random_waypoint_refuses_no_top_speed_and_a_stationary_start_not_uniformly_placed(settings, key):
    from netsim import load

    with pytest.raises(ConfigError) as err:
        load(None, ["mobility.model=random_waypoint", *settings])
    assert str(err.value).startswith(key)
