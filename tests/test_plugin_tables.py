"""A user's plugin's tables are held to what it declares (``PluginSpec.tables``): a table it
writes without declaring it is refused, one it declares and never writes is written empty,
and its columns and their dtypes are the declared ones (docs/plugins.md)."""

from typing import NamedTuple

import numpy as np
import pandas as pd
import pytest

from netsim import config
from netsim.errors import ConfigError, NetsimInputError
from netsim.run import build, execute, tables
from netsim.tools.cli import main

SMALL = [
    "world.n_robots=5",
    "duration_s=5",
    "mobility.model=static",
    "protocol.model=none",
    "coverage.start_s=0",
]

CONTROLLER = """
from netsim.params import NoParams
from netsim.plugins import PluginSpec

def build(params, parts):
    def controller(step):
        {record}
    return controller

CTL = PluginSpec(Params=NoParams, build=build, tables={tables})
"""


def _controller(tmp_path, monkeypatch, module: str, record: str, declared: dict) -> list[str]:
    """Overrides running the user's controller ``module:CTL``, which calls ``record`` (a line
    of Python on ``step``) at every control step and declares ``declared``."""
    (tmp_path / f"{module}.py").write_text(CONTROLLER.format(record=record, tables=repr(declared)))
    monkeypatch.syspath_prepend(str(tmp_path))
    return [*SMALL, f'control.controllers=["{module}:CTL"]']


def test_a_table_a_user_plugin_writes_undeclared_is_refused_in_one_line_and_nothing_written(
    tmp_path, monkeypatch, capsys
):
    """A controller records a table it does not declare: exit status 2, one line naming the
    key that chose it and the table, no directory left (it was written without a word)."""
    overrides = _controller(tmp_path, monkeypatch, "undeclared_ctl", 'step.record("too_far", pairs=1)', {})
    out = tmp_path / "out"
    code = main(["run", "--quiet", "--out", str(out), *(a for o in overrides for a in ("--set", o))])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(err) == 1
    assert "control.controllers = 'undeclared_ctl:CTL': writes table 'too_far', which its plugin does not" in err[0]
    assert not out.exists()


def test_a_table_registered_undeclared_while_built_is_refused_before_the_run(tmp_path, monkeypatch):
    """A hook that registers a table it does not declare as it is built is refused by the
    build, naming its key and the table, before any simulated second."""
    (tmp_path / "undeclared_hook.py").write_text(
        "import pandas as pd\n"
        "from netsim.params import NoParams\n"
        "from netsim.plugins import PluginSpec\n"
        "def build(params, parts):\n"
        "    parts.trace.add_frame('seen', lambda: pd.DataFrame({'t_s': [0.0]}))\n"
        "HOOK = PluginSpec(Params=NoParams, build=build)\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    cfg = config.load(None, [*SMALL, 'events.hooks=["undeclared_hook:HOOK"]'])
    with pytest.raises(NetsimInputError, match=r"^events.hooks\[0\] = 'undeclared_hook:HOOK': writes table 'seen'"):
        build(cfg)


def test_a_declared_table_never_written_is_written_empty_with_its_columns_and_dtypes(tmp_path, monkeypatch):
    """A table a plugin declares and never writes (no row recorded) is one of the run's
    tables, without rows, with the declared columns in their dtypes (it was missing), text
    as pandas holds it of its own accord (its file read back)."""
    from netsim.trace import TEXT_DTYPE

    declared = {"never": {"t_s": "float64", "count": "int64", "flag": "bool", "label": "object"}}
    cfg = config.load(None, _controller(tmp_path, monkeypatch, "silent_ctl", "pass", declared))
    frame = execute(cfg).frames["never"]
    assert len(frame) == 0
    assert {c: str(t) for c, t in frame.dtypes.items()} == {**declared["never"], "label": str(TEXT_DTYPE)}


@pytest.mark.parametrize(
    ("module", "record", "told"),
    [
        (
            "missing_ctl",
            'step.record("counts", pairs=1)',
            "table 'counts' has other columns than its plugin declares "
            r"\(missing robots\)",
        ),
        ("extra_ctl", 'step.record("counts", pairs=1, robots=2, spare=3)', r"\(not declared spare\)"),
    ],
)
def test_columns_missing_from_or_extra_to_the_declaration_are_named_in_one_line(
    tmp_path, monkeypatch, module, record, told
):
    """A table whose columns are not the declared ones is refused, naming the key, the
    table and the columns (it was written as it came)."""
    declared = {"counts": {"t_s": "float64", "pairs": "int64", "robots": "int64"}}
    cfg = config.load(None, _controller(tmp_path, monkeypatch, module, record, declared))
    with pytest.raises(NetsimInputError, match=rf"^control.controllers = '{module}:CTL': .*{told}$"):
        execute(cfg)


def test_a_column_is_cast_to_its_declared_dtype_where_no_value_changes(tmp_path, monkeypatch):
    """Whole numbers written in a column declared float64 are written as float64, and the
    columns in the declared order (they were written as they came: int64, in any order)."""
    declared = {"speeds": {"t_s": "float64", "speed_mps": "float64", "robot": "int64"}}
    record = 'step.record("speeds", robot=1, speed_mps=2)'
    frame = execute(config.load(None, _controller(tmp_path, monkeypatch, "cast_ctl", record, declared))).frames[
        "speeds"
    ]
    assert list(frame.columns) == ["t_s", "speed_mps", "robot"]
    assert {c: str(t) for c, t in frame.dtypes.items()} == declared["speeds"]


def test_a_column_whose_values_a_cast_would_change_is_refused(tmp_path, monkeypatch):
    """Fractions written in a column declared int64 are refused in one line naming the
    table, the column and both dtypes (casting would have truncated them)."""
    declared = {"speeds": {"t_s": "float64", "speed_mps": "int64"}}
    record = 'step.record("speeds", speed_mps=2.5)'
    cfg = config.load(None, _controller(tmp_path, monkeypatch, "truncating_ctl", record, declared))
    with pytest.raises(
        NetsimInputError, match=r"table 'speeds', column 'speed_mps' is written as float64, declared int64"
    ):
        execute(cfg)


def test_a_declared_column_of_no_dtype_is_refused_before_the_run(tmp_path, monkeypatch):
    """A declaration whose column type is not a dtype is refused as the run is built,
    naming the key, the table and the column (it failed, if at all, after the run)."""
    declared = {"counts": {"t_s": "float64", "pairs": "integer please"}}
    cfg = config.load(None, _controller(tmp_path, monkeypatch, "typo_ctl", "pass", declared))
    with pytest.raises(ConfigError, match=r"declares counts.pairs as 'integer please', not a dtype"):
        build(cfg)


@pytest.mark.parametrize(
    "overrides",
    [
        [],
        ["protocol.model=ack", "channel.mac=aloha", 'events.hooks=["link_breaks"]'],
        ["protocol.model=aodv", "traffic.flows=[{src=0, dst=3, start_s=0, stop_s=5, rate_bps=8000, packet_bytes=100}]"],
        ['control.controllers=["log_separation"]', "coverage.start_s=0"],
    ],
)
def test_netsim_own_models_write_the_tables_they_declare(overrides):
    """The rule a user's plugin is held to, met by netsim's own models (which the run does
    not check): every table they write is declared, with exactly its columns."""
    from netsim.trace import conform

    cfg = config.load(None, ["world.n_robots=5", "duration_s=5", *overrides])
    declared = tables(cfg)
    for name, frame in execute(cfg).frames.items():
        assert name in declared, name
        pd.testing.assert_frame_equal(conform(frame, declared[name], "netsim", name), frame)


class _Row(NamedTuple):
    t_s: float
    n: int


def test_a_table_two_models_register_is_owned_by_the_first():
    """Messages about a table name the model that registered it first: a second model
    writing the same table does not take it over."""
    from netsim.trace import Trace

    trace = Trace()
    trace.written_by("events.hooks[0] = 'a:HOOK'").emit("shared", _Row(0.0, 1))
    trace.written_by("events.hooks[1] = 'b:HOOK'").add_frame("shared", pd.DataFrame)
    assert trace.owners == {"shared": "events.hooks[0] = 'a:HOOK'"}


def test_a_table_a_model_only_declares_is_its_own():
    """A table a user's model declares through the trace, written or not, is recorded as
    that model's (so that one its plugin does not declare is refused); netsim's own
    declarations are nobody's."""
    from netsim.trace import Trace

    trace = Trace()
    trace.declare("netsims", _Row)
    trace.written_by("events.hooks[0] = 'a:HOOK'").declare("mine", _Row)
    assert trace.owners == {"mine": "events.hooks[0] = 'a:HOOK'"}
    assert trace.names() == ["mine", "netsims"]


def test_declaring_a_table_again_keeps_its_rows():
    """A second declaration of a table (a second model of one kind, say) adds nothing and
    loses none of the rows already recorded."""
    from netsim.trace import Trace

    trace = Trace()
    trace.declare("counts", _Row)
    trace.emit("counts", _Row(0.0, 3))
    trace.declare("counts", _Row)
    trace.emit("counts", _Row(1.0, 4))
    assert trace.frame("counts").to_dict("list") == {"t_s": [0.0, 1.0], "n": [3, 4]}


def test_only_text_held_as_objects_takes_the_text_dtype_as_read_back():
    """A table with rows: a declared text column held as objects becomes pandas' text dtype,
    as its Parquet file reads back; one held otherwise (categories, which Parquet keeps as
    such) is left as it is."""
    from netsim.trace import TEXT_DTYPE, as_read_back

    frame = pd.DataFrame({"label": pd.Series(["a", "b"], dtype=object), "kind": pd.Categorical(["x", "y"])})
    back = as_read_back(frame, {"label": "object", "kind": "object"})
    assert back["label"].dtype == TEXT_DTYPE and back["label"].tolist() == ["a", "b"]
    assert isinstance(back["kind"].dtype, pd.CategoricalDtype)


def test_a_table_without_rows_is_held_to_its_declaration_too():
    """Columns not declared, or of a dtype that does not cast safely, are refused in a table
    without rows as in one with rows; only a frame with neither rows nor columns is the
    declared empty table."""
    from netsim.trace import conform

    schema = {"t_s": "float64", "n": "int64"}
    extra = pd.DataFrame({"t_s": pd.Series([], dtype=float), "n": pd.Series([], dtype=int), "x": []})
    with pytest.raises(NetsimInputError, match=r"^me: table 'tbl' has other columns .*\(not declared x\)$"):
        conform(extra, schema, "me", "tbl")
    fractions = pd.DataFrame({"t_s": pd.Series([], dtype=float), "n": pd.Series([], dtype=float)})
    with pytest.raises(NetsimInputError, match=r"column 'n' is written as float64, declared int64"):
        conform(fractions, schema, "me", "tbl")
    empty = conform(pd.DataFrame(), schema, "me", "tbl")
    assert len(empty) == 0 and {c: str(t) for c, t in empty.dtypes.items()} == schema


@pytest.mark.parametrize(("written", "declared"), [("int64", "int32"), ("float64", "float32"), ("int64", "uint64")])
def test_a_column_narrower_in_its_declaration_is_refused(written, declared):
    """A cast numpy counts unsafe within one kind of number (to fewer bits, or to unsigned)
    could change values: refused, naming both dtypes."""
    from netsim.trace import conform

    frame = pd.DataFrame({"v": np.array([1, 2], dtype=written)})
    with pytest.raises(NetsimInputError, match=rf"column 'v' is written as {written}, declared {declared}"):
        conform(frame, {"v": declared}, "me", "tbl")
