"""Each experiment script runs end to end at a tiny size and writes its CSV and PNG."""

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

ROOT = Path(__file__).resolve().parents[1]


# The experiment commands of docs/experiments.md are run here, at these sizes (tests/test_readme.py
# checks that every experiment that page names is in this list).
CASES = [
    (
        "cluster_stability.py",
        ["--reps", "2", "--speeds", "1", "8", "--pauses", "0", "--duration", "40", "--n", "20"],
        "cluster_stability.csv",
    ),
    (
        "link_lifetime.py",
        ["--speeds", "2", "--pauses", "0", "--reps", "1", "--duration", "100", "--n", "40"],
        "link_lifetime.csv",
    ),
    (
        "false_role_changes.py",
        ["--pairs", "30", "--losses", "0.5", "--taus", "1.5", "--duration", "60"],
        "false_role_changes.csv",
    ),
    (
        "coverage_vs_n.py",
        [
            "--n",
            "8",
            "--map-n",
            "6",
            "--reps",
            "2",
            "--duration",
            "40",
            "--radios",
            "unit disk",
            "office, line of sight",
        ],
        "coverage_vs_n.csv",
    ),
    (
        "walls_and_shadowing.py",
        ["--reps", "2", "--sigmas", "0", "6", "--duration", "30", "--n", "15"],
        "walls_and_shadowing.csv",
    ),
    (
        "routing_compare.py",
        ["--n", "10", "--side", "250", "--duration", "40", "--warmup", "15", "--speeds", "2", "--reps", "2"],
        "routing_compare.csv",
    ),
    (
        "ack_congestion.py",
        ["--n", "20", "--densities", "8", "--periods", "0.5", "--duration", "15", "--warmup", "5", "--reps", "1"],
        "ack_congestion.csv",
    ),
]


@pytest.mark.parametrize("script", [case[0] for case in CASES])
@pytest.mark.slow
def test_a_bad_scheduler_is_one_line_exit_2_nothing_written(tmp_path, script):
    out = tmp_path / "out"
    run = subprocess.run(
        [sys.executable, str(ROOT / "experiments" / script), "--scheduler", "notanaddress", "--out", str(out)],
        capture_output=True,
        text=True,
        cwd=tmp_path,
    )
    assert run.returncode == 2 and run.stderr.count("\n") == 1, run.stderr
    assert "--scheduler 'notanaddress'" in run.stderr
    assert not out.exists()


@pytest.mark.slow
def test_link_lifetime_draws_its_figure_when_no_link_ends(tmp_path):
    """20 robots on the default square for 60 s: the few links that form outlast the run,
    so the survival curves are empty; the figure says so instead of failing."""
    args = ["--n", "20", "--speeds", "2", "--pauses", "0", "--duration", "60", "--reps", "1", "--workers", "1"]
    run = subprocess.run(
        [sys.executable, str(ROOT / "experiments" / "link_lifetime.py"), *args, "--out", str(tmp_path)],
        capture_output=True,
        text=True,
        cwd=tmp_path,
    )
    assert run.returncode == 0, run.stderr[-2000:]
    assert pd.read_csv(tmp_path / "link_lifetime.csv")["mean_s"].isna().all()  # no link ended
    assert (tmp_path / "link_lifetime.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize("script, args, csv", CASES)
@pytest.mark.slow
def test_experiment_writes_csv_and_png(tmp_path, script, args, csv):
    run = subprocess.run(
        [sys.executable, str(ROOT / "experiments" / script), *args, "--workers", "1", "--out", str(tmp_path)],
        capture_output=True,
        text=True,
        cwd=tmp_path,
    )
    assert run.returncode == 0, run.stderr[-2000:]
    df = pd.read_csv(tmp_path / csv)
    assert len(df) >= 1 and not df.isna().all(axis=None)
    png = tmp_path / csv.replace(".csv", ".png")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    if script == "coverage_vs_n.py":
        # One figure: every mode on every radio asked, each point from its own runs.
        got = set(zip(df["radio"], df["mode"]))
        assert got == {(r, m) for r in ("unit disk", "office, line of sight") for m in ("global", "local", "follow")}
        assert (df["covered_of_bound_all_final_n"] == 2).all()


@pytest.mark.slow
def test_coverage_targets_prints_its_table(tmp_path):
    """experiments/coverage_targets.py (docs/model.md section 5) runs its scenario and prints
    one row per run with the fraction of the bound, the components and the verdict."""
    run = subprocess.run(
        [sys.executable, str(ROOT / "experiments" / "coverage_targets.py"), "--n", "12", "--no-radios"]
        + ["--duration", "40", "--workers", "1", "--csv", str(tmp_path / "t.csv")],
        capture_output=True,
        text=True,
        cwd=tmp_path,
    )
    assert run.returncode == 1, run.stderr  # a network grew: the rows fail[-2000:]
    table = pd.read_csv(tmp_path / "t.csv")
    assert len(table) == 4 and set(table["plan"]) == {"global", "local"}
    assert (table["grew"] == 0).all() and table["table true"].all()
    assert "rows pass" in run.stdout


@pytest.mark.slow
@pytest.mark.parametrize(
    "args, said",
    [(["--n", "1"], "--n and --map-n"), (["--radios", "moon"], "--radios 'moon'"), (["--reps", "0"], "--reps 0")],
)
def test_coverage_vs_n_refuses_bad_options_in_one_line_and_writes_nothing(tmp_path, args, said):
    """A team of one, an unknown radio, no replications: each is one line on stderr naming
    the option, exit status 2, and no output directory."""
    out = tmp_path / "out"
    run = subprocess.run(
        [sys.executable, str(ROOT / "experiments" / "coverage_vs_n.py"), *args, "--out", str(out)],
        capture_output=True,
        text=True,
        cwd=tmp_path,
    )
    assert run.returncode == 2 and run.stderr.count("\n") == 1, run.stderr
    assert said in run.stderr
    assert not out.exists()


@pytest.mark.slow
def test_coverage_on_map_prints_its_table(tmp_path):
    """experiments/coverage_on_map.py (docs/experiments.md) runs the office from a connected
    start and prints one row per radio and plan: every start connected, the covered fraction
    of the free-area bound, the seeds that split and the verdict."""
    run = subprocess.run(
        [sys.executable, str(ROOT / "experiments" / "coverage_on_map.py"), "--n", "8", "--seeds", "1"]
        + ["--radios", "office, line of sight", "--duration", "30", "--workers", "1", "--csv", str(tmp_path / "r.csv")]
        + ["--figure", str(tmp_path / "ended.png")],
        capture_output=True,
        text=True,
        cwd=tmp_path,
    )
    assert run.returncode == 1, run.stderr  # a network grew: the rows fail[-2000:]
    runs = pd.read_csv(tmp_path / "r.csv")
    assert len(runs) == 2 and set(runs["plan"]) == {"global", "local"}
    assert (runs["comp0"] == 1).all() and not runs["split"].any()
    assert ((runs["final"] > 0) & (runs["final"] <= 1.0 + 1e-9)).all()
    # Control ran to the end (30 s is less than a stopping window after control starts).
    assert runs["settled_s"].isna().all()
    assert "rows pass" in run.stdout and "unsettled" in run.stdout
    assert (tmp_path / "ended.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.slow
def test_coverage_on_map_refuses_bad_options_in_one_line(tmp_path):
    """An unknown radio, no seeds, a figure or table in a folder that is not there or named
    as a folder, a figure of a kind it cannot draw: one line on stderr naming the option,
    exit status 2, nothing written, before any run."""
    cases = (
        (["--radios", "moon"], "--radios 'moon'"),
        (["--seeds", "0"], "--seeds 0"),
        (["--figure", "nowhere/ended.png"], "--figure nowhere/ended.png: the directory nowhere does not exist"),
        (["--csv", "nowhere/runs.csv"], "--csv nowhere/runs.csv: the directory nowhere does not exist"),
        (["--csv", "."], "--csv .: is a directory"),
        (["--figure", "sub.png/"], "--figure sub.png/: names a directory"),
        (["--figure", "ended.gif"], "--figure 'ended.gif': must end in one of .png, .svg, .pdf"),
        # The figure was written over the table.
        (["--csv", "x.png", "--figure", "x.png"], "--csv and --figure name one file, x.png: give each its own"),
    )
    refused_in_one_line("coverage_on_map.py", cases, tmp_path)


def test_routing_compare_intervals_of_a_ratio_stay_within_0_and_1():
    """A delivery ratio's Student-t interval from two replications (1.0 and 0.5) reaches
    far beyond [0, 1]; the printed one is cut there, and an interval inside is untouched."""
    from tests.fixtures import script

    module = script("experiments/routing_compare.py")
    assert module.ci95([1.0, 0.5], (0.0, 1.0)) == (0.75, 0.0, 1.0)
    mean, low, high = module.ci95([0.50, 0.52, 0.51, 0.49], (0.0, 1.0))
    assert 0.0 < low < mean < high < 1.0 and mean == pytest.approx(0.505)


@pytest.mark.slow
def refused_in_one_line(script: str, cases, folder) -> None:
    """Each ``(args, said)`` of ``cases`` run as ``experiments/SCRIPT args`` in ``folder``:
    one line on stderr holding ``said``, exit status 2, nothing written."""
    for args, said in cases:
        run = subprocess.run(
            [sys.executable, str(ROOT / "experiments" / script), *args],
            capture_output=True,
            text=True,
            cwd=folder,
        )
        assert run.returncode == 2 and run.stderr.count("\n") == 1, run.stderr
        assert said in run.stderr
    assert list(folder.iterdir()) == []


def test_ack_congestion_marks_no_saturation_where_the_carried_load_still_rises():
    """A medium whose carried load rises over the whole grid has no knee (its last point
    was marked saturated); one that peaks inside the grid has its knee at the peak."""
    from tests.fixtures import script

    ack = script("experiments/ack_congestion.py")
    df = pd.DataFrame(
        {
            "mac": ["aloha"] * 3 + ["csma"] * 3,
            "offered_ack_load": [0.1, 0.2, 0.4] * 2,
            "carried_ack_load": [0.09, 0.17, 0.30, 0.09, 0.15, 0.12],
        }
    )
    assert ack.knees(df) == {"aloha": math.inf, "csma": 0.2}


def _script(tmp_path, script, *args):
    return subprocess.run(
        [sys.executable, str(ROOT / "experiments" / script), *args],
        capture_output=True,
        text=True,
        cwd=tmp_path,
    )


@pytest.mark.slow
def test_link_lifetime_writes_its_table_when_no_link_forms(tmp_path):
    """Five robots on a 5 km square: no link ever forms; the table has its rows, with no
    figures (it ended in a KeyError, its folder half written)."""
    args = ["--n", "5", "--side", "5000", "--speeds", "1", "--pauses", "0", "--duration", "20", "--reps", "1"]
    run = _script(tmp_path, "link_lifetime.py", *args, "--workers", "1", "--out", str(tmp_path / "o"))
    assert run.returncode == 0, run.stderr[-2000:]
    table = pd.read_csv(tmp_path / "o" / "link_lifetime.csv")
    assert list(table["links"]) == [0, 0] and table["mean_s"].isna().all()


@pytest.mark.slow
def test_ack_congestion_runs_a_period_given_twice_once(tmp_path):
    """`--periods 1 1` is one point: one replication, the same figures as `--periods 1`
    (its runs and role changes were counted twice)."""
    args = ["--n", "20", "--densities", "5", "--macs", "none", "--duration", "20", "--warmup", "5", "--reps", "1"]
    tables = []
    for name, periods in (("twice", ["1", "1"]), ("once", ["1"])):
        run = _script(tmp_path, "ack_congestion.py", *args, "--periods", *periods, "--workers", "1", "--out", name)
        assert run.returncode == 0, run.stderr[-2000:]
        tables.append(pd.read_csv(tmp_path / name / "ack_congestion.csv"))
    assert list(tables[0]["replications"]) == [1]
    pd.testing.assert_frame_equal(tables[0], tables[1])


# The smallest routing comparison: what an old check let run before it failed runs quickly.
TINY_ROUTING = ["--n", "4", "--duration", "20", "--warmup", "15", "--speeds", "2", "--reps", "1", "--workers", "1"]
TINY_LIFETIME = ["--n", "5", "--duration", "10", "--pauses", "0", "--reps", "1", "--workers", "1"]
TINY_CONGESTION = ["--n", "20", "--densities", "8", "--macs", "none", "--duration", "15", "--warmup", "5"]
TINY_CONGESTION += ["--reps", "1", "--workers", "1"]


@pytest.mark.slow
@pytest.mark.parametrize(
    "script, args, said",
    [
        ("cluster_stability.py", ["--workers", "0"], "--workers 0: must be at least 1"),
        ("ack_congestion.py", ["--warmup", "40", "--duration", "40"], "--warmup 40: must be at least 0 and shorter"),
        ("ack_congestion.py", ["--warmup", "-5"], "--warmup -5: must be at least 0"),
        ("coverage_targets.py", ["--csv", "/nonexistent/f.csv"], "--csv /nonexistent/f.csv: the directory"),
        ("coverage_targets.py", ["--figure", "f.png"], "--figure applies to --shadowing runs only"),
        ("coverage_targets.py", ["--bound", "--shadowing", "--figure", "f.png"], "--figure applies to --shadowing"),
        ("coverage_targets.py", ["--shadowing", "--figure", "f.gif"], "--figure 'f.gif': must end in one of .png"),
        ("coverage_targets.py", ["--shadowing", "--figure", "/nonexistent/f.png"], "--figure /nonexistent/f.png: the"),
        ("coverage_targets.py", ["--shadowing", "--figure", "sub/"], "--figure sub/: names a directory"),
        ("coverage_targets.py", ["--shadowing", "--figure", "r.png", "--csv", "./r.png"], "--csv and --figure name"),
        # Its placement file was written first, then the sweep refused.
        ("false_role_changes.py", ["--losses", "1.5"], "--losses 1.5: each a probability in [0, 1)"),
        ("false_role_changes.py", ["--pairs", "0"], "--pairs 0: at least 1"),
        ("false_role_changes.py", ["--pairs", "2", "--workers", "0"], "--workers 0: must be at least 1"),
        ("false_role_changes.py", ["--pairs", "2", "--taus", "0.5"], "protocol.tau_s = 0.5"),
        ("false_role_changes.py", ["--pairs", "2", "--duration", "-1"], "duration_s = -1.0"),
        # A ZeroDivisionError and a math domain error.
        ("ack_congestion.py", ["--densities", "0"], "--densities 0: each must be > 0"),
        ("ack_congestion.py", ["--densities", "10", "-5"], "--densities -5: each must be > 0"),
        # A sweep ran, then an AttributeError; a ZeroDivisionError.
        ("routing_compare.py", ["--flows", "0", *TINY_ROUTING], "--flows 0: at least 1"),
        ("routing_compare.py", ["--flows", "-1", *TINY_ROUTING], "--flows -1: at least 1"),
        ("routing_compare.py", ["--interval", "0"], "--interval 0: must be > 0 s"),
        # Each ran and wrote the sweeps before the bad one.
        ("link_lifetime.py", [*TINY_LIFETIME, "--speeds", "2", "-1"], "mobility.speed_min_mps = -0.5"),
        ("link_lifetime.py", [*TINY_LIFETIME, "--side", "100", "--range", "60"], "world.side_m = 100.0: on a torus"),
        ("ack_congestion.py", [*TINY_CONGESTION, "--periods", "1", "-0.5"], "protocol.ack_period_s = -0.5"),
    ],
)
def test_experiment_options_refused_before_any_run(tmp_path, script, args, said):
    """Options that would run nothing useful, or lose the runs at the end, are one line,
    exit 2, before any run (they ran serially, gave figures of NaN, or failed after every
    run with a traceback)."""
    out = [] if script == "coverage_targets.py" else ["--out", str(tmp_path / "o")]  # it writes no folder
    run = _script(tmp_path, script, *args, *out)
    assert run.returncode == 2 and run.stderr.count("\n") == 1 and said in run.stderr, run.stderr
    assert not (tmp_path / "o").exists()


@pytest.mark.slow
@pytest.mark.parametrize("script", ["false_role_changes.py", "learn_coverage.py"])
@pytest.mark.parametrize(
    "out, said",
    [
        ("afile", "is a file, not a directory"),
        ("afile/sub", "cannot be created: afile is a file"),
        ("/proc/nope", "cannot be created (No such file or directory)"),
    ],
)
def test_an_out_that_cannot_be_made_is_one_line(tmp_path, script, out, said):
    """--out naming a file, a folder under a file, or one that cannot be made: one line,
    exit 2, nothing written (a file gave a FileExistsError traceback, learn_coverage's
    after its episodes; the others a NotADirectoryError or FileNotFoundError traceback),
    as the sweep runner says it."""
    (tmp_path / "afile").write_text("")
    run = _script(tmp_path, script, "--out", out)
    assert run.returncode == 2 and run.stderr.count("\n") == 1, run.stderr
    assert f"--out {out}: {said}" in run.stderr
    assert [p.name for p in tmp_path.iterdir()] == ["afile"]


@pytest.mark.slow
def test_false_role_changes_writes_nothing_into_another_sweeps_folder(tmp_path):
    """--out whose sweep/ holds another sweep: refused in one line before the placement
    file is written (pairs.csv was left there)."""
    (tmp_path / "o" / "sweep").mkdir(parents=True)
    (tmp_path / "o" / "sweep" / "sweep.json").write_text('{"name": "cluster_stability"}')
    run = _script(tmp_path, "false_role_changes.py", "--pairs", "2", "--workers", "1", "--out", "o")
    assert run.returncode == 2 and run.stderr.count("\n") == 1, run.stderr
    assert "holds the sweep 'cluster_stability', not 'false_role_changes'" in run.stderr
    assert [p.name for p in (tmp_path / "o").iterdir()] == ["sweep"]


def test_the_theory_of_false_role_changes_at_no_loss_is_its_limit():
    """At loss 0 no Ack is lost: the mean wait for k consecutive losses is infinite, the
    formula's limit as p falls to 0 (it divided by zero), alone and within an array."""
    from netsim.tools.analysis import expected_acks_until_spurious_timeout as theory

    assert theory(0.0, 2) == math.inf
    got = theory(np.array([0.0, 0.5]), 2)
    assert got[0] == math.inf and got[1] == pytest.approx(6.0)


@pytest.mark.slow
def test_false_role_changes_runs_at_no_loss(tmp_path):
    """--losses 0, in the [0, 1) its message allows: its row has no false leader loss, no
    wait ended, and the theory inf (the runs ended in a ZeroDivisionError)."""
    args = ["--pairs", "3", "--losses", "0", "0.5", "--taus", "1.5", "--duration", "30", "--workers", "1"]
    run = _script(tmp_path, "false_role_changes.py", *args, "--out", "o")
    assert run.returncode == 0, run.stderr[-2000:]
    at_0 = pd.read_csv(tmp_path / "o" / "false_role_changes.csv").set_index("loss_probability").loc[0.0]
    assert at_0["theory"] == math.inf and at_0["false_leader_losses_per_robot_per_min"] == 0
    assert math.isnan(at_0["acks_until_false_loss"])


def _patched_script(tmp_path, patch: str, script: str, *args):
    """experiments/SCRIPT run as ``python`` runs it (its ``__main__``), after ``patch``."""
    program = f"{patch}\nimport runpy, sys\nsys.argv = sys.argv[1:]\nrunpy.run_path(sys.argv[0], run_name='__main__')"
    command = [sys.executable, "-c", program, str(ROOT / "experiments" / script), *args]
    return subprocess.run(command, capture_output=True, text=True, cwd=tmp_path)


@pytest.mark.slow
def test_learn_coverage_without_the_rl_extra_is_one_line(tmp_path):
    """Without gymnasium (of the optional extra rl) learn_coverage says which extra to install
    in one line, exit 2, nothing written (a ModuleNotFoundError traceback, even for --help)."""
    run = _patched_script(tmp_path, "import sys; sys.modules['gymnasium'] = None", "learn_coverage.py", "--out", "o")
    assert run.returncode == 2 and run.stderr.count("\n") == 1, run.stderr
    assert "needs gymnasium, of the optional extra 'rl': pip install -e \".[rl]\"" in run.stderr
    assert list(tmp_path.iterdir()) == []


def test_the_docs_say_learn_coverage_needs_the_rl_extra():
    """docs/experiments.md says, beside learn_coverage.py, how to install what it needs."""
    text = (ROOT / "docs" / "experiments.md").read_text()
    beside = [p for p in text.split("\n\n") if "learn_coverage.py" in p]
    assert beside and all('pip install -e ".[rl]"' in p for p in beside)


# A process pool that runs nothing: its map hands out ROWS, then (INTERRUPT) a Ctrl-C, as
# one that lands between two runs (the script's runs and their time are not what is tested).
FAKE_POOL = """
from contextlib import contextmanager

import netsim.tools.sweep


class Pool:
    def imap(self, fn, jobs):
        yield from ROWS
        if INTERRUPT:
            raise KeyboardInterrupt

    def starmap(self, fn, jobs):
        return list(self.imap(fn, jobs))


@contextmanager
def process_pool(workers, jobs):
    yield Pool()


netsim.tools.sweep.process_pool = process_pool
"""
# Ctrl-C while a figure is drawn.
DRAWING_INTERRUPTED = """
import netsim.tools.figures


def pyplot():
    raise KeyboardInterrupt


netsim.tools.figures.pyplot = pyplot
"""
SHADOWING_ROW = {"plan": "global", "N": 5, "seed": 1, "of bound": 0.5, "grew": 0, "settled s": None}


@pytest.mark.slow
@pytest.mark.parametrize(
    "rows, said",
    [([], "nothing written"), ([SHADOWING_ROW], "the runs finished are in runs.csv")],
)
def test_ctrl_c_in_coverage_targets_is_one_line_saying_what_is_kept(tmp_path, rows, said):
    """Ctrl-C in coverage_targets --shadowing --csv F: one line, exit 130 (a traceback),
    saying that F holds the runs finished, when one has."""
    patch = f"ROWS, INTERRUPT = {rows!r}, True\n{FAKE_POOL}"
    args = ["--shadowing", "--seeds", "1", "--n", "5", "--csv", "runs.csv", "--no-progress"]
    run = _patched_script(tmp_path, patch, "coverage_targets.py", *args)
    assert (run.returncode, run.stderr) == (130, f"coverage_targets.py: interrupted; {said}\n")
    if rows:
        assert pd.read_csv(tmp_path / "runs.csv")["plan"].tolist() == ["global"]
    else:
        assert list(tmp_path.iterdir()) == []


@pytest.mark.slow
def test_ctrl_c_between_coverage_targets_runs_ends_the_pool_before_its_line(tmp_path):
    """Ctrl-C while coverage_targets writes --csv after a run (outside the pool's loop): the
    workers are ended, and the progress bar closed, before the one line is printed, as when
    it lands in the loop (they were left to the interpreter's exit: the bar, on a terminal,
    drawn again after the line)."""
    rows = [SHADOWING_ROW, {**SHADOWING_ROW, "plan": "local"}]
    patch = f"""ROWS, INTERRUPT = {rows!r}, False
import sys
from contextlib import contextmanager

import netsim.tools.output
import netsim.tools.sweep


class Pool:
    def imap(self, fn, jobs):
        yield from ROWS


@contextmanager
def process_pool(workers, jobs):
    try:
        yield Pool()
    finally:
        print("pool ended", file=sys.stderr)


netsim.tools.sweep.process_pool = process_pool
written = netsim.tools.output.write_atomically
calls = []


def write_atomically(path, write):
    calls.append(path)
    if len(calls) == 2:
        raise KeyboardInterrupt
    return written(path, write)


netsim.tools.output.write_atomically = write_atomically
"""
    args = ["--shadowing", "--seeds", "1", "--n", "5", "--csv", "runs.csv", "--no-progress"]
    run = _patched_script(tmp_path, patch, "coverage_targets.py", *args)
    said = "coverage_targets.py: interrupted; the runs finished are in runs.csv\n"
    assert (run.returncode, run.stderr) == (130, f"pool ended\n{said}")
    assert pd.read_csv(tmp_path / "runs.csv")["plan"].tolist() == ["global"]


@pytest.mark.slow
@pytest.mark.parametrize("quiet", [False, True])
def test_coverage_targets_shows_its_runs_progress_on_stderr(tmp_path, quiet):
    """Each finished run moves a progress bar on standard error (in a log: plain lines),
    telling the latest run's plan, N, seed and fraction; ``--no-progress`` shows none.
    Standard output holds the table alone."""
    local = {**SHADOWING_ROW, "plan": "local", "of bound": 0.25}
    patch = f"ROWS, INTERRUPT = {[SHADOWING_ROW, local]!r}, False\n{FAKE_POOL}"
    args = ["--shadowing", "--seeds", "1", "--n", "5", *(["--no-progress"] if quiet else [])]
    run = _patched_script(tmp_path, patch, "coverage_targets.py", *args)
    assert run.returncode == 1, run.stderr
    if quiet:
        assert run.stderr == ""
    else:
        lines = run.stderr.splitlines()
        assert lines[0].startswith("coverage_targets.py: 50% (1/2 runs), latest global, N = 5, seed 1: 0.500 of")
        assert lines[-1].startswith("coverage_targets.py: 100% (2/2 runs), latest local, N = 5, seed 1: 0.250 of")
    assert "{" not in run.stdout and "rows pass" in run.stdout


@pytest.mark.slow
@pytest.mark.parametrize("duration", ["120", "600"])
def test_a_run_shorter_than_the_targets_says_its_verdicts_are_not_the_targets(tmp_path, duration):
    """--duration below the targets' 600 s: after the table, a note that the teams were cut
    while spreading, so the verdicts are not the targets' (a row passed or failed with no
    word of it); at 600 s, none."""
    local = {**SHADOWING_ROW, "plan": "local", "of bound": 0.25}
    patch = f"ROWS, INTERRUPT = {[SHADOWING_ROW, local]!r}, False\n{FAKE_POOL}"
    args = ["--shadowing", "--seeds", "1", "--n", "5", "--no-progress", "--duration", duration]
    run = _patched_script(tmp_path, patch, "coverage_targets.py", *args)
    assert run.returncode == 1, run.stderr
    note = "note: --duration 120 s is shorter than the targets' 600 s: the teams were cut while spreading"
    assert (note in run.stdout) is (duration == "120")


@pytest.mark.slow
def test_coverage_targets_draws_its_shadowing_runs(tmp_path):
    """--shadowing --figure F draws the runs (each seed by plan; local over global against
    the target) into F; Ctrl-C while it draws after --csv says the runs are kept and the
    figure is not, and leaves no figure."""
    local = {**SHADOWING_ROW, "plan": "local", "of bound": 0.25}
    rows = f"ROWS, INTERRUPT = {[SHADOWING_ROW, local]!r}, False\n{FAKE_POOL}"
    args = ["--shadowing", "--seeds", "1", "--n", "5", "--no-progress", "--figure", "f.png"]
    run = _patched_script(tmp_path, rows, "coverage_targets.py", *args)
    assert run.returncode == 1, run.stderr
    assert (tmp_path / "f.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    (tmp_path / "f.png").unlink()
    run = _patched_script(tmp_path, f"{rows}\n{DRAWING_INTERRUPTED}", "coverage_targets.py", *args, "--csv", "r.csv")
    said = "coverage_targets.py: interrupted; the runs are in r.csv, the figure is not\n"
    assert (run.returncode, run.stderr) == (130, said)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.csv"]


@pytest.mark.slow
def test_coverage_targets_figure_names_a_grown_network_once(tmp_path):
    """Seeds whose network grew, at two N: the figure's legend names their marker once (it
    was named again at each N that had one)."""
    rows = [
        {**SHADOWING_ROW, "N": n, "plan": plan, "grew": int(plan == "local")}
        for n in (5, 8)
        for plan in ("global", "local")
    ]
    patch = f"ROWS, INTERRUPT = {rows!r}, False\n{FAKE_POOL}"
    args = ["--shadowing", "--seeds", "1", "--n", "5", "8", "--no-progress", "--figure", "f.svg"]
    run = _patched_script(tmp_path, patch, "coverage_targets.py", *args)
    assert run.returncode == 1, run.stderr  # a network grew: the rows fail
    # Matplotlib's SVG gives each text a comment holding it.
    assert (tmp_path / "f.svg").read_text().count("<!-- a network grew -->") == 1


@pytest.mark.slow
def test_ctrl_c_while_coverage_on_map_draws_says_the_table_is_kept(tmp_path):
    """Ctrl-C while coverage_on_map draws --figure after writing --csv: the line says the
    rows are written and the figure is not (it said "interrupted" alone)."""
    row = {"radio": "office, line of sight", "plan": "global", "N": 5, "seed": 1, "comp0": 1, "start": 0.2}
    row |= {"final": 0.6, "split": False, "moved_m": 9.0, "settled_s": None, "final_xy": [[1.0, 2.0]], "radius_m": 9.0}
    row["map"] = "office"
    patch = f"ROWS, INTERRUPT = {[row]!r}, False\n{FAKE_POOL}\n{DRAWING_INTERRUPTED}"
    args = ["--radios", "office, line of sight", "--plans", "global", "--seeds", "1", "--n", "5", "--no-progress"]
    run = _patched_script(tmp_path, patch, "coverage_on_map.py", *args, "--csv", "r.csv", "--figure", "f.png")
    said = "coverage_on_map.py: interrupted; every run's row is written in r.csv, the figure is not\n"
    assert (run.returncode, run.stderr) == (130, said)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.csv"]
    assert pd.read_csv(tmp_path / "r.csv")["final"].tolist() == [0.6]


# Ctrl-C in an episode, as it ends.
EPISODE_INTERRUPTED = """
import netsim.metrics


def covered_fraction_exact(*args):
    raise KeyboardInterrupt


netsim.metrics.covered_fraction_exact = covered_fraction_exact
"""


@pytest.mark.slow
@pytest.mark.parametrize(
    "patch, said, kept",
    [
        (EPISODE_INTERRUPTED, "nothing written", []),
        (DRAWING_INTERRUPTED, "o/learn_coverage.csv is written, learn_coverage.png is not", ["learn_coverage.csv"]),
    ],
)
def test_ctrl_c_in_learn_coverage_is_one_line_saying_what_is_kept(tmp_path, patch, said, kept):
    """Ctrl-C in learn_coverage: one line, exit 130 (a traceback), nothing written during
    the episodes (the folder it made removed), the table kept while the figure is drawn."""
    args = ["--n", "3", "--cycles", "2", "--episodes", "1", "--out", "o"]
    run = _patched_script(tmp_path, patch, "learn_coverage.py", *args)
    assert (run.returncode, run.stderr) == (130, f"learn_coverage.py: interrupted; {said}\n")
    if kept:
        assert sorted(p.name for p in (tmp_path / "o").iterdir()) == kept
    else:
        assert not (tmp_path / "o").exists()


def test_coverage_targets_why_writes_its_table_to_csv(tmp_path, monkeypatch):
    """--why --csv F writes the --why table to F, a row per N (F was never written)."""
    from tests.fixtures import script

    module = script("experiments/coverage_targets.py")
    monkeypatch.setattr(module, "why", lambda n, seed, duration_s: {"N": n, "seed": seed, "of bound": 0.5, "moved": 3})
    csv = tmp_path / "why.csv"
    assert module.main(["--why", "--n", "20", "60", "--csv", str(csv)]) == 0
    table = pd.read_csv(csv)
    assert table["N"].tolist() == [20, 60] and list(table.columns) == ["N", "seed", "of bound", "moved"]


@pytest.mark.slow
def test_coverage_on_map_draws_the_map_its_runs_read_without_a_warning(tmp_path):
    """The figure draws the map each run read (its row's ``map``), with no warning: it
    loaded each panel's configuration again with a 1 s run to find it, and each load
    warned that control starts after that run's end."""
    import warnings

    from tests.fixtures import script

    module = script("experiments/coverage_on_map.py")
    ended = {"plan": "global", "N": 2, "seed": 1, "final": 0.5, "final_xy": [[50.0, 50.0], [60.0, 60.0]]}
    ended |= {"radius_m": 10.0, "map": "office"}
    runs = pd.DataFrame([{"radio": radio, **ended} for radio in module.MAP_RADIOS])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        module.figure(runs, str(tmp_path / "ended.png"))
    assert (tmp_path / "ended.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.slow
def test_false_role_changes_counts_pairs_and_waits_apart(tmp_path):
    """pairs_measured counts pairs in which a robot became a member, at most --pairs, and
    waits_measured the waits the mean is over, one per such robot, as the roles table has
    them (pairs_measured counted the robots, more than the pairs here: both robots of some
    pairs became members in turn)."""
    from netsim.protocols.roles import LABELS

    from netsim.tools import sweep as sweepmod

    args = ["--pairs", "50", "--losses", "0.5", "--taus", "1.5", "--duration", "60", "--workers", "1"]
    run = _script(tmp_path, "false_role_changes.py", *args, "--out", "o")
    assert run.returncode == 0, run.stderr[-2000:]
    row = pd.read_csv(tmp_path / "o" / "false_role_changes.csv").iloc[0]
    members = sweepmod.load_table(tmp_path / "o" / "sweep", "roles").query(f"role == {LABELS.member!r}")
    robots, pairs = members["robot"].nunique(), (members["robot"] // 2).nunique()
    assert robots > pairs  # the case counted wrong
    assert (row["pairs_measured"], row["waits_measured"]) == (pairs, robots) and pairs <= 50


def test_routing_compare_draws_latencies_alike_flat(tmp_path):
    """Latencies and ratios alike but for their last bits are drawn flat, each tick its
    value: the latency axis zoomed into 1e-15 s and, against an offset ("1e-15+1e-3"),
    showed a steep fall."""
    from tests.fixtures import script

    module = script("experiments/routing_compare.py")
    table = pd.DataFrame(
        {
            "protocol": ["aodv", "aodv"],
            "speed_mps": [1.0, 5.0],
            "delivery_ratio": [1.0, 1.0 - 1e-15],
            "latency_p50_s": [0.0010000000000012221, 0.0009999999999994458],
            "stretch": [1.25, 1.25 + 1e-15],
            "control_per_robot_per_s": [1.0, 1.0 + 1e-15],
        }
    )
    columns = ("delivery_ratio", "latency_p50_s", "stretch", "control_per_robot_per_s")
    for col in columns:
        table[f"{col}_ci_low"] = table[f"{col}_ci_high"] = np.nan
    fig = module.figure(table)
    fig.canvas.draw()
    for ax, col in zip(fig.axes, columns, strict=True):
        low, high = ax.get_ylim()
        assert table[col].max() - table[col].min() < 1e-6 * (high - low), col
        assert ax.yaxis.get_offset_text().get_text() == "", col


@pytest.mark.slow
def test_link_lifetime_runs_a_speed_given_twice_once(tmp_path):
    """`--speeds 2 2` is one speed: a row per model, as `--speeds 2` (each was written twice)."""
    args = ["--n", "5", "--side", "5000", "--pauses", "0", "--duration", "20", "--reps", "1", "--workers", "1"]
    run = _script(tmp_path, "link_lifetime.py", *args, "--speeds", "2", "2", "--out", "o")
    assert run.returncode == 0, run.stderr[-2000:]
    table = pd.read_csv(tmp_path / "o" / "link_lifetime.csv")
    assert table["model"].tolist() == ["random_waypoint", "random_direction_torus"]


def test_routing_compare_stretch_is_hops_over_shortest_of_packets_that_had_a_path():
    """A run's path stretch is the mean of hops / shortest_hops over its delivered packets
    that had a path when sent: one lost and one that arrived over a path formed later are
    left out."""
    from tests.fixtures import script

    module = script("experiments/routing_compare.py")
    runs = pd.DataFrame({"run_id": [0], "mobility.speed_max_mps": [5.0], "protocol.routing": ["aodv"]})
    packets = pd.DataFrame(
        {
            "run_id": [0] * 4,
            "delivered": [True, True, True, False],
            "hops": [3, 2, 4, 0],
            "shortest_hops": [2.0, 2.0, np.inf, 1.0],
            "latency_s": [0.1, 0.2, 0.3, np.nan],
        }
    )
    control = pd.DataFrame({"run_id": [0], "sent": [100]})
    (row,) = module.per_run(runs, packets, control, 10, 20.0).to_dict("records")
    assert row["stretch"] == pytest.approx(1.25)
    assert row["delivery_ratio"] == pytest.approx(0.75) and row["control_per_robot_per_s"] == pytest.approx(0.5)
