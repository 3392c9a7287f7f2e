"""Rules of netsim.tools.output that a mutation audit found no test for: a run's tables and
files read back, and the directories a command may write into."""

import json

import pandas as pd
import pytest

from netsim.errors import NetsimInputError
from netsim.tools import output


def test_a_table_naming_a_negative_robot_is_one_line(tmp_path):
    pd.DataFrame({"a": [-1, 0], "b": [1, 2], "t_up_s": [0.0, 0.0], "t_down_s": [1.0, 1.0]}).to_parquet(
        tmp_path / "links.parquet"
    )
    with pytest.raises(NetsimInputError, match=r"links.parquet: names robot -1 \(a\), but config.toml has 3 robots"):
        output.read_run_table(tmp_path, "links", 3)


@pytest.mark.parametrize("ended", [0, 0.0, True, "12"])
def test_a_summary_end_that_is_no_time_within_the_run_keeps_the_planned_end(tmp_path, ended):
    """A session's end is read from its summary only as a number between 0 and the plan's:
    0 would leave the run no duration, a boolean is no time."""
    (tmp_path / "config.toml").write_text("duration_s = 30.0\n[world]\nn_robots = 3\n")
    (tmp_path / "summary.json").write_text(json.dumps({"duration_s": ended}))
    assert output.read_run_config(tmp_path)["duration_s"] == 30.0


def test_a_session_ended_early_ends_its_configuration_there(tmp_path):
    (tmp_path / "config.toml").write_text("duration_s = 30.0\n[world]\nn_robots = 3\n")
    (tmp_path / "summary.json").write_text(json.dumps({"duration_s": 12.5}))
    assert output.read_run_config(tmp_path)["duration_s"] == 12.5


def test_a_foreign_directory_is_named_by_its_first_three_entries(tmp_path):
    for name in ("a", "b", "c", "d"):
        (tmp_path / name).write_text("")
    with pytest.raises(
        NetsimInputError, match=r"the directory is not empty \(a, b, c, \.\.\.\) and holds no netsim run"
    ):
        output.check_run_dir(tmp_path)
    (tmp_path / "d").unlink()
    with pytest.raises(NetsimInputError, match=r"the directory is not empty \(a, b, c\) and holds no netsim run"):
        output.check_run_dir(tmp_path)


def test_a_directory_holding_only_an_interrupted_writes_leftovers_is_taken(tmp_path):
    """A temporary file a killed command left is no one else's: the directory is empty."""
    (tmp_path / f"{output.TMP_PREFIX}summary.json").write_text("")
    output.check_run_dir(tmp_path)
    output.check_sweep_dir(tmp_path)
