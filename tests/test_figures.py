"""``netsim figures`` on runs of any kind, and the shared colours of groups."""

import numpy as np
import pytest

from netsim.tools import style
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
