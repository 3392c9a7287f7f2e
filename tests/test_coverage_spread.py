"""Spread mode (``coverage.members = "spread"``): every robot is pushed apart by the forces
its leader computes, a spanning forest of the network is kept, the hierarchy adapts."""

import math

import numpy as np
import pytest
from netsim.mobility.forces import SQRT3, border_forces, component_centres, expansion_forces
from netsim.mobility.spread import disk_links, forest_rows, pass_on_pulls, plan_spread
from netsim.mobility.steps import StepLimits
from netsim.protocols.roles import LEADER, MEMBER, UNDECIDED

from netsim import config
from netsim.metrics import components, components_at_link_events, connected_coverage_bound
from netsim.run import execute
from netsim.tools.validate import coverage_settings
from netsim.topology import geometric_pairs

RC = 100.0


def n_components(pos):
    return int(components(pos, RC).max() + 1)


def random_team(seed):
    """A dense random team: leaders, members joined to their nearest leader (a few to a
    farther one, possibly out of range, as a released member is), undecided robots; and
    who may move, as the controller decides."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(20, 80))
    pos = rng.uniform(300, 300 + rng.uniform(150, 400), size=(n, 2))
    role = np.full(n, MEMBER, dtype=np.int8)
    leaders = []
    for i in range(n):
        if all(np.hypot(*(pos[i] - pos[j])) > RC for j in leaders):
            leaders.append(i)
    leaders = np.array(leaders)
    role[leaders] = LEADER
    role[rng.choice(np.flatnonzero(role == MEMBER), 2, replace=False)] = UNDECIDED
    nearest = leaders[np.argmin(np.hypot(*(pos[:, None, :] - pos[leaders][None]).transpose(2, 0, 1)), axis=1)]
    leader = np.where(rng.random(n) < 0.15, rng.choice(leaders, n), nearest)
    leader = np.where(role == MEMBER, leader, -1)
    in_range = np.hypot(*(pos - pos[np.maximum(leader, 0)]).T) <= RC
    commandable = (role == MEMBER) & in_range
    mobile = (role == LEADER) | commandable
    return rng, pos, mobile, np.where(commandable, leader, -1)


@pytest.mark.parametrize("seed", range(40))
def test_plan_keeps_the_network_connected_throughout_the_step_whoever_holds(seed):
    """Every kept link is in range at both ends of the step, so at every instant of it
    (checked at 21 instants); and still when any of the commanded robots holds instead
    (a missed command), since each end of a link keeps to its own half."""
    rng, pos, mobile, commander_of = random_team(seed)
    before = n_components(pos)
    wish = rng.normal(0, 3.0, size=(len(pos), 2))
    limits = StepLimits(20.0, RC, 1.0, 2.0, 1000.0)  # steps of 40 m: unchecked, they break links
    plan = plan_spread(pos, mobile, commander_of, wish, limits)
    assert (np.hypot(*plan.velocity_mps.T) > 0).sum() > len(pos) // 3
    holds = rng.random(len(pos)) < 0.3
    for velocity in (plan.velocity_mps, np.where(holds[:, None], 0.0, plan.velocity_mps)):
        for f in np.linspace(0, 1, 21):
            assert n_components(pos + velocity * 20.0 * f) <= before
    end = pos + plan.velocity_mps * 20.0
    assert (np.hypot(*plan.velocity_mps.T) <= 2.0 + 1e-9).all()
    assert ((end >= 0) & (end <= 1000.0)).all()
    assert (plan.velocity_mps[~mobile] == 0).all()
    moving = np.hypot(*plan.velocity_mps.T) > 0
    assert (plan.commander[moving] == commander_of[moving]).all() and (plan.commander[~moving] == -1).all()


def test_spanning_forest_has_the_components_of_the_network():
    rng = np.random.default_rng(3)
    pos = rng.uniform(0, 600, size=(150, 2))
    links = disk_links(pos, StepLimits(1.0, RC, 1.0, 2.0, 1000.0))
    kept = forest_rows(len(pos), links)
    i, j, d = links.i[kept], links.j[kept], links.d[kept]
    labels = components(pos, RC)
    assert len(i) == len(pos) - (labels.max() + 1)
    assert (d <= RC).all() and (labels[i] == labels[j]).all()
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    forest = coo_matrix((np.ones(len(i)), (i, j)), shape=(len(pos), len(pos)))
    assert connected_components(forest, directed=False)[0] == labels.max() + 1


def test_a_robot_on_a_taut_link_slides_along_it():
    """Pushed half along a taut link, half across it, a robot still moves (across), and
    the link stays in range: its step is projected into the allowed disk, not scaled
    down to nothing."""
    pos = np.array([[500.0, 500.0], [599.0, 500.0]])
    mobile = np.array([False, True])
    wish = np.array([[0.0, 0.0], [1.0, 1.0]])
    plan = plan_spread(pos, mobile, np.array([-1, 0]), wish, StepLimits(1.0, RC, 1.0, 2.0, 1000.0))
    v = plan.velocity_mps[1]
    assert v[1] > 0.9 and plan.held[1]
    assert np.hypot(*(pos[1] + v - pos[0])) <= 99.0 + 1e-9


def test_both_ends_of_a_link_keep_to_their_half():
    """Two moving robots 98 m apart, both pushed apart: each gains half the slack."""
    pos = np.array([[500.0, 500.0], [598.0, 500.0]])
    wish = np.array([[-2.0, 0.0], [2.0, 0.0]])
    plan = plan_spread(pos, np.array([True, True]), np.array([-1, -1]), wish, StepLimits(1.0, RC, 1.0, 2.0, 1000.0))
    assert plan.velocity_mps[:, 0] == pytest.approx([-0.5, 0.5], abs=1e-6)


def test_both_ends_of_a_link_share_its_allowed_travel():
    """Under shadowing a kept link allows its pair a travel over the step (the fade
    rule's); when both ends may move each takes half, so that the pair's travel keeps to
    it even when both move sideways, the link's length unchanged."""
    from netsim.mobility.steps import Candidates

    pos = np.array([[500.0, 500.0], [540.0, 500.0]])
    wish = np.array([[0.0, 2.0], [0.0, -2.0]])
    d = np.array([40.0])
    link = Candidates(np.array([0]), np.array([1]), d, d, np.array([99.0]), np.array([1.4]), np.array([RC]))
    limits = StepLimits(1.0, RC, 1.0, 2.0, 1000.0)
    plan = plan_spread(pos, np.array([True, True]), np.array([-1, -1]), wish, limits, link)
    travel = np.hypot(*plan.velocity_mps.T) * limits.period_s
    assert travel.sum() == pytest.approx(1.4, rel=1e-6)
    assert travel[0] == pytest.approx(travel[1])


def test_pulls_count_a_wish_up_to_the_range_per_period():
    """A chain A - B - C, taut: A wishes away from B a million m/s (the inverse-square law
    between two robots a hair apart), C wishes sideways. A's wish counts up to the range
    per period, so C still goes sideways as much as it is pulled, instead of being dragged
    wholly after A's one close pair."""
    pos = np.array([[500.0, 500.0], [598.0, 500.0], [696.0, 500.0]])
    mobile, commander = np.ones(3, bool), np.full(3, -1)
    limits = StepLimits(1.0, RC, 1.0, 2.0, 1000.0)
    plans = [
        plan_spread(pos, mobile, commander, np.array([[-a, 0.0], [0.0, 0.0], [0.0, 50.0]]), limits) for a in (RC, 1e6)
    ]
    v = plans[1].velocity_mps[2]
    assert v[1] / np.hypot(*v) > 0.3
    assert np.array_equal(plans[0].velocity_mps, plans[1].velocity_mps)


def test_robots_stay_inside_the_area():
    pos = np.array([[3.0, 500.0]])
    wish = np.array([[-2.0, 1.0]])
    plan = plan_spread(pos, np.array([True]), np.array([-1]), wish, StepLimits(5.0, RC, 1.0, 2.0, 1000.0))
    end = pos + plan.velocity_mps * 5.0
    assert end[0, 0] == pytest.approx(0.0, abs=1e-6) and end[0, 1] > 500.0


def test_pulls_travel_along_taut_links():
    """A chain of three taut links: the last robot's outward wish reaches the first in
    three hops; a link with slack passes on only what the slack cannot absorb; a push
    toward a neighbour is no pull."""
    pos = np.array([[0.0, 0.0], [99.0, 0.0], [198.0, 0.0], [297.0, 0.0]])
    link = (np.array([0, 1, 2]), np.array([1, 2, 3]), np.full(3, 99.0))
    wish = np.array([[0.0, 0.0], [0.0, 0.0], [0.0, 0.0], [1.0, 0.0]])
    mobile = np.ones(4, bool)
    out = pass_on_pulls(pos, wish, mobile, link, np.full(3, 99.0), 1.0)
    assert out[:, 0] == pytest.approx([1.0, 1.0, 1.0, 1.0])
    slack = pass_on_pulls(pos, wish, mobile, link, np.array([99.0, 99.0, 99.8]), 1.0)
    assert slack[:, 0] == pytest.approx([0.6, 0.6, 0.6, 1.0])
    inward = pass_on_pulls(pos, -wish, mobile, link, np.full(3, 99.0), 1.0)
    assert inward[:, 0] == pytest.approx([0.0, 0.0, 0.0, -1.0])
    held = pass_on_pulls(pos, wish, np.array([True, True, False, True]), link, np.full(3, 99.0), 1.0)
    assert held[:, 0] == pytest.approx([0.0, 0.0, 0.0, 1.0])


def _pulled_along_taut_chain(n: int) -> np.ndarray:
    """The wishes after pulls along a chain of ``n`` robots on taut links, the outer one
    wishing to move outward."""
    pos = np.column_stack([99.0 * np.arange(n), np.zeros(n)])
    link = (np.arange(n - 1), np.arange(1, n), np.full(n - 1, 99.0))
    wish = np.zeros((n, 2))
    wish[-1, 0] = 1.0
    return pass_on_pulls(pos, wish, np.ones(n, bool), link, np.full(n - 1, 99.0), 1.0)


def test_a_pull_travels_a_long_taut_chain_in_one_step():
    """The outer robot of a chain of twenty taut links pulls every robot of it in the same
    step: the tension of a taut chain is not stopped after a few links, so a long branch
    follows its tip instead of blocking it."""
    out = _pulled_along_taut_chain(21)
    assert out[:, 0] == pytest.approx(np.ones(21))


def test_a_pull_travels_thirty_links_deep_and_no_farther():
    """A pull passes along taut links up to thirty deep in one step, the longest branch
    the plan expects, and stops there: the depth is the rule's, not an accident of the
    chain's length."""
    out = _pulled_along_taut_chain(32)
    assert out[1:, 0] == pytest.approx(np.ones(31))
    assert out[0, 0] == 0.0


def test_leaders_know_their_two_hop_neighbourhood_from_acks(build_sim):
    """On a static loss-free network, after a few Ack periods, what every robot knows is
    exactly who it hears and who they hear (a symmetric relation), at their positions."""
    sim = build_sim(
        world={"n_robots": 40, "side_m": 500.0},
        mobility={"model": "static"},
        channel={"range_m": 100.0},
        protocol={"message_rate_hz": 0.0},
    )
    sim.run(until_s=8.0)
    robot, other, xy = sim.groups.neighbourhood(sim.now)
    pos = sim.state.positions_at(sim.now)
    n = len(pos)
    a, b, _ = geometric_pairs(pos, 100.0)
    hears = np.zeros((n, n), bool)
    hears[a, b] = hears[b, a] = True
    expected = hears | (hears.astype(int) @ hears.astype(int) > 0)
    np.fill_diagonal(expected, False)
    known = np.zeros((n, n), bool)
    known[robot, other] = True
    assert (known == expected).all() and (known == known.T).all()
    assert xy == pytest.approx(pos[other])


def test_a_wished_speed_below_stop_speed_mps_is_a_wish_to_hold(tmp_path, build_sim):
    """docs/model.md 5: a robot whose wished speed (gain x resultant force) is below
    ``coverage.stop_speed_mps`` wishes to hold: its velocity is exactly 0. Two lone leaders
    near opposite borders, out of each other's reach: the border pushes robot 0 at half the
    stop speed and robot 1 at twice it. Robot 1 moves; robot 0 never does (the wish kept,
    it crept along at 0.01 m/s)."""
    margin = SQRT3 * RC / 2  # the borders push within this, by (margin - distance) x gain
    xy = [(margin - 0.1, 500.0), (1000.0 - margin + 0.4, 500.0)]
    path = tmp_path / "robots.csv"
    path.write_text("x_m,y_m\n" + "".join(f"{x!r},{y!r}\n" for x, y in xy))
    sim = build_sim(
        duration_s=14.0,
        world={"n_robots": 2, "side_m": 1000.0, "placement": str(path)},
        mobility={"model": "static"},
        channel={"range_m": RC},
        protocol={"message_rate_hz": 0.0},
        coverage={"enabled": True, "expansion": 0.0},
        output={"position_interval_s": 0.0},
    )
    cov = sim.models["coverage"]
    c = sim.config.coverage
    wished = np.hypot(*border_forces(np.array(xy), 1000.0, RC, c.gain).T)
    assert wished == pytest.approx([0.5 * c.stop_speed_mps, 2.0 * c.stop_speed_mps])
    proposed: list[np.ndarray] = []
    propose = cov._propose_spread  # the wishes, before the plan keeps links (none here)

    def recorded(step):
        propose(step)
        assert (step.leader == [0, 1]).all()  # both lead themselves: both may move
        proposed.append(step.velocity_mps.copy())

    cov._propose_spread = recorded
    sim.run()
    speeds = np.hypot(*np.array(proposed).transpose(2, 0, 1))  # (steps, robots)
    assert len(speeds) >= 3
    assert (speeds[:, 0] == 0.0).all() and (speeds[:, 1] > c.stop_speed_mps).all(), speeds
    legs = sim.state.legs()
    assert (legs.loc[legs["robot"] == 0, ["vx_mps", "vy_mps"]] == 0.0).all().all()
    assert (legs.loc[legs["robot"] == 1, "vx_mps"] < 0.0).any()
    assert (sim.state.positions_at(sim.now)[0] == xy[0]).all()


# -- whole runs ------------------------------------------------------------------------


def spread_run(n, seed, side, duration=700, **extra):
    overrides = [
        f"world.n_robots={n}",
        f"world.side_m={side}",
        'world.placement="centre"',
        f"world.centre_side_m={150 + 2 * n}",
        'mobility.model="static"',
        "channel.range_m=100",
        "coverage.enabled=true",
        "protocol.message_rate_hz=0",
        f"duration_s={duration}",
        f"seed={seed}",
        "output.position_interval_s=0",
    ] + [f"{k}={v!r}".replace("'", '"') for k, v in extra.items()]
    return execute(config.load(None, overrides))


def assert_settled_hierarchy(sim):
    """Leaders independent (no two in range), every member in range of a leader it
    follows, nobody undecided (docs/validation.md item 13, after the team has stopped)."""
    st = sim.groups
    pos = sim.state.positions_at(sim.now)
    a, b, _ = geometric_pairs(pos, RC)
    lead = st.role == LEADER
    assert not (lead[a] & lead[b]).any()
    members = np.flatnonzero(st.role == MEMBER)
    assert lead[st.leader[members]].all()
    assert (np.hypot(*(pos[members] - pos[st.leader[members]]).T) <= RC).all()
    assert not (st.role == UNDECIDED).any()


@pytest.mark.slow
@pytest.mark.parametrize("n,seed,side", [(30, 1, 800.0), (60, 2, 1000.0), (100, 3, 1500.0)])
def test_the_whole_team_spreads_and_stays_connected(n, seed, side):
    """From a dense start: the disks of all robots end covering at least 80 % of the most
    a connected team can cover, min(1, U(N)/A); one component at every control step and
    at the end; control settles and the hierarchy then settles too."""
    r = spread_run(n, seed, side)
    s = r.summary
    assert s["components_start"] == 1
    assert s["covered_of_bound_all_final"] >= 0.8
    assert s["covered_fraction_all_final"] > 2 * s["covered_fraction_all_start"]
    assert (r.frames["control"]["components"] == 1).all() and r.frames["coverage"]["connected"].all()
    assert s["components_final"] == 1
    assert math.isfinite(s["control_settled_s"]) and s["control_settled_s"] < 700 - 30
    assert s["leaders_final"] > 2 * r.frames["control"]["leaders"].iloc[0]  # groups split as the team spreads
    assert_settled_hierarchy(r.sim)


@pytest.mark.slow
def test_under_loss_members_that_miss_a_command_hold_and_no_link_is_lost():
    """With 30 % of receptions lost, commands are missed (those members hold); each end
    of a kept link keeps to its own half, so the network stays in one component."""
    r = spread_run(40, 4, 1000.0, duration=150, **{"channel.loss_probability": 0.3})
    cmd = r.sim.channel.counters_for("command")
    assert cmd.sent.sum() > 0 and cmd.dropped[0].sum() > 0
    assert r.summary["components_start"] == 1
    assert (r.frames["control"]["components"] == 1).all() and r.frames["coverage"]["connected"].all()
    assert r.summary["covered_fraction_all_final"] > 1.5 * r.summary["covered_fraction_all_start"]


@pytest.mark.slow
def test_control_stops_when_coverage_stops_growing():
    """The stopping rule: over the last stop_hold_s the covered fraction of the bound rose
    less than stop_gain; then nobody moves."""
    r = spread_run(30, 5, 800.0, duration=600, **{"coverage.stop_gain": 0.01})
    settled = r.summary["control_settled_s"]
    assert math.isfinite(settled) and settled < 600
    cov = r.frames["coverage"].set_index("t_s")["covered_of_bound_all"]
    window = cov[(cov.index >= settled - 20.0 - 1e-9) & (cov.index <= settled + 1e-9)]
    assert window.iloc[1:].max() - window.iloc[0] < 0.01
    earlier = cov[(cov.index >= settled - 40.0 - 1e-9) & (cov.index <= settled - 20.0 + 1e-9)]
    assert earlier.iloc[1:].max() - earlier.iloc[0] >= 0.01
    legs = r.sim.state.legs()
    assert legs[legs["t_s"] > settled + 1.5].empty
    # One odometer: the coverage table's last sample and the travel table read the same law.
    assert r.frames["coverage"]["distance_mean_m"].iloc[-1] == r.frames["travel"]["distance_m"].mean()


def test_any_motion_starts_the_quiet_over_so_control_stops_stop_hold_s_after_the_last():
    """Spread's motion stopping rule (docs/model.md 5, "Stopping"): control ends once no
    robot's planned speed has reached stop_speed_mps for stop_hold_s, so any robot's motion
    starts the quiet over. With the coverage rule off (stop_gain = 0) and stop_hold_s = 5 s,
    plans quiet at 10 and 11 s, one robot moving at 12 and 14 s, quiet in between and from
    15 s on: control stops at 20 s, stop_hold_s after the first quiet step that follows the
    last motion (without the reset the quiet counted from 10 s and control stopped at 15 s,
    a robot having moved 1 s before)."""
    from types import SimpleNamespace

    from netsim.mobility.coverage import CoverageController, CoverageParams

    cfg = CoverageParams(stop_gain=0.0, stop_hold_s=5.0)
    stops: list[float] = []
    clock = SimpleNamespace(now=0.0)
    ctl = SimpleNamespace(
        cfg=cfg,
        env=clock,
        all_quiet_since=math.nan,
        settled_s=math.nan,
        loop=SimpleNamespace(stop=lambda: stops.append(clock.now)),
    )
    quiet = np.zeros((3, 2))
    moving = quiet.copy()
    moving[1] = [0.3, 0.4]
    for t in range(10, 40):
        clock.now = float(t)
        CoverageController._stopping_rule(ctl, SimpleNamespace(velocity_mps=moving if t in (12, 14) else quiet))
        if stops:
            break
    assert stops == [20.0] and ctl.settled_s == 20.0
    assert ctl.settled_s >= 14.0 + cfg.hold_s


@pytest.mark.slow
def test_global_knowledge_spreads_too():
    r = spread_run(30, 6, 800.0, duration=200, **{"coverage.knowledge": "global"})
    assert (r.frames["control"]["components"] == 1).all()
    assert r.summary["covered_fraction_all_final"] > 2 * r.summary["covered_fraction_all_start"]


@pytest.mark.slow
def test_same_seed_same_spread():
    a, b = (spread_run(20, 7, 600.0, duration=60) for _ in range(2))
    assert a.sim.state.legs().equals(b.sim.state.legs())
    assert a.frames["coverage"].equals(b.frames["coverage"])


# -- expansion (docs/model.md section 5, "Expansion") --------------------------------------


def test_expansion_pushes_each_robot_away_from_the_centre_of_its_component():
    """``gain x expansion x (p - c)``, ``c`` the mean position of the robot's own component:
    a robot at its component's centre feels nothing, the push grows with the distance, and
    it sums to nothing over a component."""
    pos = np.array([[0.0, 0.0], [10.0, 0.0], [20.0, 0.0], [500.0, 500.0], [500.0, 540.0]])
    centre = component_centres(pos, np.array([0, 0, 0, 1, 1]))
    f = expansion_forces(pos, centre, 0.1, 1e6, 0.5)
    np.testing.assert_allclose(f, [[-0.5, 0.0], [0.0, 0.0], [0.5, 0.0], [0.0, -1.0], [0.0, 1.0]], atol=1e-12)


def test_expansion_is_capped_below_the_borders_push():
    """Far from the centre the push stops growing at sqrt(3) r_c / 4 (times the gain), half
    the border's strongest push: a robot the expansion drives at the border is pushed back
    inside."""
    far = np.array([[999.0, 500.0]])
    f = expansion_forces(far, np.array([[0.0, 500.0]]), 0.1, RC, 0.5)
    np.testing.assert_allclose(f, [[0.5 * math.sqrt(3) * RC / 4, 0.0]])
    assert (f + border_forces(far, 1000.0, RC, 0.5))[0, 0] < 0


def expansion_run(n, loss, duration, *extra):
    overrides = coverage_settings("unit disk", "global", n, loss, 1, duration) + list(extra)
    return execute(config.load(None, overrides))


@pytest.mark.slow
def test_expansion_unfolds_the_team_far_past_the_even_disk():
    """From a dense start (30 robots, 30 % of receptions lost): with the expansion the team
    covers at least 0.85 of min(1, U(N) / A) and its network never splits; without it
    (expansion = 0) the team jams as an even disk below 0.85 of it."""
    n = 30
    r = expansion_run(n, 0.3, 300)
    times, counts = components_at_link_events(
        *(r.frames["links"][c].to_numpy() for c in ("a", "b", "t_up_s", "t_down_s", "censored_end")), n
    )
    assert counts.max() == 1 and (times > r.sim.config.coverage.start_s).sum() > 10
    assert r.summary["covered_of_bound_all_final"] >= 0.85
    off = expansion_run(n, 0.3, 300, "coverage.expansion=0")
    assert off.summary["covered_of_bound_all_final"] < 0.85


def test_expansion_defaults_to_0_1_with_either_plan_from_a_file_too(tmp_path):
    """Unset, ``expansion`` is 0.1 with either plan, from a file as from --set; 0 turns it off."""
    scenario = tmp_path / "s.toml"
    scenario.write_text('[coverage]\nplan = "local"\n')
    assert config.load(scenario, []).coverage.expansion == 0.1
    assert config.load(scenario, ["coverage.plan=global"]).coverage.expansion == 0.1
    assert config.load(scenario, ["coverage.expansion=0"]).coverage.expansion == 0.0


@pytest.mark.slow
def test_expansion_leaves_follow_mode_alone():
    """The paper's controller moves leaders by their forces alone, whatever ``expansion``."""
    settings = coverage_settings("unit disk", "global", 20, 0.0, 1, 60) + ["coverage.members=follow"]
    a, b = (execute(config.load(None, settings + [f"coverage.expansion={e}"])) for e in (0.0, 0.5))
    assert len(a.sim.state.legs()) > 20
    assert a.sim.state.legs().equals(b.sim.state.legs())


@pytest.mark.slow
def test_with_unequal_ranges_the_team_never_covers_more_than_the_bound():
    """Unequal ranges (100, 100 and four of 150 m): the team, connected through links
    longer than the smallest range, covers at most U with one range per robot
    (docs/validation.md item 16), so covered_of_bound_all never exceeds 1."""
    ranges = [100.0, 100.0, 150.0, 150.0, 150.0, 150.0]
    r = spread_run(6, 1, 1200.0, duration=150, **{"world.centre_side_m": 100.0, "channel.range_m": ranges})
    cov = r.frames["coverage"]
    assert cov["connected"].all()
    assert (cov["covered_fraction_all"] - cov["covered_error_bound_all"] <= cov["coverage_bound"]).all()
    assert cov["covered_of_bound_all"].max() > 0.85
    assert cov["coverage_bound"].iloc[-1] == pytest.approx(
        connected_coverage_bound(6, 100.0, ranges) / 1200.0**2, rel=1e-15
    )
