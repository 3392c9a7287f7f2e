"""A malformed command line, to ``netsim`` or to any script of experiments/ and benchmarks/,
is one line on stderr and exit status 2, nothing written (netsim.tools.args.Parser): the
same as every other bad input. Running each script also shows that it still imports."""

import shutil
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

from netsim.tools.cli import main

ROOT = Path(__file__).resolve().parents[1]
# Scripts with a command line of their own; the ns-3 and plain-SimPy reference workloads
# run without netsim (in ns-3's Python), so they keep argparse's own messages.
SCRIPTS = sorted(
    str(p.relative_to(ROOT))
    for folder in ("experiments", "benchmarks")
    for p in (ROOT / folder).glob("*.py")
    if '__name__ == "__main__"' in p.read_text() and "from netsim" in p.read_text()
)
COMMANDS = ["run", "bridge", "scenario", "scenario generate", "sweep", "validate", "figures", "view", "export"]
COMMANDS += ["config", "calibrate"]


def test_every_script_with_a_command_line_is_checked():
    assert "experiments/coverage_targets.py" in SCRIPTS and "benchmarks/ab.py" in SCRIPTS
    assert len(SCRIPTS) >= 25


@pytest.mark.slow
@pytest.mark.parametrize("path", SCRIPTS)
def test_a_scripts_unknown_option_is_one_line_exit_2_nothing_written(tmp_path, path):
    run = subprocess.run(
        [sys.executable, str(ROOT / path), "--no-such-option"], capture_output=True, text=True, cwd=tmp_path
    )
    name = Path(path).name
    assert run.returncode == 2, run.stderr
    lines = run.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"{name}: error: "), run.stderr
    assert f"({name} --help lists the options)" in lines[0]
    assert run.stdout == "" and list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("command", COMMANDS)
@pytest.mark.parametrize("bad", [["--no-such-option"], ["--seed", "x"]])
def test_a_netsim_usage_error_is_one_line_exit_2_nothing_written(tmp_path, monkeypatch, capsys, command, bad):
    monkeypatch.chdir(tmp_path)
    assert status([*command.split(), *bad]) == 2
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and err.startswith("netsim"), err
    assert "error: " in err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("command", COMMANDS)
def test_an_unknown_option_of_a_command_is_refused_in_the_commands_name(capsys, command):
    """`netsim bridge --bogus` names `netsim bridge`, as a bad value to one of its options
    does (it said `netsim: error:`, argparse leaving a sub-command's unknown options to the
    top parser)."""
    assert status([*command.split(), "--no-such-option"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"netsim {command}: error: "), err
    assert err.rstrip().endswith(f"(netsim {command} --help lists the options)"), err


@pytest.mark.parametrize(
    ("argv", "said"),
    [
        (["run", "--sed", "3"], "netsim run: error: unrecognized arguments: --sed (did you mean '--seed'?)"),
        (
            ["view", "r", "--outt=x.html"],
            "netsim view: error: unrecognized arguments: --outt=x.html (did you mean '--out'?)",
        ),
        (["run", "--zzz"], "netsim run: error: unrecognized arguments: --zzz"),
    ],
)
def test_a_misspelt_option_names_the_one_meant(capsys, argv, said):
    """A misspelt option of a command names the option meant, as a misspelt key does; one
    close to none, nothing more."""
    assert status(argv) == 2
    (line,) = capsys.readouterr().err.splitlines()
    assert line == f"{said} (netsim {argv[0]} --help lists the options)"


@pytest.mark.parametrize("argv", [[], ["no-such-command"], ["scenario"]])
def test_a_missing_or_unknown_command_is_one_line(capsys, argv):
    assert status(argv) == 2
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and "--help lists the options" in err, err


def status(argv: list[str]) -> int:
    """The exit status of ``netsim ARGV``: a usage error exits, other bad input returns 2."""
    try:
        return main(argv)
    except SystemExit as exit_:
        assert isinstance(exit_.code, int)
        return exit_.code


@pytest.mark.slow
@pytest.mark.parametrize(
    "path, args, said",
    [
        ("benchmarks/routing_ns3.py", ["--ns3-python", "no/such/python"], "--ns3-python no/such/python: no such file"),
        ("benchmarks/replay.py", ["--size", "12x", "--no-browser"], "--size '12x': WIDTHxHEIGHT"),
        ("benchmarks/routing_ns3.py", ["--side", "netsim"], "--side netsim runs one scenario and one protocol"),
        ("benchmarks/routing_ns3.py", ["--ns3-arp", "none"], "argument --ns3-arp: invalid choice: 'none'"),
    ],
)
def test_a_benchmark_refuses_what_it_cannot_run_in_one_line(tmp_path, path, args, said):
    run = subprocess.run([sys.executable, str(ROOT / path), *args], capture_output=True, text=True, cwd=tmp_path)
    assert run.returncode == 2 and len(run.stderr.splitlines()) == 1 and said in run.stderr, run.stderr
    assert list(tmp_path.iterdir()) == []


def test_the_ns3_side_of_the_routing_comparison_runs_without_netsim():
    """benchmarks/routing_ns3.py runs itself in ns-3's own Python, which has no netsim."""
    code = (
        "import runpy, sys; sys.modules['netsim'] = None; sys.argv = ['routing_ns3.py', '--help']; "
        f"runpy.run_path({str(ROOT / 'benchmarks' / 'routing_ns3.py')!r}, run_name='__main__')"
    )
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert run.returncode == 0 and "--ns3-python" in run.stdout, run.stderr


@pytest.mark.parametrize(
    "argv, said",
    [
        (["--seeds", "0"], "--seeds 0: at least 1"),
        (["--write", "no/such/dir/site.csv"], "the directory no/such/dir does not exist"),
        (["--write", "mine.csv"], "--write mine.csv: exists already"),
    ],
)
def test_the_calibration_log_maker_refuses_bad_input_in_one_line(tmp_path, monkeypatch, capsys, argv, said):
    """`python -m tests.calibration_logs`, which the README runs to make a log."""
    from tests.calibration_logs import main as make_logs

    monkeypatch.chdir(tmp_path)
    (tmp_path / "mine.csv").write_text("a user's file")
    with pytest.raises(SystemExit) as exit_:
        make_logs(argv)
    err = capsys.readouterr().err
    assert exit_.value.code == 2 and len(err.splitlines()) == 1 and said in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mine.csv"]
    assert (tmp_path / "mine.csv").read_text() == "a user's file"


@pytest.mark.parametrize("command", ["view", "export", "figures"])
def test_a_missing_run_directory_is_one_line_alike_for_every_command(tmp_path, capsys, command):
    """Every command that reads a run refuses a directory that is not there in the same
    words, writing nothing."""
    missing, out = tmp_path / "nowhere", tmp_path / "out"
    extra = {"view": [], "export": ["--format", "bonnmotion", "--out", str(out)], "figures": ["--out", str(out)]}
    assert main([command, str(missing), *extra[command]]) == 2
    err = capsys.readouterr().err.strip()
    assert err == f"netsim: error: {missing}: no such run directory (the --out of a `netsim run`)"
    assert list(tmp_path.iterdir()) == []


@pytest.fixture(scope="module")
def small_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("runs") / "run"
    settings = ["world.n_robots=4", "duration_s=5"]
    assert main(["run", "--quiet", *(a for s in settings for a in ("--set", s)), "--out", str(out)]) == 0
    return out


READERS = {"view": [], "export": ["--format", "bonnmotion"], "figures": []}


@pytest.mark.parametrize("command", list(READERS))
@pytest.mark.parametrize(
    "damage, said",
    [
        ("file", "is a file, not a run directory"),
        ("table", "cannot be read as Parquet"),
        ("config", "as TOML"),
        ("columns", "lacks the column"),
        ("empty config", "holds no run's configuration"),
        ("fewer robots", "names robot 3 (robot), but config.toml has 3 robots"),
    ],
)
def test_a_damaged_run_is_one_line_alike_for_every_command(tmp_path, capsys, small_run, command, damage, said):
    """A file given as the run, a run whose tables were cut short, lack their columns or
    name robots its config.toml does not have, or whose config.toml is not TOML or empty:
    one line naming the file for every command
    that reads a run, nothing written (a KeyError's or numpy's traceback before)."""
    run, out = tmp_path / "run", tmp_path / ("out.movements" if command == "export" else "out")
    if damage == "file":
        run.write_text("not a run")
    else:
        shutil.copytree(small_run, run)
        if damage == "table":
            for table in run.glob("*.parquet"):
                table.write_bytes(table.read_bytes()[:100])
        elif damage == "columns":
            for table in run.glob("*.parquet"):
                pd.DataFrame({"other": [1.0]}).to_parquet(table)
        elif damage == "empty config":
            (run / "config.toml").write_text("")
        elif damage == "fewer robots":  # its tables name robot 3 (an IndexError's traceback)
            text = (run / "config.toml").read_text()
            assert "n_robots = 4" in text
            (run / "config.toml").write_text(text.replace("n_robots = 4", "n_robots = 3"))
        else:
            (run / "config.toml").write_text("[world\n")
    assert main([command, str(run), *READERS[command], "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("netsim: error: ") and err.count("\n") == 1 and said in err, err
    assert not out.exists()


@pytest.mark.parametrize(
    "command, table",
    [
        ("view", "groups"),
        ("figures", "groups"),
        ("view", "hops"),
        ("view", "messages"),
        ("view", "beliefs"),
        ("view", "neighbour_beliefs"),
        ("view", "ack_delivery"),
    ],
)
def test_a_protocol_table_without_its_columns_is_one_line(tmp_path, capsys, small_run, command, table):
    """One protocol table replaced by another (acks.parquet): the command that reads it
    refuses it in one line naming it, nothing written (a KeyError's traceback before)."""
    run, out = tmp_path / "run", tmp_path / "out"
    shutil.copytree(small_run, run)
    assert (run / f"{table}.parquet").is_file()
    shutil.copy(run / "acks.parquet", run / f"{table}.parquet")
    assert main([command, str(run), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"netsim: error: {run / table}.parquet: lacks the column") and err.count("\n") == 1, err
    assert not out.exists()


def test_not_a_file_names_what_the_path_is(tmp_path):
    """The words for a path that is not a readable file: a directory, something else that
    exists (a pipe), or nothing."""
    import os

    from netsim.errors import not_a_file

    pipe = tmp_path / "pipe"
    os.mkfifo(pipe)
    assert not_a_file(tmp_path) == "is a directory, not a file"
    assert not_a_file(pipe) == "is not a regular file"
    assert not_a_file(tmp_path / "nowhere") == "no such file"


def test_a_run_whose_summary_is_not_json_is_one_line_for_view(tmp_path, capsys, small_run):
    """netsim view reads the run's summary.json: one that is cut short is refused in one
    line naming it, nothing written."""
    run, out = tmp_path / "run", tmp_path / "v.html"
    shutil.copytree(small_run, run)
    (run / "summary.json").write_text('{"n_robots": 4,')
    assert main(["view", str(run), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("netsim: error: ") and err.count("\n") == 1 and "summary.json: cannot be read as JSON" in err
    assert not out.exists()


@pytest.mark.parametrize(
    "args, said",
    [
        (["run", "--quiet", "{d}"], "is a directory, not a file"),
        (["run", "--quiet", "--set", "world.map={d}"], "is a directory, not a file"),
        (
            ["run", "--quiet", "--set", "mobility.model=trace", "--set", "mobility.trace_file={d}.movements"],
            "is a directory, not a file",
        ),
        (
            ["run", "--quiet", "--set", "mobility.model=trace", "--set", "mobility.trace_file={d}.tcl"],
            "has no metadata.yaml",
        ),
        (["sweep", "{d}"], "is a directory, not a file"),
    ],
    ids=["scenario", "map", "bonnmotion", "ns2", "sweep"],
)
def test_a_directory_given_for_a_file_is_named_a_directory(tmp_path, capsys, args, said):
    """A directory where a file is expected is refused as a directory (not as a file that
    does not exist), in one line, nothing written; a trace that is a directory is read as a
    rosbag2 bag, and one without metadata.yaml is refused as such."""
    d = tmp_path / "given"
    for suffix in ("", ".movements", ".tcl"):
        Path(f"{d}{suffix}").mkdir()
    out = tmp_path / "out"
    assert main([a.format(d=d) for a in args] + ["--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("netsim: error: ") and err.count("\n") == 1 and said in err, err
    assert not out.exists()


@pytest.mark.parametrize("value, number", [("-8e1", -80.0), ("-1E-3", -0.001), ("-inf", float("-inf"))])
def test_a_negative_number_in_any_spelling_is_an_options_value(value, number):
    """A float option takes a negative number written with an exponent or as ``-inf``, as it
    takes ``-80`` (argparse alone reads those as an unknown option)."""
    from netsim.tools.args import Parser

    p = Parser(prog="x")
    p.add_argument("--level", type=float)
    assert p.parse_args(["--level", value]).level == number


def test_a_bag_whose_metadata_is_not_yaml_is_one_line(tmp_path, capsys):
    """A bag folder whose metadata.yaml does not parse is refused in one line (the YAML
    parser's message, which spans lines, was printed as it was), nothing written."""
    bag = tmp_path / "bag"
    bag.mkdir()
    (bag / "metadata.yaml").write_text("garbage: [\n")
    out = tmp_path / "out"
    args = ["run", "--quiet", "--set", "mobility.model=trace", "--set", f"mobility.trace_file={bag}"]
    assert main([*args, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("netsim: error: ") and err.count("\n") == 1, err
    assert "cannot be read as a rosbag2 bag" in err
    assert not out.exists()


def test_version_prints_the_installed_version(capsys):
    """`netsim --version`: one line, exit 0 (it was an error asking for a command)."""
    from netsim import __version__

    with pytest.raises(SystemExit) as exit_:
        main(["--version"])
    assert exit_.value.code == 0 and capsys.readouterr().out == f"netsim {__version__}\n"


def test_a_run_written_before_a_table_gained_a_column_is_still_read(tmp_path, capsys, small_run):
    """legs.parquet without its `cause` column (as runs were written before it): the
    export, which does not need it, still writes the file."""
    run, out = tmp_path / "run", tmp_path / "out.movements"
    shutil.copytree(small_run, run)
    legs = pd.read_parquet(run / "legs.parquet")
    legs.drop(columns=["cause"]).to_parquet(run / "legs.parquet")
    assert main(["export", str(run), "--format", "bonnmotion", "--out", str(out)]) == 0
    assert out.is_file()


@pytest.mark.parametrize("command", ["view", "figures"])
def test_a_map_edited_since_the_run_is_one_line_for_the_drawing_commands(tmp_path, capsys, command):
    """A run on a map file records the map's fingerprint; a drawing of the run after the
    file was edited is refused in one line, nothing written (the replay drew walls the run
    never had, from the file as it is now)."""
    import numpy as np

    from netsim.world.maps import save_map

    occ = np.zeros((40, 40), dtype=bool)
    occ[:, 20] = True  # a wall across the middle
    occ[18:22, 20] = False  # with a door
    yaml = save_map(tmp_path / "floor.yaml", occ, ~occ, 1.0)
    run = tmp_path / "run"
    settings = ["world.n_robots=4", "duration_s=5", f"world.map='{yaml}'", "world.side_m=40", "channel.range_m=10"]
    assert main(["run", "--quiet", *(a for s in settings for a in ("--set", s)), "--out", str(run)]) == 0
    assert main([command, str(run), "--out", str(tmp_path / "before")]) == 0
    occ[18:22, 20] = True  # the door walled up
    save_map(yaml, occ, ~occ, 1.0)
    capsys.readouterr()
    out = tmp_path / "after"
    assert main([command, str(run), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("netsim: error: ") and err.count("\n") == 1 and "are not those the run" in err, err
    assert not out.exists()
    # The fingerprint is read from manifest.json: one damaged is one line too.
    for damaged, said in (("{not json", "cannot be read as JSON"), ("[1, 2]", "holds no table of what the run was")):
        (run / "manifest.json").write_text(damaged)
        assert main([command, str(run), "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert err.startswith("netsim: error: ") and err.count("\n") == 1 and said in err, err
        assert not out.exists()


def test_a_runs_map_fingerprint_is_of_the_map_it_was_built_on(tmp_path, monkeypatch):
    """The fingerprint `netsim run` records is that of the map the run was built on, not of
    the file as it is when the run ends: a map edited during a run is then refused by the
    drawing commands, not taken for the run's (the file was read again at the end)."""
    import json

    import numpy as np

    import netsim.run
    from netsim.world.maps import load_map, save_map

    occ = np.zeros((40, 40), dtype=bool)
    occ[:, 20] = True
    occ[18:22, 20] = False
    yaml = save_map(tmp_path / "floor.yaml", occ, ~occ, 1.0)
    built_on = load_map(yaml).sha256
    execute = netsim.run.execute

    def edited_while_running(*args, **kwargs):
        result = execute(*args, **kwargs)
        occ[18:22, 20] = True
        save_map(yaml, occ, ~occ, 1.0)
        return result

    monkeypatch.setattr(netsim.run, "execute", edited_while_running)
    run = tmp_path / "run"
    settings = ["world.n_robots=3", "duration_s=2", f"world.map='{yaml}'", "world.side_m=40", "channel.range_m=10"]
    assert main(["run", "--quiet", *(a for s in settings for a in ("--set", s)), "--out", str(run)]) == 0
    assert load_map(yaml).sha256 != built_on
    assert json.loads((run / "manifest.json").read_text())["map_sha256"] == built_on
    assert main(["view", str(run), "--out", str(tmp_path / "v.html")]) == 2


def test_a_bag_message_that_does_not_decode_is_one_line(tmp_path, capsys):
    """A bag whose odometry message is not CDR of its declared type is refused in one line
    naming the topic (the library's SerdeError was a traceback, exit 1), nothing written."""
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    bag, out = tmp_path / "garbled", tmp_path / "out"
    store = get_typestore(Stores.ROS2_HUMBLE)
    with Writer(bag, version=8) as w:
        for i in range(2):
            conn = w.add_connection(f"/robot_{i}/odom", "nav_msgs/msg/Odometry", typestore=store)
            w.write(conn, 1, b"\x00\x01\x00\x00garbage")
    args = ["run", "--quiet", "--set", "world.n_robots=2", "--set", "mobility.model=trace"]
    assert main([*args, "--set", f"mobility.trace_file={bag}", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("netsim: error: ") and err.count("\n") == 1, err
    assert "a message on '/robot_0/odom' is not a nav_msgs/msg/Odometry" in err
    assert not out.exists()


def test_a_full_disk_is_one_line_and_nothing_is_left(tmp_path, capsys, monkeypatch):
    """A disk that fills while the tables are written: one line, exit 2, no directory
    left (it was the traceback of pyarrow's OSError, exit 1)."""
    import errno

    from netsim.tools import output

    def full(table, path):
        raise OSError(errno.ENOSPC, "No space left on device", str(path))

    monkeypatch.setattr(output, "write_arrow", full)
    out = tmp_path / "out"
    argv = ["run", "--quiet", "--set", "world.n_robots=4", "--set", "duration_s=5", "--out", str(out)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"netsim: error: cannot write in {tmp_path}") and err.endswith(": No space left on device\n")
    assert err.count("\n") == 1 and not out.exists()


def test_a_full_disk_once_the_run_is_in_place_says_it_is_kept(tmp_path, capsys, monkeypatch):
    """A disk that fills while the replay is written, the run already in place: the line
    says the run is written and its view.html is not (it said nothing was written)."""
    import errno

    from netsim.tools import viewer

    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device", "view.html")

    monkeypatch.setattr(viewer, "write", full)
    out = tmp_path / "out"
    argv = ["run", "--quiet", "--view", "--set", "world.n_robots=4", "--set", "duration_s=5", "--out", str(out)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    want = f"netsim: error: cannot write: No space left on device; the run is written in {out}/, its view.html is not\n"
    assert err == want
    assert (out / "summary.json").is_file()


def test_a_seed_past_63_bits_is_refused_by_a_sweep_alone(tmp_path, capsys):
    """A sweep tables its runs' seeds as signed 64-bit integers: a larger seed is refused in
    one line before any run (past 2^64 a sweep ended in a traceback of an OverflowError; past
    2^63 its rows held the seed as a float, not the one that ran). A single run, which
    tables no seed, runs with it, as a learning environment's 64-bit draws need."""
    spec = tmp_path / "big.toml"
    spec.write_text(f'name = "big"\n[base]\nduration_s = 2.0\n[base.world]\nn_robots = 3\n[grid]\nseed = [{2**63}]\n')
    out = tmp_path / "sweep"
    assert main(["sweep", str(spec), "--out", str(out), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"seed = {2**63}: must be below 2^63 in a sweep" in err
    assert not out.exists()
    run = tmp_path / "run"
    args = ["run", "--quiet", "--no-progress", "--seed", str(2**63), "--out", str(run)]
    assert main([*args, "--set", "world.n_robots=3", "--set", "duration_s=2"]) == 0
    assert (run / "summary.json").is_file()


@pytest.mark.parametrize(
    "argv", [["--seed", "3", "run", "my.toml"], ["--out", "x", "sweep", "s.toml"], ["-o", "y", "run"]]
)
def test_an_option_before_the_command_is_said_to_go_after_it(tmp_path, monkeypatch, capsys, argv):
    """`netsim --seed 3 run`: not "invalid choice: '3'", but where the option goes."""
    monkeypatch.chdir(tmp_path)
    assert status(argv) == 2
    err = capsys.readouterr().err.strip()
    command = argv[2]
    assert err == (
        f"netsim: error: {argv[0]} goes after the command: netsim {command} {argv[0]} ... "
        "(netsim --help lists the options)"
    )
    assert list(tmp_path.iterdir()) == []
