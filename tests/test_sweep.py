"""Sweeps: grid and random points, content-addressed runs, local pool and Dask give the
same frames, resuming after a kill, failures recorded, bad sweep files."""

import json
import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import pandas as pd
import pytest

from netsim import config as cfgmod
from netsim.errors import NetsimInputError
from netsim.tools import sweep as sweepmod
from netsim.tools.cli import main

BASE = {
    "duration_s": 20.0,
    "world": {"n_robots": 12, "side_m": 300.0},
    "protocol": {"model": "clustering"},
    "output": {"position_interval_s": 0.0},
}


def small_sweep(**extra):
    tree = {
        "name": "t",
        "replications": 2,
        "tables": ["links"],
        "base": BASE,
        "grid": {"mobility.speed_max_mps": [2.0, 6.0], "channel.loss_probability": [0.0, 0.2]},
    }
    tree.update(extra)
    return sweepmod.parse(tree)


def standing_trace(n: int) -> str:
    """An ns-2 trace of ``n`` robots standing 20 m apart on a line."""
    return "".join(f"$node_({i}) set X_ {10 + 20 * i}.0\n$node_({i}) set Y_ 10.0\n" for i in range(n))


def metrics_frame(out):
    return sweepmod.load(out).drop(columns=["wall_s"])


def test_grid_expands_every_combination_with_replications():
    runs = small_sweep().runs()
    assert len(runs) == 2 * 2 * 2
    assert len({r.run_id for r in runs}) == 8
    assert {r.replication for r in runs} == {0, 1}
    # The id is a content address: the same run gets the same id in another sweep.
    again = small_sweep(name="other").runs()
    assert [r.run_id for r in runs] == [r.run_id for r in again]


def test_random_points_are_reproducible_and_keep_integers():
    tree = {
        "base": {**BASE, "world": {"side_m": 300.0}},  # n_robots swept: a base's would never run
        "random": {
            "samples": 5,
            "seed": 3,
            "ranges": {"world.n_robots": [5, 9], "channel.loss_probability": [0.0, 0.5]},
        },
    }
    a, b = sweepmod.parse(tree).points, sweepmod.parse(tree).points
    assert a == b and len(a) == 5
    assert all(isinstance(p["world.n_robots"], int) and 5 <= p["world.n_robots"] <= 9 for p in a)
    assert all(0.0 <= p["channel.loss_probability"] <= 0.5 for p in a)


@pytest.mark.slow
def test_local_pool_and_dask_give_identical_frames(tmp_path):
    from distributed import Client, LocalCluster

    sweep = small_sweep()
    local = sweepmod.run_sweep(sweep, tmp_path / "local", workers=2, progress=False)
    assert local.done == 8 and not local.failed
    with LocalCluster(n_workers=2, processes=False, dashboard_address=None) as cluster, Client(cluster) as client:
        remote = sweepmod.run_sweep(sweep, tmp_path / "dask", scheduler=client, progress=False)
    assert remote.done == 8
    a, b = metrics_frame(tmp_path / "local"), metrics_frame(tmp_path / "dask")
    pd.testing.assert_frame_equal(a, b)
    assert {
        "mobility.speed_max_mps",
        "channel.loss_probability",
        "seed",
        "replication",
        "run_id",
        "acks_received",
        "leaders_time_mean",
    } <= set(a.columns)
    links_a = sweepmod.load_table(tmp_path / "local", "links").sort_values(["run_id", "t_up_s", "a", "b"])
    links_b = sweepmod.load_table(tmp_path / "dask", "links").sort_values(["run_id", "t_up_s", "a", "b"])
    pd.testing.assert_frame_equal(links_a.reset_index(drop=True), links_b.reset_index(drop=True))


@pytest.mark.slow
def test_killed_sweep_restarts_and_completes_every_run_exactly_once(tmp_path):
    """The sweep process is killed (SIGKILL, by one of its pool's runs) half-way; started again
    it skips the finished runs and ends with each run exactly once, as an uninterrupted
    sweep would."""
    (tmp_path / "killer.py").write_text(
        textwrap.dedent("""
        import os, signal, time
        from pathlib import Path
        from netsim import plugins
        from netsim.params import NoParams

        MARK = Path(__file__).with_name("killed.marker")
        RUNS = Path(__file__).with_name("out") / "runs"

        def build(params, parts):
            if parts.state.n == 7 and not MARK.exists():
                # Kill only once another run is safely on disk (the other worker's).
                for _ in range(600):
                    if any(RUNS.glob("*.parquet")):
                        break
                    time.sleep(0.1)
                MARK.write_text("killed once")
                os.kill(os.getppid(), signal.SIGKILL)
            static = plugins.resolve(plugins.MOBILITY, "static", "mobility.model")
            return static.build(static.Params(), parts)

        PLUGIN = plugins.PluginSpec(Params=NoParams, build=build)
    """)
    )
    (tmp_path / "s.toml").write_text(
        textwrap.dedent("""
        name = "killed"
        replications = 1
        [base]
        duration_s = 10.0
        [base.mobility]
        model = "killer:PLUGIN"
        [base.output]
        position_interval_s = 0.0
        [grid]
        "world.n_robots" = [4, 5, 6, 7, 8, 9]
    """)
    )
    cmd = [
        str(Path(sys.executable).parent / "netsim"),
        "sweep",
        "s.toml",
        "--workers",
        "2",
        "--out",
        "out",
        "--no-progress",
    ]
    if not Path(cmd[0]).exists():
        pytest.skip("the netsim console script is not installed next to this Python")
    with open(tmp_path / "first.log", "w") as log:
        first = subprocess.Popen(cmd, cwd=tmp_path, stdout=log, stderr=log, start_new_session=True)
        code = first.wait(timeout=300)
    try:
        os.killpg(first.pid, signal.SIGKILL)  # anything the killed sweep left behind
    except ProcessLookupError:
        pass
    assert code == -9  # killed
    done_before = sweepmod.done_ids(tmp_path / "out")
    assert 0 < len(done_before) < 6
    second = subprocess.run(cmd, cwd=tmp_path, capture_output=True, text=True)
    assert second.returncode == 0, second.stderr
    assert f"{len(done_before)} already done" in second.stdout
    runs = sweepmod.load(tmp_path / "out")
    assert len(runs) == 6 and runs.run_id.is_unique
    assert sorted(runs["world.n_robots"]) == [4, 5, 6, 7, 8, 9]
    clean = subprocess.run(cmd[:-3] + ["--out", "clean", "--no-progress"], cwd=tmp_path, capture_output=True, text=True)
    assert clean.returncode == 0
    pd.testing.assert_frame_equal(metrics_frame(tmp_path / "out"), metrics_frame(tmp_path / "clean"))


def test_a_failing_run_is_recorded_and_the_others_finish(tmp_path):
    good, bad = tmp_path / "standing.tcl", tmp_path / "scenario.tcl"
    good.write_text(standing_trace(BASE["world"]["n_robots"]))
    bad.write_text("not a trace\n")
    sweep = sweepmod.parse(
        {
            "name": "f",
            "base": {**BASE, "mobility": {"model": "trace"}},
            "grid": {"mobility.trace_file": [str(good), str(bad)]},
        }
    )
    out = tmp_path / "out"
    report = sweepmod.run_sweep(sweep, out, workers=1, progress=False)
    assert report.done == 1 and len(report.failed) == 1
    failed = json.loads(next((out / "failed").glob("*.json")).read_text())
    assert "no ns-2 movement line" in failed["error"] and failed["point"]["mobility.trace_file"] == str(bad)
    assert "failed" in report.text() and "no ns-2 movement line" in report.text()
    assert len(sweepmod.load(out)) == 1


def test_a_point_naming_a_missing_file_is_refused_before_any_run(tmp_path, capsys):
    """A trace file that is not there is refused as `netsim run` refuses it: one line, exit
    2, nothing written (the sweep ran the other points and failed that one, exit 1)."""
    (tmp_path / "s.toml").write_text(
        'name = "m"\n[base]\nduration_s = 5.0\n[base.world]\nn_robots = 3\n[grid]\n'
        '"mobility.model" = ["static", "trace"]\n"mobility.trace_file" = ["/nonexistent/t.tcl"]\n'
    )
    out = tmp_path / "out"
    assert main(["sweep", str(tmp_path / "s.toml"), "--out", str(out), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "mobility.trace_file = '/nonexistent/t.tcl': no such file" in err, err
    assert not out.exists()


def test_a_point_past_the_machines_memory_is_refused_before_any_run(tmp_path, capsys):
    """As `netsim run` refuses a run that cannot fit in memory, so a sweep refuses a point
    that cannot, before its first run (the run died of an allocation error)."""
    (tmp_path / "s.toml").write_text(
        'name = "m"\n[base]\nduration_s = 300.0\n[grid]\n"output.position_interval_s" = [1.0, 1e-9]\n'
    )
    out = tmp_path / "out"
    assert main(["sweep", str(tmp_path / "s.toml"), "--out", str(out), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "'output.position_interval_s': 1e-09" in err and "of memory" in err, err
    assert not out.exists()


def test_a_table_added_to_the_list_runs_the_finished_runs_again(tmp_path):
    """Runs finished without a table the sweep now keeps are run again to keep it (they
    counted as done, and the table stayed empty); a table a run's models do not write is
    kept as none, so the run is not run again for it."""
    base = {**BASE, "duration_s": 5.0, "protocol": {"model": "ack"}}
    grid = {"channel.mac": ["none", "aloha"]}
    first = sweepmod.parse({"name": "t", "tables": ["links"], "base": base, "grid": grid})
    assert sweepmod.run_sweep(first, tmp_path, workers=1, progress=False).done == 2
    second = sweepmod.parse({"name": "t", "tables": ["links", "medium"], "base": base, "grid": grid})
    report = sweepmod.run_sweep(second, tmp_path, workers=1, progress=False)
    assert (report.skipped, report.done) == (0, 2)
    medium = sweepmod.load_table(tmp_path, "medium")
    runs = sweepmod.load(tmp_path)
    assert list(medium["run_id"].unique()) == list(runs.loc[runs["channel.mac"] == "aloha", "run_id"])
    assert sweepmod.run_sweep(second, tmp_path, workers=1, progress=False).skipped == 2
    assert sweepmod.load_table(tmp_path, "links")["run_id"].nunique() == 2


def test_points_that_resolve_to_one_configuration_run_once_with_a_warning(tmp_path):
    """Comparing two models over a key only one of them reads: the other model's points
    are one configuration, run once, and a warning says so (the sweep was refused)."""
    sweep = sweepmod.parse(
        {
            "name": "a",
            "base": {**BASE, "duration_s": 5.0},
            "grid": {"mobility.model": ["random_waypoint", "gauss_markov"], "mobility.alpha": [0.5, 0.75]},
        }
    )
    with (
        pytest.warns(cfgmod.ConfigWarning, match="mobility.alpha: not used by 'random_waypoint'"),
        pytest.warns(cfgmod.ConfigWarning, match="1 of 4 points resolve to the configuration of a point before"),
    ):
        runs = sweep.runs()
    assert len(runs) == 3 and len({r.run_id for r in runs}) == 3


def test_a_base_may_leave_to_the_grid_a_key_its_model_needs(tmp_path):
    """A trace model in [base] with its files in [grid]: every point is whole, so the
    sweep runs (the base was checked alone and refused for its empty trace_file)."""
    traces = []
    for k in range(2):
        path = tmp_path / f"t{k}.tcl"
        path.write_text(
            f"$node_(0) set X_ {10 + k}.0\n$node_(0) set Y_ 10.0\n$node_(1) set X_ 50.0\n$node_(1) set Y_ 10.0\n"
        )
        traces.append(str(path))
    base = {"duration_s": 5.0, "world": {"n_robots": 2, "side_m": 100.0}, "mobility": {"model": "trace"}}
    sweep = sweepmod.parse({"name": "b", "base": base, "grid": {"mobility.trace_file": traces}})
    assert len(sweep.runs()) == 2
    with pytest.raises(NetsimInputError, match=r"\[base\] mobility.trace_file = '': must name a file"):
        sweepmod.parse({"name": "b", "base": base, "grid": {"world.n_robots": [2]}})
    # The tables it may keep are its points' (the base alone was built for them, and refused).
    kept = sweepmod.parse({"name": "b", "base": base, "tables": ["links"], "grid": {"mobility.trace_file": traces}})
    assert kept.tables == ("links",)
    # A [random] that is not a table is named in one line (a traceback of an AttributeError).
    with pytest.raises(NetsimInputError, match=r"^sweep file: \[base\] mobility.trace_file"):
        sweepmod.parse({"name": "b", "base": base, "random": [1, 2]})


@pytest.mark.parametrize("axes", ["grid", "random"])
def test_a_base_value_under_a_swept_key_is_said_never_to_run(axes, recwarn):
    """A [base] that sets a key an axis sweeps: the points' values run, never the base's,
    and the sweep says so once, naming the key (it ran without a word)."""
    base = {"duration_s": 5.0, "world": {"n_robots": 5}, "channel": {"loss_probability": 0.3}}
    spec = (
        {"grid": {"channel.loss_probability": [0.0, 0.1]}}
        if axes == "grid"
        else {"random": {"samples": 2, "ranges": {"channel.loss_probability": [0.0, 0.1]}}}
    )
    sweep = sweepmod.parse({"name": "c", "base": base, **spec})
    said = [str(w.message) for w in recwarn if issubclass(w.category, cfgmod.ConfigWarning)]
    assert said == ["[base] channel.loss_probability: swept too; each point's value is run, never the base's"]
    assert all(r.config["channel"]["loss_probability"] != 0.3 for r in sweep.runs())
    recwarn.clear()
    sweepmod.parse({"name": "c", "base": {**base, "channel": {}}, **spec})
    assert not [w for w in recwarn if issubclass(w.category, cfgmod.ConfigWarning)]


def test_a_full_disk_in_a_sweep_says_the_finished_runs_are_kept(tmp_path, capsys, monkeypatch):
    """A disk that fills after a run is written: one line that says the finished runs are
    kept and the command resumes (it said nothing was written), exit 2."""
    import errno

    from netsim.tools import output

    real, calls = output.write_arrow, []

    def fills(table, path):
        calls.append(path)
        if len(calls) > 2:  # the first run's table and row are written
            raise OSError(errno.ENOSPC, "No space left on device", str(path))
        real(table, path)

    monkeypatch.setattr(output, "write_arrow", fills)
    (tmp_path / "s.toml").write_text(
        'name = "d"\ntables = ["links"]\n[base]\nduration_s = 5.0\n[base.world]\nn_robots = 4\n'
        '[grid]\n"world.side_m" = [100.0, 200.0]\n'
    )
    out = tmp_path / "out"
    assert main(["sweep", str(tmp_path / "s.toml"), "--out", str(out), "--workers", "1", "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert err == (
        f"netsim: error: cannot write: No space left on device; the runs finished are kept in {out}/ (the same "
        "command resumes)\n"
    )
    assert len(sweepmod.load(out)) == 1


def test_a_directory_run_by_another_sweep_loads_the_latest_sweeps_runs_only(tmp_path):
    """A script run again with other options into its folder: its table must hold this
    sweep's runs, not the earlier ones pooled in; those stay, and are reused when their
    sweep comes back."""
    base = {**BASE, "duration_s": 5.0}

    def sweep(speeds):
        tree = {"name": "s", "tables": ["links"], "base": base, "grid": {"mobility.speed_max_mps": speeds}}
        return sweepmod.parse(tree)

    first, second = sweep([2.0, 4.0]), sweep([8.0])
    sweepmod.run_sweep(first, tmp_path, progress=False)
    sweepmod.run_sweep(second, tmp_path, progress=False)
    assert sweepmod.load(tmp_path)["mobility.speed_max_mps"].tolist() == [8.0]
    assert set(sweepmod.load_table(tmp_path, "links")["run_id"]) == {r.run_id for r in second.runs()}
    again = sweepmod.run_sweep(first, tmp_path, progress=False)
    assert again.skipped == 2 and again.done == 0
    assert sorted(sweepmod.load(tmp_path)["mobility.speed_max_mps"]) == [2.0, 4.0]


@pytest.mark.parametrize("folder", ["runs", "tables/links"])
def test_a_sweep_folder_whose_runs_cannot_be_written_is_refused_before_any_run(tmp_path, folder):
    """A sweep resumed in a directory an earlier one made (a collaborator's, say) whose
    folders it cannot write: refused in one line before a run is computed, not after."""
    tree = {"name": "s", "tables": ["links"], "base": {**BASE, "duration_s": 5.0}}
    sweepmod.run_sweep(sweepmod.parse({**tree, "grid": {"mobility.speed_max_mps": [2.0]}}), tmp_path, progress=False)
    blocked = tmp_path / folder
    for f in blocked.iterdir():
        f.unlink()
    blocked.rmdir()
    blocked.write_text("in the way")  # as root, a mode would not bind; a file does
    more = sweepmod.parse({**tree, "grid": {"mobility.speed_max_mps": [2.0, 4.0]}})
    with pytest.raises(NetsimInputError, match=f"cannot be resumed: {blocked} cannot be written"):
        sweepmod.run_sweep(more, tmp_path, progress=False)
    other = tmp_path / ("tables/links" if folder == "runs" else "runs")
    assert len(list(other.iterdir())) == 1  # the first sweep's run, and no other computed


def test_ctrl_c_in_a_sweep_says_the_finished_runs_are_kept(tmp_path, monkeypatch, capsys):
    from netsim.tools.cli import main

    sweep_file = tmp_path / "s.toml"
    sweep_file.write_text(
        'name = "c"\n[base]\nduration_s = 5.0\n[base.world]\nn_robots = 8\n'
        '[grid]\n"mobility.speed_max_mps" = [1.0, 2.0, 3.0]\n'
    )
    execute, calls = sweepmod._safe_execute, []

    def interrupted_at_the_second(run, tables):
        calls.append(run)
        if len(calls) == 2:
            raise KeyboardInterrupt
        return execute(run, tables)

    monkeypatch.setattr(sweepmod, "_safe_execute", interrupted_at_the_second)
    out = tmp_path / "out"
    code = main(["sweep", str(sweep_file), "--out", str(out), "--workers", "1", "--no-progress"])
    err = capsys.readouterr().err
    assert (
        code == 130 and err == f"netsim: interrupted; the runs finished are kept in {out}/ (the same command resumes)\n"
    )
    assert len(list((out / "runs").iterdir())) == 1


def started_execute(run, tables):
    """The sweep's own run, leaving a mark (in NETSIM_TEST_MARKS) that it started: a worker
    process imports this module to call it."""
    (Path(os.environ["NETSIM_TEST_MARKS"]) / run.run_id).touch()
    return SAFE_EXECUTE(run, tables)


SAFE_EXECUTE = sweepmod._safe_execute


def test_ctrl_c_with_local_workers_stops_them_at_once(tmp_path, monkeypatch):
    """Ctrl-C in a sweep on a local pool ends its workers at once: the runs not begun are
    never started, the runs recorded before it are kept, and none is recorded after it."""
    marks = tmp_path / "marks"
    marks.mkdir()
    monkeypatch.setenv("NETSIM_TEST_MARKS", str(marks))
    monkeypatch.setattr(sweepmod, "_safe_execute", started_execute)
    record, calls = sweepmod._record, []

    def interrupted_at_the_second(out, run, outcome):
        calls.append(run.run_id)
        if len(calls) == 2:
            raise KeyboardInterrupt
        record(out, run, outcome)

    monkeypatch.setattr(sweepmod, "_record", interrupted_at_the_second)
    sweep = small_sweep(replications=3)  # 12 runs
    with pytest.raises(KeyboardInterrupt):
        sweepmod.run_sweep(sweep, tmp_path / "out", workers=2, progress=False)
    started = len(list(marks.iterdir()))
    assert started <= 7, started
    assert len(calls) == 2
    assert {p.stem for p in (tmp_path / "out" / "runs").iterdir()} == {calls[0]}


def test_an_error_recording_a_run_ends_the_workers_and_is_raised_once(tmp_path, monkeypatch):
    """A run whose files cannot be written (a full disk, say) ends the sweep with that error,
    raised once; no other run is recorded after it."""
    calls = []

    def disk_full(out, run, outcome):
        calls.append(run.run_id)
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(sweepmod, "_record", disk_full)
    with pytest.raises(OSError, match="No space left") as err:
        sweepmod.run_sweep(small_sweep(), tmp_path / "out", workers=2, progress=False)
    assert len(calls) == 1 and err.value.__context__ is None


def test_a_table_whose_run_has_no_row_is_not_loaded(tmp_path):
    """A run interrupted between writing its tables and its row is not finished: its
    tables are left out of load_table as its row is out of load."""
    sweepmod.run_sweep(small_sweep(), tmp_path, progress=False)
    row = sorted((tmp_path / "runs").iterdir())[0]
    row.unlink()
    assert row.stem not in set(sweepmod.load_table(tmp_path, "links")["run_id"])
    assert set(sweepmod.load_table(tmp_path, "links")["run_id"]) == set(sweepmod.load(tmp_path)["run_id"])


def test_a_directory_of_a_sweep_of_another_name_is_refused(tmp_path):
    """Run into the directory of another sweep (by name), a sweep would hide that one's
    runs from load: refused in one line, nothing written."""
    tree = {"name": "first", "tables": ["links"], "base": {**BASE, "duration_s": 5.0}}
    sweepmod.run_sweep(sweepmod.parse({**tree, "grid": {"mobility.speed_max_mps": [2.0]}}), tmp_path, progress=False)
    before = sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*"))
    other = sweepmod.parse({**tree, "name": "second", "grid": {"mobility.speed_max_mps": [4.0]}})
    with pytest.raises(NetsimInputError, match="holds the sweep 'first', not 'second'"):
        sweepmod.run_sweep(other, tmp_path, progress=False)
    assert sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*")) == before


def test_ctrl_c_is_ignored_while_an_interrupt_is_reported():
    """Within ignoring_interrupts a SIGINT does nothing (a second Ctrl-C cannot cut the
    line that reports the first); the handler is back after it."""
    from netsim.tools.interrupt import ignoring_interrupts

    before = signal.getsignal(signal.SIGINT)
    with ignoring_interrupts():
        os.kill(os.getpid(), signal.SIGINT)
    assert signal.getsignal(signal.SIGINT) is before


@pytest.mark.parametrize(
    "resumable, said", [(True, "the runs finished are kept (the same command resumes)"), (False, "nothing written")]
)
def test_ctrl_c_in_an_experiment_script_is_one_line_and_130(monkeypatch, capsys, resumable, said):
    monkeypatch.setattr(sys, "argv", ["cluster_stability.py"])

    def main():
        raise KeyboardInterrupt

    with pytest.raises(SystemExit) as exit_:
        sweepmod.run_script(main, resumable=resumable)
    assert exit_.value.code == 130
    assert capsys.readouterr().err == f"cluster_stability.py: interrupted; {said}\n"


def test_ctrl_c_after_a_script_put_results_in_place_says_what_is_kept(monkeypatch, capsys):
    """An interrupt within kept_if_interrupted is its line, exit 130 (the script said
    "interrupted" alone, its table written)."""
    from netsim.tools.interrupt import kept_if_interrupted

    monkeypatch.setattr(sys, "argv", ["coverage_on_map.py"])

    def main():
        with kept_if_interrupted("coverage_on_map.py: interrupted; runs.csv is written, the figure is not"):
            raise KeyboardInterrupt

    with pytest.raises(SystemExit) as exit_:
        sweepmod.run_script(main)
    assert exit_.value.code == 130
    assert capsys.readouterr().err == "coverage_on_map.py: interrupted; runs.csv is written, the figure is not\n"


@pytest.mark.parametrize("text", ["[]", "", '{"run_ids": null}', "{not json"])
def test_a_sweep_json_that_lists_no_runs_loads_the_whole_folder(tmp_path, text):
    """A sweep.json from before it listed the runs, or one damaged: every run is read."""
    sweep = sweepmod.parse(
        {"name": "s", "base": {**BASE, "duration_s": 5.0}, "grid": {"mobility.speed_max_mps": [2.0]}}
    )
    sweepmod.run_sweep(sweep, tmp_path, progress=False)
    (tmp_path / "sweep.json").write_text(text)
    assert len(sweepmod.load(tmp_path)) == 1


def test_a_stray_file_among_the_tables_does_not_stop_a_resume(tmp_path):
    tree = {"name": "s", "tables": ["links"], "base": {**BASE, "duration_s": 5.0}}
    sweepmod.run_sweep(sweepmod.parse({**tree, "grid": {"mobility.speed_max_mps": [2.0]}}), tmp_path, progress=False)
    (tmp_path / "tables" / "NOTES.txt").write_text("mine")
    more = sweepmod.parse({**tree, "grid": {"mobility.speed_max_mps": [2.0, 4.0]}})
    report = sweepmod.run_sweep(more, tmp_path, progress=False)
    assert report.skipped == 1 and report.done == 1


def test_random_integer_points_drawn_twice_run_once():
    base = {**BASE, "world": {"side_m": 300.0}}  # n_robots swept: a base's would never run
    tree = {"base": base, "random": {"samples": 20, "seed": 1, "ranges": {"world.n_robots": [10, 100]}}}
    sweep = sweepmod.parse(tree)  # said once every point is known valid: by runs()
    with pytest.warns(cfgmod.ConfigWarning, match=r"\[random\] 20 samples drew 19 distinct points; each is run once"):
        sweep.runs()
    points = sweep.points
    values = [p["world.n_robots"] for p in points]
    assert len(values) == len(set(values)) == 19


@pytest.mark.parametrize(
    "axis, table",
    [
        ({"events.hooks": [[], ["link_breaks"]]}, "link_breaks"),
        ({"channel.mac": ["none", "aloha"]}, "medium"),
        ({"output.receptions": [False, True]}, "receptions"),
    ],
)
def test_a_sweep_keeps_a_table_its_axis_switches_on(tmp_path, axis, table):
    base = {**BASE, "duration_s": 5.0, "protocol": {"model": "ack"}}
    sweep = sweepmod.parse({"name": "k", "tables": [table], "base": base, "grid": axis})
    report = sweepmod.run_sweep(sweep, tmp_path, progress=False)
    assert report.done == 2 and not report.failed
    kept = sweepmod.load_table(tmp_path, table)
    assert kept["run_id"].nunique() == 1  # the point that switched it on


def test_aggregate_gives_means_and_t_intervals():
    df = pd.DataFrame({"v": [1, 1, 1, 2, 2, 2], "m": [1.0, 2.0, 3.0, 10.0, 10.0, 10.0]})
    agg = sweepmod.aggregate(df, ["v"], ["m"]).set_index("v")
    assert agg.loc[1, "m_mean"] == 2.0 and agg.loc[1, "m_n"] == 3
    half = 4.302652729911275 * 1.0 / 3**0.5  # t(0.975, 2) * sd / sqrt(n)
    assert agg.loc[1, "m_ci_high"] == pytest.approx(2.0 + half)
    assert agg.loc[2, "m_ci_low"] == pytest.approx(10.0)


@pytest.mark.parametrize(
    "tree, words",
    [
        ({"base": BASE, "grid": {"mobility.speed_max_mps": [1.0]}, "colour": 1}, "unknown key"),
        ({"base": BASE}, "exactly one of [grid] and [random]"),
        ({"base": BASE, "grid": {"mobility.speed_max_mps": 3.0}}, "non-empty list"),
        ({"base": BASE, "grid": {"mobility.top_speed": [1.0]}}, "not a configuration key"),
        ({"base": BASE, "grid": {"world.n_robots": [1]}, "replications": 0}, "replications"),
        ({"base": BASE, "grid": {"channel.range_m": [-1.0]}}, "sweep point"),
        ({"base": {"world": {"n_robots": -3}}, "grid": {"seed": [1]}}, "[base] world.n_robots"),
        ({"base": BASE, "random": {"samples": 3, "ranges": {"seed": [5, 1]}}}, "low must not exceed"),
        ({"base": BASE, "grid": {"seed": [1]}, "tables": ["everything"]}, "tables"),
        # A point no run could finish is refused with the others, before any run.
        ({"base": BASE, "grid": {"protocol.message_rate_hz": [0.2, 1e12]}}, "protocol.message_rate_hz"),
    ],
)
def test_bad_sweep_files(tree, words):
    with pytest.raises(NetsimInputError, match=words.replace("[", r"\[").replace("]", r"\]")):
        sweep = sweepmod.parse(tree)
        sweep.runs()


def test_a_misspelt_sweep_key_is_named_with_the_closest_key():
    """A grid axis that is no configuration key, but close to one, says which."""
    tree = {"name": "s", "base": BASE, "grid": {"mobility.speed_maxx_mps": [1.0]}}
    with pytest.raises(NetsimInputError, match=r"\(did you mean 'mobility.speed_max_mps'\?\)"):
        sweepmod.parse(tree)


def test_an_unquoted_dotted_sweep_key_is_told_to_be_quoted(tmp_path, capsys):
    """TOML reads an unquoted `mobility.speed_max_mps = [...]` under [grid] as a table named
    mobility: the one line says to quote the key, naming the key meant."""
    from netsim.tools.cli import main

    f = tmp_path / "s.toml"
    f.write_text("[grid]\nmobility.speed_max_mps = [1.0, 2.0]\n")
    assert main(["sweep", str(f), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [
        "netsim: error: sweep file: 'mobility' is not a configuration key: a dotted key is quoted in TOML "
        '("mobility.speed_max_mps" = [...]), else it is read as a table'
    ]
    assert not (tmp_path / "o").exists()


def test_workers_and_a_scheduler_together_are_refused(tmp_path, capsys):
    """--workers counts local processes, --scheduler hands the runs to a cluster: given
    both, the count would be dropped unsaid; one line, exit 2, nothing written."""
    from netsim.tools.cli import main

    f = tmp_path / "s.toml"
    f.write_text('[grid]\n"seed" = [1]\n')
    code = main(["sweep", str(f), "--out", str(tmp_path / "o"), "--workers", "2", "--scheduler", "tcp://h:8786"])
    assert code == 2
    assert capsys.readouterr().err.strip().splitlines() == [
        "netsim: error: --workers 2 and --scheduler tcp://h:8786: give one (local worker processes, or a "
        "Dask cluster's)"
    ]
    assert not (tmp_path / "o").exists()


def test_cli_bad_sweep_file_exits_2(tmp_path, capsys):
    from netsim.tools.cli import main

    f = tmp_path / "s.toml"
    f.write_text("[grid]\nnot_a_key = [1]\n")
    assert main(["sweep", str(f), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("netsim: error: sweep file:")
    assert not (tmp_path / "o").exists()


def test_more_workers_than_the_machine_can_use_is_one_line(tmp_path, capsys):
    """`--workers` beyond four a core is refused in one line, exit 2, nothing written (it
    started thousands of processes that Ctrl-C could not stop)."""
    from netsim.tools.cli import WORKERS_PER_CORE, main

    sweep_file = tmp_path / "s.toml"
    sweep_file.write_text('name = "w"\n[grid]\n"mobility.speed_max_mps" = [1.0, 2.0]\n')
    too_many = WORKERS_PER_CORE * len(os.sched_getaffinity(0)) + 1
    code = main(["sweep", str(sweep_file), "--out", str(tmp_path / "out"), "--workers", str(too_many)])
    lines = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(lines) == 1
    assert lines[0].startswith(f"netsim: error: --workers {too_many}: at most {too_many - 1} on this machine")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.toml"]


def test_a_local_pool_starts_no_more_workers_than_runs(tmp_path, monkeypatch):
    """Two runs on eight workers start two processes."""
    import multiprocessing

    sizes, pool = [], multiprocessing.Pool

    def counted(processes, *args, **kwargs):
        sizes.append(processes)
        return pool(processes, *args, **kwargs)

    monkeypatch.setattr(multiprocessing, "Pool", counted)
    sweep = small_sweep(replications=1, grid={"mobility.speed_max_mps": [2.0, 6.0]})
    report = sweepmod.run_sweep(sweep, tmp_path / "out", workers=8, progress=False)
    assert sizes == [2] and len(sweepmod.load(tmp_path / "out")) == 2, report


def _run_forever(started) -> None:
    started.put(True)
    while True:  # a run under way, ended only by its pool
        pass


def test_leaving_a_process_pool_early_ends_its_workers_at_once():
    """Ctrl-C (or any error) in the block of :func:`process_pool`, which the experiments'
    scripts run their seeds on, ends the workers at once, their runs under way."""
    import multiprocessing

    with multiprocessing.Manager() as manager:
        started = manager.Queue()
        with pytest.raises(KeyboardInterrupt), sweepmod.process_pool(2, 5) as pool:
            workers = list(pool._pool)
            pool.map_async(_run_forever, [started, started], chunksize=1)
            started.get(), started.get()
            raise KeyboardInterrupt
    assert len(workers) == 2 and [w.exitcode for w in workers] == [-signal.SIGTERM] * 2


POOL_ENDED_BY_TERMINATE = r"""
import multiprocessing, signal
from netsim.tools.interrupt import on_sigint
from netsim.tools.sweep import _die_with_parent

started = multiprocessing.SimpleQueue()


def busy(_):
    started.put(True)
    while True:  # a run under way, ended only by the pool
        pass


if __name__ == "__main__":
    signal.signal(signal.SIGTERM, on_sigint)  # as the netsim command sets it
    pool = multiprocessing.Pool(1, initializer=_die_with_parent)
    pool.map_async(busy, [0])
    started.get()
    pool.terminate()  # SIGTERM to the worker, as a sweep that stops ends its pool
    pool.join()
"""


def test_a_sweeps_workers_end_quietly_when_the_pool_is_terminated():
    """A worker inherits the command's SIGTERM handler (a sweep stopped ends its pool with
    SIGTERM): the pool's initializer gives it back the default, so each worker dies at once
    and says nothing, where each printed a KeyboardInterrupt traceback."""
    import subprocess
    import sys

    done = subprocess.run([sys.executable, "-c", POOL_ENDED_BY_TERMINATE], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0 and done.stderr == "", done.stderr


# -- rules a mutation audit found no test for ------------------------------------------------
@pytest.mark.parametrize(
    "extra, words",
    [
        ({"name": ".."}, "name = '..'"),
        ({"name": "a\\b"}, r"name = 'a\\\\b'"),
        ({"replications": True}, "replications = True"),
        ({"tables": ["links", ["x"]]}, r"tables = \['links', \['x'\]\]: must be a list of table names"),
        ({"base": [1, 2]}, r"\[base\] must be a table"),
    ],
)
def test_a_sweep_files_top_level_values_are_checked(extra, words):
    """A name that would leave the output folder, a count that is a boolean, a table list
    holding a list (unhashable: a TypeError past this check), a [base] that is no table: each
    one line naming it."""
    tree = {"base": BASE, "grid": {"seed": [1]}, **extra}
    with pytest.raises(NetsimInputError, match=f"^sweep file: {words}"):
        sweepmod.parse(tree)


@pytest.mark.parametrize(
    "random, words",
    [
        ({"samples": 2, "seed": -1, "ranges": {"seed": [1, 3]}}, r"\[random\] seed = -1"),
        ({"samples": 2, "sead": 1, "ranges": {"seed": [1, 3]}}, r"\[random\] unknown key\(s\) \['sead'\]"),
        ({"samples": 2, "ranges": {"seed": [True, 3]}}, r"\[random.ranges\] seed = \[True, 3\]: must be \[low, high\]"),
    ],
)
def test_a_random_sweeps_values_are_checked(random, words):
    with pytest.raises(NetsimInputError, match=f"^sweep file: {words}"):
        sweepmod.parse({"base": BASE, "random": random})


def test_equal_random_bounds_fix_the_value():
    sweep = sweepmod.parse(
        {"base": BASE, "random": {"samples": 1, "ranges": {"channel.loss_probability": [0.25, 0.25]}}}
    )
    assert sweep.points == ({"channel.loss_probability": 0.25},)


def test_the_run_limit_counts_points_and_replications(monkeypatch):
    """Each limit is the largest count allowed, not one less; points times replications
    is what is counted; a grid or a sample count past it is refused before its points are
    made."""
    monkeypatch.setattr(sweepmod, "MAX_RUNS", 4)
    grid = {"seed": [1, 2]}
    assert len(sweepmod.parse({"base": BASE, "grid": grid, "replications": 2}).points) == 2
    with pytest.raises(NetsimInputError, match=r"^sweep file: 3 points x 2 replications: at most 4 runs"):
        sweepmod.parse({"base": BASE, "grid": {"seed": [1, 2, 3]}, "replications": 2})
    with pytest.raises(NetsimInputError, match=r"^sweep file: \[grid\] has 5 points; at most 4 runs"):
        sweepmod.parse({"base": BASE, "grid": {"seed": [1, 2, 3, 4, 5]}})
    with pytest.raises(NetsimInputError, match=r"^sweep file: \[random\] samples = 5: must be an integer from 1 to 4"):
        sweepmod.parse({"base": BASE, "random": {"samples": 5, "ranges": {"channel.loss_probability": [0.0, 1.0]}}})


def test_a_base_file_is_found_beside_the_sweep_file_and_base_overrides_it(tmp_path, monkeypatch):
    """A relative base_file is read from the sweep file's folder, wherever the command is
    run; the sweep's own [base] values win over the file's."""
    folder = tmp_path / "study"
    folder.mkdir()
    (folder / "scenario.toml").write_text("duration_s = 5.0\n[world]\nn_robots = 4\nside_m = 200.0\n")
    (folder / "sweep.toml").write_text(
        'base_file = "scenario.toml"\n[base.world]\nn_robots = 6\n[grid]\n"seed" = [1]\n'
    )
    monkeypatch.chdir(tmp_path)
    (run,) = sweepmod.load_file("study/sweep.toml").runs()
    assert run.config["world"]["n_robots"] == 6 and run.config["world"]["side_m"] == 200.0


def test_a_configuration_several_points_share_is_named_by_the_first(recwarn):
    """The run of points that resolve to one configuration carries the first point's values
    (those its failure or its row is reported under), not a later one's."""
    sweep = sweepmod.parse(
        {
            "base": {**BASE, "duration_s": 5.0},
            "grid": {"mobility.model": ["random_waypoint"], "mobility.alpha": [0.5, 0.75]},
        }
    )
    (run,) = sweep.runs()
    assert run.point == {"mobility.model": "random_waypoint", "mobility.alpha": 0.5}


def test_a_random_sweep_may_leave_to_its_ranges_a_key_its_base_needs():
    """A base refused alone (a least speed above the default top speed) is checked with the
    low end of each range, which makes it whole."""
    base = {**BASE, "mobility": {"speed_min_mps": 8.0}}
    sweep = sweepmod.parse({"base": base, "random": {"samples": 2, "ranges": {"mobility.speed_max_mps": [10.0, 20.0]}}})
    assert all(r.config["mobility"]["speed_min_mps"] == 8.0 for r in sweep.runs())


def test_workers_zero_is_one_line_and_nothing_written(tmp_path, capsys):
    """`--workers 0` was read as no count given (all cores)."""
    f = tmp_path / "s.toml"
    f.write_text('[grid]\n"seed" = [1]\n')
    assert main(["sweep", str(f), "--out", str(tmp_path / "o"), "--workers", "0"]) == 2
    assert capsys.readouterr().err.strip().splitlines() == ["netsim: error: --workers 0: must be at least 1"]
    assert not (tmp_path / "o").exists()


def test_a_runs_table_holds_a_list_value_as_its_text(tmp_path):
    """A list-valued key (the world's bounds) is one text cell of the runs table, as the
    configuration writes it."""
    sweep = sweepmod.parse({"base": {**BASE, "duration_s": 5.0}, "grid": {"seed": [1]}})
    sweepmod.run_sweep(sweep, tmp_path, progress=False)
    (bounds,) = sweepmod.load(tmp_path)["world.bounds_m"]
    assert bounds == str(sweep.runs()[0].config["world"]["bounds_m"])


def test_a_run_that_succeeds_on_retry_leaves_no_failure_behind(tmp_path, monkeypatch):
    sweep = sweepmod.parse({"base": {**BASE, "duration_s": 5.0}, "grid": {"seed": [1]}})
    real = sweepmod.execute_run
    monkeypatch.setattr(sweepmod, "execute_run", lambda run, tables: 1 / 0)
    assert len(sweepmod.run_sweep(sweep, tmp_path, progress=False).failed) == 1
    assert list((tmp_path / "failed").glob("*.json"))
    monkeypatch.setattr(sweepmod, "execute_run", real)
    report = sweepmod.run_sweep(sweep, tmp_path, progress=False)
    assert report.done == 1 and not report.failed
    assert not list((tmp_path / "failed").glob("*.json"))


def test_a_kept_table_keeps_its_column_types_when_some_runs_write_none(tmp_path):
    """The empty tables of the runs whose models write none are left out of the frame:
    mixed in, they turned its integer columns to floats."""
    base = {**BASE, "duration_s": 5.0, "protocol": {"model": "ack"}}
    sweep = sweepmod.parse(
        {"name": "k", "tables": ["receptions"], "base": base, "grid": {"output.receptions": [False, True]}}
    )
    sweepmod.run_sweep(sweep, tmp_path, progress=False)
    kept = sweepmod.load_table(tmp_path, "receptions")
    (one,) = [
        pd.read_parquet(f) for f in (tmp_path / "tables" / "receptions").glob("*.parquet") if len(pd.read_parquet(f))
    ]
    assert kept.dtypes.to_dict() == one.dtypes.to_dict()


def test_aggregate_leaves_out_a_runs_missing_value():
    df = pd.DataFrame({"v": [1, 1, 1], "m": [1.0, float("nan"), 3.0]})
    agg = sweepmod.aggregate(df, ["v"], ["m"]).set_index("v")
    assert agg.loc[1, "m_mean"] == 2.0 and agg.loc[1, "m_n"] == 2


def test_loading_a_folder_that_holds_no_sweep_is_one_line(tmp_path):
    """A mistyped or wrong folder is said to be one, not read as a sweep without runs."""
    with pytest.raises(NetsimInputError, match=r"nothere: no such directory$"):
        sweepmod.load(tmp_path / "nothere")
    (tmp_path / "run").mkdir()
    (tmp_path / "run" / "summary.json").write_text("{}")
    for load in (sweepmod.load, lambda p: sweepmod.load_table(p, "links")):
        with pytest.raises(NetsimInputError, match=r"run: holds no sweep \(netsim sweep writes sweep.json"):
            load(tmp_path / "run")
    (tmp_path / "file").write_text("")
    with pytest.raises(NetsimInputError, match=r"file: is not a directory$"):
        sweepmod.load_table(tmp_path / "file", "links")


def test_a_table_the_sweep_did_not_keep_is_one_line(tmp_path):
    sweep = sweepmod.parse(
        {"name": "t", "tables": ["links"], "base": {**BASE, "duration_s": 2.0}, "grid": {"seed": [1]}}
    )
    sweepmod.run_sweep(sweep, tmp_path, workers=1, progress=False)
    assert len(sweepmod.load_table(tmp_path, "links"))
    with pytest.raises(NetsimInputError, match=r"kept no table 'roles' \(kept: links; a sweep keeps the tables"):
        sweepmod.load_table(tmp_path, "roles")


def test_a_sweep_with_no_run_finished_loads_empty(tmp_path):
    (tmp_path / "sweep.json").write_text('{"name": "t", "run_ids": []}')
    assert sweepmod.load(tmp_path).empty and sweepmod.load_table(tmp_path, "links").empty


def test_aggregate_names_a_column_the_runs_do_not_have():
    runs = pd.DataFrame({"mobility.speed_max_mps": [1.0, 1.0], "mean_degree": [3.0, 4.0]})
    assert sweepmod.aggregate(runs, ["mobility.speed_max_mps"], ["mean_degree"])["mean_degree_n"].tolist() == [2]
    with pytest.raises(NetsimInputError, match=r"^no column 'mean_degre' among the runs' \(2 columns\)$"):
        sweepmod.aggregate(runs, ["mobility.speed_max_mps"], ["mean_degre"])
    with pytest.raises(NetsimInputError, match=r"^no column 'speed', 'x' among the runs' \(0 columns: no run\)$"):
        sweepmod.aggregate(pd.DataFrame(), ["speed"], ["x"])


def test_a_connect_timeout_without_a_scheduler_is_refused(tmp_path, capsys):
    """Local workers connect to nothing: a --connect-timeout there would be dropped unsaid."""
    f = tmp_path / "s.toml"
    f.write_text('[grid]\n"seed" = [1]\n')
    assert main(["sweep", str(f), "--out", str(tmp_path / "o"), "--workers", "1", "--connect-timeout", "2"]) == 2
    assert capsys.readouterr().err.strip().splitlines() == [
        "netsim: error: --connect-timeout 2: only with --scheduler (a Dask cluster's)"
    ]
    assert not (tmp_path / "o").exists()


def test_a_refused_default_folder_is_named_as_the_default_out(tmp_path, capsys, monkeypatch):
    """Without --out the sweep's folder is sweep-out/NAME: a refusal names it so, not as
    an --out the user never gave."""
    monkeypatch.chdir(tmp_path)
    Path("s.toml").write_text('name = "speed"\n[grid]\n"seed" = [1]\n')
    Path("sweep-out/speed").mkdir(parents=True)
    Path("sweep-out/speed/mine.txt").write_text("mine")
    assert main(["sweep", "s.toml", "--workers", "1", "--no-progress"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("netsim: error: the default --out sweep-out/speed: the directory is not empty (mine.txt)")
    assert sorted(p.name for p in Path("sweep-out/speed").iterdir()) == ["mine.txt"]


def test_whole_number_bounds_of_a_float_key_are_warned_of(recwarn):
    """`"protocol.ack_period_s" = [1, 2]` draws 1 or 2 (an integer range), where a user
    asking of a float key means U(1, 2): said, with the bounds that draw that; an integer
    key's whole-number bounds are not."""
    tree = {"base": BASE, "random": {"samples": 4, "ranges": {"protocol.ack_period_s": [1, 2]}}}
    sweep = sweepmod.parse(tree)
    with pytest.warns(cfgmod.ConfigWarning, match=r"ack_period_s = \[1, 2\]: whole-number bounds draw whole numbers; "):
        sweep.runs()
    assert {p["protocol.ack_period_s"] for p in sweep.points} <= {1, 2}
    recwarn.clear()
    for key, bounds, base in (
        ("world.n_robots", [5, 9], {**BASE, "world": {"side_m": 300.0}}),
        ("protocol.ack_period_s", [2, 2], BASE),
    ):
        sweepmod.parse({"base": base, "random": {"samples": 2, "ranges": {key: bounds}}}).runs()
    assert not [w for w in recwarn if "whole-number" in str(w.message)]


def test_a_random_sweep_refused_says_one_line_and_nothing_else(tmp_path, capsys):
    """A point refused after the file was read (a period of 0) is the command's only line:
    the word on whole-number bounds, due only once every point is valid, is not said."""
    f = tmp_path / "s.toml"
    f.write_text('[random]\nsamples = 20\nseed = 1\n[random.ranges]\n"protocol.ack_period_s" = [0, 2]\n')
    assert main(["sweep", str(f), "--out", str(tmp_path / "o"), "--workers", "1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("netsim: error: sweep point"), err


def test_pooled_runs_come_in_order_each_told_on_its_own_line_in_a_log(capsys):
    """netsim.tools.sweep.pooled: every job's result, in the jobs' order, and where standard
    error is a log one progress line per run, each telling that run's result (a bar of a few
    lines left most runs untold); ``progress=False``, none."""
    jobs = [(-k, k) for k in range(1, 13)]
    got = list(sweepmod.pooled(max, jobs, 2, "t", star=True, describe=lambda r: f"r{r}"))
    assert got == list(range(1, 13))
    lines = capsys.readouterr().err.splitlines()
    assert [line.split("latest ")[1].split(",")[0] for line in lines] == [f"r{k}" for k in range(1, 13)]
    assert list(sweepmod.pooled(abs, [-1, -2], 1, "t", progress=False)) == [1, 2]
    assert capsys.readouterr().err == ""
