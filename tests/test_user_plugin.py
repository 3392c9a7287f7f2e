"""A user's plugin with its own section (tests/separation_plugin.py), end to end: the CLI
runs it and writes its table, ``netsim config`` prints and explains its section, a sweep
varies its key and keeps its table, and a bad value is refused in one line."""

import contextlib
import io
import tomllib

import pandas as pd
import pytest

from netsim.errors import NetsimInputError
from netsim.tools import sweep as sweepmod
from netsim.tools.cli import main

PLUGIN = "tests.separation_plugin:PLUGIN"
SCENARIO = [
    "--set",
    "world.n_robots=12",
    "--set",
    "world.side_m=60",
    "--set",
    "duration_s=20",
    "--set",
    "protocol.model=none",
    "--set",
    f'control.controllers=["{PLUGIN}"]',
]


def cli(*argv):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main([str(a) for a in argv])
    return code, out.getvalue(), err.getvalue()


def test_the_cli_runs_a_user_plugin_with_its_own_section(tmp_path):
    code, _, err = cli("run", *SCENARIO, "--set", "separation.min_distance_m=30", "--out", tmp_path / "r", "--quiet")
    assert code == 0, err
    table = pd.read_parquet(tmp_path / "r" / "too_close.parquet")
    # The control loop steps every second from coverage.start_s (10 s by default).
    assert len(table) == 10 and list(table.columns) == ["t_s", "robots", "pairs"]
    # 12 robots in a 60 m square: at 30 m someone is always too close to someone.
    assert (table["pairs"] > 0).all()
    resolved = tomllib.loads((tmp_path / "r" / "config.toml").read_text())
    assert resolved["separation"] == {"min_distance_m": 30.0}


def test_the_plugin_key_changes_what_it_records(tmp_path):
    counts = []
    for d in (1e-3, 30):
        code, _, err = cli(
            "run", *SCENARIO, "--set", f"separation.min_distance_m={d}", "--out", tmp_path / str(d), "--quiet"
        )
        assert code == 0, err
        counts.append(pd.read_parquet(tmp_path / str(d) / "too_close.parquet")["pairs"].sum())
    assert counts[0] < counts[1]


def test_netsim_config_prints_and_explains_the_plugin_section():
    code, out, err = cli("config", *SCENARIO)
    assert code == 0, err
    assert "[separation]" in out and "closest approach counted as too close" in out
    assert tomllib.loads(out)["separation"]["min_distance_m"] == 2.0


def test_a_bad_value_of_the_plugin_key_is_one_line_exit_2_nothing_written(tmp_path):
    out = tmp_path / "r"
    code, _, err = cli("run", *SCENARIO, "--set", "separation.min_distance_m=-1", "--out", out, "--quiet")
    assert code == 2
    assert err.count("\n") == 1 and "separation.min_distance_m" in err and "-1" in err
    assert not out.exists()


def test_a_section_without_its_plugin_is_refused():
    code, _, err = cli("config", "--set", "separation.min_distance_m=3")
    assert code == 2 and "separation" in err


def test_a_sweep_varies_the_plugin_key_and_keeps_its_table(tmp_path):
    sweep = sweepmod.parse(
        {
            "name": "sep",
            "tables": ["too_close"],
            "base": {
                "world": {"n_robots": 12, "side_m": 60.0},
                "duration_s": 20.0,
                "protocol": {"model": "none"},
                "control": {"controllers": [PLUGIN]},
                "output": {"position_interval_s": 0.0},
            },
            "grid": {"separation.min_distance_m": [1e-3, 30.0]},
        }
    )
    report = sweepmod.run_sweep(sweep, tmp_path, workers=1, progress=False)
    assert report.done == 2 and not report.failed
    runs = sweepmod.load(tmp_path)
    assert sorted(runs["separation.min_distance_m"]) == [1e-3, 30.0]
    kept = sweepmod.load_table(tmp_path, "too_close").merge(runs[["run_id", "separation.min_distance_m"]])
    pairs = kept.groupby("separation.min_distance_m")["pairs"].sum()
    assert pairs[1e-3] < pairs[30.0]


def test_a_sweep_refuses_a_table_no_plugin_writes(tmp_path):
    """A sweep keeping a table that no plugin of its base writes is refused by name, as bad
    input, before any run."""
    with pytest.raises(NetsimInputError, match=r"^sweep file: tables = \['too_close'\]: must be a list drawn from"):
        sweepmod.parse({"name": "x", "tables": ["too_close"], "base": {"duration_s": 5.0}, "grid": {"seed": [1, 2]}})
