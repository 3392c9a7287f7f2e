"""Ctrl-C on ``netsim run`` is one line on standard error, exit status 130, and nothing
written, wherever it lands: while the libraries load, during the run, while the tables are
written, and when a compiled call turns the interrupt into another exception or swallows
it.

Each instant is reached without timing: the child announces it (a line on standard
output, or its first progress line on standard error) and waits; the signal is sent then.
"""

import signal
import subprocess
import sys

import pytest

from netsim.tools import cli
from netsim.tools.command import EXIT_INTERRUPTED, INTERRUPTED_LINE

# The child: ``netsim run`` as the console script runs it, with an audit hook that stops
# once at an instant (the import of pandas, the writing of the run's config.toml), says
# "ready" and waits for the signal; what the wait does with the KeyboardInterrupt is the
# second argument: let it through, turn it into a SystemError (with the interrupt as its
# context, or with none, as a compiled call may), or swallow it. The wait is inside its
# ``try`` before "ready" is said, so the signal cannot land outside it.
CHILD = r"""
import sys

stop, mode = sys.argv[1], sys.argv[2]
sys.argv = ["netsim", *sys.argv[3:]]
stopped = []


def wait():
    caught = False
    try:
        print("ready", flush=True)
        sys.stdin.readline()  # never returns: the test sends SIGINT and leaves stdin open
    except KeyboardInterrupt:
        if mode == "raise":
            raise
        if mode == "system_error_from":
            raise SystemError("<built-in function kernel> returned a result with an exception set")
        caught = True
    if caught and mode == "system_error":
        raise SystemError("error return without exception set")


def hook(event, args):
    if stopped:
        return
    at_import = stop == "import" and event == "import" and args[0] == "pandas"
    at_write = stop == "write" and event == "open" and str(args[0]).endswith("config.toml") and "w" in str(args[1])
    if at_import or at_write:
        stopped.append(True)
        wait()


sys.addaudithook(hook)
from netsim.tools.command import command

command()
"""

RUN = ["run", "--set", "world.n_robots=20", "--set", "world.side_m=500", "--set", "channel.range_m=120"]


def _interrupt(tmp_path, stop: str, mode: str = "raise", duration_s: float = 30.0, sig=signal.SIGINT):
    out = tmp_path / "out"
    args = [*RUN, "--set", f"duration_s={duration_s}", "--out", str(out)]
    if stop != "progress":
        args.append("--no-progress")
    child = subprocess.Popen(
        [sys.executable, "-c", CHILD, stop, mode, *args],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    progress = []
    if stop == "progress":
        line = child.stderr.readline()
        while "compiling the simulator's loops" in line:  # a cold cache says so first
            line = child.stderr.readline()
        assert line.startswith("netsim run:") and "%" in line, line
        progress.append(line)
    else:
        assert child.stdout.readline() == "ready\n"
    child.send_signal(sig)
    child.wait(timeout=600)  # stdin stays open: only the signal ends the child's wait
    stderr = child.stderr.read()
    child.stdin.close()
    child.stdout.close()
    child.stderr.close()
    lines = [ln for ln in (progress + stderr.splitlines(keepends=True)) if not ln.startswith("netsim run: ")]
    return child.returncode, [ln.rstrip("\n") for ln in lines], out


@pytest.mark.slow
@pytest.mark.parametrize(
    "stop, mode",
    [
        ("import", "raise"),
        ("progress", "raise"),
        ("write", "raise"),
        ("write", "system_error_from"),
        ("write", "system_error"),
        ("write", "swallow"),
    ],
)
def test_ctrl_c_is_one_line_exit_130_nothing_written(tmp_path, stop, mode):
    """SIGINT while the libraries load, during the run (after its first progress line),
    while the tables are written, or turned by a compiled call into a SystemError (with or
    without the interrupt as its context) or swallowed: one line, exit 130, no output
    directory."""
    duration = 3000.0 if stop == "progress" else 30.0
    code, lines, out = _interrupt(tmp_path, stop, mode, duration)
    assert (code, lines) == (EXIT_INTERRUPTED, [INTERRUPTED_LINE])
    assert not out.exists()


@pytest.mark.slow
@pytest.mark.parametrize("stop", ["progress", "write"])
def test_sigterm_is_given_up_as_ctrl_c(tmp_path, stop):
    """SIGTERM (a timeout, a batch scheduler) during the run or while the tables are
    written: one line, exit 130, no output directory, as Ctrl-C; Python's default ended
    the process at once and left the run directory it had made."""
    duration = 3000.0 if stop == "progress" else 30.0
    code, lines, out = _interrupt(tmp_path, stop, "raise", duration, sig=signal.SIGTERM)
    assert (code, lines) == (EXIT_INTERRUPTED, [INTERRUPTED_LINE])
    assert not out.exists()


def test_the_commands_own_exit_after_an_interrupt_is_not_reported_again(monkeypatch, capsys):
    """A command that said what an interrupt left (a sweep: the runs kept) and exits with
    130 from a thread-holding process (sys.exit) is not followed by "nothing written"."""
    from netsim.tools import command as commandmod
    from netsim.tools import interrupt

    def sweep_interrupted():
        print("netsim: interrupted; the runs finished are kept in out/", file=sys.stderr)
        sys.exit(EXIT_INTERRUPTED)

    def reported_again():
        raise AssertionError("the interrupt was reported again")

    monkeypatch.setattr(interrupt, "_INTERRUPTED", True)
    monkeypatch.setattr(cli, "command", sweep_interrupted)
    monkeypatch.setattr(commandmod, "exit_interrupted", reported_again)
    with pytest.raises(SystemExit) as exit_:
        commandmod.command()
    assert exit_.value.code == EXIT_INTERRUPTED
    assert capsys.readouterr().err.splitlines() == ["netsim: interrupted; the runs finished are kept in out/"]


def test_system_error_from_an_interrupt_is_an_interrupt(monkeypatch, tmp_path, capsys):
    """In ``main``, an exception raised because of a KeyboardInterrupt (a compiled call's
    SystemError) is the interrupt: one line, exit 130."""

    def run(args):
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt:
            raise SystemError("<built-in function kernel> returned a result with an exception set") from None

    monkeypatch.setattr(cli, "cmd_run", run)
    assert cli.main(["run", "--out", str(tmp_path / "out")]) == EXIT_INTERRUPTED
    assert capsys.readouterr().err.splitlines() == [INTERRUPTED_LINE]


def test_other_errors_are_not_taken_for_an_interrupt(monkeypatch, tmp_path):
    """An error with no interrupt behind it still raises (a bug shows as a bug)."""

    def run(args):
        raise SystemError("a bug")

    monkeypatch.setattr(cli, "cmd_run", run)
    with pytest.raises(SystemError, match="a bug"):
        cli.main(["run", "--out", str(tmp_path / "out")])


def test_ctrl_c_while_the_run_moves_into_place_never_leaves_half_a_run(tmp_path, monkeypatch):
    """SIGINT while the finished run's files move into place (over an earlier run's) is
    held off until every file is there, then dropped: the directory holds the new run,
    whole, and nothing of the earlier one."""
    import os

    from netsim.tools import output
    from netsim.tools.cli import main

    out = tmp_path / "out"
    small = ["--set", "world.n_robots=5", "--set", "duration_s=5", "--no-progress", "--quiet", "--out", str(out)]
    assert main(["run", *small, "--set", "seed=1"]) == 0
    before = {f.name: f.read_bytes() for f in out.iterdir()}
    replace = os.replace
    sent = []

    def replace_and_interrupt(src, dst):
        if not sent and os.path.dirname(os.fspath(dst)) == os.fspath(out):
            sent.append(True)
            os.kill(os.getpid(), signal.SIGINT)
        replace(src, dst)

    monkeypatch.setattr(output.os, "replace", replace_and_interrupt)
    assert main(["run", *small, "--set", "seed=2"]) == 0
    assert sent
    after = {f.name: f.read_bytes() for f in out.iterdir()}
    assert after.keys() == before.keys()
    assert after["positions.parquet"] != before["positions.parquet"]
    assert '"seed": 2' in after["config.toml"].decode() or "seed = 2" in after["config.toml"].decode()


@pytest.mark.parametrize(
    "command, draw, words", [("run", "viewer", "its view.html is not"), ("figures", "figures", "its figures are not")]
)
def test_ctrl_c_after_the_run_is_in_place_says_it_is_kept(tmp_path, monkeypatch, capsys, command, draw, words):
    """Ctrl-C while the replay or the figures are drawn, the run already in place: exit 130
    and a line that says the run is written (it said nothing was, with the run there)."""
    import importlib

    drawing = importlib.import_module(f"netsim.tools.{draw}")

    def interrupt(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(drawing, "write" if draw == "viewer" else "draw", interrupt)
    out = tmp_path / "out"
    small = ["--set", "world.n_robots=5", "--set", "duration_s=15", "--no-progress", "--quiet", "--out", str(out)]
    argv = ["run", "--view", *small] if command == "run" else ["figures", *small]
    assert cli.main(argv) == EXIT_INTERRUPTED
    assert capsys.readouterr().err.splitlines()[-1:] == [f"netsim: interrupted; the run is written in {out}/, {words}"]
    assert (out / "summary.json").is_file() and (out / "positions.parquet").is_file()
