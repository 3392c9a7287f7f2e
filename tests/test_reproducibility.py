"""Same seed, same trace, bit for bit; components' random streams are independent."""

import json

import pandas as pd
import pytest

from netsim.tools.cli import main

BASE = {"world.n_robots": "25", "duration_s": "60", "channel.loss_probability": "0.1"}
SMALL = [*(a for key, value in BASE.items() for a in ("--set", f"{key}={value}")), "--quiet"]


def _run(tmp_path, name, *extra):
    """A run of :data:`BASE`, ``extra``'s ``--set`` in place of its own of the same key."""
    out = tmp_path / name
    given = [extra[k + 1].partition("=") for k in range(len(extra) - 1) if extra[k] == "--set"]
    sets = {**BASE, **{key: value for key, _, value in given}}
    rest = [a for k, a in enumerate(extra) if a != "--set" and (k == 0 or extra[k - 1] != "--set")]
    args = [a for key, value in sets.items() for a in ("--set", f"{key}={value}")]
    assert main(["run", "--out", str(out), *args, "--quiet", *rest]) == 0
    return out


@pytest.fixture(scope="module")
def seed_7(tmp_path_factory):
    """The run of seed 7, made once for the tests that compare another run with it."""
    return _run(tmp_path_factory.mktemp("seed_7"), "a", "--seed", "7")


def test_same_seed_gives_identical_files(tmp_path, seed_7):
    """The same seed writes the same tables, configuration and summary, byte for byte."""
    a, b = seed_7, _run(tmp_path, "b", "--seed", "7")
    for name in ("positions", "links", "acks", "roles", "groups", "messages", "beliefs", "legs", "hops"):
        assert (a / f"{name}.parquet").read_bytes() == (b / f"{name}.parquet").read_bytes(), name
    assert (a / "config.toml").read_text() == (b / "config.toml").read_text()
    sa, sb = json.loads((a / "summary.json").read_text()), json.loads((b / "summary.json").read_text())
    sa.pop("wall_s"), sb.pop("wall_s")
    assert sa == sb


@pytest.mark.slow
def test_other_seed_gives_other_results(tmp_path, seed_7):
    """Another seed gives other positions, links and Acks."""
    a, b = seed_7, _run(tmp_path, "b", "--seed", "8")
    for name in ("positions", "links", "acks"):
        assert not pd.read_parquet(a / f"{name}.parquet").equals(pd.read_parquet(b / f"{name}.parquet")), name


@pytest.mark.slow
def test_protocol_parameters_leave_positions_unchanged(tmp_path, seed_7):
    """Changing the protocol's parameters never changes the robots' motion (streams per component)."""
    a = seed_7
    b = _run(
        tmp_path,
        "b",
        "--seed",
        "7",
        "--set",
        "protocol.ack_period_s=0.5",
        "--set",
        "protocol.tau_s=2",
        "--set",
        "channel.loss_probability=0.4",
        "--set",
        "channel.latency_jitter_s=0.01",
    )
    assert (a / "positions.parquet").read_bytes() == (b / "positions.parquet").read_bytes()
    assert not pd.read_parquet(a / "acks.parquet").equals(pd.read_parquet(b / "acks.parquet"))


@pytest.mark.parametrize("jitter", [None, "channel.latency_jitter_s=0.05"])
def test_messages_leave_the_acks_draws_unchanged(tmp_path, jitter):
    """Each kind of frame draws its loss and its latency from a stream of its own
    (``channel.loss.<kind>``, ``channel.latency.<kind>``): without a shared medium, sending
    more messages changes no Ack's fate, so the clustering is the same."""
    extra = ["--seed", "7", "--set", "world.n_robots=12", "--set", "duration_s=20"] + (
        ["--set", jitter] if jitter else []
    )
    a = _run(tmp_path, "a", *extra, "--set", "protocol.message_rate_hz=0.2")
    b = _run(tmp_path, "b", *extra, "--set", "protocol.message_rate_hz=2")
    assert len(pd.read_parquet(a / "messages.parquet")) < len(pd.read_parquet(b / "messages.parquet"))
    for name in ("acks", "roles", "groups", "beliefs"):
        assert (a / f"{name}.parquet").read_bytes() == (b / f"{name}.parquet").read_bytes(), name


def test_output_directory_contents_and_schema(tmp_path):
    out = _run(tmp_path, "a")
    names = {p.name for p in out.iterdir()}
    assert names == {
        "config.toml",
        "manifest.json",
        "summary.json",
        "positions.parquet",
        "links.parquet",
        "acks.parquet",
        "ack_delivery.parquet",
        "roles.parquet",
        "groups.parquet",
        "messages.parquet",
        "beliefs.parquet",
        "neighbour_beliefs.parquet",
        "legs.parquet",
        "hops.parquet",
    }
    assert list(pd.read_parquet(out / "positions.parquet").columns) == ["t_s", "robot", "x_m", "y_m"]
    links = pd.read_parquet(out / "links.parquet")
    assert list(links.columns)[:5] == ["a", "b", "t_up_s", "t_down_s", "censored"]
    assert (links.a < links.b).all()
    acks = pd.read_parquet(out / "acks.parquet")
    assert {"robot", "sent", "received", "dropped_loss"} <= set(acks.columns)
    assert list(pd.read_parquet(out / "roles.parquet").columns) == ["t_s", "robot", "role", "leader", "cause"]
    legs = pd.read_parquet(out / "legs.parquet")
    assert list(legs.columns) == ["t_s", "robot", "x_m", "y_m", "vx_mps", "vy_mps", "cause"]
    hops = pd.read_parquet(out / "hops.parquet")
    assert list(hops.columns) == ["msg_id", "hop", "sender", "receiver", "t_sent_s", "t_received_s"]
    pos = pd.read_parquet(out / "positions.parquet")
    assert sorted(pos.t_s.unique()) == [float(t) for t in range(61)]
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["seed"] == 1 and "numpy" in manifest["versions"]


def test_manifest_versions_are_the_installed_distributions():
    """A manifest names each distribution's installed version, whether its module is loaded
    (its own ``__version__``) or not (the installed metadata)."""
    from importlib import metadata

    import pyarrow  # noqa: F401  # loaded, so its __version__ is the one read

    from netsim.tools.output import VERSIONED, versions

    found = versions()
    for dist in VERSIONED:
        try:
            installed = metadata.version(dist)
        except metadata.PackageNotFoundError:
            installed = "not installed"
        assert found[dist] == installed, dist


@pytest.mark.parametrize("rows", [0, 1, 50])
def test_tables_are_the_files_pandas_writes(tmp_path, rows):
    """A run's table is written byte for byte as ``DataFrame.to_parquet(index=False)``
    writes it (integers, floats, booleans, text; a frame's ``attrs`` kept)."""
    import numpy as np

    from netsim.tools.output import write_run, write_table
    from tests.fixtures import make_config

    frame = pd.DataFrame(
        {
            "robot": np.arange(rows, dtype=np.int64),
            "t_s": np.linspace(0.0, 1.0, rows),
            "up": np.arange(rows) % 3 == 0,
            "cause": pd.Series(["leg", "jump"] * rows, dtype="str")[:rows],
        },
        index=np.arange(rows) + 7,
    )
    for attrs in ({}, {"source": "test"}):
        frame.attrs = attrs
        frame.to_parquet(tmp_path / "pandas.parquet", index=False)
        write_table(frame, tmp_path / "netsim.parquet")
        assert (tmp_path / "netsim.parquet").read_bytes() == (tmp_path / "pandas.parquet").read_bytes()
        # As netsim run writes it: in a writing thread, beside another table.
        write_run(tmp_path / "run", make_config(), {"other": frame.iloc[::-1], "t": frame}, {}, {})
        assert (tmp_path / "run" / "t.parquet").read_bytes() == (tmp_path / "pandas.parquet").read_bytes()


def test_a_text_column_with_no_value_is_written_as_text(tmp_path):
    """A text column (object) with no value in any row is written as Arrow text, not
    Arrow's null type: one table of two runs, one where nothing was dropped (every
    ``cause`` empty), reads as one dataset, whichever file comes first."""
    import pyarrow.dataset as ds
    import pyarrow.parquet as pq

    from netsim.tools.output import write_table

    none = pd.DataFrame({"t_s": [2.0], "cause": pd.Series([None], dtype=object)})
    some = pd.DataFrame({"t_s": [0.0, 1.0], "cause": pd.Series(["loss", None])})
    write_table(none, tmp_path / "a.parquet")
    write_table(some, tmp_path / "b.parquet")
    assert pq.read_schema(tmp_path / "a.parquet").types == pq.read_schema(tmp_path / "b.parquet").types
    table = ds.dataset([str(tmp_path / "a.parquet"), str(tmp_path / "b.parquet")]).to_table()
    assert table.column("cause").to_pylist() == [None, "loss", None]
    assert pd.read_parquet(tmp_path / "a.parquet")["cause"].isna().all()


def test_a_table_without_rows_has_its_declared_column_types(tmp_path):
    """A run whose model wrote no row of a table it declares (no role change under the Ack
    protocol, no message at a message rate of 0) writes that table with the declared
    types, as a run with rows does: numbers as numbers, so the runs of a sweep read as one
    dataset with numeric columns."""
    import pyarrow.parquet as pq

    from netsim.run import execute, tables
    from netsim.tools.output import write_run
    from tests.fixtures import make_config

    for protocol, table in (({"model": "ack"}, "roles"), ({"model": "clustering", "message_rate_hz": 0.0}, "messages")):
        out = tmp_path / table
        config = make_config(duration_s=5.0, world={"n_robots": 4}, protocol=protocol)
        result = execute(config)
        assert len(result.frames[table]) == 0
        write_run(out, config, result.frames, result.summary, {})
        schema = pq.read_schema(out / f"{table}.parquet")
        declared = tables(config)[table]
        for name, dtype in declared.items():
            arrow = {"object": "large_string", "float64": "double", "int64": "int64", "bool": "bool"}
            want = arrow[dtype]
            assert str(schema.field(name).type) == want, (table, name, schema.field(name).type)


def test_tables_written_together_are_the_files_written_one_at_a_time(tmp_path, monkeypatch, seed_7):
    """write_run writes its tables a few at a time: every file is the one it writes alone."""
    from netsim.tools import output

    a = seed_7
    monkeypatch.setattr(output, "WRITERS", 1)
    b = _run(tmp_path, "b", "--seed", "7")
    tables = sorted(p.name for p in a.glob("*.parquet"))
    assert len(tables) >= 9 and tables == sorted(p.name for p in b.glob("*.parquet"))
    for name in tables:
        assert (a / name).read_bytes() == (b / name).read_bytes(), name


def test_a_table_that_cannot_be_written_leaves_no_run(tmp_path, monkeypatch):
    """A table whose writing fails (in one of the writing threads) fails the run's writing
    as a whole: the error reaches the caller and the directory holds no table."""
    from netsim.tools import output

    def failing(table, path):
        if path.name == "groups.parquet":
            raise OSError("disk full")
        real(table, path)

    real = output.write_arrow
    monkeypatch.setattr(output, "write_arrow", failing)
    with pytest.raises(OSError, match="disk full"):
        main(["run", "--out", str(tmp_path / "a"), *SMALL])
    assert not list((tmp_path / "a").glob("*.parquet"))


def test_a_run_that_fails_after_its_first_tables_leaves_nothing(tmp_path, monkeypatch):
    """Tables are written while the later ones are made: if the run then fails (here, its
    summary), the tables already written go too, and the directory made for it."""
    import netsim.run

    def failing(*args, **kwargs):
        raise RuntimeError("summary failed")

    started = []
    real = netsim.run.collect
    monkeypatch.setattr(
        netsim.run, "collect", lambda sim, emit=None, progress=False: real(sim, lambda *a: started.append(emit(*a)))
    )
    monkeypatch.setattr(netsim.run, "summarize", failing)
    with pytest.raises(RuntimeError, match="summary failed"):
        main(["run", "--out", str(tmp_path / "a"), *SMALL])
    assert len(started) >= 9
    assert not (tmp_path / "a").exists()


def test_a_run_whose_first_file_cannot_be_written_leaves_nothing(tmp_path, monkeypatch):
    """The writer's first file (config.toml, in its temporary directory) failing: the
    error reaches the caller and neither that directory nor the one made for the run stays."""
    from netsim.tools import output

    def failing(_tree):
        raise OSError("disk full")

    monkeypatch.setattr(output.tomli_w, "dumps", failing)
    with pytest.raises(OSError, match="disk full"):
        main(["run", "--out", str(tmp_path / "a"), *SMALL])
    assert not (tmp_path / "a").exists()


def test_two_tables_of_one_name_are_refused(tmp_path):
    """A run never writes two tables to one file: a model's table named like one the engine
    writes is refused before any is written, and a writer takes each name once."""
    from netsim.errors import NetsimInputError
    from netsim.run import build, collect
    from netsim.tools.output import RunWriter
    from tests.fixtures import make_config

    sim = build(make_config(duration_s=5.0, world={"n_robots": 5}))
    sim.run()
    sim.trace.add_frame("legs", lambda: pd.DataFrame({"t_s": [0.0]}))
    written = []
    with pytest.raises(NetsimInputError, match="legs"):
        collect(sim, lambda name, frame: written.append(name))
    assert written == []
    with RunWriter(tmp_path / "b", make_config()) as writer:
        writer.table("links", pd.DataFrame({"a": [1]}))
        with pytest.raises(ValueError, match="links"):
            writer.table("links", pd.DataFrame({"a": [2]}))


def test_a_plugin_table_named_like_an_engine_table_is_one_line_and_exit_2(tmp_path, monkeypatch, capsys):
    """A user's model whose table takes a name netsim writes itself: one line naming it,
    exit status 2, and no directory left."""
    (tmp_path / "clashing_model.py").write_text(
        "import pandas as pd\n"
        "from netsim.params import NoParams\n"
        "from netsim.plugins import PluginSpec\n"
        "def build(params, parts):\n"
        "    parts.trace.add_frame('links', lambda: pd.DataFrame({'a': [0]}))\n"
        "STILL = PluginSpec(Params=NoParams, build=build)\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    out = tmp_path / "out"
    code = main(["run", "--out", str(out), "--set", "mobility.model=clashing_model:STILL", *SMALL])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(err) == 1 and "links" in err[0]
    assert not out.exists()


def test_a_plugin_declaring_a_table_named_like_an_engine_table_is_refused_before_the_run(tmp_path, monkeypatch):
    """A hook that declares a table named like one netsim writes is refused as the run is
    built, naming its key, before any simulated second (it was refused after the whole run,
    naming nobody)."""
    from netsim.errors import ConfigError
    from netsim.run import build
    from tests.fixtures import make_config

    (tmp_path / "declares_links.py").write_text(
        "from netsim.params import NoParams\n"
        "from netsim.plugins import PluginSpec\n"
        "HOOK = PluginSpec(Params=NoParams, build=lambda params, parts: None, tables={'links': {'a': 'int64'}})\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    config = make_config(duration_s=5.0, world={"n_robots": 5}, events={"hooks": ["declares_links:HOOK"]})
    with pytest.raises(ConfigError, match=r"^events.hooks\[0\] = 'declares_links:HOOK': declares links, a table"):
        build(config)
