"""One source of defaults and closed choices: a configuration made in Python, from a file
or with --set is the same object, validated when made; derived defaults are derived
wherever it is made; an unknown name is an error everywhere."""

import enum
from dataclasses import dataclass

import numpy as np
import pytest
from netsim.protocols.clustering import rules_record
from netsim.protocols.stack import ClusteringParams

from netsim import config as cfgmod
from netsim.config import Config, ProtocolSection, WorldParams
from netsim.errors import ConfigError
from netsim.params import MAX_EVENTS_PER_RUN, Params, check_schedules, describe, param, plain, positive
from netsim.plugins import resolve
from netsim.radio.models import LOSS


def test_a_derived_default_is_derived_however_the_configuration_is_made(tmp_path):
    in_python = Config(protocol=ProtocolSection("clustering", ClusteringParams(ack_period_s=2.0)))
    f = tmp_path / "s.toml"
    f.write_text("[protocol]\nack_period_s = 2.0\n")
    from_file = cfgmod.load(f)
    from_set = cfgmod.load(None, ["protocol.ack_period_s=2.0"])
    assert in_python.protocol.tau_s == from_file.protocol.tau_s == from_set.protocol.tau_s == 6.0
    assert in_python.protocol.merge_delay_s == from_file.protocol.merge_delay_s == 4.0
    assert in_python == from_file == from_set


def test_replace_derives_again_what_was_derived_and_keeps_what_was_given():
    again = cfgmod.from_dict({}).replace(protocol={"ack_period_s": 5.0})
    assert again.protocol.tau_s == 15.0
    given = cfgmod.from_dict({"protocol": {"tau_s": 4.0}}).replace(protocol={"ack_period_s": 2.0})
    assert given.protocol.tau_s == 4.0
    assert ClusteringParams(ack_period_s=1.0).replace(ack_period_s=3.0).tau_s == 9.0


def test_numpy_numbers_are_the_python_numbers_they_hold():
    """A value computed with numpy (``np.int64``, ``np.float32``, ``np.bool_``) is taken as the
    int, float or bool it holds, and stored as one; a bool is still no number."""
    world = WorldParams(n_robots=np.int64(7), side_m=np.float32(250.0), torus=np.bool_(True))
    assert (world.n_robots, world.side_m, world.torus) == (7, 250.0, True)
    assert [type(v) for v in (world.n_robots, world.side_m, world.torus)] == [int, float, bool]
    for value in (np.bool_(True), True, 7.0):
        with pytest.raises(ConfigError, match="world.n_robots = .*: must be an integer"):
            WorldParams(n_robots=value)


def test_a_bad_value_is_refused_when_the_object_is_made():
    with pytest.raises(ConfigError) as err:
        WorldParams(n_robots=-3)
    assert err.value.key == "world.n_robots"
    with pytest.raises(ConfigError, match="protocol.tau_s"):
        ClusteringParams(ack_period_s=2.0, tau_s=1.0)


@pytest.mark.parametrize(
    "refused, taken, key",
    [
        ({"ack_period_s": 2.0, "tau_s": 2.0}, {"ack_period_s": 2.0, "tau_s": 2.000001}, "protocol.tau_s"),
        (
            {"ack_period_s": 1.0, "ack_jitter_s": 0.5},
            {"ack_period_s": 1.0, "ack_jitter_s": 0.499999},
            "protocol.ack_jitter_s",
        ),
    ],
)
def test_the_ack_timings_bounds_are_strict_when_the_params_are_made(refused, taken, key):
    """tau must exceed the Ack period, and the jitter stay below half of it, already when
    the parameters are made (docs/model.md 4): a tau equal to the period, or a jitter of
    exactly half, is refused; a hair inside either is taken."""
    with pytest.raises(ConfigError) as err:
        ClusteringParams(**refused)
    assert err.value.key == key
    ClusteringParams(**taken)


@pytest.mark.parametrize(
    "overrides, key, words",
    [
        # The longest gap between two Acks without loss, 1 + 0.25 + 0.5 s, is not enough.
        (
            ["protocol.ack_jitter_s=0.25", "channel.latency_jitter_s=0.5", "protocol.tau_s=1.75"],
            "protocol.tau_s",
            "= 1.75",
        ),
        # 64 bytes at 512 b/s without a preamble: an Ack occupies the air for exactly a period.
        (
            ["channel.mac='csma'", "channel.preamble_s=0", "channel.data_rate_bps=512", "protocol.ack_bytes=64"],
            "channel.data_rate_bps",
            "an airtime of 1 s: must be shorter than protocol.ack_period_s = 1",
        ),
    ],
)
def test_the_ack_timings_limits_against_the_channel_are_strict(overrides, key, words):
    """tau must exceed the longest gap between two Acks without loss, and an Ack's airtime
    on a shared medium must be shorter than the Ack period: equal to either is refused."""
    with pytest.raises(ConfigError) as err:
        cfgmod.load(None, overrides)
    assert err.value.key == key and words in str(err.value)


@pytest.mark.parametrize(
    "key, value",
    [
        ("protocol.join_policy", "neerest"),
        ("protocol.merge_policy", "biggest"),
        ("protocol.election_policy", "oldest"),
        ("protocol.routing", "flood"),
        ("channel.loss_model", "rayleigh"),
        ("coverage.law", "gravity"),
        ("coverage.members", "scatter"),
        ("mobility.model", "levy_walk"),
    ],
)
def test_an_unknown_choice_is_a_config_error_naming_what_is_allowed(key, value):
    with pytest.raises(ConfigError) as err:
        cfgmod.load(None, [f'{key}="{value}"'])
    assert err.value.key == key and value in str(err.value)


def test_a_policy_name_is_checked_where_it_is_used_too():
    with pytest.raises(ValueError):
        rules_record(3.0, 1.0, False, "neerest", "lowest_id")
    with pytest.raises(ValueError):
        rules_record(3.0, 1.0, False, "nearest", "lowest")
    with pytest.raises(ConfigError):
        resolve(LOSS, "rayleigh", "channel.loss_model")


# -- rules a mutation audit found no test for ------------------------------------------------
@pytest.mark.parametrize(
    "tree, words",
    [
        ({"protocol": {"model": "aodv", "ttl_start": 256}}, "protocol.ttl_start = 256: must be in 1 .. 255"),
        ({"protocol": {"model": "aodv", "ttl_start": 0}}, "protocol.ttl_start = 0: must be in 1 .. 255"),
        ({"channel": {"max_frame_bytes": 2**31}}, f"channel.max_frame_bytes = {2**31}: must be in 1 .. {2**31 - 1}"),
        # The rule and the key's meaning: not the speed of light's limit, which an infinity also breaks.
        ({"mobility": {"speed_max_mps": float("inf")}}, "mobility.speed_max_mps = inf: must be a finite speed >= 0 "),
        ({"channel": {"range_m": True}}, "channel.range_m = true: must be a number$"),
        ({"channel": {"range_m": 10**400}}, "channel.range_m = 1000.*: is too large for a number$"),
        ({"mobility": {"model": "trace", "trace_file": 5}}, "mobility.trace_file = 5: must be a string$"),
        ({"world": {"n_robots": -3}}, r"^world.n_robots = -3: must be > 0 \(number of robots N\)$"),
    ],
)
def test_a_value_out_of_its_keys_range_or_type_is_named_with_the_rule(tree, words):
    with pytest.raises(ConfigError, match=words):
        cfgmod.from_dict(tree)


def test_the_widest_ttl_and_frame_are_accepted():
    config = cfgmod.from_dict({"protocol": {"model": "aodv", "ttl_start": 1, "net_diameter": 255}})
    assert (config.protocol.ttl_start, config.protocol.net_diameter) == (1, 255)
    assert cfgmod.from_dict({"channel": {"max_frame_bytes": 2**31 - 1}}).channel.max_frame_bytes == 2**31 - 1


def test_a_relative_file_key_is_made_absolute(tmp_path, monkeypatch):
    """A run directory's config.toml finds the file from anywhere."""
    monkeypatch.chdir(tmp_path)
    config = cfgmod.from_dict({"mobility": {"model": "trace", "trace_file": "moves.tcl"}})
    assert config.mobility.trace_file == str(tmp_path / "moves.tcl")


@dataclass(frozen=True)
class _Scheduled(Params):
    section = "s"
    rate_hz: float = param(1.0, positive, "events a second", schedules="run")
    period_s: float = param(1.0, positive, "time between a robot's events", schedules="robot")
    names: tuple = param(None, default_factory=lambda: ("a", "b"), kind=tuple, coerce=lambda key, value: tuple(value))


def test_the_event_limit_is_the_most_events_allowed():
    limit = float(MAX_EVENTS_PER_RUN)
    check_schedules(_Scheduled(rate_hz=1.0), duration_s=limit, n_robots=1)
    with pytest.raises(
        ConfigError, match=r"^s.rate_hz = 2.0: the run would make 2e\+08 events .*; lower it, or lower duration_s$"
    ):
        check_schedules(_Scheduled(rate_hz=2.0), duration_s=limit, n_robots=1)
    with pytest.raises(
        ConfigError, match=r"^s.period_s = 0.5: 1 robots each would make .*; raise it, or lower duration_s or"
    ):
        check_schedules(_Scheduled(rate_hz=1e-9, period_s=0.5), duration_s=limit, n_robots=1)


def test_a_keys_default_made_by_a_factory_is_described():
    """`netsim config` shows a plugin's list default, not none."""
    assert ("names", ("a", "b"), "", "") in describe(_Scheduled)


class _Colour(enum.Enum):
    RED = "red"
    BLUE = "blue"


def test_a_tuple_of_choices_is_written_as_a_list_of_names():
    """Nested tuples too: TOML cannot write a choice's object."""
    assert plain(((_Colour.RED, _Colour.BLUE),)) == [["red", "blue"]]
