"""``netsim figures`` on runs of any kind, and the shared colours of groups."""

import numpy as np
import pandas as pd
import pytest

from netsim.tools import figures, style
from netsim.tools.cli import main

PNG = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def waypoint_run(tmp_path_factory):
    """A short random waypoint run without coverage."""
    out = tmp_path_factory.mktemp("rwp")
    assert (
        main(
            [
                "run",
                "--quiet",
                "--no-progress",
                "--out",
                str(out),
                "--set",
                "world.n_robots=20",
                "--set",
                "duration_s=40",
            ]
        )
        == 0
    )
    return out


@pytest.mark.slow
def test_figures_of_a_run_without_coverage_say_what_they_cannot_show(waypoint_run, tmp_path, capsys):
    """Paths are drawn for any mobility model; at t = 0 nobody has a group yet, and a run
    without coverage has no coverage disks: each is said in one line."""
    assert main(["figures", str(waypoint_run), "--out", str(tmp_path), "--at", "0"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 3
    assert "fig6" in lines[0] and "every robot is undecided" in lines[0]
    assert lines[1].endswith("fig7_leader_paths.png")
    assert "no coverage disks" in lines[2]
    for name in ("fig6_initial_deployment.png", "fig7_leader_paths.png", "fig8_final_deployment.png"):
        assert (tmp_path / name).read_bytes()[:8] == PNG


def test_figures_quiet_print_nothing_and_draw_all_three(waypoint_run, tmp_path, capsys):
    """``--quiet``, as `netsim run`'s: nothing on either stream, the three figures drawn."""
    assert main(["figures", str(waypoint_run), "--out", str(tmp_path), "--quiet"]) == 0
    captured = capsys.readouterr()
    assert captured.out == "" and captured.err == ""
    for name in ("fig6_initial_deployment.png", "fig7_leader_paths.png", "fig8_final_deployment.png"):
        assert (tmp_path / name).read_bytes()[:8] == PNG


@pytest.mark.slow
def test_figures_of_a_run_without_coverage_draw_fig6_when_every_robot_is_in_a_group(waypoint_run, tmp_path, capsys):
    """Without coverage (no control start to draw at), Fig. 6 is drawn at the first sample
    at which every robot is in a group, and the line written says which time that is."""
    from netsim.tools import figures

    assert main(["figures", str(waypoint_run), "--out", str(tmp_path)]) == 0
    first = capsys.readouterr().out.splitlines()[0]
    run = figures.read_run(waypoint_run)
    times = np.sort(run.positions["t_s"].unique())
    undecided = [int((figures.snapshot(run, t).role == "gamma").sum()) for t in times]
    k = undecided.index(0)
    assert k > 0 and undecided[k - 1] > 0
    assert "fig6" in first and f"drawn at t = {times[k]:g} s" in first and "undecided" not in first


@pytest.mark.slow
def test_undecided_robots_are_counted_as_the_figures_read_the_roles(waypoint_run):
    """The count of undecided robots at each sample equals the undecided robots of
    :func:`figures.snapshot` there (a robot's last role record at or before the sample)."""
    from netsim.tools import figures

    run = figures.read_run(waypoint_run)
    times = np.sort(run.positions["t_s"].unique())
    counted = figures.undecided_at(run, times)
    assert counted.tolist() == [int((figures.snapshot(run, t).role == "gamma").sum()) for t in times]
    assert counted[0] == 20 and counted.min() == 0


@pytest.mark.slow
def test_figures_of_a_run_without_roles(tmp_path, capsys):
    """The Ack beacon alone gives no roles: robots are plain dots, and the figures say so."""
    run = tmp_path / "run"
    sets = ["protocol.model=ack", "world.n_robots=10", "duration_s=10"]
    assert main(["run", "--quiet", "--no-progress", "--out", str(run), *[a for s in sets for a in ("--set", s)]]) == 0
    assert main(["figures", str(run), "--out", str(tmp_path / "f")]) == 0
    assert "no roles" in capsys.readouterr().out.splitlines()[0]
    assert (tmp_path / "f" / "fig7_leader_paths.png").read_bytes()[:8] == PNG


@pytest.mark.slow
def test_figures_at_a_chosen_time(waypoint_run, tmp_path, capsys):
    assert main(["figures", str(waypoint_run), "--out", str(tmp_path), "--at", "20"]) == 0
    assert "undecided" not in capsys.readouterr().out


@pytest.mark.parametrize("at", ["-1", "41", "nan"])
def test_figures_at_a_time_outside_the_run_is_an_error_and_writes_nothing(waypoint_run, tmp_path, capsys, at):
    out = tmp_path / "figs"
    assert main(["figures", str(waypoint_run), "--out", str(out), "--at", at]) == 2
    err = capsys.readouterr().err
    assert err.startswith("netsim: error: --at") and "between 0 and 40" in err
    assert not out.exists()


def test_figures_scenario_rejects_a_time_beyond_its_duration_before_running(tmp_path, capsys):
    assert main(["figures", "--out", str(tmp_path / "f"), "--set", "duration_s=30", "--at", "31"]) == 2
    assert "duration_s = 30" in capsys.readouterr().err
    assert not (tmp_path / "f").exists()


def test_neighbouring_groups_never_share_a_colour():
    """300 groups, far more than colours: any two leaders that could have touching groups
    differ; the same leaders get the same colours again."""
    rng = np.random.default_rng(8)
    leaders = rng.permutation(1000)[:300]
    xy = rng.uniform(0, 5000, (300, 2))
    colours = style.group_colours(leaders, xy, 100.0)
    assert colours == style.group_colours(leaders, xy, 100.0)
    assert set(colours.values()) <= set(style.GROUP_PALETTE)
    d = np.hypot(*(xy[:, None] - xy[None]).transpose(2, 0, 1))
    i, j = np.nonzero(np.triu(d < style.NEIGHBOUR_RANGES * 100.0, 1))
    assert len(i) > 300
    assert all(colours[int(leaders[a])] != colours[int(leaders[b])] for a, b in zip(i, j))


def test_style_is_plain_values_for_other_viewers():
    import json

    data = json.loads(json.dumps(style.as_json()))
    assert data["roles"]["alpha"]["marker"] == "^" and len(data["group_palette"]) == len(set(style.GROUP_PALETTE))
    assert style.NO_GROUP not in style.GROUP_PALETTE


@pytest.mark.slow
def test_figures_draw_the_map_under_the_robots(tmp_path, capsys):
    """A run on the office map: every figure shows its walls (the wall grey), and a run in
    open space has none of that grey."""
    from PIL import Image

    def grey_pixels(run_args, out):
        assert main(["run", "--quiet", "--no-progress", "--out", str(out), *run_args]) == 0
        assert main(["figures", str(out), "--out", str(out / "figs")]) == 0
        counts = []
        for name in ("fig6_initial_deployment.png", "fig7_leader_paths.png", "fig8_final_deployment.png"):
            img = np.asarray(Image.open(out / "figs" / name).convert("RGB")).astype(int)
            counts.append(int((np.abs(img - 89) <= 2).all(axis=-1).sum()))
        return counts

    common = ["--set", "world.n_robots=15", "--set", "duration_s=20", "--set", "world.side_m=100"]
    on_map = grey_pixels(
        [*common, "--set", "world.map=office", "--set", "mobility.stationary_start=false"], tmp_path / "map"
    )
    open_space = grey_pixels(common, tmp_path / "open")
    # Antialiased text and lines have a few such pixels; walls have thousands.
    assert min(on_map) > 10 * max(open_space), (on_map, open_space)


@pytest.mark.slow
def test_fig8_on_a_map_gives_the_runs_own_covered_fraction_of_the_free_region(tmp_path, monkeypatch):
    """On a map coverage is of the free region the team started in (docs/model.md 5.3): Fig. 8
    says what the run's summary says, not the share of the whole square, walls included."""
    import json
    import re

    import matplotlib.axes

    titles = []
    set_title = matplotlib.axes.Axes.set_title
    monkeypatch.setattr(
        matplotlib.axes.Axes,
        "set_title",
        lambda ax, text, *a, **k: (titles.append(text), set_title(ax, text, *a, **k))[1],
    )
    run = ["world.map=cave", "world.side_m=200", "world.n_robots=12", "duration_s=20", "mobility.model=static"]
    run += ["coverage.enabled=true", "channel.range_m=40", "world.placement=uniform", "protocol.message_rate_hz=0"]
    out = tmp_path / "cave"
    assert (
        main(["run", "--quiet", "--no-progress", "--out", str(out), "--seed", "2", *[f"--set={k}" for k in run]]) == 0
    )
    assert main(["figures", str(out), "--out", str(tmp_path / "figs")]) == 0
    summary = json.loads((out / "summary.json").read_text())
    title = next(t for t in titles if t.startswith("Fig. 8"))
    covered, bound = (
        float(x) for x in re.search(r"([\d.]+) % of the free region covered.* at most (\d+) %", title, re.S).groups()
    )
    assert covered == pytest.approx(100 * summary["covered_fraction_all_final"], abs=0.05)
    assert bound == round(100 * summary["coverage_bound"])


def _torus_run(out, placement, model, **extra):
    """A 100 m torus run of the robots at ``placement`` (rows of x_m, y_m), range 10 m."""
    csv = out / "start.csv"
    csv.write_text("x_m,y_m\n" + "".join(f"{x},{y}\n" for x, y in placement))
    overrides = {"world.n_robots": len(placement), "world.side_m": 100, "world.torus": "true"}
    overrides |= {"world.placement": f'"{csv}"', "mobility.model": model, "channel.range_m": 10, "duration_s": 20}
    overrides |= extra
    args = [a for k, v in overrides.items() for a in ("--set", f"{k}={v}")]
    assert main(["run", "--quiet", "--no-progress", "--out", str(out / "run"), *args]) == 0
    from netsim.tools import figures

    return figures, figures.read_run(out / "run")


def _drawn_segments(ax) -> list[np.ndarray]:
    return [np.asarray(s) for c in ax.collections if hasattr(c, "get_segments") for s in c.get_segments()]


def test_figures_on_a_torus_draw_a_link_across_the_seam_from_both_ends(tmp_path):
    """Robots 3 m apart across the seam of a 100 m torus are linked: Figs. 6 and 8 draw
    that link as two 3 m segments, one from each robot toward the border (not a 97 m line
    across the area, nor nothing)."""
    figures, run = _torus_run(tmp_path, [(1.0, 50.0), (98.0, 50.0), (50.0, 10.0)], "static")
    plt = figures.pyplot()
    fig, ax = plt.subplots()
    snap = figures.snapshot(run, 19.0)
    figures.draw_deployment(ax, snap, figures.run_colours(run), figures.links_at(run, snap), side_m=100.0)
    segs = _drawn_segments(ax)
    plt.close(fig)
    assert len(segs) == 2
    inside = [tuple(p) for s in segs for p in s if 0.0 <= p[0] < 100.0]
    assert sorted(inside) == [(1.0, 50.0), (98.0, 50.0)]
    assert all(np.hypot(*(s[1] - s[0])) == pytest.approx(3.0) for s in segs)


def test_figures_on_a_torus_cut_a_path_where_it_crosses_the_seam(tmp_path):
    """A robot driving at 2 m/s across the seam: Fig. 7 draws no step longer than its
    travel between two samples, and counts its travel across the seam."""
    figures, run = _torus_run(
        tmp_path,
        [(95.0, 50.0), (5.0, 50.0)],
        "random_direction",
        **{"mobility.speed_min_mps": 2, "mobility.speed_max_mps": 2, "output.position_interval_s": 1.0},
    )
    plt = figures.pyplot()
    fig, ax = plt.subplots()
    end = figures.snapshot(run, float(run.positions.t_s.max()))
    note = figures.draw_paths(ax, run, 0.0, end.t_s, end, figures.run_colours(run), 10.0)
    segs = _drawn_segments(ax)
    plt.close(fig)
    longest = max(float(np.hypot(*np.diff(s, axis=0).T).max()) for s in segs if len(s) > 1)
    assert note == "" and longest <= 2.0 + 1e-9
    wrapped = run.positions.groupby("robot")["x_m"].agg(lambda x: np.abs(np.diff(x)).max()).max()
    assert wrapped > 50.0  # the run did cross the seam


@pytest.mark.parametrize(
    "sets",
    [
        ["channel.range_m=[80.0, 160.0, 80.0, 160.0, 80.0, 160.0, 80.0, 160.0]", "world.side_m=400"],
        ["channel.propagation=log_distance", "channel.shadowing_sigma_db=6", "world.side_m=200"],
    ],
)
def test_deployment_figures_draw_the_runs_own_links(tmp_path, sets):
    """Figs. 6 and 8 draw the links the run had at their instant: with unequal ranges each
    pair within both ends' ranges (the least range for all drew 9 of 15), under shadowing
    the channel's links of links.parquet (the implied range's disks drew 26 of 30)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import pandas as pd
    from matplotlib.collections import LineCollection

    from netsim.metrics import links_up_at
    from netsim.tools import figures

    base = ["world.n_robots=8", "duration_s=30", "mobility.speed_max_mps=8"]
    out = tmp_path / "run"
    assert main(["run", "--quiet", "--out", str(out), *(a for s in base + sets for a in ("--set", s))]) == 0
    run = figures.read_run(out)
    snap = figures.snapshot(run, 20.0)
    links = pd.read_parquet(out / "links.parquet")
    up = links_up_at(
        links["t_up_s"].to_numpy(), links["t_down_s"].to_numpy(), links["censored_end"].to_numpy(), snap.t_s
    )
    want = {(int(a), int(b)) for a, b in zip(links["a"][up], links["b"][up])}
    if "channel.propagation" not in sets[0]:
        d = np.hypot(*(snap.pos[:, None] - snap.pos[None]).transpose(2, 0, 1))
        r = np.array([80.0, 160.0] * 4)
        assert want == {(a, b) for a in range(8) for b in range(a + 1, 8) if d[a, b] <= min(r[a], r[b])}
    assert len(want) >= 3
    fig, ax = plt.subplots()
    figures.draw_deployment(ax, snap, {}, figures.links_at(run, snap))
    drawn = next(c for c in ax.collections if isinstance(c, LineCollection)).get_segments()
    plt.close(fig)
    # Each segment's ends are its robots' positions (to rounding: a link is drawn as a + (b - a)).
    ends = {tuple(sorted(int(np.argmin(np.hypot(*(snap.pos - p).T))) for p in seg)) for seg in drawn}
    assert ends == want


def test_figures_that_cannot_all_be_written_leave_none(waypoint_run, tmp_path, capsys):
    """A figure's name taken by a directory in --out: one line naming it, exit 2, and no
    figure written (Fig. 6 was left behind, with a traceback)."""
    out = tmp_path / "o"
    (out / "fig7_leader_paths.png").mkdir(parents=True)
    assert main(["figures", str(waypoint_run), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "fig7_leader_paths.png is a directory" in err[0], err
    assert [p.name for p in out.iterdir()] == ["fig7_leader_paths.png"]


@pytest.mark.slow
def test_figures_scenario_progress_is_named_netsim_figures(tmp_path, capsys):
    """The run `netsim figures` makes for itself reports its progress as `netsim figures`,
    not as a `netsim run` the user did not type (standard error is not a terminal here:
    plain lines)."""
    sets = ["world.n_robots=10", "duration_s=20", "coverage.enabled=false"]
    assert main(["figures", "--out", str(tmp_path / "f"), *[a for s in sets for a in ("--set", s)]]) == 0
    progress = [line for line in capsys.readouterr().err.splitlines() if "% (" in line]
    assert progress and all(line.startswith("netsim figures: ") for line in progress), progress


def _made_run(sets, positions, roles=(), groups=None, links=None):
    """A run as figures.read_run gives it, made by hand: the configuration of ``sets``,
    ``positions`` rows (t_s, robot, x_m, y_m), ``roles`` rows (t_s, robot, role, leader, cause)."""
    import pandas as pd

    from netsim import config as cfgmod
    from netsim.tools import figures

    positions = pd.DataFrame(positions, columns=["t_s", "robot", "x_m", "y_m"])
    roles = pd.DataFrame(list(roles), columns=["t_s", "robot", "role", "leader", "cause"])
    return figures, figures.Run(cfgmod.load(None, sets), positions, roles, groups, links)


def _standing(n, times, x_m=None):
    """Position rows of ``n`` robots standing 10 m apart on y = 50 m at each of ``times``."""
    x_m = [10.0 * (i + 1) for i in range(n)] if x_m is None else x_m
    return [(t, i, x_m[i], 50.0) for t in times for i in range(n)]


def test_a_snapshot_holds_the_roles_recorded_at_its_instant():
    """The roles of a snapshot are each robot's last record at or before its sample,
    records at the sample's very instant included; before a robot's first, it is undecided."""
    roles = [(1.0, 0, "alpha", 0, "rule6_elected"), (1.0, 1, "beta", 0, "rule2_join"), (2.5, 1, "gamma", -1, "x")]
    figures, run = _made_run(["world.n_robots=2", "world.side_m=100"], _standing(2, [0.0, 1.0, 2.0]), roles)
    at_1 = figures.snapshot(run, 0.5)
    assert at_1.t_s == 1.0
    assert at_1.role.tolist() == ["alpha", "beta"] and at_1.leader.tolist() == [0, 0]
    at_0 = figures.snapshot(run, 0.0)
    assert at_0.role.tolist() == ["gamma", "gamma"] and at_0.leader.tolist() == [-1, -1]


def test_a_snapshot_of_a_run_without_roles_has_plain_robots():
    """Under a protocol that forms no groups every robot's role is "none", not undecided."""
    figures, run = _made_run(["world.n_robots=2", "protocol.model=ack"], _standing(2, [0.0, 1.0]))
    assert figures.snapshot(run, 1.0).role.tolist() == ["none", "none"]


def test_a_snapshot_knows_each_gateways_other_group():
    """Robot 1, a member of robot 0's group, also belongs to robot 2's: a gateway whose
    other group is 2; the leaders are no gateway."""
    import pandas as pd

    groups = pd.DataFrame(
        {"t_s": 1.0, "robot": [0, 1, 1, 2], "group": [0, 0, 2, 2], "primary": [True, True, False, True]}
    )
    roles = [(0.5, 0, "alpha", 0, ""), (0.5, 1, "beta", 0, ""), (0.5, 2, "alpha", 2, "")]
    figures, run = _made_run(["world.n_robots=3"], _standing(3, [0.0, 1.0]), roles, groups=groups)
    assert figures.snapshot(run, 1.0).other_group.tolist() == [-1, 2, -1]


def test_links_drawn_are_those_up_at_the_instant_links_open_at_the_end_included():
    """From links.parquet: the links up at the instant; at the run's end, those still up
    then (drawn), not one that went down at that very instant."""
    import pandas as pd

    links = pd.DataFrame(
        {
            "a": [0, 0, 1],
            "b": [1, 2, 2],
            "t_up_s": [0.0, 0.0, 1.0],
            "t_down_s": [2.0, 2.0, 2.0],
            "censored": [True, False, True],
            "censored_start": [False, False, False],
            "censored_end": [True, False, True],
        }
    )
    figures, run = _made_run(["world.n_robots=3"], _standing(3, [0.0, 1.0, 2.0]), links=links)
    pairs = figures.links_at(run, figures.snapshot(run, 2.0))
    assert [p.tolist() for p in pairs] == [[0, 1], [1, 2]]
    pairs = figures.links_at(run, figures.snapshot(run, 1.0))
    assert [p.tolist() for p in pairs] == [[0, 0, 1], [1, 2, 2]]


def test_without_a_links_table_links_are_the_unit_disk_on_a_torus_and_none_under_shadowing():
    """A run without links.parquet: on a 100 m torus two robots 4 m apart across the seam
    (range 10 m) are linked; under shadowing no range says which pairs were, so none is drawn."""
    sets = ["world.n_robots=2", "world.side_m=100", "channel.range_m=10"]
    figures, run = _made_run([*sets, "world.torus=true"], _standing(2, [0.0], x_m=[1.0, 97.0]))
    assert [p.tolist() for p in figures.links_at(run, figures.snapshot(run, 0.0))] == [[0], [1]]
    shadowing = ["channel.propagation=log_distance", "channel.shadowing_sigma_db=6", "world.n_robots=2"]
    figures, run = _made_run(shadowing, _standing(2, [0.0], x_m=[1.0, 2.0]))
    assert [p.tolist() for p in figures.links_at(run, figures.snapshot(run, 0.0))] == [[], []]


def test_undecided_robots_are_counted_at_each_instant_from_its_records_on():
    """Undecided before a robot's first record, records at the instant itself counted; a
    run whose roles table is empty has every robot undecided throughout."""
    roles = [(1.0, 0, "alpha", 0, "rule6_elected"), (1.0, 1, "beta", 0, "rule2_join"), (2.5, 1, "gamma", -1, "x")]
    figures, run = _made_run(["world.n_robots=3"], _standing(3, [0.0, 1.0, 2.0, 3.0]), roles)
    assert figures.undecided_at(run, np.array([0.0, 0.5, 1.0, 2.0, 3.0])).tolist() == [3, 3, 1, 1, 2]
    figures, run = _made_run(["world.n_robots=3"], _standing(3, [0.0, 1.0]))
    assert figures.undecided_at(run, np.array([0.0, 1.0])).tolist() == [3, 3]
    assert figures.groups_formed_s(run) == (0.0, 3)


def test_a_gateway_to_the_group_of_robot_0_is_drawn_as_a_gateway():
    """A member of robot 1's group that also belongs to group 0 (robot 0's id, as good a
    group id as any) is drawn as a gateway, beside a plain member."""
    from netsim.tools import figures

    pos = np.array([[10.0, 50.0], [20.0, 50.0]])
    snap = figures.Snapshot(0.0, pos, np.array(["beta", "beta"]), np.array([1, 1]), np.array([0, -1]))
    plt = figures.pyplot()
    fig, ax = plt.subplots()
    figures.draw_deployment(ax, snap, {0: "red", 1: "blue"}, (np.empty(0, int), np.empty(0, int)))
    labels = ax.get_legend_handles_labels()[1]
    plt.close(fig)
    assert style.ROLE_STYLE["gateway"]["label"] in labels and style.ROLE_STYLE["beta"]["label"] in labels


def test_each_piece_of_a_path_cut_at_the_seam_has_its_robots_colour():
    """On a torus a path crossing the seam is cut there and its step across drawn from both
    sides: every piece, the two half steps included, in its own robot's colour."""
    from netsim.tools import figures

    crossing = np.array([[96.0, 50.0], [99.0, 50.0], [2.0, 50.0], [5.0, 50.0]])
    standing = np.full((4, 2), 50.0)
    pieces, colours = figures._path_pieces(np.stack([crossing, standing]), ["red", "blue"], 100.0)
    assert len(pieces) == len(colours) == 5
    assert colours == ["red"] * 4 + ["blue"]
    np.testing.assert_array_equal(pieces[-1], standing)


def test_paths_start_at_their_instant_and_are_framed_to_the_team_within_the_area():
    """Fig. 7 starts every path at its first instant (the hollow markers there), frames the
    team with a margin of one range but no more than 2 % beyond the area, and says so when
    nobody moved."""
    figures, run = _made_run(
        ["world.n_robots=2", "world.side_m=100", "protocol.model=ack"],
        [(t, i, x, 50.0) for t in (0.0, 1.0, 2.0) for i, x in enumerate((1.0, 99.0))],
    )
    end = figures.snapshot(run, 2.0)
    plt = figures.pyplot()
    fig, ax = plt.subplots()
    note = figures.draw_paths(ax, run, 1.0, 2.0, end, {}, 10.0)
    first = next(c for c in ax.collections if c.get_label() == "at 1 s")
    xlim = ax.get_xlim()
    plt.close(fig)
    assert note == "nobody moved between 1 s and 2 s"
    np.testing.assert_allclose(first.get_offsets(), [[1.0, 50.0], [99.0, 50.0]])
    assert xlim == pytest.approx((-2.0, 102.0))


@pytest.fixture
def drawn(monkeypatch):
    """figures.draw without encoding PNGs: each figure's title and note, by file name."""
    from pathlib import Path

    from netsim.tools import figures

    seen = {}

    def save(fig, path, note):
        seen[Path(path).name] = (fig.axes[0].get_title(), note)
        figures.pyplot().close(fig)
        Path(path).write_bytes(b"")
        return figures.Drawn(path, note)

    monkeypatch.setattr(figures, "_save", save)
    return seen


def _coverage_run(out, *sets):
    base = ["world.n_robots=7", "world.side_m=200", "mobility.model=static", "duration_s=10"]
    base += ["coverage.enabled=true", "coverage.start_s=4", "protocol.message_rate_hz=0"]
    args = [a for s in [*base, *sets] for a in ("--set", s)]
    assert main(["run", "--quiet", "--no-progress", "--out", str(out), *args]) == 0
    return out


def test_coverage_figures_start_when_control_does_and_draw_the_coverage_disks(tmp_path, drawn):
    """Fig. 6 of a coverage run is drawn when control starts (coverage.start_s) and counts
    the groups (leaders) then; Fig. 8's disks have coverage.radius_m."""
    from netsim.tools import figures

    run = _coverage_run(tmp_path / "run", "coverage.radius_m=30")
    figures.draw(run, tmp_path / "f")
    snap = figures.snapshot(figures.read_run(run), 4.0)
    leaders, members = int((snap.role == "alpha").sum()), int((snap.role == "beta").sum())
    assert leaders != members
    assert drawn["fig6_initial_deployment.png"][0] == f"Fig. 6  Deployment at t = 4 s: 7 robots, {leaders} groups"
    assert "(r = 30 m)" in drawn["fig8_final_deployment.png"][0]


def test_coverage_disks_default_to_the_least_range(tmp_path, drawn):
    from netsim.tools import figures

    run = _coverage_run(tmp_path / "run", "channel.range_m=[80.0, 60.0, 80.0, 80.0, 80.0, 80.0, 80.0]")
    figures.draw(run, tmp_path / "f")
    assert "(r = 60 m)" in drawn["fig8_final_deployment.png"][0]


def test_without_coverage_fig6_says_how_few_were_left_undecided(waypoint_run, tmp_path, drawn):
    """When one robot never joins a group, Fig. 6 is drawn at the first sample with the
    fewest undecided and says so (it does not claim every robot is in a group); the last
    sample may be asked for."""
    import shutil

    import pandas as pd

    from netsim.tools import figures

    run = tmp_path / "run"
    shutil.copytree(waypoint_run, run)
    joined = [(5.0, i, "alpha" if i == 1 else "beta", 1, "") for i in range(1, 20)]
    pd.DataFrame(joined, columns=["t_s", "robot", "role", "leader", "cause"]).to_parquet(run / "roles.parquet")
    (fig6,) = [d for d in figures.draw(run, tmp_path / "f") if d.path.name.startswith("fig6")]
    assert fig6.note == "drawn at t = 5 s, the first sample with the fewest robots undecided (1); see --at"
    figures.draw(run, tmp_path / "g", at_s=40.0)
    assert drawn["fig6_initial_deployment.png"][0].startswith("Fig. 6  Deployment at t = 40 s")


@pytest.mark.parametrize(
    ("sets", "remove", "said"),
    [
        ([], "roles.parquet", "not a run directory with positions (missing roles.parquet)"),
        (
            ["output.position_interval_s=0"],
            "legs.parquet",
            "positions were not sampled (output.position_interval_s = 0) and legs.parquet is missing",
        ),
    ],
    ids=["no-roles", "unsampled"],
)
def test_figures_of_a_run_without_positions_or_roles_is_one_line(tmp_path, capsys, sets, remove, said):
    """A run directory lacking roles.parquet, or whose positions were not sampled and whose
    legs are gone: one line naming what is missing, exit 2, no figure written."""
    run = tmp_path / "run"
    args = [a for s in ["world.n_robots=3", "duration_s=5", *sets] for a in ("--set", s)]
    assert main(["run", "--quiet", "--no-progress", "--out", str(run), *args]) == 0
    if remove:
        (run / remove).unlink()
    capsys.readouterr()
    assert main(["figures", str(run), "--out", str(tmp_path / "f")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"netsim: error: {run}: {said}"]
    assert not (tmp_path / "f").exists()


@pytest.mark.parametrize("duration_s, samples", [(12.0, 13), (12.4, 14)])
def test_figures_of_a_run_that_sampled_no_positions_sample_its_legs(tmp_path, duration_s, samples):
    """A run with output.position_interval_s = 0 keeps its exact motion (legs.parquet): the
    figures sample it at the default interval, the positions a sampled run of the same seed
    wrote, its end included."""
    base = ["world.n_robots=6", f"duration_s={duration_s}"]
    for name, sets in (("sampled", base), ("unsampled", [*base, "output.position_interval_s=0"])):
        args = [a for s in sets for a in ("--set", s)]
        assert main(["run", "--quiet", "--no-progress", "--out", str(tmp_path / name), *args]) == 0
    want = pd.read_parquet(tmp_path / "sampled" / "positions.parquet")
    got = figures.read_run(tmp_path / "unsampled").positions
    assert len(got) == len(want) == 6 * samples
    cols = ["t_s", "robot", "x_m", "y_m"]
    assert np.allclose(got[cols].to_numpy(float), want[cols].to_numpy(float), atol=1e-9)
    assert len(figures.draw(tmp_path / "unsampled", tmp_path / "f")) > 0
