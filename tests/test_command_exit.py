"""The ``netsim`` command ends its process at once when main returns (netsim.tools.cli.command):
nothing it printed or wrote is lost, and its exit code is main's."""

import os
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

from netsim.tools.cli import main

COMMAND = str(Path(sys.executable).with_name("netsim"))
# Block-buffered output, as in a user's shell (a test runner may ask for unbuffered).
ENV = {k: v for k, v in os.environ.items() if k != "PYTHONUNBUFFERED"}


@pytest.mark.slow
def test_command_flushes_what_it_printed_through_a_pipe(capsys):
    """``netsim config`` piped (so stdout is block-buffered) prints all that main prints."""
    main(["config", "--set", "world.n_robots=12"])
    expected = capsys.readouterr().out
    run = subprocess.run([COMMAND, "config", "--set", "world.n_robots=12"], capture_output=True, text=True, env=ENV)
    assert run.returncode == 0 and len(expected) > 2000
    assert run.stdout == expected


@pytest.mark.slow
def test_command_run_writes_every_table_and_exits_zero(tmp_path):
    run = subprocess.run(
        [COMMAND, "run", "--out", str(tmp_path), "--no-progress", "--set", "world.n_robots=8", "--set", "duration_s=5"],
        capture_output=True,
        text=True,
    )
    assert run.returncode == 0, run.stderr
    assert (tmp_path / "manifest.json").exists() and (tmp_path / "summary.json").exists()
    assert len(pd.read_parquet(tmp_path / "roles.parquet")) >= 8


@pytest.mark.slow
def test_command_exits_with_mains_code_on_bad_input(tmp_path):
    """A user's error: exit 2, one line, nothing written (as main returns it)."""
    out = tmp_path / "run"
    run = subprocess.run(
        [COMMAND, "run", "--out", str(out), "--no-progress", "--set", "world.n_robots=-3"],
        capture_output=True,
        text=True,
    )
    assert run.returncode == 2
    assert len(run.stderr.strip().splitlines()) == 1 and run.stderr.startswith("netsim: error:")
    assert not out.exists()


def test_command_freezes_what_the_build_loaded_and_the_library_does_not(tmp_path, monkeypatch):
    """In the command's own process, what a run's build loaded (numba's registries for the
    compiled loops) is frozen out of the collector's passes before the run; called as a
    library (``main``), the collector is left alone."""
    import gc

    from netsim.tools import cli

    frozen = []
    monkeypatch.setattr(gc, "freeze", lambda: frozen.append(True))
    args = ["run", "--set", "world.n_robots=5", "--set", "duration_s=5", "--quiet"]
    assert main([*args, "--out", str(tmp_path / "a")]) == 0
    assert frozen == []
    monkeypatch.setattr(cli, "_OWN_PROCESS", True)
    assert main([*args, "--out", str(tmp_path / "b")]) == 0
    assert frozen == [True]


@pytest.mark.slow
@pytest.mark.parametrize("unbuffered", [False, True])
def test_a_reader_that_goes_away_ends_the_command_quietly_with_the_run_written(tmp_path, unbuffered):
    """``netsim run ... | head``: the reader of stdout closes it before the run prints its
    last lines (which then fail as they are printed, unbuffered, or when they are flushed).
    The run's tables are all written, nothing but the run's own lines reaches stderr (no
    traceback), and the status is that of a command ended by SIGPIPE (141)."""
    out = tmp_path / "run"
    argv = [COMMAND, "run", "--out", str(out), "--no-progress", "--set", "world.n_robots=8", "--set", "duration_s=5"]
    env = {**ENV, "PYTHONUNBUFFERED": "1"} if unbuffered else ENV
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env)
    proc.stdout.close()
    err = proc.stderr.read().decode()
    assert proc.wait() == 141, err
    assert "Traceback" not in err and "BrokenPipeError" not in err
    assert (out / "manifest.json").exists() and (out / "summary.json").exists()


def test_a_broken_pipe_other_than_stdout_is_a_failure_not_a_quiet_end():
    """Only stdout's reader going away ends the command quietly (141): a broken pipe of
    anything else (a worker's, an output's) is the failure it is, with its traceback."""
    code = "import netsim.tools.cli as c\n"
    code += "def b(argv=None): raise BrokenPipeError(32, 'a worker pipe')\n"
    code += "c.main = b\nc.command()"
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=ENV)
    assert run.returncode == 1 and "BrokenPipeError: [Errno 32] a worker pipe" in run.stderr
