"""One source of defaults and closed choices: a configuration made in Python, from a file
or with --set is the same object, validated when made; derived defaults are derived
wherever it is made; an unknown name is an error everywhere."""

import numpy as np
import pytest
from netsim.protocols.clustering import rules_record
from netsim.protocols.stack import ClusteringParams

from netsim import config as cfgmod
from netsim.config import Config, ProtocolSection, WorldParams
from netsim.errors import ConfigError
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
