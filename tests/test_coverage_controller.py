"""The virtual-force coverage controller (docs/model.md section 5): the bridge-keeping plan of
one step, and whole runs from dense random static deployments."""

import functools
import math
from pathlib import Path

import numpy as np
import pytest
from netsim.mobility.bridges import plan_follow
from netsim.mobility.steps import SAFETY, StepLimits
from netsim.protocols.roles import LEADER, MEMBER, UNDECIDED

from netsim import config
from netsim.errors import ConfigError
from netsim.metrics import components
from netsim.run import execute

RC = 100.0
SQRT3 = math.sqrt(3.0)


def greedy_groups(pos, range_m, undecided=()):
    """A dominating independent set of leaders, members joined to their nearest leader."""
    n = len(pos)
    role = np.full(n, MEMBER, dtype=np.int8)
    leader = np.full(n, -1)
    leaders = []
    for i in range(n):
        if i in undecided:
            role[i] = UNDECIDED
            continue
        if not any(np.hypot(*(pos[i] - pos[j])) <= range_m for j in leaders):
            leaders.append(i)
    for i in range(n):
        if i in leaders:
            role[i], leader[i] = LEADER, i
        elif role[i] == MEMBER:
            d = [np.hypot(*(pos[i] - pos[j])) for j in leaders]
            leader[i] = leaders[int(np.argmin(d))]
    return role, leader


def n_components(pos):
    return int(components(pos, RC).max() + 1)


@pytest.mark.parametrize("seed", range(40))
def test_plan_keeps_the_network_connected_throughout_the_step(seed):
    """Rule of section 5: bridges kept, members in range; checked at 21 instants of the step."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(20, 80))
    pos = rng.uniform(300, 300 + rng.uniform(150, 400), size=(n, 2))
    role, leader = greedy_groups(pos, RC, undecided=set(rng.choice(n, 2, replace=False).tolist()))
    before = n_components(pos)
    wish = rng.normal(0, 3.0, size=(n, 2))
    # Steps of up to 40 m (0.4 r_c): long enough that unchecked wishes break links.
    plan = plan_follow(pos, leader, wish, StepLimits(20.0, RC, 1.0, 2.0, 1000.0))
    for f in np.linspace(0, 1, 21):
        assert n_components(pos + plan.velocity_mps * 20.0 * f) <= before
    members = (role == MEMBER) & (np.hypot(*(pos - pos[np.maximum(leader, 0)]).T) <= RC)
    end = pos + plan.velocity_mps * 20.0
    assert (np.hypot(*(end[members] - end[leader[members]]).T) <= RC).all()
    assert (np.hypot(*plan.velocity_mps.T) <= 2.0 + 1e-9).all()
    assert (plan.velocity_mps[role == UNDECIDED] == 0).all()


def test_members_follow_their_leader_rigidly():
    """A member that is no gateway moves with its leader's velocity."""
    pos = np.array([[500.0, 500.0], [540.0, 500.0], [500.0, 560.0]])
    leader = np.array([0, 0, 0])
    wish = np.array([[1.0, 0.5], [0, 0], [0, 0]])
    plan = plan_follow(pos, leader, wish, StepLimits(1.0, RC, 1.0, 2.0, 1000.0))
    assert plan.velocity_mps[1] == pytest.approx(wish[0])
    assert plan.velocity_mps[2] == pytest.approx(wish[0])
    assert plan.commander.tolist() == [-1, 0, 0]


def test_gateway_rides_toward_the_middle_of_the_lens():
    """Two leaders 1.2 r_c apart pulling apart; their gateway, off-centre, moves toward
    the midpoint of their planned positions and stays in range of both."""
    pos = np.array([[400.0, 500.0], [520.0, 500.0], [430.0, 520.0]])
    leader = np.array([0, 1, 0])
    wish = np.array([[-1.0, 0.0], [1.0, 0.0], [0.0, 0.0]])
    plan = plan_follow(pos, leader, wish, StepLimits(1.0, RC, 1.0, 2.0, 1000.0))
    assert plan.velocity_mps[2, 0] > 0  # toward x = 460
    end = pos + plan.velocity_mps
    assert np.hypot(*(end[2] - end[0])) <= RC and np.hypot(*(end[2] - end[1])) <= RC


def test_leader_holds_rather_than_break_its_only_bridge():
    """Two groups joined only by a stretched member-to-member link: a leader pulling away
    is held, so the link survives."""
    pos = np.array([[300.0, 500.0], [380.0, 500.0], [479.5, 500.0], [560.0, 500.0]])
    leader = np.array([0, 0, 3, 3])
    wish = np.array([[-2.0, 0.0], [0, 0], [0, 0], [2.0, 0.0]])
    plan = plan_follow(pos, leader, wish, StepLimits(1.0, RC, 1.0, 2.0, 1000.0))
    assert plan.held[0] and plan.held[3]
    end = pos + plan.velocity_mps
    assert np.hypot(*(end[2] - end[1])) <= RC


def test_groups_stay_inside_the_area():
    """A leader pushed toward the border stops where its farthest member reaches it."""
    pos = np.array([[60.0, 500.0], [5.0, 500.0]])
    wish = np.array([[-2.0, 0.0], [0, 0]])
    plan = plan_follow(pos, np.array([0, 0]), wish, StepLimits(10.0, RC, 1.0, 2.0, 1000.0))
    end = pos + plan.velocity_mps * 10.0
    assert (end >= 0).all() and end[1, 0] == pytest.approx(0.0, abs=1e-6)


# -- whole runs ------------------------------------------------------------------------


def coverage_run(n, seed, **extra):
    overrides = [
        f"world.n_robots={n}",
        "world.side_m=1000",
        'world.placement="centre"',
        f"world.centre_side_m={150 + 2 * n}",
        'mobility.model="static"',
        "channel.range_m=100",
        "coverage.enabled=true",
        "protocol.message_rate_hz=0",
        'coverage.members="follow"',
        "duration_s=260",
        f"seed={seed}",
        "output.position_interval_s=0",
    ] + [f"{k}={v!r}".replace("'", '"') for k, v in extra.items()]
    return execute(config.load(None, overrides))


@pytest.fixture(scope="module")
def shared_run():
    """``coverage_run(n, seed)``, run once in this module for all the tests that only read
    it (a run is a pure function of its configuration)."""
    return functools.cache(coverage_run)


@pytest.mark.slow
@pytest.mark.parametrize("n,seed", [(40, 1), (80, 2), (120, 3)])
def test_coverage_grows_spacing_reaches_target_and_network_stays_connected(n, seed, shared_run):
    """From a dense random static deployment: covered fraction grows; the median
    nearest-leader spacing ends within 10 % of sqrt(3) r_c; connected at the start, at
    every control step, and at the end."""
    r = shared_run(n, seed)
    s = r.summary
    assert s["components_start"] == 1
    assert s["covered_fraction_leaders_final"] > 1.1 * s["covered_fraction_leaders_start"]
    assert s["covered_fraction_all_final"] > s["covered_fraction_all_start"]
    assert abs(s["spacing_median_ratio_final"] - 1.0) <= 0.10
    steps = r.frames["control"]
    assert len(steps) > 20 and (steps["components"] == 1).all()
    assert r.frames["coverage"]["connected"].all()
    assert s["connected_final"]


@pytest.mark.slow
@pytest.mark.parametrize("law", ["repulsion", "inverse_square"])
def test_alternative_laws_spread_leaders_and_keep_connectivity(law):
    r = coverage_run(60, 4, **{"coverage.law": law})
    s = r.summary
    assert (r.frames["control"]["components"] == 1).all()
    assert s["covered_fraction_leaders_final"] > s["covered_fraction_leaders_start"]
    # Repulsion only pushes: leaders end at least about the target apart.
    assert s["spacing_median_ratio_final"] >= 0.9


@pytest.mark.slow
def test_global_knowledge_mode_also_converges():
    r = coverage_run(40, 5, **{"coverage.knowledge": "global"})
    assert abs(r.summary["spacing_median_ratio_final"] - 1.0) <= 0.10
    assert (r.frames["control"]["components"] == 1).all()


@pytest.mark.slow
def test_stopping_rule_ends_control_and_robots_stay_still(shared_run):
    """Once every leader's force has asked for less than stop_speed_mps for stop_hold_s,
    control ends and nobody moves any more."""
    r = shared_run(40, 1)
    settled = r.summary["control_settled_s"]
    assert math.isfinite(settled) and settled < 260
    legs = r.sim.state.legs()
    after = legs[legs["t_s"] > settled + 1.0]
    assert after.empty
    last = legs.sort_values("t_s").groupby("robot").tail(1)
    assert (last[["vx_mps", "vy_mps"]] == 0).all().all()


@pytest.mark.slow
def test_members_that_miss_their_command_hold():
    """Commands go over the lossy channel; a member that misses one stays put that step."""
    r = coverage_run(40, 2, **{"channel.loss_probability": 0.3})
    cmd = r.sim.channel.counters_for("command")
    assert cmd.sent.sum() > 0 and cmd.dropped[0].sum() > 0
    assert r.summary["covered_fraction_leaders_final"] > r.summary["covered_fraction_leaders_start"]


@pytest.mark.slow
def test_coverage_metrics_are_sampled_over_time(shared_run):
    """The coverage table has its columns and a row every metrics interval (5 s), the mean
    distance travelled never falls, and the travel table agrees with the summary."""
    r = shared_run(40, 1)
    cov = r.frames["coverage"]
    expected = {
        "t_s",
        "covered_fraction_leaders",
        "covered_fraction_all",
        "covered_error_bound_all",
        "connected",
        "components",
        "spacing_median_ratio",
        "hexagonality",
        "distance_mean_m",
    }
    assert expected <= set(cov.columns)
    assert cov["t_s"].diff().dropna().eq(5.0).all()
    assert cov["distance_mean_m"].is_monotonic_increasing
    travel = r.frames["travel"]
    assert len(travel) == 40 and travel["distance_m"].mean() == pytest.approx(r.summary["distance_mean_m"])


@pytest.mark.parametrize("seed", range(40))
def test_follow_mode_reproduces_the_paper_faithful_controller(seed):
    """``coverage.members = "follow"`` plans every step exactly as the controller did before
    spreading members existed: on the 40 random cases of the connectivity test above, the
    velocities, commanders, held leaders and kept bridges equal those recorded from that
    version (commit deb6747, ``tests/data/follow_plans_deb6747.npz``). Plans, not whole runs,
    are compared, so that changes to the clustering protocol do not enter. Velocities agree
    to rounding (a step's end on a circle is the link solvers' root, which that version
    solved by another formula: the last bits differ) and to the hair a step at the reach is
    now cut short by (``SAFETY``: a relative 1e-9, so that it never rounds past the cap,
    which moves the steps a bound holds back by a few times that)."""
    ref = np.load(Path(__file__).parent / "data" / "follow_plans_deb6747.npz")
    rng = np.random.default_rng(seed)
    n = int(rng.integers(20, 80))
    pos = rng.uniform(300, 300 + rng.uniform(150, 400), size=(n, 2))
    role, leader = greedy_groups(pos, RC, undecided=set(rng.choice(n, 2, replace=False).tolist()))
    wish = rng.normal(0, 3.0, size=(n, 2))
    plan = plan_follow(pos, leader, wish, StepLimits(20.0, RC, 1.0, 2.0, 1000.0))
    np.testing.assert_allclose(plan.velocity_mps, ref[f"v{seed}"], rtol=0, atol=1e-13 + 4 * 2.0 * (1.0 - SAFETY))
    assert np.array_equal(plan.commander, ref[f"c{seed}"])
    assert np.array_equal(plan.held, ref[f"h{seed}"])
    assert plan.bridges == int(ref[f"b{seed}"])


@pytest.mark.slow
def test_same_seed_same_coverage_trace(shared_run):
    """Two runs of the same seed under coverage control move every robot the same way."""
    a, b = shared_run(40, 1), coverage_run(40, 1)
    assert a.sim.state.legs().equals(b.sim.state.legs())


@pytest.mark.parametrize(
    "overrides,key",
    [
        (["coverage.enabled=true"], "coverage.enabled"),  # random waypoint moves the robots
        (["coverage.enabled=true", 'mobility.model="static"', "world.torus=true"], "coverage.enabled"),
        (["coverage.enabled=true", 'mobility.model="static"', 'protocol.model="ack"'], "coverage.enabled"),
        (["coverage.enabled=true", 'mobility.model="static"', "channel.latency_s=2.0"], "coverage.control_period_s"),
        (['coverage.law="magnetic"'], "coverage.law"),
        (['coverage.knowledge="oracle"'], "coverage.knowledge"),
        (['coverage.members="lead"'], "coverage.members"),
        (['coverage.area_method="monte_carlo"'], "coverage.area_method"),
        (["coverage.stop_gain=-0.1"], "coverage.stop_gain"),
        (
            ["coverage.enabled=true", 'mobility.model="static"', "coverage.metrics_interval_s=30"],
            "coverage.metrics_interval_s",
        ),
        (["coverage.gain=0"], "coverage.gain"),
        (['control.controllers="avoid_collisions"'], "control.controllers"),
        (["control.options=3"], "control.options"),
        (['world.placement="centre"', "world.centre_side_m=5000"], "world.centre_side_m"),
    ],
)
def test_bad_coverage_configuration_names_the_key(overrides, key):
    with pytest.raises(ConfigError) as err:
        config.load(None, overrides)
    assert err.value.key == key


@pytest.mark.slow
def test_figures_command_runs_the_coverage_scenario_and_draws_three_pngs(tmp_path):
    from netsim.tools.cli import main

    out = tmp_path / "figs"
    code = main(["figures", "--out", str(out), "--no-progress", "--set", "world.n_robots=30", "--set", "duration_s=60"])
    assert code == 0
    for name in ("fig6_initial_deployment.png", "fig7_leader_paths.png", "fig8_final_deployment.png"):
        data = (out / name).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 10_000
    # Redrawn from the run directory alone.
    assert main(["figures", str(out), "--out", str(tmp_path / "again")]) == 0
    assert (tmp_path / "again" / "fig8_final_deployment.png").is_file()


def test_figures_of_a_directory_that_is_no_run_is_a_clear_error(tmp_path, capsys):
    from netsim.tools.cli import main

    assert main(["figures", str(tmp_path)]) == 2
    assert "not a run directory" in capsys.readouterr().err


def test_leaders_hear_of_leaders_beyond_range_through_their_gateways(tmp_path, build_sim):
    """Knowledge "acks": two leaders 1.7 r_c apart cannot hear each other, but each learns
    the other's position from the gateway between them; a leader 3 r_c away stays unknown."""
    csv = tmp_path / "line.csv"
    csv.write_text("x_m,y_m\n100,500\n185,500\n270,500\n600,500\n")
    sim = build_sim(
        world={"n_robots": 4, "placement": str(csv)},
        mobility={"model": "static"},
        channel={"range_m": 100.0},
        protocol={"message_rate_hz": 0.0, "join_policy": "lowest_id"},
    )
    sim.run(until_s=20.0)
    role = sim.groups.role.tolist()
    assert role == [LEADER, MEMBER, LEADER, LEADER]
    ids, xy = sim.groups.heard_leaders(0, sim.now)
    assert ids.tolist() == [2]
    assert xy[0] == pytest.approx([270.0, 500.0])
    ids3, _ = sim.groups.heard_leaders(3, sim.now)
    assert ids3.tolist() == []


def test_follow_never_drives_a_robot_past_the_speed_cap():
    """Follow: a step at the reach, over the control period, can round past the speed cap;
    steps are cut a hair short of the reach, as the spread plans' are."""
    from netsim.config import load
    from netsim.run import execute

    keys = [
        "world.n_robots=30",
        "world.placement=centre",
        "mobility.model=static",
        "coverage.enabled=true",
        "coverage.members=follow",
        "duration_s=200",
        "protocol.message_rate_hz=0",
    ]
    config = load(None, keys)
    legs = execute(config, run=0).frames["legs"]
    speeds = np.hypot(legs["vx_mps"].to_numpy(), legs["vy_mps"].to_numpy())
    assert speeds.max() <= config.coverage.speed_max_mps
    assert speeds.max() > 0.99 * config.coverage.speed_max_mps  # robots do reach the cap
