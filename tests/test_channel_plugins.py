"""A user's channel models, end to end: a propagation model (two-ray ground,
tests/two_ray_plugin.py) and a medium access control (TDMA, tests/tdma_plugin.py), named
as ``"package.module:attr"``. Each runs, decides what it should, shows its keys in
``netsim config``, is a sweep axis, and refuses a bad value in one line."""

import contextlib
import io
import math
import re
import tomllib

import numpy as np
import pytest

from netsim import config as cfgmod
from netsim.run import build, execute
from netsim.tools import sweep as sweepmod
from netsim.tools.cli import main
from tests import two_ray_plugin

TWO_RAY = "tests.two_ray_plugin:PLUGIN"
TDMA = "tests.tdma_plugin:PLUGIN"
SMALL = ["world.n_robots=12", "world.side_m=200", "duration_s=20", "protocol.model=ack"]


def cli(*argv):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main([str(a) for a in argv])
    return code, out.getvalue(), err.getvalue()


def sets(*overrides):
    return [a for o in overrides for a in ("--set", o)]


def test_a_user_propagation_model_decides_who_hears_a_frame():
    """Under two-ray ground a robot hears exactly the robots within the model's implied
    range (the generic path evaluates the user's loss term), and the run's ranges and
    summary follow the model."""
    two_ray = [f"channel.propagation={TWO_RAY}", "channel.tx_power_dbm=5", "channel.sensitivity_dbm=-70"]
    config = cfgmod.load(None, [*SMALL, *two_ray])
    range_m = two_ray_plugin.implied_range_m(config.channel.radio)
    assert 30 < range_m < 100
    sim = build(config)
    sim.run(until_s=5.0)
    pos = sim.state.positions_at(sim.env.now)
    heard = 0
    for i in range(sim.state.n):
        receivers, _ = sim.channel.in_range(i)
        d = np.hypot(*(pos - pos[i]).T)
        expected = np.flatnonzero((d <= range_m) & (np.arange(sim.state.n) != i))
        assert receivers.tolist() == expected.tolist()
        heard += len(receivers)
        # The decision itself, beyond the neighbour search's reach too.
        others = np.flatnonzero(np.arange(sim.state.n) != i)
        decided = sim.channel.reception.decide(sim.env.now, i, others, d[others])
        assert decided.tolist() == (d[others] <= range_m).tolist()
    assert heard > 0
    result = execute(config)
    assert result.summary["propagation"] == TWO_RAY
    assert result.summary["implied_range_m"] == pytest.approx(range_m)


def test_the_cli_runs_a_user_propagation_model_and_records_its_keys(tmp_path):
    """``netsim run`` with two-ray ground writes the run, and its resolved configuration
    holds the model's keys as keys of [channel] (range_m, which the model implies, not)."""
    out = tmp_path / "r"
    code, _, err = cli(
        "run", *sets(*SMALL, f"channel.propagation={TWO_RAY}", "channel.antenna_height_m=2"), "--out", out, "--quiet"
    )
    assert code == 0, err
    channel = tomllib.loads((out / "config.toml").read_text())["channel"]
    assert channel["propagation"] == TWO_RAY and channel["antenna_height_m"] == 2.0
    assert "range_m" not in channel and "path_loss_exponent" not in channel


def test_netsim_config_shows_and_explains_the_user_models_keys():
    """``netsim config`` lists a chosen user model's keys with their meaning, ready to edit."""
    code, out, err = cli("config", *sets(*SMALL, f"channel.propagation={TWO_RAY}", f"channel.mac={TDMA}"))
    assert code == 0, err
    channel = tomllib.loads(out)["channel"]
    assert channel["antenna_height_m"] == 1.5 and channel["tdma_slot_s"] == 0.002
    assert "height of every antenna above the ground" in out and "length of a slot" in out


@pytest.mark.parametrize(
    "override, key",
    [
        ("channel.antenna_height_m=-1", "channel.antenna_height_m"),
        ("channel.frequency_hz=0", "channel.frequency_hz"),
        ("channel.tdma_slot_s=0", "channel.tdma_slot_s"),
        ("channel.tdma_slots=10000", "channel.tdma_slots"),
    ],
)
def test_a_bad_value_of_a_user_models_key_is_one_line_exit_2_nothing_written(tmp_path, override, key):
    """A bad value of a user model's key (its own check or its Params' check): exit
    status 2, one line naming the key, no run directory."""
    out = tmp_path / "r"
    models = sets(f"channel.propagation={TWO_RAY}", f"channel.mac={TDMA}", override)
    code, _, err = cli("run", *sets(*SMALL), *models, "--out", out, "--quiet")
    assert code == 2
    assert err.count("\n") == 1 and key in err
    assert not out.exists()


def test_a_user_model_that_does_not_load_is_one_line_exit_2(tmp_path):
    """A user model named by a path that does not hold one: one line naming the key."""
    out = tmp_path / "r"
    code, _, err = cli("run", *sets(*SMALL, "channel.mac=tests.tdma_plugin:NOTHING"), "--out", out, "--quiet")
    assert code == 2 and err.count("\n") == 1 and "channel.mac" in err
    assert not out.exists()


@pytest.mark.parametrize(
    ("key", "name", "said"),
    [
        ("propagation", "netsim.radio.loss:BERNOULLI", "is a LossModel (of netsim.loss), not a PropagationModel"),
        ("loss_model", "netsim.radio.propagation_models:UNIT_DISK", "is a PropagationModel (of netsim.propagation)"),
    ],
)
def test_a_channel_model_of_another_kind_is_one_line_exit_2(tmp_path, key, name, said):
    """A channel model named under another model's key (a loss model as the propagation) is
    refused naming the key and both kinds, before anything is written (its calls failed
    with a traceback midway through the build)."""
    out = tmp_path / "o"
    code, _, err = cli("run", *sets(*SMALL, f"channel.{key}={name}"), "--out", out, "--quiet")
    assert code == 2 and err.count("\n") == 1, err
    assert f"channel.{key}" in err and said in err
    assert not out.exists()


def test_a_user_mac_sends_each_frame_in_its_senders_slot():
    """Under TDMA every frame goes on the air at the start of its sender's own slot: each
    delivery comes one latency after such a start, and every frame handed over is sent."""
    config = cfgmod.load(None, [*SMALL, f"channel.mac={TDMA}", "channel.tdma_slot_s=0.005"])
    sim = build(config)
    arrivals = []
    sim.events.on("delivery", lambda d: arrivals.append((d.t_s, d.sender)))
    sim.run()
    assert len(arrivals) > 50
    cycle_s = 0.005 * 12
    for t_s, sender in arrivals:
        on_air = t_s - config.channel.latency_s
        phase = on_air / cycle_s - math.floor(on_air / cycle_s + 1e-6)
        assert phase * 12 == pytest.approx(sender, abs=1e-6)
    medium = sim.channel.mac
    assert int(medium.frames_sent.sum()) == int(sim.channel.counters["ack"].sent.sum())


def test_the_cli_runs_a_user_mac_and_writes_its_table(tmp_path):
    """``netsim run`` with TDMA writes the medium's own table and its summary figures."""
    out = tmp_path / "r"
    code, _, err = cli("run", *sets(*SMALL, f"channel.mac={TDMA}"), "--out", out, "--quiet")
    assert code == 0, err
    import json

    import pandas as pd

    medium = pd.read_parquet(out / "medium.parquet")
    assert list(medium.columns) == ["robot", "frames_sent"] and medium["frames_sent"].sum() > 0
    assert json.loads((out / "summary.json").read_text())["mac"] == "tdma"


@pytest.mark.slow
def test_a_sweep_varies_the_user_models_keys(tmp_path):
    """A sweep takes a user model's key as an axis: a higher antenna reaches farther
    (more links), a longer TDMA slot delays the Acks (fewer sent in the run)."""
    sweep = sweepmod.parse(
        {
            "name": "radio",
            "base": {
                "world": {"n_robots": 12, "side_m": 200.0},
                "duration_s": 20.0,
                "protocol": {"model": "ack"},
                "channel": {"propagation": TWO_RAY, "mac": TDMA},
                "output": {"position_interval_s": 0.0},
            },
            "grid": {"channel.antenna_height_m": [1.0, 1.5], "channel.tdma_slot_s": [0.002, 0.2]},
        }
    )
    report = sweepmod.run_sweep(sweep, tmp_path, workers=1, progress=False)
    assert report.done == 4 and not report.failed
    runs = sweepmod.load(tmp_path)
    by_height = runs.groupby("channel.antenna_height_m")["implied_range_m"].first()
    assert by_height[1.0] < by_height[1.5]
    by_slot = runs.groupby("channel.tdma_slot_s")["tdma_frames"].sum()
    assert by_slot[0.2] < by_slot[0.002]


def test_a_user_loss_model_drops_what_it_says():
    """A user's loss model (tests/loss_plugin.py) is the channel's: receptions beyond its
    edge are dropped as ``loss``, those within kept, and its key is a key of [channel]."""
    loss = "tests.loss_plugin:PLUGIN"
    config = cfgmod.load(None, [*SMALL, f"channel.loss_model={loss}", "channel.edge_fraction=0.5"])
    assert cfgmod.to_dict(config)["channel"]["edge_fraction"] == 0.5
    sim = build(config)
    kept = sim.channel.survives(0, np.array([1, 2, 3]), np.array([10.0, 75.0, 76.0]))
    assert kept.tolist() == [True, True, False]  # channel.range_m = 150
    result = execute(config)
    assert result.summary["acks_dropped_loss"] > 0 and result.summary["acks_received"] > 0


def test_a_user_loss_model_is_handed_a_numpy_generator_on_the_channels_loss_stream():
    """A plugin's ``rng`` is a numpy Generator (a library may take it, a model may bind its
    methods once): the channel's stream ``channel.loss``, shared by every kind of frame. The
    built-in models draw each kind from its own stream instead."""
    from netsim.rng import KindStreams, stream

    config = cfgmod.load(None, [*SMALL, "channel.loss_model=tests.loss_plugin:COIN"])
    sim = build(config)
    model = sim.channel.survives.survives  # inside the check of a plugin's answers
    expected = stream(config.seed, 0, "channel.loss").random(3)
    assert model.random(3).tolist() == expected.tolist()
    assert sim.channel.loss_rng is None
    builtin = build(cfgmod.load(None, [*SMALL, "channel.loss_probability=0.1"])).channel
    assert isinstance(builtin.loss_rng, KindStreams) and builtin.survives.rng is builtin.loss_rng


@pytest.mark.slow
def test_the_engine_compares_against_no_channel_model_name():
    """No comparison in the engine (netsim/ but its tools) or the protocols names a
    built-in channel model: what a model does is asked of its declaration, so a user's
    model is never treated otherwise than a built-in one."""
    import ast
    from pathlib import Path

    from netsim import plugins
    from netsim.radio.models import LOSS, MAC, PROPAGATION

    root = Path(__file__).resolve().parents[1]
    built_in = {name for group in (PROPAGATION, LOSS, MAC) for name in plugins.available(group)}
    assert {"unit_disk", "log_distance", "none", "aloha", "csma", "bernoulli"} <= built_in
    files = [f for f in (root / "netsim").rglob("*.py") if "tools" not in f.parts]
    files += list((root / "protocols").rglob("*.py"))
    found = []
    for f in files:
        for node in ast.walk(ast.parse(f.read_text())):
            if isinstance(node, ast.Compare):
                operands = [node.left, *node.comparators]
                names = {o.value for o in operands if isinstance(o, ast.Constant) and isinstance(o.value, str)}
                if names & built_in:
                    found.append((f.relative_to(root), node.lineno))
    assert found == []


@pytest.mark.parametrize(
    "answer, got",
    [
        ("np.full(len(receivers), 1.5)", "not an array of dtype float64 and shape ("),
        ("np.zeros(len(receivers), dtype=int)", "not an array of dtype int64 and shape ("),
        ("np.ones(len(receivers) - 1, dtype=bool)", "not an array of dtype bool and shape ("),
        ("[True] * len(receivers)", "not an object of type list"),
    ],
)
def test_a_user_loss_model_answering_other_than_a_mask_is_refused_naming_it(tmp_path, monkeypatch, answer, got):
    """A user's loss model whose answer is not None or one bool a receiver (a probability, an
    integer array read as indices, a short mask, a list) is refused naming
    channel.loss_model: it was taken as it was, and the counts went wrong without a word."""
    from netsim.errors import ConfigError

    module = f"bad_loss_{abs(hash(answer))}"
    (tmp_path / f"{module}.py").write_text(
        "import numpy as np\n"
        "from netsim.params import Params\n"
        "from netsim.radio.models import LossModel\n"
        "def survives(sender, receivers, distances_m):\n"
        f"    return {answer}\n"
        "PLUGIN = LossModel(Params, lambda params, range_m, rng: survives)\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    config = cfgmod.load(None, [*SMALL, f"channel.loss_model={module}:PLUGIN"])
    refused = rf"^channel.loss_model = '{module}:PLUGIN': .*must return None or a bool array"
    with pytest.raises(ConfigError, match=refused) as e:
        execute(config)
    assert got in str(e.value)


def test_a_mac_without_airtime_is_refused_when_named(tmp_path, monkeypatch):
    """A plugin with a MAC's Params and build but no airtime_s (the docs' mobility model, a
    PluginSpec) is refused as not a MacModel when named (it passed, then the protocol's
    check failed with a traceback)."""
    from netsim.errors import ConfigError

    (tmp_path / "not_a_mac.py").write_text(
        "from netsim.params import NoParams\n"
        "from netsim.plugins import PluginSpec\n"
        "MAC = PluginSpec(Params=NoParams, build=lambda params, parts: None)\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(ConfigError, match=r"is not a MacModel \(an object with Params, build, airtime_s\)"):
        cfgmod.load(None, [*SMALL, "channel.mac=not_a_mac:MAC"])


def test_a_user_loss_model_is_still_reachable_through_the_channel():
    """The check around a user's loss model hands on its attributes (a Python user reads
    the model's own figures through sim.channel.survives) and takes an empty answer when
    there is nobody to decide for."""
    from netsim.radio.loss import CheckedLoss

    class Counting:
        calls = 0

        def __call__(self, sender, receivers, distances_m):
            self.calls += 1
            return np.array([True] * len(receivers)) if len(receivers) else np.array([])

    checked = CheckedLoss(Counting(), "mine:COUNTING")
    assert checked(0, np.array([1, 2]), None).tolist() == [True, True]
    assert checked(0, np.array([], dtype=np.int64), None).tolist() == []
    assert checked.calls == 2


def test_a_medium_without_airtime_is_refused_when_named(tmp_path, monkeypatch):
    """A MacModel with a build but airtime_s None (None means no medium) is refused in one
    line: the protocols' airtime checks would have been skipped without a word."""
    from netsim.errors import ConfigError

    (tmp_path / "half_mac.py").write_text(
        "from netsim.radio.models import MacModel, NoMacParams\n"
        "MAC = MacModel(NoMacParams, build=lambda params, channel, rng, power: None)\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(ConfigError, match=r"^channel.mac = 'half_mac:MAC': is a medium .* without airtime_s"):
        cfgmod.load(None, [*SMALL, "channel.mac=half_mac:MAC"])


@pytest.mark.parametrize(
    "answer, said", [("np.full(len(pairs.a), np.nan)", "gave NaN"), ("np.zeros(2)", "gave shape (2,)")]
)
def test_a_user_loss_term_giving_nan_or_the_wrong_shape_is_refused(tmp_path, monkeypatch, answer, said):
    """A propagation term of a user's whose loss is NaN (every frame went unheard without a
    word) or of the wrong shape (a broadcasting traceback) is refused in one line naming
    channel.propagation."""
    from netsim.errors import NetsimInputError

    module = f"bad_term_{len(said)}"
    (tmp_path / f"{module}.py").write_text(
        "import numpy as np\n"
        "from tests.two_ray_plugin import PLUGIN as TWO_RAY, TwoRayLoss\n"
        "from netsim.radio.models import PropagationModel\n"
        "from netsim.radio.propagation import LossChain, Propagation\n"
        "class Bad(TwoRayLoss):\n"
        "    def loss_db(self, pairs):\n"
        f"        return {answer}\n"
        "def make(params, range_m, occupancy, rng):\n"
        "    good = TWO_RAY.make(params, range_m, occupancy, rng)\n"
        "    return Propagation(LossChain(Bad(params)), good.radio, good.range_m, good.reach_m)\n"
        "PLUGIN = PropagationModel(TWO_RAY.Params, make, ranges=TWO_RAY.ranges, reach=TWO_RAY.reach)\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    config = cfgmod.load(None, [*SMALL, f"channel.propagation={module}:PLUGIN"])
    with pytest.raises(NetsimInputError, match=rf"^channel.propagation: Bad.loss_db {re.escape(said)}"):
        execute(config)


def test_a_shadowed_user_model_that_leaves_its_reach_unsaid_is_taken_at_its_range(tmp_path, monkeypatch):
    """A user's propagation model may say it is shadowed and leave its reach unsaid (None,
    the plugin contract's default): the configuration's check of a reach past any area
    takes its range then, and the run is built."""
    (tmp_path / "unsaid_reach.py").write_text(
        "import dataclasses\n"
        "from netsim.radio.propagation_models import LOG_DISTANCE\n"
        "PLUGIN = dataclasses.replace(LOG_DISTANCE, reach=lambda params: None)\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    config = cfgmod.load(None, [*SMALL, "channel.propagation=unsaid_reach:PLUGIN", "channel.shadowing_sigma_db=4"])
    assert config.channel.propagation_model.reach(config.channel.radio) is None
    assert build(config).channel is not None
