"""The ``[bridge]`` table's rules and ``netsim bridge``'s input checks (netsim.bridge.settings),
without DDS: each is refused in one line before a session starts, so a rule broken here
must fail at once rather than start a bridge of real time."""

import math

import pytest

from netsim.bridge.settings import BridgeSettings, Relay, check_rate, commented, load, settings
from netsim.errors import ConfigError, NetsimInputError
from netsim.tools.cli import main

# The long run's keys a test of the stamp limit needs, so that nothing else refuses it first.
LONG_RUN = ["mobility.model=external", "protocol.model=none", "output.position_interval_s=0", "bridge.odom_hz=1e-9"]


def refused(raw: dict, message: str) -> None:
    with pytest.raises(ConfigError) as caught:
        settings(raw)
    assert str(caught.value) == message


def test_an_empty_table_is_domain_zero_at_ten_steps_a_second():
    got = settings({})
    assert got == BridgeSettings(0, 10.0, ()) and got.domain_id == 0 and got.odom_hz == 10.0


def test_a_negative_domain_is_refused():
    refused({"domain_id": -1}, "bridge.domain_id = -1: must be an integer from 0 to 232")


def test_a_fractional_domain_is_refused():
    refused({"domain_id": 1.5}, "bridge.domain_id = 1.5: must be an integer from 0 to 232")


@pytest.mark.parametrize("hz", [0, 0.0, -1.0, math.inf, math.nan, True])
def test_odom_hz_must_be_a_positive_finite_number(hz):
    with pytest.raises(ConfigError, match="^bridge.odom_hz = .*: must be a positive number, Hz$"):
        settings({"odom_hz": hz})


def test_an_integer_odom_hz_is_written_as_a_number_of_hz():
    got = settings({"odom_hz": 10})
    assert isinstance(got.odom_hz, float)
    assert "\nodom_hz = 10.0\n" in commented(got)


def test_an_unknown_bridge_key_is_refused_naming_the_allowed_ones():
    refused({"rate_hz": 10}, "bridge.rate_hz = 10: unknown key; allowed: domain_id, odom_hz, relay")


def test_relay_must_be_a_list_of_tables():
    refused({"relay": "chat"}, "bridge.relay = 'chat': must be a list of tables [[bridge.relay]]")


@pytest.mark.parametrize(
    "entry",
    [{"name": "chat"}, {"name": "chat", "type": "std_msgs/msg/String", "qos": "reliable"}],
    ids=["type_missing", "extra_key"],
)
def test_a_relay_entry_is_exactly_a_name_and_a_type(entry):
    with pytest.raises(ConfigError, match=r"^bridge.relay\[0\] = .*: must be a table \{name"):
        settings({"relay": [entry]})


@pytest.mark.parametrize("name", ["chat!", "9chat", "chat/", "/chat", "a//b", ""])
def test_a_relayed_name_is_a_topic_name_from_a_letter(name):
    with pytest.raises(ConfigError, match=r"^bridge.relay\[0\].name = .*: must be a topic name"):
        settings({"relay": [{"name": name, "type": "std_msgs/msg/String"}]})


def test_a_relayed_name_may_have_levels():
    got = settings({"relay": [{"name": "team/chat_2", "type": "std_msgs/msg/String"}]})
    assert got.relay == (Relay("team/chat_2", "std_msgs/msg/String"),)


def test_a_short_relay_type_is_kept_as_pkg_msg_type():
    got = settings({"relay": [{"name": "chat", "type": "std_msgs/String"}]})
    assert got.relay == (Relay("chat", "std_msgs/msg/String"),)
    assert 'type = "std_msgs/msg/String"' in commented(got)


def test_a_topic_is_relayed_once():
    entry = {"name": "chat", "type": "std_msgs/msg/String"}
    refused({"relay": [entry, dict(entry)]}, "bridge.relay = ['chat', 'chat']: each topic name may be relayed once")


@pytest.mark.parametrize("rate", [0.0, -2.0, math.inf, math.nan])
def test_rate_must_be_a_positive_finite_number(rate):
    with pytest.raises(NetsimInputError, match="must be a positive number of simulated seconds per wall second"):
        check_rate(rate)


def test_the_bridge_moves_only_external_robots():
    with pytest.raises(ConfigError, match="^mobility.model = 'random_waypoint': the bridge moves robots"):
        load(None, ["mobility.model=random_waypoint"])


def test_too_many_bridge_steps_are_refused():
    with pytest.raises(ConfigError, match="^bridge.odom_hz = 1000000000.0: the run would make"):
        load(None, ["mobility.model=external", "bridge.odom_hz=1e9"])


def test_a_run_of_two_to_the_31_seconds_is_past_a_stamp():
    with pytest.raises(ConfigError, match="^duration_s = 2147483648.0: the bridge stamps its messages"):
        load(None, [*LONG_RUN, "duration_s=2147483648"])
    config, _ = load(None, [*LONG_RUN, "duration_s=2147483647"])
    assert config.duration_s == 2**31 - 1


def test_printed_configuration_of_a_run_scenario_has_its_bridge_table_commented_out(tmp_path, capsys):
    """A scenario with no [bridge] table is a run's: `netsim config` lists the bridge's keys
    as comments, so the printed file stays a run's scenario."""
    (tmp_path / "run.toml").write_text("duration_s = 10\n")
    assert main(["config", str(tmp_path / "run.toml")]) == 0
    out = capsys.readouterr().out
    assert "\n# [bridge]\n" in out and "\n[bridge]" not in out
