"""Coverage on the radio the robots really have (docs/model.md section 5, "Staying
connected"; mobility/keep.py): the coverage and control tables count the links of
links.parquet, and the plan keeps a spanning forest of those links up over every step."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from netsim.mobility.keep import FADE_SIGMAS, LinkRules, fade_travel_m, plausible_change_db
from netsim.mobility.spread import forest_rows
from netsim.mobility.steps import Candidates

from netsim import config
from netsim.errors import ConfigError
from netsim.metrics import components_in_links_table, components_of_links
from netsim.radio.propagation import LogDistanceParams, effective_range_m
from netsim.run import execute
from netsim.tools.cli import main
from netsim.world.los import walls_crossed

COVERAGE = ["mobility.model=static", "coverage.enabled=true", "protocol.message_rate_hz=0", "world.placement=centre"]
OFFICE = ["world.map=office", "world.side_m=200", "world.n_robots=30", "world.centre_side_m=50", "duration_s=80"]
RADIOS = {
    "unit_disk": ["world.n_robots=30", "world.side_m=800", "world.centre_side_m=200", "channel.range_m=100"],
    "shadowing": [
        "world.n_robots=40",
        "world.side_m=1000",
        "channel.propagation=log_distance",
        "channel.shadowing_sigma_db=4",
        "duration_s=200",
    ],
    "office_line_of_sight": [*OFFICE, "channel.range_m=30"],
    "office_wall_loss": [
        *OFFICE,
        "channel.propagation=log_distance",
        "channel.sensitivity_dbm=-68",
        "channel.wall_loss_db=5",
    ],
}


def real_components(links, n: int, t: float) -> int:
    """Components of the links.parquet network at ``t`` (a link is up on ``[t_up, t_down)``)."""
    return int(components_in_links_table(links, n, [t])[0])


@pytest.fixture(scope="module")
def radio_run(request):
    cfg = config.load(None, [*COVERAGE, *RADIOS[request.param]])
    return cfg, execute(cfg)


@pytest.mark.slow
@pytest.mark.parametrize("radio_run", list(RADIOS), indirect=True)
def test_coverage_table_counts_the_links_of_links_parquet(radio_run):
    """At every sample the coverage table's components (and connected) are those of the
    links.parquet network; at every step the control table's are too."""
    cfg, r = radio_run
    n, links = cfg.world.n_robots, r.frames["links"]
    cov = r.frames["coverage"]
    real = [real_components(links, n, t) for t in cov["t_s"]]
    assert cov["components"].tolist() == real
    assert cov["connected"].tolist() == [c == 1 for c in real]
    steps = r.frames["control"]
    assert len(steps) > 5
    assert steps["components"].tolist() == [real_components(links, n, t) for t in steps["t_s"]]


@pytest.mark.slow
@pytest.mark.parametrize("radio_run", ["unit_disk", "shadowing"], indirect=True)
def test_real_network_never_splits_after_control_starts(radio_run):
    """From the first control step on, the number of components of the links.parquet
    network never grows: checked at every link event, for a team that starts connected
    (on a map, where links.parquet is sampled, the next test checks the exact network)."""
    cfg, r = radio_run
    n, links = cfg.world.n_robots, r.frames["links"]
    start = cfg.sections["coverage"].start_s
    events = np.unique(np.r_[links["t_up_s"], links["t_down_s"]])
    events = events[(events >= start) & (events < cfg.duration_s)]
    counts = [real_components(links, n, t) for t in [start, *events.tolist()]]
    assert len(events) > 10
    assert np.all(np.diff(counts) <= 0), counts
    # The team did spread.
    assert r.summary["covered_fraction_all_final"] > 1.2 * r.summary["covered_fraction_all_start"]


def exact_components(cfg, r, times) -> np.ndarray:
    """Components of the network the radio makes on the map at each of ``times``, from the
    exact positions (the legs) and the exact walls crossed."""
    from netsim.radio.propagation import path_loss_db
    from netsim.topology import geometric_pairs
    from netsim.trajectory import sample_positions
    from netsim.world.maps import cached_map

    n, m = cfg.world.n_robots, cached_map(cfg.world.map)
    ch = cfg.channel
    xy = sample_positions(r.frames["legs"], n, times)[["x_m", "y_m"]].to_numpy().reshape(len(times), n, 2)
    ranges = r.sim.state.range_m
    out = []
    for pos in xy:
        a, b, d = geometric_pairs(pos, ranges)
        walls = walls_crossed(m, pos[a], pos[b])
        if ch.propagation == "unit_disk":
            up = walls == 0
        else:
            p = ch.radio
            up = path_loss_db(d, p) + p.wall_loss_db * walls <= p.tx_power_dbm - p.sensitivity_dbm
        out.append(components_of_links(n, a[up], b[up]).max() + 1)
    return np.array(out)


@pytest.mark.slow
@pytest.mark.parametrize("radio_run", ["office_line_of_sight", "office_wall_loss"], indirect=True)
def test_on_a_map_the_network_never_has_more_components_than_at_the_last_step(radio_run):
    """On a map, from the exact geometry (every 0.05 s): the number of components never
    exceeds its value at the start of the latest control step, and never grows from one
    step to the next. (Between steps a link that comes up may merge two components and go
    down again: nothing kept it.)"""
    cfg, r = radio_run
    steps = r.frames["control"]["t_s"].to_numpy()
    assert len(steps) > 5
    times = np.arange(steps[0], cfg.duration_s, 0.05)
    counts = exact_components(cfg, r, times)
    at_steps = exact_components(cfg, r, steps)
    assert np.all(np.diff(at_steps) <= 0), at_steps
    latest = np.searchsorted(steps, times + 1e-9, side="right") - 1
    over = np.flatnonzero(counts > at_steps[latest])
    assert len(over) == 0, list(zip(times[over], counts[over], at_steps[latest[over]]))


@pytest.mark.slow
def test_issue_28_shadowing_reproduction_reports_the_real_network():
    """The issue's run: 40 robots from the centre of a 1 km square, log-distance with 4 dB
    shadowing, coverage on. The table said 1 component while links.parquet had up to 18;
    now it agrees at every sample, and the real network never splits after control starts."""
    cfg = config.load(
        None,
        [
            *COVERAGE,
            "world.n_robots=40",
            "world.side_m=1000",
            "channel.propagation=log_distance",
            "channel.shadowing_sigma_db=4",
            "duration_s=400",
        ],
    )
    r = execute(cfg)
    links, cov = r.frames["links"], r.frames["coverage"]
    assert len(cov) == 81  # every 5 s from 0 to the end
    assert cov["components"].tolist() == [real_components(links, 40, t) for t in cov["t_s"]]
    events = np.unique(np.r_[links["t_up_s"], links["t_down_s"]])
    events = events[(events >= 10.0) & (events < 400.0)]
    counts = [real_components(links, 40, t) for t in [10.0, *events.tolist()]]
    assert max(counts) == counts[0] == 1


# -- the rules of a kept link -----------------------------------------------------------------
def test_fade_travel_keeps_the_plausible_change_within_the_budget():
    """The pair travel allowed is the largest over which the shadowing's drift plus
    FADE_SIGMAS standard deviations of its change stays within the link's budget."""
    rng = np.random.default_rng(3)
    budget = np.r_[rng.uniform(1.0, 15.0, 200), 40.0, 60.0]
    x = np.r_[rng.uniform(-16.0, 16.0, 200), -16.0, 0.0]
    sigma, dcorr = 4.0, 10.0
    travel = fade_travel_m(budget, x, sigma, dcorr)

    def change(delta, x):
        rho = np.exp(-delta / dcorr)
        return (1 - rho) * np.maximum(-x, 0) + FADE_SIGMAS * sigma * np.sqrt(1 - rho**2)

    f = np.isfinite(travel)
    assert f.sum() == 200
    assert np.allclose(change(travel[f], x[f]), budget[f], atol=1e-6)
    assert np.all(change(1.01 * travel[f], x[f]) > budget[f])
    # Inf: even complete decorrelation stays within the budget.
    assert np.all(change(np.full((~f).sum(), 1e9), x[~f]) <= budget[~f])
    assert fade_travel_m(np.array([0.0, -1.0]), np.zeros(2), sigma, dcorr).tolist() == [0.0, 0.0]


def shadowed_rules(pos, x_db, anchor_m, travelled_m, fade_margin_db=8.0, margin_m=1.0):
    """LinkRules of a log-distance radio with 4 dB shadowing over the links (0, k), each
    with its measured shadowing ``x_db`` drawn at pair travel ``anchor_m``."""
    params = LogDistanceParams(shadowing_sigma_db=4.0)
    n = len(pos)
    table = {(0, k): (x_db[k - 1], anchor_m[k - 1]) for k in range(1, n)}

    def state(a, b):
        xs = [table[(int(p), int(q))] for p, q in zip(a, b)]
        return np.array([v[0] for v in xs]), np.array([v[1] for v in xs])

    shadow = SimpleNamespace(
        sigma_db=4.0, clip_db=16.0, decorrelation_m=10.0, state=state, loss_terms=lambda x: np.clip(x, -16.0, 16.0)
    )
    compiled = SimpleNamespace(log=SimpleNamespace(params=params), shadow=shadow, walls=None)
    reception = SimpleNamespace(compiled=compiled, map=None)
    travel = np.asarray(travelled_m, float)
    robots = SimpleNamespace(
        n=n, range_m=np.full(n, 100.0), pair_travelled_m=lambda t, a, b: travel[np.asarray(b)] + travel[np.asarray(a)]
    )
    links = SimpleNamespace(up_pairs=lambda: (np.zeros(n - 1, np.int64), np.arange(1, n)))
    return LinkRules(reception, robots, links, margin_m, fade_margin_db), params


def test_a_shadowed_link_ends_the_step_with_the_fade_margin_left():
    """A strong link (margin above the fade margin) may end the step as long as its margin,
    with the shadowing measured on it, stays at the fade margin; its pair travel is bounded
    by fade_travel_m less the travel since the shadowing was measured."""
    pos = np.array([[0.0, 0.0], [40.0, 0.0]])
    rules, params = shadowed_rules(pos, x_db=[2.0], anchor_m=[5.0], travelled_m=[3.0, 2.5])
    c = rules.candidates(pos, 0.0)
    assert c.keep_m[0] == pytest.approx(float(effective_range_m(params, 2.0 + 8.0)))
    assert c.travel_m[0] == pytest.approx(float(fade_travel_m(np.array([8.0]), np.array([2.0]), 4.0, 10.0)[0]) - 0.5)


def test_a_weak_shadowed_link_does_not_lengthen():
    """A link whose margin is below the fade margin may not end the step longer than it is,
    and its travel is bounded by its own margin."""
    pos = np.array([[0.0, 0.0], [80.0, 0.0]])
    rules, params = shadowed_rules(pos, x_db=[0.0], anchor_m=[0.0], travelled_m=[0.0, 0.0])
    c = rules.candidates(pos, 0.0)
    margin = params.budget_db - 30.0 * np.log10(80.0)
    assert 0 < margin < 8.0
    assert c.keep_m[0] == pytest.approx(80.0)
    assert c.travel_m[0] == pytest.approx(float(fade_travel_m(np.array([margin]), np.zeros(1), 4.0, 10.0)[0]))


def test_a_link_within_the_sure_distance_has_no_travel_bound():
    """Within the distance at which even the worst clipped shadowing (+4 sigma) leaves it
    up, a link is kept as a disk link: no bound on travel, guaranteed."""
    pos = np.array([[0.0, 0.0], [20.0, 0.0]])
    rules, params = shadowed_rules(pos, x_db=[12.0], anchor_m=[0.0], travelled_m=[50.0, 50.0])
    c = rules.candidates(pos, 0.0)
    sure = float(effective_range_m(params, 16.0))
    assert 20.0 < sure
    assert np.isinf(c.travel_m[0])
    assert c.keep_m[0] == pytest.approx(sure - 1.0)


def test_a_link_the_channel_has_not_up_is_not_a_candidate():
    """Candidates are the links up now as the channel made them, not the pairs in range:
    a pair within range whose measured margin is negative is left out."""
    pos = np.array([[0.0, 0.0], [30.0, 0.0], [90.0, 0.0]])
    rules, _ = shadowed_rules(pos, x_db=[0.0, 15.0], anchor_m=[0.0, 0.0], travelled_m=[0.0, 0.0, 0.0])
    c = rules.candidates(pos, 0.0)
    assert list(zip(c.i.tolist(), c.j.tolist())) == [(0, 1)]


def test_a_link_is_a_candidate_exactly_when_the_radio_hears_a_frame_across_it():
    """A measured link is a candidate iff a frame across it now is heard:
    ``P_t - (PL(d) + X) >= sensitivity``, the radio's sum to the last bit, with pairs placed
    within a few floats of each one's edge."""
    rng = np.random.default_rng(5)
    x = rng.uniform(-10.0, 10.0, 60)
    params = LogDistanceParams(shadowing_sigma_db=4.0)
    edge = effective_range_m(params, np.clip(x, -16.0, 16.0))
    d = np.array([np.nextafter(r, np.inf if k % 2 else 0.0) for r, k in zip(edge, rng.integers(0, 2, 60))])
    for _ in range(3):
        d = np.nextafter(d, np.where(rng.random(60) < 0.5, np.inf, 0.0))
    pos = np.vstack([[0.0, 0.0], np.c_[d, np.zeros(60)]])
    rules, _ = shadowed_rules(pos, x_db=x, anchor_m=np.zeros(60), travelled_m=np.zeros(61))
    c = rules.candidates(pos, 0.0)
    heard = params.tx_power_dbm - (params.path_loss_db(d) + np.clip(x, -16.0, 16.0)) >= params.sensitivity_dbm
    assert 0 < heard.sum() < 60
    assert sorted(c.j.tolist()) == (np.flatnonzero(heard) + 1).tolist()


def test_the_forest_prefers_the_links_with_the_largest_margin():
    """Of a triangle, the spanning forest lets go of the link with the least margin (the
    largest weight), however short it is."""
    i, j = np.array([0, 0, 1]), np.array([1, 2, 2])
    d = np.array([10.0, 50.0, 45.0])
    weight = np.array([9.0, 1.0, 2.0])  # the short link 0-1 is the weakest
    inf = np.full(3, np.inf)
    rows = forest_rows(3, Candidates(i, j, d, weight, d, inf, d))
    assert sorted(rows.tolist()) == [1, 2]


def test_a_link_whose_pair_moved_since_its_shadowing_was_measured_weighs_more():
    """Two links alike but for the pair travel since their shadowing was measured: the
    stale one weighs more by the plausible change of its shadowing over that travel (its
    margin left), so a forest lets it go first. A link left unkept while its robots moved
    on is weaker than its measurement says."""
    pos = np.array([[0.0, 0.0], [60.0, 0.0], [0.0, 60.0]])
    rules, _ = shadowed_rules(pos, x_db=[1.0, 1.0], anchor_m=[0.0, 0.0], travelled_m=[0.0, 0.0, 3.0])
    c = rules.candidates(pos, 0.0)
    assert list(zip(c.i.tolist(), c.j.tolist())) == [(0, 1), (0, 2)]
    change = float(plausible_change_db(np.array([3.0]), np.array([1.0]), 4.0, 10.0)[0])
    assert change > 1.0
    assert c.weight[1] - c.weight[0] == pytest.approx(change)


@pytest.mark.slow
def test_snapshot_with_the_link_state_has_the_channels_links():
    """Under shadowing, a snapshot given the run's link state has the links up now (those of
    the live graph and of links.parquet), where the unit disk of the implied range differs."""
    from netsim.run import build
    from netsim.topology import snapshot

    cfg = config.load(
        None,
        [
            "world.n_robots=30",
            "world.side_m=400",
            "duration_s=30",
            "channel.propagation=log_distance",
            "channel.shadowing_sigma_db=6",
        ],
    )
    sim = build(cfg)
    live = sim.live_topology()
    wrong, differs = [], []

    def compare():
        for t in np.linspace(3.0, 29.0, 14).tolist():
            yield sim.env.timeout(t - sim.env.now)
            g = snapshot(sim.state, sim.now, links=sim.links)
            if set(g.edges) != set(live.graph.edges):
                wrong.append(t)
            differs.append(set(g.edges) != set(snapshot(sim.state, sim.now).edges))

    sim.env.process(compare())
    sim.run()
    assert wrong == []
    assert any(differs)


def wall_rules(blocks, resolution_m=0.5, side_m=40.0):
    """LinkRules of the unit disk (range 30 m) with line of sight on a map whose occupied
    cells are the rectangles ``blocks`` ((x0, x1, y0, y1), metres)."""
    from netsim.world.maps import OccupancyMap

    cells = int(side_m / resolution_m)
    occupied = np.zeros((cells, cells), bool)
    for x0, x1, y0, y1 in blocks:
        rows = slice(int(y0 / resolution_m), int(y1 / resolution_m))
        occupied[rows, int(x0 / resolution_m) : int(x1 / resolution_m)] = True
    m = OccupancyMap(occupied, ~occupied, resolution_m, (0.0, 0.0))
    compiled = SimpleNamespace(log=None, shadow=None, walls=None)
    robots = SimpleNamespace(n=2, range_m=np.full(2, 30.0))
    return LinkRules(SimpleNamespace(compiled=compiled, map=m), robots, None, 1.0, 8.0), m


def one_link(pos):
    d = np.array([float(np.hypot(*(pos[0] - pos[1])))])
    return Candidates(np.array([0]), np.array([1]), d, d, np.array([29.0]), np.array([np.inf]), np.array([30.0]))


def line_of_sight_throughout(m, pos, move, steps=2001):
    t = np.linspace(0.0, 1.0, steps)[:, None]
    return bool((walls_crossed(m, pos[0] + move[0] * t, pos[1] + move[1] * t) == 0).all())


def test_a_step_is_cut_before_a_wall_sweeps_between_two_robots():
    """Two robots translating side by side past a wall keep line of sight at both ends of
    the step but lose it in between: the step is cut just before the loss (the walls
    between them are computed over the whole step, not at its ends)."""
    rules, m = wall_rules([(9.0, 11.0, 10.0, 12.0)])
    pos = np.array([[5.0, 5.0], [15.0, 5.0]])
    move = np.array([[0.0, 20.0], [0.0, 20.0]])
    assert line_of_sight_throughout(m, pos, np.zeros_like(move))
    assert not line_of_sight_throughout(m, pos, move)
    assert walls_crossed(m, pos[[0]] + move[[0]], pos[[1]] + move[[1]])[0] == 0  # clear at the end
    scale = rules.cut_for_walls(pos, move, np.array([False, False]), one_link(pos), np.array([0]), 1.0)
    assert 0.2 < scale[0] == scale[1] < 0.25
    assert line_of_sight_throughout(m, pos, move * scale[:, None])


def test_a_missed_command_is_checked_too():
    """A commanded robot may miss its command and hold while its partner moves: the step
    is cut so that the link keeps line of sight in that case too, even where both moving
    would keep it."""
    rules, m = wall_rules([(9.5, 10.0, 8.5, 9.0)])
    pos = np.array([[0.0, 10.0], [20.0, 10.0]])
    move = np.array([[0.0, 3.0], [0.0, -3.0]])
    held_first = move * [[0.0], [1.0]]
    assert line_of_sight_throughout(m, pos, move)
    assert not line_of_sight_throughout(m, pos, held_first)
    commanded = np.array([True, False])
    scale = rules.cut_for_walls(pos, move, commanded, one_link(pos), np.array([0]), 1.0)
    assert scale[1] < 1.0
    cut = move * scale[:, None]
    assert line_of_sight_throughout(m, pos, cut)
    assert line_of_sight_throughout(m, pos, cut * [[0.0], [1.0]])


# -- bad input ------------------------------------------------------------------------------
def test_negative_fade_margin_is_one_line_exit_2_nothing_written(tmp_path, capsys):
    out = tmp_path / "out"
    argv = ["run", "--quiet", "--out", str(out), "--set", "coverage.fade_margin_db=-1"]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("netsim: error: coverage.fade_margin_db = -1"), err
    assert "\n" not in err
    assert not out.exists()


def test_coverage_needs_link_events_during_the_run():
    """The controller counts and keeps the links as the channel makes them during the run."""
    with pytest.raises(ConfigError) as err:
        config.load(None, [*COVERAGE, "events.runtime_links=off"])
    assert err.value.key == "events.runtime_links"
