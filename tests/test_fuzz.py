"""Fuzzing of every reader of user input (hypothesis): the TOML configuration loader, the
``--set`` parser, the ns-2 trace parser, the placement CSV reader and the sweep-file
parser get arbitrary and mutated inputs. Every input gives a valid result or the
project's own one-line error (``ConfigError`` / ``NetsimInputError``), never another
exception.

The quick loop runs a few hundred examples per reader (a few seconds each); the ``slow``
runs ask for many more.
"""

import math
import re
import tempfile
from pathlib import Path

import numpy as np
import pytest
import tomli_w
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from netsim import config as cfgmod
from netsim import placement
from netsim.config import Config
from netsim.errors import NetsimInputError
from netsim.formats import ns2
from netsim.tools import sweep as sweepmod

QUICK = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
THOROUGH = settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.too_slow])

WORKDIR = Path(tempfile.mkdtemp(prefix="netsim-fuzz-"))

# Odd input netsim takes (an unused key, robots on one spot) is rightly warned of: not what fuzzing checks.
ODD_BUT_TAKEN = pytest.mark.filterwarnings("ignore::netsim.config.ConfigWarning")
# Likewise the ns-2 reader's warnings of a trace it takes, each naming the fuzzed file first.
ODD_TRACE = pytest.mark.filterwarnings(r"ignore:.*/trace\.tcl:UserWarning")

KEYS = [k for k, _, _ in cfgmod.describe()]

# Values that have broken parsers before, or would: wrong types, out of range, huge,
# non-finite, unclosed, nested.
ODD_VALUES = [
    "0",
    "-1",
    "1",
    "2.5",
    "1e309",
    "-1e309",
    "1e-320",
    "nan",
    "inf",
    "-inf",
    "+inf",
    "99999999999999999999999",
    "9223372036854775808",
    '""',
    '"x"',
    "'x'",
    "true",
    "false",
    "[]",
    "[1.0, 2.0]",
    "[[1]]",
    '["a", 1]',
    "{}",
    "{a = 1}",
    "[",
    "{",
    '"',
    "0x10",
    "1_000",
    "1979-05-27",
    "12:00:00",
    "[1.0,",
    "{a=",
    "-0.0",
]
FUZZ_CHARS = st.characters(codec="utf-8", exclude_categories=("Cs",))
PUNCTUATION = list("[]{}\"'=.,#\n\r\t -+_:$()\\0123456789eE")


def mutate(seeds, tokens=ODD_VALUES):
    """Texts made from ``seeds`` by a few edits: characters inserted, deleted or replaced,
    lines dropped, duplicated or swapped, a number or word replaced by an odd value."""

    @st.composite
    def strategy(draw):
        text = draw(st.sampled_from(seeds))
        for _ in range(draw(st.integers(0, 5))):
            kind = draw(st.sampled_from(["insert", "delete", "replace", "drop", "dup", "swap", "token", "truncate"]))
            n = len(text)
            if kind in ("insert", "replace") or n == 0:
                at = draw(st.integers(0, n))
                piece = draw(st.one_of(st.sampled_from(PUNCTUATION + tokens), st.text(FUZZ_CHARS, max_size=4)))
                cut = draw(st.integers(0, 3)) if kind == "replace" else 0
                text = text[:at] + piece + text[at + cut :]
            elif kind == "delete":
                at = draw(st.integers(0, n - 1))
                text = text[:at] + text[at + draw(st.integers(1, 5)) :]
            elif kind == "truncate":
                text = text[: draw(st.integers(0, n))]
            elif kind in ("drop", "dup", "swap"):
                lines = text.split("\n")
                i, j = draw(st.integers(0, len(lines) - 1)), draw(st.integers(0, len(lines) - 1))
                if kind == "drop":
                    del lines[i]
                elif kind == "dup":
                    lines.insert(j, lines[i])
                else:
                    lines[i], lines[j] = lines[j], lines[i]
                text = "\n".join(lines)
            else:
                spans = [m.span() for m in re.finditer(r"[-+]?[0-9][0-9.eE+_-]*|\b[a-z_]+\b|\"[^\"\n]*\"", text)]
                if spans:
                    a, b = draw(st.sampled_from(spans))
                    text = text[:a] + draw(st.sampled_from(tokens)) + text[b:]
        return text

    return strategy()


def write(name: str, text) -> Path:
    path = WORKDIR / name
    if isinstance(text, bytes):
        path.write_bytes(text)
    else:
        path.write_text(text, encoding="utf-8", errors="surrogatepass")
    return path


# -- the TOML configuration loader ---------------------------------------------------------
CONFIG_SEEDS = [
    cfgmod.commented_toml(),
    "seed = 3\nduration_s = 20.0\n[world]\nn_robots = 4\nside_m = 100.0\ntorus = true\n[channel]\nrange_m = 10.0\n",
    '[world]\nn_robots = 2\n[channel]\nrange_m = [10.0, 20.0]\n[control]\ncontrollers = ["log_separation"]\n'
    "[control.options]\nmin_separation_m = 2.0\n",
    '[mobility]\nmodel = "trace"\ntrace_file = "x.tcl"\n[protocol]\nack_period_s = 2.0\ntau_s = 5.0\n',
    '[coverage]\nenabled = true\nlaw = "repulsion"\n[mobility]\nmodel = "static"\n',
]


# Scalars of every TOML type, with the edges that break naive code: integers beyond 64 bits
# (TOML readers accept them), numbers beyond a float, non-finite floats, odd strings.
SCALARS = st.one_of(
    st.integers(),
    st.sampled_from([0, -1, 1, 2**63, -(2**63) - 1, 10**400, -(10**400)]),
    st.floats(),
    st.sampled_from([math.inf, -math.inf, math.nan, 1e308, -0.0, 5e-324]),
    st.booleans(),
    st.text(FUZZ_CHARS, max_size=8),
    st.sampled_from(["", ".", "..", "grid", "uniform", "centre", "static", "trace", "clustering", "/", "a/b"]),
)
VALUES = st.recursive(
    SCALARS,
    lambda inner: st.one_of(st.lists(inner, max_size=4), st.dictionaries(st.text(max_size=4), inner, max_size=3)),
    max_leaves=6,
)


@st.composite
def config_trees(draw, keys=KEYS):
    """Nested tables built from the real keys (a few unknown ones too), with values of
    any TOML type, and now and then a whole section replaced by a value."""
    tree: dict = {}
    sections = sorted({k.split(".")[0] for k in keys})
    for key in draw(st.lists(st.sampled_from(keys + ["world.colour", "nonsense"] + sections), max_size=6)):
        tree = cfgmod.merge(tree, cfgmod.nest(key, draw(VALUES)))
    return tree


def check_config_file(text):
    path = write("config.toml", text)
    try:
        config = cfgmod.load(path)
    except NetsimInputError as exc:
        assert "\n" not in str(exc).strip() or "not valid TOML" in str(exc)
        return
    assert isinstance(config, Config)
    # What loads is what runs: the resolved configuration loads back the same.
    assert cfgmod.from_dict(cfgmod.to_dict(config)) == config


@ODD_BUT_TAKEN
@QUICK
@given(st.one_of(mutate(CONFIG_SEEDS), st.text(FUZZ_CHARS, max_size=200)))
@pytest.mark.slow
def test_fuzz_config_file(text):
    check_config_file(text)


@ODD_BUT_TAKEN
@QUICK
@given(config_trees())
@pytest.mark.slow
def test_fuzz_config_tables(tree):
    try:
        text = tomli_w.dumps(tree)
    except (TypeError, ValueError):
        return  # not expressible in TOML (tomli_w refuses it): nothing a user could write
    check_config_file(text)


@ODD_BUT_TAKEN
@pytest.mark.slow
@THOROUGH
@given(st.one_of(mutate(CONFIG_SEEDS), config_trees().map(lambda t: tomli_w.dumps(t)), st.text(FUZZ_CHARS)))
def test_fuzz_config_file_thoroughly(text):
    check_config_file(text)


EDGE_VALUES = [
    0, -1, 1, 3, 2**63, -(2**63) - 1, 10**400, -(10**400), math.inf, -math.inf, math.nan, 1e308, -0.0, 5e-324,
    True, "", "x", "grid", [], [1.0], [1.0, 2.0, 3.0], [10**400], ["a"], {}, {"a": 1},
]  # fmt: skip


@ODD_BUT_TAKEN
@pytest.mark.parametrize("key", KEYS)
def test_every_key_with_every_edge_value(key):
    """Not random: every configuration key with every edge value, from a file and from
    ``--set`` (where TOML can write the value)."""
    for value in EDGE_VALUES:
        try:
            text = tomli_w.dumps(cfgmod.nest(key, value))
        except (TypeError, ValueError):
            continue
        check_config_file(text)
        check_set([f"{key}={text.split(' = ', 1)[1].strip()}"] if " = " in text else [f"{key}={value}"])


# -- the --set parser ----------------------------------------------------------------------
@st.composite
def set_options(draw):
    key = draw(st.one_of(st.sampled_from(KEYS), st.text(FUZZ_CHARS, max_size=10)))
    value = draw(st.one_of(st.sampled_from(ODD_VALUES), st.text(FUZZ_CHARS, max_size=12), mutate(ODD_VALUES)))
    return f"{key}{draw(st.sampled_from(['=', ' = ', '==', '']))}{value}"


def check_set(options):
    try:
        config = cfgmod.load(None, options)
    except NetsimInputError as exc:
        assert str(exc)
        return
    assert isinstance(config, Config)


@ODD_BUT_TAKEN
@QUICK
@given(st.lists(st.one_of(set_options(), st.text(FUZZ_CHARS, max_size=30)), min_size=1, max_size=3))
@pytest.mark.slow
def test_fuzz_set_options(options):
    check_set(options)


@ODD_BUT_TAKEN
@pytest.mark.slow
@THOROUGH
@given(st.lists(st.one_of(set_options(), st.text(FUZZ_CHARS)), min_size=1, max_size=4))
def test_fuzz_set_options_thoroughly(options):
    check_set(options)


# -- the ns-2 trace parser -----------------------------------------------------------------
TRACE_SEEDS = [
    "$node_(0) set X_ 10.0\n$node_(0) set Y_ 20.0\n$node_(0) set Z_ 0.0\n"
    "$node_(1) set X_ 30.0\n$node_(1) set Y_ 40.0\n"
    '$ns_ at 1.0 "$node_(0) setdest 50.0 60.0 2.5"\n'
    '$ns_ at 2.5 "$node_(1) set X_ 35.0"\n'
    '$god_ set-dist 0 1 1\n# a comment\n$ns_ at 3.0 "$node_(1) setdest 0.0 0.0 1.0"\n',
    "$node_(0) set X_ 1e2\n$node_(0) set Y_ 2\n",
]


def check_trace(text, n_robots):
    path = write("trace.tcl", text)
    try:
        scen = ns2.read(path, n_robots)
    except NetsimInputError as exc:
        assert str(exc)
        return
    assert scen.initial_m.shape == (scen.n_robots, 2) and np.isfinite(scen.initial_m).all()
    assert n_robots is None or scen.n_robots <= n_robots
    assert (scen.events["robot"] < scen.n_robots).all()
    assert scen.events["t_s"].is_monotonic_increasing
    assert np.isfinite(scen.events[["x_m", "y_m"]].to_numpy()).all()


TRACE_TOKENS = ODD_VALUES + ["$node_(99999)", "$node_(-1)", "$node_(2)", "setdest", "set", "X_", "Y_", '"', "$ns_"]


@ODD_TRACE
@QUICK
@given(
    st.one_of(mutate(TRACE_SEEDS, TRACE_TOKENS), st.text(FUZZ_CHARS, max_size=120)), st.sampled_from([None, 1, 2, 3])
)
@pytest.mark.slow
def test_fuzz_trace(text, n_robots):
    check_trace(text, n_robots)


@ODD_TRACE
@pytest.mark.slow
@THOROUGH
@given(st.one_of(mutate(TRACE_SEEDS, TRACE_TOKENS), st.text(FUZZ_CHARS)), st.sampled_from([None, 1, 2, 3]))
def test_fuzz_trace_thoroughly(text, n_robots):
    check_trace(text, n_robots)


def test_a_huge_node_number_is_refused_at_once():
    """A stray huge node number must not make the parser walk (or allocate positions for)
    every number below it: with the team size given, or without it."""
    path = write("huge.tcl", "$node_(0) set X_ 1\n$node_(0) set Y_ 1\n$node_(999999999) set X_ 1\n")
    with pytest.raises(NetsimInputError, match=r":3: node 999999999 is beyond the 1,000,000 nodes"):
        ns2.read(path)
    with pytest.raises(NetsimInputError, match=r":3: node 999999999 is beyond world.n_robots = 2"):
        ns2.read(path, 2)


# -- the placement CSV reader --------------------------------------------------------------
CSV_SEEDS = ["x_m,y_m\n1.0,2.0\n3.5,4\n", "x_m,y_m\n0,0\n100,100\n", 'x_m,y_m\n"1",2\n3,4\n']


def check_placement(data, n):
    path = write("placement.csv", data)
    try:
        xy = placement.from_csv(str(path), n, 100.0)
    except NetsimInputError as exc:
        assert exc.key == "world.placement"
        return
    assert xy.shape == (n, 2) and np.isfinite(xy).all() and (xy >= 0).all() and (xy <= 100.0).all()


CSV_TOKENS = ODD_VALUES + ["x_m", "y_m", "z_m", ",", ";", '"', "\t", "NA", "", "1e2", "0b1"]


@ODD_BUT_TAKEN
@QUICK
@given(
    st.one_of(mutate(CSV_SEEDS, CSV_TOKENS), st.text(FUZZ_CHARS, max_size=60), st.binary(max_size=60)),
    st.sampled_from([1, 2, 3]),
)
@pytest.mark.slow
def test_fuzz_placement_csv(data, n):
    check_placement(data, n)


@ODD_BUT_TAKEN
@pytest.mark.slow
@THOROUGH
@given(st.one_of(mutate(CSV_SEEDS, CSV_TOKENS), st.text(FUZZ_CHARS), st.binary()), st.sampled_from([1, 2, 3]))
def test_fuzz_placement_csv_thoroughly(data, n):
    check_placement(data, n)


# -- the sweep-file parser -----------------------------------------------------------------
SWEEP_SEEDS = [
    'name = "speed"\nreplications = 2\ntables = ["links"]\n[base]\nduration_s = 30.0\n[base.world]\nn_robots = 5\n'
    '[grid]\n"mobility.speed_max_mps" = [1.0, 5.0]\n"mobility.pause_s" = [0.0, 30.0]\n',
    '[base]\nduration_s = 10.0\n[random]\nsamples = 3\nseed = 1\n[random.ranges]\n"world.n_robots" = [2, 9]\n'
    '"channel.loss_probability" = [0.0, 0.5]\n',
    'name = "b"\nbase_file = "config.toml"\n[grid]\nseed = [1, 2]\n',
]
SWEEP_TOKENS = ODD_VALUES + ['"world.n_robots"', '"seed"', "[grid]", "[random]", "[base]", "samples", "replications"]


def check_sweep(text):
    write("config.toml", "[world]\nn_robots = 4\n")
    path = write("sweep.toml", text)
    try:
        sweep = sweepmod.load_file(path)
    except NetsimInputError as exc:
        assert str(exc)
        return
    check_sweep_runs(sweep)


def check_sweep_runs(sweep):
    try:
        runs = sweep.runs()
    except NetsimInputError as exc:
        assert str(exc)
        return
    assert len(runs) == len(sweep.points) * sweep.replications <= sweepmod.MAX_RUNS
    for run in runs[:20]:
        assert isinstance(cfgmod.from_dict(run.config), Config)


KNOWN_TABLES = sorted(sweepmod.known_tables({}))
AXIS_KEYS = st.one_of(st.sampled_from(KEYS), st.text(FUZZ_CHARS, max_size=8))


@st.composite
def sweep_trees(draw):
    """Sweep descriptions with every part present or not, right or wrong."""
    tree = {}
    maybe = lambda: draw(st.booleans())
    if maybe():
        tree["name"] = draw(st.one_of(SCALARS, VALUES))
    if maybe():
        tree["replications"] = draw(st.one_of(st.integers(-2, 4), SCALARS))
    if maybe():
        tree["tables"] = draw(
            st.one_of(
                st.lists(st.one_of(st.sampled_from(sorted(sweepmod.known_tables({}))), VALUES)),
                VALUES,
            )
        )
    if maybe():
        tree["base"] = draw(st.one_of(config_trees(), VALUES))
    if maybe():
        tree["base_file"] = draw(st.one_of(st.just("config.toml"), st.just("sweep.toml"), SCALARS))
    if maybe():
        tree["grid"] = draw(
            st.one_of(st.dictionaries(AXIS_KEYS, st.one_of(st.lists(SCALARS, max_size=4), VALUES), max_size=3), VALUES)
        )
    if maybe():
        bound = st.one_of(SCALARS, st.integers(-5, 5), st.floats(-5, 5))
        ranges = st.dictionaries(AXIS_KEYS, st.one_of(st.lists(bound, min_size=2, max_size=2), VALUES), max_size=3)
        random = {
            "samples": st.one_of(st.integers(-1, 5), SCALARS),
            "seed": SCALARS,
            "ranges": st.one_of(ranges, VALUES),
        }
        tree["random"] = {k: draw(v) for k, v in random.items() if maybe()}
        if maybe():
            tree["random"][draw(st.text(max_size=3))] = draw(SCALARS)
    if maybe():
        tree[draw(st.text(max_size=5))] = draw(SCALARS)
    return tree


def check_sweep_tree(tree):
    write("config.toml", "[world]\nn_robots = 4\n")
    try:
        sweep = sweepmod.parse(tree, WORKDIR / "sweep.toml")
    except NetsimInputError as exc:
        assert str(exc)
        return
    check_sweep_runs(sweep)


RANGE_EDGES = [
    0,
    1,
    -1,
    2**63,
    -(2**63) - 1,
    10**400,
    0.5,
    0.0,
    -0.0,
    math.inf,
    -math.inf,
    math.nan,
    1e308,
    -1e308,
    True,
    "a",
]


@ODD_BUT_TAKEN
@pytest.mark.parametrize("low", RANGE_EDGES, ids=repr)
def test_random_sweep_with_every_edge_range(low):
    """Not random: [random.ranges] bounds at every pair of edges."""
    for high in RANGE_EDGES:
        for key in ("seed", "world.n_robots", "channel.loss_probability"):
            tree = {"random": {"samples": 2, "seed": 1, "ranges": {key: [low, high]}}}
            check_sweep_tree(tree)


@ODD_BUT_TAKEN
@QUICK
@given(sweep_trees())
@pytest.mark.slow
def test_fuzz_sweep_tables(tree):
    check_sweep_tree(tree)


@ODD_BUT_TAKEN
@pytest.mark.slow
@THOROUGH
@given(sweep_trees())
def test_fuzz_sweep_tables_thoroughly(tree):
    check_sweep_tree(tree)


@ODD_BUT_TAKEN
@QUICK
@given(st.one_of(mutate(SWEEP_SEEDS, SWEEP_TOKENS), st.text(FUZZ_CHARS, max_size=120)))
@pytest.mark.slow
def test_fuzz_sweep_file(text):
    check_sweep(text)


@ODD_BUT_TAKEN
@pytest.mark.slow
@THOROUGH
@given(st.one_of(mutate(SWEEP_SEEDS, SWEEP_TOKENS), st.text(FUZZ_CHARS)))
def test_fuzz_sweep_file_thoroughly(text):
    check_sweep(text)


def test_fuzz_helpers_make_valid_seeds():
    """The seeds the mutations start from are valid inputs themselves, so the fuzzers
    explore near valid files rather than only far from them."""
    for text in CONFIG_SEEDS[:3]:
        assert isinstance(cfgmod.load(write("seed.toml", text)), Config)
    assert ns2.read(write("seed.tcl", TRACE_SEEDS[0]), 2).n_robots == 2
    assert placement.from_csv(str(write("seed.csv", CSV_SEEDS[0])), 2, 100.0).shape == (2, 2)
    assert len(sweepmod.load_file(write("sweep.toml", SWEEP_SEEDS[0])).runs()) == 8
