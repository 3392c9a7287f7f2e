"""Bad input is refused before any work and leaves nothing behind; no stale or half-made
output; progress reports suit a log file.

Every CLI refusal is checked the same way: exit status 2, exactly one line on standard
error (captured at the file-descriptor level, so a library's log line would show),
starting ``netsim: error:``, no traceback, and the directory tree unchanged.
"""

import io
import json
import os
import stat
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

from netsim import config as cfgmod
from netsim import run as runmod
from netsim.errors import NetsimInputError
from netsim.progress import PlainLines, progress_bar
from netsim.tools import sweep as sweepmod
from netsim.tools.cli import main
from netsim.tools.output import claim_dir

SMALL = ["--set", "world.n_robots=5", "--set", "duration_s=5", "--set", "world.side_m=200"]


def tree(root: Path) -> dict:
    """Every path under ``root`` with its size (directories: None)."""
    return {str(p.relative_to(root)): (None if p.is_dir() else p.stat().st_size) for p in sorted(Path(root).rglob("*"))}


def refused(capfd, code, before, root, *fragments):
    """The CLI refused: exit 2, one line, no traceback, nothing written under ``root``."""
    out, err = capfd.readouterr()
    lines = err.strip().splitlines()
    assert code == 2, err
    assert len(lines) == 1, err
    assert lines[0].startswith("netsim: error: ")
    assert "Traceback" not in err
    for f in fragments:
        assert f in lines[0], lines[0]
    assert tree(root) == before, "something was written"
    return lines[0]


@pytest.fixture
def no_simulation(monkeypatch):
    """Fail the test if a simulation starts: a refusal must come before the work."""

    def execute(*a, **k):
        raise AssertionError("the simulation ran before the output directory was checked")

    monkeypatch.setattr(runmod, "execute", execute)


# -- the output directory is checked before simulating --------------------------------------
@pytest.mark.parametrize(
    "make, out, words",
    [
        (lambda d: (d / "afile").write_text("x"), "afile", "is a file, not a directory"),
        (lambda d: (d / "afile").write_text("x"), "afile/sub/run", "cannot be created"),
    ],
)
def test_out_that_is_or_lies_under_a_file_is_refused_before_simulating(
    tmp_path, capfd, monkeypatch, no_simulation, make, out, words
):
    monkeypatch.chdir(tmp_path)
    make(tmp_path)
    before = tree(tmp_path)
    code = main(["run", "--out", out, *SMALL])
    refused(capfd, code, before, tmp_path, words, out)


@pytest.mark.parametrize(
    "args",
    [
        ["sweep", "s.toml", "--out", "afile/o"],
        ["sweep", "s.toml", "--out", "afile"],
        ["figures", "--out", "afile"],
        ["figures", "rundir", "--out", "afile/figs"],
    ],
    ids=["sweep-under-file", "sweep-file", "figures-file", "figures-of-run-under-file"],
)
def test_every_command_that_writes_checks_its_output_first(tmp_path, capfd, monkeypatch, no_simulation, args):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "afile").write_text("x")
    (tmp_path / "s.toml").write_text(SWEEP)
    (tmp_path / "rundir").mkdir()
    (tmp_path / "rundir" / "config.toml").write_text("")
    monkeypatch.setattr(sweepmod, "_safe_execute", lambda *a: pytest.fail("a sweep run started"))
    before = tree(tmp_path)
    refused(capfd, main(args), before, tmp_path, "afile")


@pytest.mark.skipif(not Path("/proc/self").is_dir(), reason="needs Linux /proc, where no directory can be made")
def test_out_that_cannot_be_created_is_refused_before_simulating(tmp_path, capfd, no_simulation):
    before = tree(tmp_path)
    code = main(["run", "--out", "/proc/netsim-test/out", *SMALL])
    refused(capfd, code, before, tmp_path, "/proc/netsim-test/out", "cannot be created")


@pytest.mark.skipif(os.name != "posix" or os.geteuid() == 0, reason="permissions do not bind root")
def test_out_in_a_read_only_directory_is_refused_before_simulating(tmp_path, capfd, no_simulation):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    try:
        before = tree(tmp_path)
        code = main(["run", "--out", str(ro / "out"), *SMALL])
        refused(capfd, code, before, tmp_path, "cannot be created")
    finally:
        ro.chmod(0o700)


@pytest.fixture(scope="module")
def small_run(tmp_path_factory):
    """A finished run of 5 robots for 5 s."""
    out = tmp_path_factory.mktemp("small") / "run"
    assert main(["run", "--quiet", "--out", str(out), *SMALL]) == 0
    return out


def _unwritable_proc(d):
    if not Path("/proc/self").is_dir():
        pytest.skip("needs Linux /proc, where nothing can be written")


@pytest.mark.parametrize(
    "make, out, words",
    [
        (lambda d: (d / "adir").mkdir(), "adir", "is a directory"),
        (lambda d: (d / "afile").write_text("x"), "afile/view.html", "the directory afile is a file"),
        (lambda d: (d / "afile").write_text("x"), "afile/sub/view.html", "the directory afile is a file"),
        (_unwritable_proc, "/proc/netsim-test/view.html", "cannot write in /proc"),
        (lambda d: None, "nd2/", "names a directory"),
        (lambda d: None, "nd2/.", "names a directory"),
        (lambda d: None, "sub/a_view.png", "the replay is a web page; name a .html file"),
    ],
    ids=[
        "existing-directory",
        "under-a-file",
        "under-a-file-deeper",
        "unwritable-place",
        "new-directory",
        "dot",
        "not-html",
    ],
)
def test_view_out_that_cannot_take_the_file_is_one_line(tmp_path, capfd, monkeypatch, small_run, make, out, words):
    """`netsim view RUN --out X` where X is a directory, lies under a file, or is in a place
    nothing can be written: one line, exit 2, nothing written. A new name ending in a
    separator asks for a directory (it wrote a file named without it)."""
    monkeypatch.chdir(tmp_path)
    make(tmp_path)
    before, run_before = tree(tmp_path), tree(small_run)
    refused(capfd, main(["view", str(small_run), "--out", out]), before, tmp_path, words, out)
    assert tree(small_run) == run_before


@pytest.mark.skipif(os.name != "posix" or os.geteuid() == 0, reason="permissions do not bind root")
def test_view_out_in_a_read_only_directory_is_one_line(tmp_path, capfd, small_run):
    """`netsim view RUN --out X` in a directory the user may not write: one line, exit 2."""
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    try:
        before = tree(tmp_path)
        code = main(["view", str(small_run), "--out", str(ro / "view.html")])
        refused(capfd, code, before, tmp_path, "cannot write in")
    finally:
        ro.chmod(0o700)


def test_claim_dir_removes_what_it_created_when_the_work_fails(tmp_path):
    with pytest.raises(RuntimeError), claim_dir(tmp_path / "a" / "b" / "c"):
        raise RuntimeError("the work failed")
    assert list(tmp_path.iterdir()) == []


def test_failing_run_leaves_no_output_directory(tmp_path, capfd):
    """A configuration error found only when the run is built (the stationary start draws
    its own positions) still leaves nothing."""
    before = tree(tmp_path)
    grid = ["--set", "world.placement=grid", "--set", "mobility.stationary_start=true"]
    code = main(["run", "--out", str(tmp_path / "a" / "out"), *SMALL, *grid])
    refused(capfd, code, before, tmp_path, "stationary_start")


@pytest.mark.parametrize(
    "output, words",
    [("missing_dir/s.tcl", "the directory missing_dir does not exist"), (".", "is a directory")],
)
def test_scenario_generate_refuses_an_unwritable_file_before_simulating(tmp_path, capfd, monkeypatch, output, words):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(runmod, "build", lambda *a, **k: pytest.fail("simulated before checking -o"))
    before = tree(tmp_path)
    code = main(
        ["scenario", "generate", "--n", "3", "--side", "100", "--speed-max", "2", "--duration", "5"]
        + [
            "-o",
            output,
        ]
    )
    refused(capfd, code, before, tmp_path, words)


GENERATE = ["scenario", "generate", "--n", "3", "--side", "100", "--speed-max", "2", "--duration", "5"]


def test_scenario_generate_refuses_an_existing_file(tmp_path, capfd, monkeypatch):
    """`netsim scenario generate -o FILE` never overwrites a file that exists: one line,
    exit 2, the file untouched (as `netsim export` refuses an existing --out)."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "s.tcl").write_text("the user's own scenario\n")
    before = tree(tmp_path)
    line = refused(capfd, main([*GENERATE, "-o", "s.tcl"]), before, tmp_path, "-o s.tcl", "exists already")
    assert (tmp_path / "s.tcl").read_text() == "the user's own scenario\n", line


def test_scenario_generate_quiet_prints_nothing_and_writes_the_file(tmp_path, capfd, monkeypatch):
    """`--quiet` leaves out the line naming the file written; the file is the same."""
    monkeypatch.chdir(tmp_path)
    assert main([*GENERATE, "-o", "loud.tcl"]) == 0
    assert capfd.readouterr().out == "wrote loud.tcl\n"
    assert main([*GENERATE, "-o", "quiet.tcl", "--quiet"]) == 0
    assert capfd.readouterr() == ("", "")
    assert (tmp_path / "quiet.tcl").read_text() == (tmp_path / "loud.tcl").read_text()


def test_view_out_refuses_an_existing_file(tmp_path, capfd, small_run):
    """`netsim view RUN --out FILE` never overwrites a file that exists: one line, exit 2,
    the file untouched."""
    (tmp_path / "replay.html").write_text("the user's own page\n")
    before = tree(tmp_path)
    refused(
        capfd,
        main(["view", str(small_run), "--out", str(tmp_path / "replay.html")]),
        before,
        tmp_path,
        "exists already",
    )
    assert (tmp_path / "replay.html").read_text() == "the user's own page\n"


@pytest.mark.slow
def test_view_remakes_the_runs_own_replay(tmp_path, capfd, small_run):
    """Without --out, `netsim view RUN` writes RUN/view.html, the run's own file, again
    when it is there already (as `netsim run --view` left it)."""
    (small_run / "view.html").write_text("stale\n")
    try:
        assert main(["view", str(small_run)]) == 0, capfd.readouterr().err
        assert (small_run / "view.html").read_text().startswith("<!")
    finally:
        (small_run / "view.html").unlink(missing_ok=True)


# -- a team of one ------------------------------------------------------------------------
@pytest.mark.parametrize("routing", ["backbone", "oracle"])
def test_a_team_of_one_robot_runs_and_sends_no_messages(tmp_path, capfd, routing):
    code = main(
        ["run", "--quiet", "--out", str(tmp_path / "o"), "--set", "world.n_robots=1"]
        + [
            "--set",
            "duration_s=60",
            "--set",
            "protocol.message_rate_hz=5",
            "--set",
            f"protocol.routing={routing}",
        ]
    )
    assert code == 0, capfd.readouterr().err
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert summary["messages"] == 0 and summary["robots"] == 1
    assert pd.read_parquet(tmp_path / "o" / "roles.parquet")["role"].iloc[-1] == "alpha"


# -- sweeps: the scheduler and the axes are checked before anything is written -------------
SWEEP = """
name = "s"
[base]
duration_s = 5.0
[base.world]
n_robots = 3
[grid]
seed = [1, 2]
"""


@pytest.mark.parametrize(
    "address, words",
    [
        ("notanaddress", "not a scheduler address"),
        ("tcp://127.0.0.1:1", "no Dask scheduler answered within 0.5 s"),
    ],
)
@pytest.mark.parametrize("out_exists", [False, True])
def test_unreachable_scheduler_is_one_line_and_writes_nothing(tmp_path, capfd, address, words, out_exists):
    (tmp_path / "s.toml").write_text(SWEEP)
    out = tmp_path / "out"
    if out_exists:
        out.mkdir()
    before = tree(tmp_path)
    code = main(
        ["sweep", str(tmp_path / "s.toml"), "--out", str(out), "--scheduler", address]
        + [
            "--connect-timeout",
            "0.5",
        ]
    )
    refused(capfd, code, before, tmp_path, words, address)
    assert not (out / "sweep.json").exists()


def test_a_sweep_for_a_scheduler_is_not_held_to_this_machines_memory(tmp_path, capfd):
    """Points run on a scheduler's workers: a sweep too large for the submitting machine
    (its memory refused it first) goes on to the scheduler; locally it is refused."""
    spec = tmp_path / "big.toml"
    spec.write_text(
        'name = "big"\n[base]\nduration_s = 12000.0\n[base.world]\nn_robots = 400000\n'
        '[base.protocol]\nmodel = "none"\n[base.mobility]\nmodel = "static"\n'
        "[base.output]\nposition_interval_s = 1.0\n[grid]\nseed = [1]\n"
    )
    code = main(["sweep", str(spec), "--out", str(tmp_path / "a"), "--scheduler", "notanaddress"])
    err = capfd.readouterr().err
    assert code == 2 and "not a scheduler address" in err and "memory" not in err
    code = main(["sweep", str(spec), "--out", str(tmp_path / "b"), "--no-progress"])
    err = capfd.readouterr().err
    assert code == 2 and "GiB of memory" in err


@pytest.mark.slow
def test_scheduler_refusal_from_the_console_script_is_one_line(tmp_path):
    """As a user sees it: a separate process, its whole standard error."""
    (tmp_path / "s.toml").write_text(SWEEP)
    cmd = [sys.executable, "-m", "netsim.tools.cli", "sweep", "s.toml", "--scheduler", "tcp://127.0.0.1:1"]
    run = subprocess.run(cmd + ["--connect-timeout", "0.5"], cwd=tmp_path, capture_output=True, text=True)
    assert run.returncode == 2
    assert run.stderr.strip().splitlines() == [
        "netsim: error: --scheduler tcp://127.0.0.1:1: no Dask scheduler answered within 0.5 s (connect timeout; "
        "--connect-timeout to change it): Timed out trying to connect to tcp://127.0.0.1:1 after 0.5 s"
    ]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.toml"]


def test_bad_sweep_axis_value_writes_nothing(tmp_path, capfd, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "bad.toml").write_text('name = "bad"\n[grid]\n"channel.range_m" = [100.0, -1.0]\n')
    before = tree(tmp_path)
    code = main(["sweep", "bad.toml"])
    refused(capfd, code, before, tmp_path, "channel.range_m = -1.0")
    assert not (tmp_path / "sweep-out").exists()


def test_a_scenario_file_given_as_a_sweep_says_where_its_keys_go(tmp_path, capfd, monkeypatch):
    """`netsim sweep scenario.toml`: the one-line error lists the unknown keys and says that
    a sweep file puts the scenario under [base] (or base_file) and the axes under [grid]
    or [random]; nothing written."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "scenario.toml").write_text("duration_s = 30.0\n[world]\nn_robots = 5\n")
    before = tree(tmp_path)
    line = refused(capfd, main(["sweep", "scenario.toml"]), before, tmp_path, "unknown key(s) ['duration_s', 'world']")
    assert "under [base]" in line and "base_file" in line and "[grid] or [random]" in line


def test_an_unknown_key_that_is_not_a_scenario_key_gets_no_base_hint(tmp_path, capfd, monkeypatch):
    """The [base] hint is for scenario keys only: a plain typo is listed without it."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "s.toml").write_text('nmae = "typo"\n' + SWEEP)
    before = tree(tmp_path)
    line = refused(capfd, main(["sweep", "s.toml"]), before, tmp_path, "unknown key(s) ['nmae']")
    assert "[base]" not in line


def test_sweep_refuses_a_directory_that_holds_something_else(tmp_path, capfd):
    (tmp_path / "s.toml").write_text(SWEEP)
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "notes.txt").write_text("mine")
    before = tree(tmp_path)
    code = main(["sweep", str(tmp_path / "s.toml"), "--out", str(tmp_path / "out"), "--workers", "1"])
    refused(capfd, code, before, tmp_path, "holds no sweep", "notes.txt")


def test_sweep_results_follow_the_umask(tmp_path):
    """runs/, tables/ and failed/ are as readable as every other output (not 0600)."""
    good, bad = tmp_path / "s.tcl", tmp_path / "t.tcl"
    good.write_text("".join(f"$node_({i}) set X_ {10 * i + 10}.0\n$node_({i}) set Y_ 10.0\n" for i in range(3)))
    bad.write_text("not a trace\n")
    base = {"duration_s": 5.0, "world": {"n_robots": 3}, "mobility": {"model": "trace"}}
    sweep = sweepmod.parse(
        {
            "name": "m",
            "tables": ["links"],
            "base": {**base, "output": {"position_interval_s": 0.0}},
            # The run of the bad trace fails (no movement line in the file) and is recorded under failed/.
            "grid": {"mobility.trace_file": [str(good), str(bad)]},
        }
    )
    old = os.umask(0o022)
    try:
        report = sweepmod.run_sweep(sweep, tmp_path / "o", workers=1, progress=False)
    finally:
        os.umask(old)
    assert report.done == 1 and len(report.failed) == 1
    files = [p for p in (tmp_path / "o").rglob("*") if p.is_file()]
    kinds = {p.relative_to(tmp_path / "o").parts[0] for p in files}
    assert kinds == {"runs", "tables", "failed", "sweep.json"}
    for p in files:
        assert stat.S_IMODE(p.stat().st_mode) == 0o644, p


@pytest.mark.parametrize("umask, mode", [(0o077, 0o600), (0o002, 0o664)])
def test_the_replay_file_follows_the_umask(tmp_path, small_run, umask, mode):
    """view.html is as readable as the run's other outputs: private under 077, group
    writable under 002 (it was 0644 whatever the umask)."""
    from netsim.tools import viewer

    old = os.umask(umask)
    try:
        page = viewer.write(small_run, tmp_path / "view.html")
    finally:
        os.umask(old)
    assert stat.S_IMODE(page.stat().st_mode) == mode


# -- traces, --set values ----------------------------------------------------------------
def test_trace_node_beyond_n_robots_is_named(tmp_path, capfd):
    trace = tmp_path / "t.tcl"
    trace.write_text("".join(f"$node_({i}) set X_ 1.0\n$node_({i}) set Y_ 2.0\n" for i in (0, 1, 9)))
    before = tree(tmp_path)
    code = main(
        ["run", "--out", str(tmp_path / "o"), "--set", "mobility.model=trace"]
        + [
            "--set",
            f"mobility.trace_file={trace}",
            "--set",
            "world.n_robots=2",
        ]
    )
    refused(capfd, code, before, tmp_path, "t.tcl:5: node 9 is beyond world.n_robots = 2")


@pytest.mark.parametrize(
    "value, what",
    [
        ("[100.0, 150.0", "list"),
        ("[100.0, 150.0]]", "list"),
        ("{min_separation_m = 2", "inline table"),
        ('"grid', "string"),
        ("'grid", "string"),
    ],
)
def test_malformed_set_value_is_named_not_taken_as_a_string(tmp_path, capfd, value, what):
    key = "control.options" if value.startswith("{") else "channel.range_m"
    before = tree(tmp_path)
    code = main(["run", "--out", str(tmp_path / "o"), "--set", f"{key}={value}"])
    refused(capfd, code, before, tmp_path, f"{key} = ", f"is not a valid TOML {what}")


def test_bare_words_are_still_strings():
    assert cfgmod.parse_override("world.placement=grid") == {"world": {"placement": "grid"}}
    assert cfgmod.parse_override("mobility.model=mymodels:circle") == {"mobility": {"model": "mymodels:circle"}}


# -- no stale output -----------------------------------------------------------------------
COVERAGE_RUN = SMALL + ["--set", "mobility.model=static", "--set", "coverage.enabled=true"]
COVERAGE_RUN += ["--set", "coverage.start_s=0"]  # control steps inside the short run


def test_a_run_replaces_the_earlier_run_in_its_directory(tmp_path, capfd):
    out = tmp_path / "o"
    assert main(["run", "--quiet", "--out", str(out), *COVERAGE_RUN]) == 0
    assert {"coverage.parquet", "control.parquet", "travel.parquet"} <= {p.name for p in out.iterdir()}
    (out / "fig6_initial_deployment.png").write_bytes(b"drawn from the first run")
    (out / "notes.txt").write_text("the user's own")
    (out / "bridge.toml").write_text("[bridge]\n")  # a user's scenario of that name, not the run's
    assert main(["run", "--quiet", "--out", str(out), *SMALL, "--set", "protocol.model=ack"]) == 0
    names = {p.name for p in out.iterdir()}
    assert not names & {"coverage.parquet", "control.parquet", "travel.parquet", "groups.parquet"}
    assert "fig6_initial_deployment.png" not in names
    assert "bridge.toml" in names
    assert "notes.txt" in names  # not netsim's: left alone
    assert cfgmod.load(out / "config.toml").protocol.model == "ack"
    assert not [n for n in names if n.startswith(".")]


def test_a_run_over_a_bridge_sessions_folder_removes_the_sessions_settings(tmp_path, capfd):
    """A bridge session's folder holds its ``bridge.toml`` (its DDS domain, relayed topics):
    a run given that folder replaces the session, that file too (it was left, naming a
    relay whose table was gone)."""
    out = tmp_path / "o"
    assert main(["run", "--quiet", "--out", str(out), *SMALL]) == 0
    summary = json.loads((out / "summary.json").read_text())
    (out / "summary.json").write_text(json.dumps({**summary, "bridge_rate": 1.0}))  # as a session's
    (out / "bridge.toml").write_text("domain_id = 77\n")
    assert main(["run", "--quiet", "--out", str(out), *SMALL]) == 0
    assert not (out / "bridge.toml").exists()


def test_a_non_empty_directory_that_holds_no_run_is_refused(tmp_path, capfd, no_simulation):
    out = tmp_path / "o"
    out.mkdir()
    (out / "coverage.parquet").write_bytes(b"not from netsim")
    before = tree(tmp_path)
    code = main(["run", "--out", str(out), *SMALL])
    refused(capfd, code, before, tmp_path, "holds no netsim run", "new or empty directory")


def test_figures_of_a_missing_run_directory_create_nothing(tmp_path, capfd, monkeypatch):
    monkeypatch.chdir(tmp_path)
    before = tree(tmp_path)
    refused(capfd, main(["figures", "nothere"]), before, tmp_path, "nothere")
    (tmp_path / "empty").mkdir()
    before = tree(tmp_path)
    refused(capfd, main(["figures", "empty", "--out", "figs"]), before, tmp_path, "not a run directory")


# -- the printed configuration -------------------------------------------------------------
def test_printed_configuration_derives_tau_and_merge_delay_from_the_ack_period(tmp_path, capsys):
    assert main(["config"]) == 0
    text = capsys.readouterr().out
    edited = text.replace("\nack_period_s = 1.0\n", "\nack_period_s = 5.0\n")
    assert edited != text
    (tmp_path / "c.toml").write_text(edited)
    c = cfgmod.load(tmp_path / "c.toml")
    assert (c.protocol.ack_period_s, c.protocol.tau_s, c.protocol.merge_delay_s) == (5.0, 15.0, 10.0)
    assert cfgmod.load(None, ["protocol.ack_period_s=5"]) == c


BRIDGE_SCENARIO = """duration_s = 60
[mobility]
model = "external"
[bridge]
domain_id = 7
odom_hz = 20
relay = [{name = "chat", type = "std_msgs/msg/String"}]
"""


def test_printed_configuration_of_a_bridge_scenario_keeps_its_bridge_table(tmp_path, capsys):
    """`netsim config` reads a `netsim bridge` scenario (docs/ros2.md): its [bridge] keys are
    printed with their meaning and values, and the printed file reads back as the same
    run and bridge; without a file the [bridge] keys are listed, commented out."""
    from netsim.bridge import settings

    (tmp_path / "b.toml").write_text(BRIDGE_SCENARIO)
    assert main(["config", str(tmp_path / "b.toml")]) == 0
    text = capsys.readouterr().out
    assert "\n[bridge]\n" in text and "ROS_DOMAIN_ID" in text
    (tmp_path / "printed.toml").write_text(text)
    assert settings.load(str(tmp_path / "printed.toml"), []) == settings.load(str(tmp_path / "b.toml"), [])
    assert main(["config"]) == 0
    default = capsys.readouterr().out
    assert "\n# [bridge]\n# the DDS domain" in default and "\n[bridge]" not in default


def test_a_bridge_scenario_given_to_run_names_the_bridge_in_one_line(tmp_path, capfd):
    (tmp_path / "b.toml").write_text(BRIDGE_SCENARIO)
    assert main(["run", str(tmp_path / "b.toml"), "--out", str(tmp_path / "out")]) == 2
    err = capfd.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "netsim bridge" in err[0] and not (tmp_path / "out").exists()


def test_printed_configuration_refuses_a_bad_bridge_key_in_one_line(tmp_path, capfd):
    (tmp_path / "b.toml").write_text(BRIDGE_SCENARIO.replace("domain_id = 7", "domain_id = 300"))
    assert main(["config", str(tmp_path / "b.toml")]) == 2
    out, err = capfd.readouterr()
    assert out == "" and err.strip().splitlines() == [
        "netsim: error: bridge.domain_id = 300: must be an integer from 0 to 232"
    ]


# -- progress in a log file ----------------------------------------------------------------
def test_progress_in_a_log_file_is_a_few_plain_lines():
    log = io.StringIO()  # not a terminal
    sim = runmod.build(cfgmod.from_dict({"duration_s": 40.0, "world": {"n_robots": 5}}))
    bar = progress_bar(40.0, "netsim run", "sim s", stream=log)
    assert isinstance(bar, PlainLines)
    with bar:
        for k in range(1, 201):
            sim.run(until_s=40.0 * k / 200)
            bar.update(sim.now - bar.n)
    lines = log.getvalue().splitlines()
    assert "\r" not in log.getvalue()
    assert [line.split(": ")[1].split("%")[0] for line in lines] == ["25", "50", "75", "100"]


@pytest.mark.slow
def test_simulation_progress_goes_to_standard_error_as_lines_when_not_a_terminal(tmp_path):
    run = subprocess.run(
        [
            sys.executable,
            "-m",
            "netsim.tools.cli",
            "run",
            "--out",
            "o",
            "--set",
            "world.n_robots=5",
            "--set",
            "world.side_m=200",
            "--set",
            "duration_s=100",
        ],
        cwd=tmp_path,
        capture_output=True,
        text=True,
    )
    assert run.returncode == 0
    assert "\r" not in run.stderr
    assert len(run.stderr.splitlines()) == 4 and run.stderr.splitlines()[-1].startswith("netsim run: 100% (100/100")


class _Terminal(io.StringIO):
    def isatty(self):
        return True


def test_sweep_bar_redraws_once_per_run(tmp_path, monkeypatch):
    import netsim.progress

    term = _Terminal()
    real = netsim.progress.progress_bar
    # Every refresh drawn (no rate limit), to a terminal: what is left is the calls themselves.
    monkeypatch.setattr(
        netsim.progress,
        "progress_bar",
        lambda *a, **k: real(*a, **{**k, "stream": term, "mininterval": 0, "miniters": 1}),
    )
    sweep = sweepmod.parse(
        {"name": "bar", "base": {"duration_s": 2.0, "world": {"n_robots": 3}}, "grid": {"seed": [1, 2, 3, 4]}}
    )
    sweepmod.run_sweep(sweep, tmp_path / "o", workers=1)
    draws = term.getvalue().count("\r")
    assert 4 <= draws <= 4 + 2  # one per run, plus the first and last draw


# -- a first run: what it says while it compiles, and what it cannot hold ----------------------
class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_the_bar_estimates_no_time_left_before_the_first_unit_of_work():
    """On a terminal the bar shows no estimate of the time left until the first unit of
    work (a simulated second) is done, and then estimates from the rate since then: the
    start-up (compiling the loops) does not make the rest look slower."""
    bar = progress_bar(
        300,
        "netsim run",
        "sim s",
        stream=_Terminal(),
        mininterval=0,
        bar_format="{n:.1f}/{total:.0f} [{elapsed}<{remaining}]",
    )
    clock = [0.0]
    bar._time = lambda: clock[0]
    bar.start_t = bar.last_print_t = 0.0
    clock[0] = 30.0  # the first half second took the compile
    bar.update(0.5)
    assert str(bar) == "0.5/300 [00:30<?]"
    clock[0] = 31.0
    bar.update(1.0)
    assert str(bar).endswith("<?]")
    clock[0] = 33.0
    bar.update(3.0)  # 3 s simulated in the 2 s since the first second: 1.5 sim s per s
    assert str(bar) == "4.5/300 [00:33<03:17]"
    bar.close()


KERNEL_SOURCE = "from netsim.compiled import jit\n\n\n@jit()\ndef plus_one(x):\n    return x + 1\n"


def _cold_kernel_module(tmp_path, monkeypatch, name, folder="checkout"):
    """A kernel module (one compiled function, keyed as every kernel module's compiled copy
    is) in ``folder``, with a new, empty cache directory."""
    where = tmp_path / folder
    where.mkdir(exist_ok=True)
    (where / f"{name}.py").write_text(KERNEL_SOURCE)
    monkeypatch.syspath_prepend(str(where))
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.delitem(sys.modules, name, raising=False)
    return where / f"{name}.py"


def _fresh_copy(name):
    """The module's compiled copy as a new process would make it (keyed anew)."""
    from netsim import compiled

    compiled._COPIES.pop(name, None)
    sys.modules.pop(name, None)
    return compiled.compiled_copy(name)


def test_a_kernel_module_numba_would_compile_is_told_once(tmp_path, monkeypatch):
    """when_cold's callback hears of the first kernel module whose loops numba is about to
    compile, once: with an empty cache; not once its code is cached; again for the same
    source in another folder (another checkout: numba files code by the source's folder),
    though that leaves code in the keyed directory."""
    from netsim import compiled, kernel_cache

    told = []
    name = "cold_probe_a"
    try:
        _cold_kernel_module(tmp_path, monkeypatch, name)
        kernel_cache.when_cold(told.append)
        assert _fresh_copy(name).plus_one(1) == 2  # compiled, and its code cached
        assert len(told) == 1 and told[0].parent == tmp_path / "cache"
        kernel_cache.when_cold(told.append)
        _fresh_copy(name)
        assert len(told) == 1, "a module whose code numba loads is not cold"
        _cold_kernel_module(tmp_path, monkeypatch, name, "other")
        _fresh_copy(name).plus_one(1)
        assert len(told) == 2 and told[1] == told[0], "another checkout's code is not this one's"
        kernel_cache.when_cold(told.append)
        _fresh_copy(name)
        assert len(told) == 2
    finally:
        kernel_cache.when_cold(None)
        compiled._COPIES.pop(name, None)
        sys.modules.pop(name, None)


@pytest.mark.parametrize("quiet", [False, True], ids=["says-so", "quiet"])
def test_netsim_run_says_it_compiles_when_the_cache_is_cold(tmp_path, capfd, monkeypatch, quiet):
    """`netsim run` with a cold kernel cache prints one line on standard error, as the
    compiling starts, that it compiles the simulator's loops; with --quiet, nothing."""
    from netsim import compiled, kernel_cache

    _cold_kernel_module(tmp_path, monkeypatch, "cold_probe_b")

    def execute(*a, **k):  # the build makes the kernel modules' compiled copies; then stop
        compiled.compiled_copy("cold_probe_b")
        raise NetsimInputError("stopped after the build")

    monkeypatch.setattr(runmod, "execute", execute)
    try:
        code = main(["run", *(["--quiet"] if quiet else []), "--out", str(tmp_path / "o"), *SMALL])
    finally:
        kernel_cache.when_cold(None)
        compiled._COPIES.pop("cold_probe_b", None)
        sys.modules.pop("cold_probe_b", None)
    err = capfd.readouterr().err.strip().splitlines()
    assert code == 2 and err[-1] == "netsim: error: stopped after the build"
    compiling = [line for line in err if "compiling the simulator's loops" in line]
    assert compiling == (
        []
        if quiet
        else [
            "netsim run: compiling the simulator's loops this run uses (each once for this version "
            f"of netsim; other models' when a run first uses them; cached in {tmp_path / 'cache'})..."
        ]
    )


def test_a_team_that_cannot_fit_in_memory_is_refused_up_front(tmp_path, capfd, monkeypatch, no_simulation):
    """`world.n_robots` beyond what the machine's memory can hold (the robots' state and the
    positions table alone) is one line naming the key, exit 2, before any work, nothing
    written."""
    from netsim.machine import machine_memory_bytes
    from netsim.tools import preflight

    monkeypatch.setattr(runmod, "build", lambda *a, **k: pytest.fail("built before checking the memory"))
    monkeypatch.chdir(tmp_path)
    n = 100_000_000
    # No protocol: the Acks of 10^8 robots would be refused first, as too many events.
    config = cfgmod.load(None, [f"world.n_robots={n}", "protocol.model=none"])
    memory = machine_memory_bytes()
    if memory is None or preflight.least_memory_bytes(config) <= memory:
        pytest.skip("this machine could hold the state of 10^8 robots")
    before = tree(tmp_path)
    line = refused(
        capfd,
        main(["run", "--set", f"world.n_robots={n}", "--set", "protocol.model=none"]),
        before,
        tmp_path,
        f"world.n_robots = {n}: the run would hold at least",
        "of memory",
    )
    assert "GiB" in line


def test_course_changes_past_memory_are_refused_by_run_and_sweep(tmp_path, capfd, monkeypatch, no_simulation):
    """A random waypoint run of motion alone whose course changes cannot fit in memory (2
    robots for 10^12 s: no protocol's events to refuse it) is one line naming duration_s,
    exit 2, nothing written, from `netsim run` as from `netsim sweep` and `scenario
    generate`. (`netsim run` and a sweep started it, silent, and grew until stopped.)"""
    from netsim.machine import machine_memory_bytes

    if machine_memory_bytes() is None:
        pytest.skip("this machine does not tell its memory")
    monkeypatch.chdir(tmp_path)
    sets = ["duration_s=1e12", "world.n_robots=2", "output.position_interval_s=0", "protocol.model=none"]
    (tmp_path / "s.toml").write_text(
        'name = "long"\n[base]\nduration_s = 1e12\n[base.protocol]\nmodel = "none"\n'
        '[base.output]\nposition_interval_s = 0\n[grid]\n"world.n_robots" = [2, 3]\n'
    )
    before = tree(tmp_path)
    for argv in (["run", *[a for s in sets for a in ("--set", s)]], ["sweep", "s.toml"]):
        refused(capfd, main(argv), before, tmp_path, "duration_s = 1000000000000.0: the scenario would hold", "course")


@pytest.mark.parametrize("override", ["duration_s=1e300", "output.position_interval_s=1e-9"])
def test_samples_past_any_memory_are_refused_without_making_them(tmp_path, capfd, monkeypatch, no_simulation, override):
    """A positions table past any memory (a duration of 1e300 s, a sample every ns) is one
    line, exit 2, nothing written: its rows are counted, never made (making the instants
    first was a traceback of a numpy allocation error)."""
    from netsim import samples

    monkeypatch.setattr(samples, "sample_times", lambda *a: pytest.fail("made the instants to count them"))
    monkeypatch.chdir(tmp_path)
    before = tree(tmp_path)
    refused(
        capfd,
        main(["run", "--set", "world.n_robots=5", "--set", "protocol.model=none", "--set", override]),
        before,
        tmp_path,
        "world.n_robots = 5: the run would hold at least",
        "of memory",
    )


def test_the_least_memory_grows_with_the_team_and_the_samples():
    """The memory floor counts each robot's state and each row of positions.parquet."""
    from netsim.tools import preflight

    one = preflight.least_memory_bytes(cfgmod.load(None, ["world.n_robots=1", "output.position_interval_s=0"]))
    assert one > 0
    ten = preflight.least_memory_bytes(cfgmod.load(None, ["world.n_robots=10", "output.position_interval_s=0"]))
    assert ten == 10 * one
    sampled = preflight.least_memory_bytes(cfgmod.load(None, ["world.n_robots=10", "duration_s=9"]))
    assert sampled == ten + 10 * 10 * 32  # 10 samples (0..9 s) of 4 eight-byte columns


def test_the_least_memory_of_an_unsampled_run_is_what_the_robots_state_allocates():
    """Without positions samples the floor is the robots' state alone: the bytes a
    RobotState of the team allocates (its complex views of origin and velocity share
    their arrays' memory, counted once), as traced, to 1 %."""
    import tracemalloc

    from netsim.state import RobotState
    from netsim.tools import preflight

    n = 100_000
    floor = preflight.least_memory_bytes(cfgmod.load(None, [f"world.n_robots={n}", "output.position_interval_s=0"]))
    tracemalloc.start()
    try:
        state = RobotState(n, 1.0, 1.0)
        allocated, _ = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert state.n == n
    assert floor == pytest.approx(allocated, rel=0.01)


# A random waypoint scenario whose longest leg is 102 s (a 30 m x 40 m area's 50 m
# diagonal at 0.5 m/s, and a 2 s pause): over 102,000 s each of its 3 robots changes
# course at least 1,000 times, 3,000 rows of the leg log in all.
LEGS = [
    "world.bounds_m=[0, 0, 30, 40]",
    "mobility.speed_min_mps=0.5",
    "mobility.pause_s=2",
    "world.n_robots=3",
    "protocol.model=none",
    "output.position_interval_s=0",
]


def test_course_changes_are_refused_exactly_beyond_the_memory():
    """A random waypoint run is refused when its course changes (at least duration_s over
    the longest leg, the diagonal at the least speed and a pause, per robot) cannot fit in
    the memory; one that just fits is not."""
    from netsim.errors import ConfigError
    from netsim.tools import preflight

    config = cfgmod.load(None, [*LEGS, "duration_s=102000"])
    need = 3_000 * preflight.LEG_BYTES
    preflight.check_legs_fit_in_memory(config, need)
    with pytest.raises(ConfigError) as err:
        preflight.check_legs_fit_in_memory(config, need - 1)
    assert err.value.key == "duration_s"


def test_course_changes_are_not_counted_without_a_least_speed_or_a_known_memory():
    """No least speed (a leg may last forever) or a machine that does not tell its memory:
    no refusal, whatever the duration; nor for a model other than random waypoint."""
    from netsim.tools import preflight

    long = "duration_s=1e15"
    preflight.check_legs_fit_in_memory(cfgmod.load(None, [*LEGS, long, "mobility.speed_min_mps=0"]), 1)
    preflight.check_legs_fit_in_memory(cfgmod.load(None, [*LEGS, long]), None)
    preflight.check_legs_fit_in_memory(cfgmod.load(None, [*LEGS, long, "mobility.model=random_direction"]), 1)


def test_the_course_changes_refusal_says_how_much_against_the_machines_memory():
    """The refusal names duration_s, the course changes' GiB, how often a robot changes
    course at least (the area crossed at the least speed, and the pause) and the machine's
    memory, in that order, and what else lowers them."""
    from netsim.errors import ConfigError
    from netsim.tools import preflight

    # 3 x 2^30 / 100 legs of 100 bytes: 3 GiB of course changes, against 1 GiB.
    duration = 102 * 2**30 / 100
    config = cfgmod.load(None, [*LEGS, f"duration_s={duration!r}"])
    with pytest.raises(ConfigError) as err:
        preflight.check_legs_fit_in_memory(config, 2**30)
    assert str(err.value) == (
        f"duration_s = {duration!r}: the scenario would hold at least 3.0 GiB of course changes (a robot changes "
        "course at least every 102 s, crossing the area at mobility.speed_min_mps and pausing mobility.pause_s), "
        "more than this machine's 1.0 GiB of memory; shorten it, or enlarge the area, or raise the pause or lower "
        "the least speed"
    )


def test_a_team_is_refused_exactly_beyond_the_machines_memory(monkeypatch):
    """The robots' state and positions that just fit in the machine's memory are run; a
    byte more than it has is refused, naming world.n_robots."""
    from netsim.errors import ConfigError
    from netsim.tools import preflight

    config = cfgmod.load(None, ["world.n_robots=50", "duration_s=9", "protocol.model=none"])
    need = preflight.least_memory_bytes(config)
    monkeypatch.setattr(preflight, "machine_memory_bytes", lambda: need)
    preflight.check_run(config)
    monkeypatch.setattr(preflight, "machine_memory_bytes", lambda: need - 1)
    with pytest.raises(ConfigError) as err:
        preflight.check_run(config)
    assert err.value.key == "world.n_robots"


@pytest.mark.parametrize(
    ("sets", "held", "advice"),
    [
        (["output.position_interval_s=0"], "the robots' state", ""),
        (
            [],
            "the robots' state and positions.parquet's rows",
            ", or duration_s, or raise output.position_interval_s (0: no positions table)",
        ),
    ],
    ids=["unsampled", "sampled"],
)
def test_a_team_past_the_memory_is_told_what_it_would_hold_and_what_to_lower(
    tmp_path, capfd, monkeypatch, no_simulation, sets, held, advice
):
    """The refusal says what the floor holds (the positions' rows only when sampled), the
    GiB it needs against the machine's, and what to lower (duration_s and the sampling
    only when there are samples): one line, exit 2, nothing written."""
    from netsim.machine import gib
    from netsim.tools import preflight

    n = 10_000_000
    args = [f"world.n_robots={n}", "protocol.model=none", *sets]
    need = preflight.least_memory_bytes(cfgmod.load(None, args))
    monkeypatch.setattr(preflight, "machine_memory_bytes", lambda: 2**29)
    monkeypatch.chdir(tmp_path)
    before = tree(tmp_path)
    line = refused(capfd, main(["run", *(a for s in args for a in ("--set", s))]), before, tmp_path)
    assert gib(need) != "0.5"
    assert line == (
        f"netsim: error: world.n_robots = {n}: the run would hold at least {gib(need)} GiB ({held}, before any "
        f"model's), more than this machine's 0.5 GiB of memory; lower it{advice}"
    )


def test_two_commands_never_write_one_directory_at_once(tmp_path):
    """While one command holds its output directory, a second one given it is refused in one
    line before any work (two bridges on one --out: the second silently replaced the
    first's results); once the first is done, the directory can be claimed again."""
    out = tmp_path / "out"
    with claim_dir(out, "--out", kind="run"):
        with pytest.raises(NetsimInputError, match=r"^--out .*out: another netsim command is writing there now"):
            with claim_dir(out, "--out", kind="run"):
                pass
        # A table moved in before the manifest: still told as busy, not as a folder of no run.
        (out / "links.parquet").write_bytes(b"")
        with pytest.raises(NetsimInputError, match=r"another netsim command is writing there now"):
            with claim_dir(out, "--out", kind="run"):
                pass
        assert out.is_dir()  # the refusal removed nothing of the first's
        (out / "links.parquet").unlink()
    with claim_dir(out, "--out", kind="run"):
        pass
