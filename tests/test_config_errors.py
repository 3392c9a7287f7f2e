"""Every configuration error: one clear line naming key, value and what is allowed;
exit status 2; no traceback; nothing written to the output directory."""

import subprocess
import sys
import textwrap

import pytest

from netsim import config as cfgmod
from netsim.errors import ConfigError
from netsim.tools.cli import main


@pytest.mark.parametrize(
    "override, key, words",
    [
        ("channel.range_m=-5", "channel.range_m", "> 0"),
        ("world.n_robots=0", "world.n_robots", "> 0"),
        ("protocol.tau_s=1.0", "protocol.tau_s", "greater than protocol.ack_period_s"),
        # The longest gap between two Acks without loss is period + jitter + latency jitter.
        ("protocol.tau_s=1.01", "protocol.tau_s", "protocol.ack_jitter_s + channel.latency_jitter_s = 1.05"),
        ("channel.latency_jitter_s=2.5", "protocol.tau_s", "= 3.55"),
        ("mobility.speed_min_mps=6", "mobility.speed_min_mps", "must not exceed"),
        ("channel.latency_s=nan", "channel.latency_s", "NaN"),
        ("world.n_robotz=5", "world.n_robotz", "unknown key"),
        ("colour=5", "colour", "unknown key"),
        ("world.n_robots=2.5", "world.n_robots", "integer"),
        ("world.torus=1", "world.torus", "true or false"),
        ("channel.loss_probability=1.5", "channel.loss_probability", "probability"),
        ("channel.loss_model=rayleigh", "channel.loss_model", "one of"),
        ("protocol.ack_jitter_s=0.6", "protocol.ack_jitter_s", "half"),
        ("channel.range_m=[1.0, 2.0]", "channel.range_m", "one range per robot"),
        ("mobility.model=trace", "mobility.trace_file", "must name a file"),
        ("duration_s=inf", "duration_s", "finite"),
        ("coverage.expansion=inf", "coverage.expansion", "finite"),
        # Accepted, these hung a run (a message rate) or ended it in NaN velocities.
        ("protocol.message_rate_hz=inf", "protocol.message_rate_hz", "finite"),
        ("coverage.gain=inf", "coverage.gain", "(0, 1e6]"),
        ("coverage.speed_max_mps=inf", "coverage.speed_max_mps", "finite"),
        ("coverage.control_period_s=inf", "coverage.control_period_s", "finite"),
        # Accepted, an infinite disk covered the whole area, whatever the team did.
        ("coverage.radius_m=inf", "coverage.radius_m", "finite"),
        # A grid past memory (an allocation's traceback).
        ("coverage.grid_cells=4001", "coverage.grid_cells", "must be at most 4,000"),
    ],
)
def test_bad_value_names_key_value_and_rule(override, key, words):
    with pytest.raises(ConfigError) as err:
        cfgmod.load(None, [override])
    assert err.value.key == key
    assert words in str(err.value)


@pytest.mark.parametrize(
    "model, key",
    [("olsr", "protocol.start_spread_s"), ("aodv", "protocol.message_rate_hz"), ("aodv", "protocol.jitter_s")],
)
def test_a_routing_protocols_infinite_timing_is_refused(model, key):
    """An infinite start spread (a traceback of numpy's uniform draw) or message rate (a
    run that never ends) is refused when the configuration is made."""
    with pytest.raises(ConfigError) as err:
        cfgmod.load(None, [f'protocol.model="{model}"', f"{key}=inf"])
    assert err.value.key == key and "must be finite" in str(err.value)


@pytest.mark.parametrize(
    "override, said",
    [
        ("mobility.speed_maxx_mps=3", "unknown key (did you mean 'speed_max_mps'?); allowed: "),
        ("world.n_robot=3", "unknown key (did you mean 'n_robots'?); allowed: "),
        ("world.colour=3", "unknown key; allowed: "),
        ("channel.shadowing_sigma=3", "unknown key (did you mean 'shadowing_sigma_db'?); allowed: "),
        ("mobility.trace_fil=3", "unknown key (did you mean 'trace_file'?); allowed: "),
    ],
)
def test_a_misspelt_key_is_named_with_the_closest_key(override, said):
    """An unknown key close to a known one says which one it may be; one close to none
    lists the keys alone."""
    with pytest.raises(ConfigError) as err:
        cfgmod.load(None, [override])
    assert said in str(err.value)


@pytest.mark.parametrize(
    "override, mine, other",
    [
        ("channel.rangee_m=3", "range_m", "shadowing_sigma_db"),
        ("mobility.speed_maxx=3", "speed_max_mps", "trace_file"),
    ],
)
def test_an_unknown_key_lists_the_keys_of_the_other_models_apart(override, mine, other):
    """The keys a section takes with another model (taken, and ignored with a warning,
    under this one) are listed apart from the chosen model's: a user reading the list for
    shadowing_sigma_db under the unit disk finds it there."""
    with pytest.raises(ConfigError) as err:
        cfgmod.load(None, [override])
    said = str(err.value)
    allowed, _, others = said.partition("; with another model: ")
    assert mine in allowed.split("allowed: ")[1].split(", ") and mine not in others.split(", ")
    assert other in others.split(", ") and other not in allowed


def test_a_truth_value_in_an_error_is_spelt_as_in_the_file():
    """``coverage.enabled = true``, as TOML writes it, not Python's ``True``."""
    with pytest.raises(ConfigError) as err:
        cfgmod.load(None, ["coverage.enabled=true", "mobility.model=random_waypoint"])
    assert str(err.value).startswith("coverage.enabled = true: needs mobility.model = 'static'"), err.value


def test_config_file_values_and_overrides(tmp_path):
    f = tmp_path / "s.toml"
    f.write_text("seed = 4\n[world]\nn_robots = 7\n[mobility]\nspeed_max_mps = 3\nstationary_start = false\n")
    c = cfgmod.load(f, ["mobility.speed_max_mps=10", "world.placement=grid"])
    assert (c.seed, c.world.n_robots, c.mobility.speed_max_mps, c.world.placement) == (4, 7, 10.0, "grid")


def test_a_rule_across_sections_is_checked_when_the_configuration_is_loaded():
    # Random waypoint's stationary start draws positions itself: refused before any run.
    with pytest.raises(ConfigError, match="world.placement"):
        cfgmod.load(None, ["world.placement=grid", "mobility.stationary_start=true"])


def test_resolved_config_round_trips():
    c = cfgmod.load(
        None,
        ["channel.range_m=[10.0, 20.0]", "world.n_robots=2", "mobility.model=random_direction"]
        + ["mobility.turn_interval_s=inf"],
    )
    import tomllib

    import tomli_w

    again = cfgmod.from_dict(tomllib.loads(tomli_w.dumps(cfgmod.to_dict(c))))
    assert again == c


def _cli(tmp_path, capsys, *args):
    code = main(["run", "--quiet", "--out", str(tmp_path / "out"), *args])
    err = capsys.readouterr().err
    return code, err


@pytest.mark.parametrize(
    "args, fragment",
    [
        (["--set", "channel.range_m=-5"], "channel.range_m = -5.0"),
        (
            ["--set", 'events.hooks=["link_breaks", "link_breaks"]'],
            "events.hooks = ['link_breaks', 'link_breaks']: names 'link_breaks' twice: each plugin runs once",
        ),
        (
            ["--set", "mobility.model=trace", "--set", 'mobility.topics=["/a/odom", "/b/odom", "/a/odom"]'],
            "mobility.topics = ['/a/odom', '/b/odom', '/a/odom']: names '/a/odom' twice",
        ),
        (
            ["--set", "mobility.model=trace", "--set", 'mobility.trace_file="  "'],
            "mobility.trace_file = '  ': must be the path of a movement file or a rosbag2 folder",
        ),
        (
            ["--set", "mobility.model=trace", "--set", 'mobility.trace_file="a\\nb.tcl"'],
            "mobility.trace_file = 'a\\nb.tcl': must be the path",
        ),
        (["--set", "duration_s"], "--set = 'duration_s': must look like key=value or section.key=value"),
        (["--set", "world..n_robots=3"], "must look like key=value or section.key=value"),
        (["--set", "world.n_robots=0"], "world.n_robots = 0"),
        (["--set", "protocol.tau_s=0.5"], "protocol.tau_s = 0.5"),
        (["--set", "protocol.tau_s=1.04"], "protocol.tau_s = 1.04: must be greater than protocol.ack_period_s"),
        (["--set", "mobility.speed_min_mps=9"], "mobility.speed_min_mps = 9.0"),
        (["--set", "channel.range_m=nan"], "channel.range_m = nan"),
        (["--set", "world.sides=3"], "world.sides"),
        (["--set", "mobility.model=trace", "--set", "mobility.trace_file=/nonexistent/x.tcl"], "no such file"),
        (
            ["--set", "world.placement=/nonexistent/p.csv", "--set", "mobility.stationary_start=false"],
            "world.placement",
        ),
        (["--set", "mobility.model=warp"], "mobility.model = 'warp'"),
        # The shared medium's keys (channel.mac, docs/radio.md).
        (["--set", "channel.mac=tdma"], "channel.mac = 'tdma'"),
        (["--set", "channel.mac=csma", "--set", "channel.data_rate_bps=0"], "channel.data_rate_bps = 0.0"),
        (["--set", "channel.mac=csma", "--set", "channel.preamble_s=-1"], "channel.preamble_s = -1.0"),
        (
            ["--set", "channel.mac=csma", "--set", "channel.interference_range_m=-1"],
            "channel.interference_range_m = -1.0",
        ),
        (
            ["--set", "channel.mac=csma", "--set", "channel.range_m=100", "--set", "channel.interference_range_m=50"],
            "channel.interference_range_m = 50.0: must be at least the largest channel.range_m",
        ),
        (
            [
                "--set",
                "channel.mac=csma",
                "--set",
                "channel.propagation=log_distance",
                "--set",
                "channel.interference_range_m=10",
            ],
            "channel.interference_range_m = 10.0: must be at least the radio's reach",
        ),
        (["--set", "channel.mac=csma", "--set", "channel.queue_frames=0"], "channel.queue_frames = 0"),
        (["--set", "channel.mac=csma", "--set", "channel.slot_s=0"], "channel.slot_s = 0.0"),
        (["--set", "channel.mac=csma", "--set", "channel.difs_s=-1"], "channel.difs_s = -1.0"),
        (["--set", "channel.mac=csma", "--set", "channel.retry_limit=-1"], "channel.retry_limit = -1"),
        (["--set", "channel.mac=csma", "--set", "channel.cw_min=30"], "channel.cw_min = 30"),
        (["--set", "channel.mac=csma", "--set", "channel.cw_max=15"], "channel.cw_max = 15"),
        (
            ["--set", "channel.mac=csma", "--set", "channel.capture_threshold_db=nan"],
            "channel.capture_threshold_db = nan",
        ),
        (
            [
                "--set",
                "channel.mac=aloha",
                "--set",
                "channel.propagation=log_distance",
                "--set",
                "channel.noise_floor_dbm=-85",
            ],
            "channel.noise_floor_dbm = -85.0",
        ),
        # A square at the origin that is not world.side_m's: the message names the bounds.
        (
            ["--set", "world.bounds_m=[0,0,60,60]", "--set", "world.placement=centre"]
            + ["--set", "world.centre_side_m=100"],
            "world.centre_side_m = 100.0: must not exceed the area's shorter side (60 m, world.bounds_m)",
        ),
        # Levels whose mW a float cannot hold (10^(v / 10) overflows).
        (
            ["--set", "channel.mac=aloha", "--set", "channel.propagation=log_distance"]
            + ["--set", "channel.capture_threshold_db=1e5"],
            "channel.capture_threshold_db = 100000.0: must be at most 3000",
        ),
        (
            ["--set", "channel.mac=csma", "--set", "channel.propagation=log_distance"]
            + ["--set", "channel.noise_floor_dbm=1e308"],
            "channel.noise_floor_dbm = 1e+308: must be at most 3000",
        ),
        (["--set", "channel.mac=csma", "--set", "protocol.ack_bytes=0"], "protocol.ack_bytes = 0"),
        (["--set", "channel.mac=csma", "--set", "protocol.message_bytes=0"], "protocol.message_bytes = 0"),
        (
            ["--set", "channel.mac=csma", "--set", "channel.data_rate_bps=1"],
            "channel.data_rate_bps = 1.0: gives an Ack",
        ),
        (["/nonexistent/scenario.toml"], "scenario file = '/nonexistent/scenario.toml': no such file"),
        # Keys that schedule events (param(schedules=...)): at most MAX_EVENTS_PER_RUN each.
        (
            ["--set", "protocol.model=aodv", "--set", "protocol.hello_interval_s=1e-9"],
            "protocol.hello_interval_s = 1e-09: 50 robots each would make 1.5e+13 events",
        ),
        (["--set", "protocol.model=olsr", "--set", "protocol.tc_interval_s=1e-9"], "protocol.tc_interval_s = 1e-09"),
        (
            ["--set", "mobility.model=gauss_markov", "--set", "mobility.update_interval_s=1e-9"],
            "mobility.update_interval_s = 1e-09",
        ),
        (["--set", "protocol.message_rate_hz=1e12"], "protocol.message_rate_hz = 1000000000000.0: the run would make"),
        (
            [
                "--set",
                "protocol.model=greedy",
                "--set",
                "protocol.message_rate_hz=1",
                "--set",
                "protocol.message_bytes=1000000000000",
            ],
            "protocol.message_bytes = 1000000000000: the random pairs' messages would send 2e+11 frames in the run",
        ),
        (
            [
                "--set",
                "protocol.model=aodv",
                "--set",
                "protocol.message_rate_hz=1e-6",
                "--set",
                "protocol.message_bytes=1000000000000",
            ],
            "protocol.message_bytes = 1000000000000: the random pairs' messages would send 6.67e+08 frames",
        ),
        (["--set", "protocol.ack_period_s=1e-9"], "protocol.ack_period_s = 1e-09"),
        (
            [
                "--set",
                "coverage.enabled=true",
                "--set",
                "mobility.model=static",
                "--set",
                "coverage.metrics_interval_s=1e-9",
            ],
            "coverage.metrics_interval_s = 1e-09: the run would make 3e+11 events",
        ),
        (
            [
                "--set",
                "coverage.enabled=true",
                "--set",
                "mobility.model=static",
                "--set",
                "coverage.control_period_s=1e-9",
            ],
            "coverage.control_period_s = 1e-09",
        ),
        (
            ["--set", "mobility.model=gauss_markov", "--set", "mobility.direction_sigma_rad=1e308"],
            "mobility.direction_sigma_rad = 1e+308: must be in [0, 100] rad",
        ),
        (
            ["--set", "coverage.enabled=true", "--set", "mobility.model=static", "--set", "coverage.gain=1e308"],
            "coverage.gain = 1e+308: must be in (0, 1e6]",
        ),
        # Refused after a key was found ignored: the refusal alone, no warning before it.
        (
            [
                "--set",
                "channel.loss_model=gilbert_elliott",
                "--set",
                "channel.loss_probability=0.5",
                "--set",
                "world.map=office",
            ],
            "world.map = 'office': covers 200 m x 200 m",
        ),
        (
            ["--set", "protocol.model=greedy", "--set", "protocol.beacon_period_s=1e-7"],
            "protocol.beacon_period_s = 1e-07",
        ),
        (
            [
                "--set",
                "mobility.model=random_direction",
                "--set",
                "world.torus=true",
                "--set",
                "mobility.turn_interval_s=1e-7",
            ],
            "mobility.turn_interval_s = 1e-07",
        ),
        # The control loop's period, set by coverage's section, with another controller alone.
        (
            [
                "--set",
                'control.controllers=["log_separation"]',
                "--set",
                "coverage.control_period_s=2e-6",
                "--set",
                "channel.latency_s=1e-6",
                "--set",
                "duration_s=1000",
            ],
            "coverage.control_period_s = 2e-06: the run would make 5e+08 events",
        ),
        # A refusal of a scheduling key after an ignored key: the refusal alone.
        (
            [
                "--set",
                "channel.loss_model=gilbert_elliott",
                "--set",
                "channel.loss_probability=0.5",
                "--set",
                "protocol.message_rate_hz=1e12",
            ],
            "protocol.message_rate_hz = 1000000000000.0",
        ),
        # The local plan's lists of a release_s as long as the run, more than any machine holds.
        pytest.param(
            [
                "--set",
                "coverage.enabled=true",
                "--set",
                "mobility.model=static",
                "--set",
                "coverage.plan=local",
                "--set",
                "coverage.release_s=inf",
                "--set",
                "world.n_robots=3000",
                "--set",
                "duration_s=30000",
            ],
            "coverage.release_s = inf: the local plan would hold",
            marks=pytest.mark.slow,
        ),
        # A range so short that no link's events can be solved in a run's time.
        (["--set", "channel.range_m=1e-9"], "channel.range_m = 1e-09: is below 0.01 m"),
        # An area whose squares overflow (numpy's overflow warnings, then a run of infinities).
        (["--set", "world.side_m=1e300"], "world.side_m = 1e+300: must be in (0, 1e+12]"),
        (["--set", "channel.range_m=1e300"], "channel.range_m = 1e+300: must be at most 1e+12 m"),
        (
            [
                "--set",
                "channel.propagation=log_distance",
                "--set",
                "channel.path_loss_exponent=0.1",
                "--set",
                "channel.sensitivity_dbm=-200",
            ],
            "channel.propagation = 'log_distance': the radio's implied range, 1e+180 m, is above 1e+12 m",
        ),
        (
            [
                "--set",
                "channel.propagation=log_distance",
                "--set",
                "channel.path_loss_exponent=1",
                "--set",
                "channel.shadowing_sigma_db=20",
            ],
            "the radio's reach under its strongest shadowing, 1e+14 m, is above 1e+12 m",
        ),
        (
            [
                "--set",
                "coverage.enabled=true",
                "--set",
                'mobility.model="static"',
                "--set",
                "coverage.speed_max_mps=1e300",
            ],
            "coverage.speed_max_mps = 1e+300: must be in (0, 2.99792e+08]",
        ),
        (
            [
                "--set",
                "coverage.enabled=true",
                "--set",
                'mobility.model="static"',
                "--set",
                "coverage.control_period_s=1e300",
            ],
            "coverage.control_period_s = 1e+300: a step at coverage.speed_max_mps = 2 m/s would reach 2e+300 m",
        ),
        (["--set", "channel.range_m=[100, 1e13]", "--set", "world.n_robots=2"], "channel.range_m = 10000000000000.0"),
        (["--set", "world.bounds_m=[0, 0, 1e13, 5]"], "world.bounds_m = [0, 0, 10000000000000.0, 5]: each"),
        (["--set", "channel.range_m=[100, 0.001]", "--set", "world.n_robots=2"], "channel.range_m = 0.001"),
        (
            ["--set", "channel.propagation=log_distance", "--set", "channel.reference_distance_m=1e-12"],
            "channel.propagation = 'log_distance': the radio's implied range, 1e-10 m, is below 0.01 m",
        ),
        # Accepted, these stopped a run midway (a robot driven faster than light at some draw)
        # or after it (a frame's bytes past 64 bits in the control table), measured nothing (a
        # backoff or a latency past the run), or gave NaN (a disk too small for its area).
        (
            ["--set", "mobility.speed_max_mps=3.1e8"],
            "mobility.speed_max_mps = 310000000.0: must be at most 2.99792e+08",
        ),
        (
            ["--set", "mobility.model=gauss_markov", "--set", "mobility.mean_speed_mps=1e9"],
            "mobility.mean_speed_mps = 1000000000.0: must be at most",
        ),
        (
            ["--set", "mobility.model=gauss_markov", "--set", "mobility.mean_speed_mps=2.5e8"]
            + ["--set", "mobility.speed_sigma_mps=2e7"],
            "mobility.speed_sigma_mps = 20000000.0: mobility.mean_speed_mps + 12 x it must be at most",
        ),
        (
            ["--set", "protocol.model=greedy", "--set", "protocol.beacon_bytes=4611686018427387904"],
            "protocol.beacon_bytes = 4611686018427387904: must be in 1 .. 2147483647",
        ),
        (["--set", "channel.max_frame_bytes=2147483648"], "channel.max_frame_bytes = 2147483648"),
        (
            ["--set", "channel.mac=csma", "--set", "channel.slot_s=1e308"],
            "channel.slot_s = 1e+308: must be in (0, 3600]",
        ),
        (
            ["--set", "channel.mac=csma", "--set", "channel.difs_s=3601"],
            "channel.difs_s = 3601.0: must be in [0, 3600]",
        ),
        (["--set", "channel.latency_s=1e308"], "channel.latency_s = 1e+308: must be shorter than duration_s"),
        (["--set", "coverage.radius_m=1e-300"], "coverage.radius_m = 1e-300: must be 0 (the range) or"),
        # Accepted, a noise floor of 0 mW made every SINR inf (numpy's division warning on the way).
        (
            ["--set", "channel.mac=csma", "--set", "channel.propagation=log_distance"]
            + ["--set", "channel.noise_floor_dbm=-1e300"],
            "channel.noise_floor_dbm = -1e+300: must be at least -3000",
        ),
        # Accepted, these ended the run in a traceback: a window whose backoff's draw (0..cw)
        # leaves the medium's 64-bit integers, and a RREQ list no memory holds (or whose last
        # wait overflows).
        (
            ["--set", "channel.mac=csma", "--set", "channel.cw_min=9223372036854775807"]
            + ["--set", "channel.cw_max=9223372036854775807"],
            "channel.cw_min = 9223372036854775807: must be 2^k - 1 with 1 <= k <= 62",
        ),
        (
            ["--set", "protocol.model=aodv", "--set", "protocol.message_rate_hz=2"]
            + ["--set", "protocol.rreq_retries=4294967296"],
            "protocol.rreq_retries = 4294967296: must be at most 1022",
        ),
        # Accepted, the clustering's message (one frame) held a shared medium for 2^63 bytes'
        # airtime: a frame's size is at most 2^31 - 1 bytes, as an Ack's.
        (
            ["--set", "channel.mac=csma", "--set", "protocol.message_bytes=9223372036854775807"],
            "protocol.message_bytes = 9223372036854775807: must be in 1 .. 2147483647",
        ),
        # A warning given while the input was checked, and then the refusal: the refusal alone.
        (["--set", "duration_s=2", "--set", "duration_s=abc"], "duration_s = 'abc': must be a number"),
        (["--set", "seed=3", "--seed", "-1"], "seed = -1: must be >= 0"),
        (
            ["--set", "channel.propagation=log_distance", "--set", "channel.range_m=100"]
            + ["--set", "output.position_interval_s=1e-300"],
            "world.n_robots = 50: the run would hold at least",
        ),
    ],
)
# Warnings shown as the command shows them: one before the refusal would be a second line.
@pytest.mark.filterwarnings("always::UserWarning")
def test_cli_bad_input_exits_2_with_one_line_and_writes_nothing(tmp_path, capsys, args, fragment):
    code, err = _cli(tmp_path, capsys, *args)
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("netsim: error: ") and fragment in lines[0]
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("command", ["run", "figures", "config"])
def test_set_with_a_space_for_the_equals_sign_gives_the_meant_form(tmp_path, capsys, monkeypatch, command):
    """`--set KEY VALUE` (a space, not `=`) leaves VALUE as the command's file argument:
    the one-line error says `--set takes KEY=VALUE` and spells what was meant, exit 2,
    nothing written."""
    monkeypatch.chdir(tmp_path)
    code = main([command, "--set", "world.n_robots", "100"])
    lines = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(lines) == 1
    assert lines[0] == (
        "netsim: error: --set world.n_robots 100: --set takes KEY=VALUE; did you mean --set world.n_robots=100?"
    )
    assert list(tmp_path.iterdir()) == []


@pytest.mark.filterwarnings("always::UserWarning")
def test_a_key_set_twice_takes_the_last_and_says_so(tmp_path, capsys, monkeypatch):
    """`--set k=a ... --set k=b`: the last value is taken (a script's own --set after its
    base ones), and one warning line names both, however the key is spaced."""
    monkeypatch.chdir(tmp_path)
    code = main(["config", "--set", "world.n_robots=8", "--set", "duration_s=5", "--set", "world.n_robots =9"])
    captured = capsys.readouterr()
    assert code == 0
    assert captured.err.strip().splitlines() == [
        "netsim: warning: --set world.n_robots=8 and --set world.n_robots =9: the last is taken"
    ]
    assert "n_robots = 9" in captured.out and "n_robots = 8" not in captured.out


# Shown where the module that gave it is named, refused (the project's error::UserWarning) elsewhere.
@pytest.mark.filterwarnings("default::UserWarning:netsim.tools.cli")
def test_a_warning_held_back_while_checking_is_shown_as_its_filters_said(tmp_path, capsys, monkeypatch):
    """A warning held back while the input is checked is shown as the filters decided where
    it was given, a filter naming that module included (-W ACTION::CATEGORY:MODULE): given
    again from its file's path it was matched a second time, against no module's name (here
    an error::UserWarning, a traceback)."""
    monkeypatch.chdir(tmp_path)
    code = main(["config", "--set", "world.n_robots=8", "--set", "world.n_robots=9"])
    assert code == 0
    assert capsys.readouterr().err.strip().splitlines() == [
        "netsim: warning: --set world.n_robots=8 and --set world.n_robots=9: the last is taken"
    ]


@pytest.mark.filterwarnings("always::UserWarning")
@pytest.mark.parametrize("command", ["run", "figures", "config"])
def test_a_key_set_twice_then_refused_is_the_refusal_alone(tmp_path, capsys, monkeypatch, command):
    """The warning that a key was set twice waits for the input to pass its checks: a
    refused command line is one line, its error (it was the warning, then the error)."""
    monkeypatch.chdir(tmp_path)
    code = main([command, "--set", "world.n_robots=8", "--set", "world.n_robots=0"])
    assert code == 2
    assert capsys.readouterr().err.strip().splitlines() == [
        "netsim: error: world.n_robots = 0: must be > 0 (number of robots N)"
    ]
    assert list(tmp_path.iterdir()) == []


@pytest.mark.filterwarnings("always::UserWarning")
@pytest.mark.parametrize(
    ("args", "said"),
    [
        (["run", "--out", "afile"], "netsim: error: --out afile: is a file, not a directory"),
        (["figures", "--out", "afile"], "netsim: error: --out afile: is a file, not a directory"),
        (["figures", "."], "netsim: error: give either a run directory or a scenario (--config/--set), not both"),
    ],
)
def test_a_key_set_twice_then_a_bad_out_is_the_refusal_alone(tmp_path, capsys, monkeypatch, args, said):
    """The warning of a key set twice waits for the output directory to be claimed too (and
    for netsim figures' choice of a run or a scenario): a refusal of either is one line (it
    was the warning, then the error)."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "afile").write_text("mine")
    code = main([*args, "--set", "duration_s=20", "--set", "duration_s=21"])
    assert code == 2
    assert capsys.readouterr().err.strip().splitlines() == [said]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile"]


@pytest.mark.filterwarnings("always::UserWarning")
@pytest.mark.parametrize("seeds", [["--seed", "3", "--set", "seed=4"], ["--set", "seed = 4", "--seed", "3"]])
def test_run_with_a_seed_given_twice_takes_seed_and_says_so(tmp_path, capsys, monkeypatch, seeds):
    """`--seed` and `--set seed=` together: --seed is --set seed= given last, so it is taken,
    with one warning line naming both, as for any key set twice."""
    monkeypatch.chdir(tmp_path)
    args = ["run", "--quiet", "--set", "world.n_robots=3", "--set", "duration_s=2", *seeds]
    assert main([*args, "--out", "out"]) == 0
    given = seeds[seeds.index("--set") + 1]
    assert capsys.readouterr().err.strip().splitlines() == [
        f"netsim: warning: --set {given} and --seed 3: --seed is taken"
    ]
    assert "seed = 3" in (tmp_path / "out" / "config.toml").read_text()


@pytest.mark.parametrize(
    "flags, message",
    [
        (["--n", "0"], "--n 0: must be > 0"),
        (["--side", "-1"], "--side -1.0: must be in (0, 1e+12] (metres)"),
        (["--speed-min", "10"], "--speed-min 10.0: must not exceed --speed-max = 5.0"),
        (["--speed-max", "nan"], "--speed-max nan: must be a number"),
        (["--pause", "-1"], "--pause -1.0: must be >= 0"),
        (["--duration", "0"], "--duration 0.0: must be > 0"),
        (["--seed", "-1"], "--seed -1: must be >= 0"),
        (["--speed-min", "0"], "--speed-min 0.0: must be > 0 without --no-stationary-start"),
        (["--n", "100000000000"], "--n 100000000000: the run would hold at least"),
        (["--duration", "1e15"], "--duration 1000000000000000.0: the scenario would hold at least"),
    ],
)
def test_scenario_generate_errors_name_its_flags(tmp_path, capsys, monkeypatch, flags, message):
    """`netsim scenario generate` names the flags typed (`--n`, `--speed-max`, ...), not the
    configuration keys they set; one line, exit 2, nothing written."""
    monkeypatch.chdir(tmp_path)
    args = {"--n": "5", "--side": "100", "--speed-max": "5", "--duration": "10"}
    args.update(zip(flags[::2], flags[1::2]))
    code = main(["scenario", "generate", *[w for kv in args.items() for w in kv], "-o", "s.tcl"])
    lines = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(lines) == 1
    assert lines[0].startswith(f"netsim: error: {message}"), lines[0]
    assert not any(key in lines[0] for key in ("world.", "mobility.", "duration_s", "_mps", "stationary_start"))
    assert list(tmp_path.iterdir()) == []


def test_cli_malformed_files(tmp_path, capsys):
    bad_toml = tmp_path / "bad.toml"
    bad_toml.write_text("[world\nn_robots = 3")
    code, err = _cli(tmp_path, capsys, str(bad_toml))
    assert code == 2 and "not valid TOML" in err

    trace = tmp_path / "t.tcl"
    trace.write_text("$node_(0) set X_ 1.0\n$node_(0) set Y_ 2.0\n$node_(0) set X_ nan\n")
    code, err = _cli(
        tmp_path,
        capsys,
        "--set",
        "mobility.model=trace",
        "--set",
        f"mobility.trace_file={trace}",
        "--set",
        "world.n_robots=1",
    )
    assert code == 2 and "t.tcl:3" in err

    # A section given a value in the file, and keys of it set on the command line: the
    # file's value is refused, not dropped by the merge.
    not_a_table = tmp_path / "world5.toml"
    not_a_table.write_text("world = 5\n")
    code, err = _cli(tmp_path, capsys, str(not_a_table), "--set", "world.n_robots=5")
    assert code == 2 and "world = 5: must be a table" in err

    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(
    "rows, words",
    [
        ("x_m,y_m\n1,2\nthree,4\n", "not numbers"),
        ("x_m,y_m\n1,2\n", "1 rows but world.n_robots = 2"),
        ("x,y\n1,2\n3,4\n", "columns x_m,y_m"),
        ("y_m,x_m\n1,2\n3,4\n", "columns x_m,y_m"),
        ("x_m,y_m\n1,2\n3,5000\n", "outside the area"),
        ("x_m,y_m\n1,2\n3,\n", "missing"),
    ],
)
def test_cli_malformed_placement_file(tmp_path, capsys, rows, words):
    csv = tmp_path / "p.csv"
    csv.write_text(rows)
    placement = ["--set", f"world.placement={csv}", "--set", "world.n_robots=2"]
    code, err = _cli(tmp_path, capsys, *placement, "--set", "mobility.stationary_start=false")
    assert code == 2 and words in err
    assert not (tmp_path / "out").exists()


def test_placement_conflicting_with_stationary_start(tmp_path, capsys):
    code, err = _cli(tmp_path, capsys, "--set", "world.placement=grid", "--set", "mobility.stationary_start=true")
    assert code == 2 and "stationary_start" in err


@pytest.mark.slow
def test_console_script_gives_no_traceback(tmp_path):
    out = subprocess.run(
        [sys.executable, "-m", "netsim.tools.cli", "run", "--set", "world.n_robots=-1", "--out", str(tmp_path / "o")],
        capture_output=True,
        text=True,
    )
    assert out.returncode == 2
    assert "Traceback" not in out.stderr
    assert out.stderr.strip() == textwrap.dedent("netsim: error: world.n_robots = -1: must be > 0 (number of robots N)")


def test_printed_configuration_loads_back_unchanged(tmp_path):
    """`netsim config` writes a file that loads to the same configuration, sub-tables included."""
    c = cfgmod.load(None, ['control.controllers=["log_separation"]', "control.options={min_separation_m=2.5}"])
    path = tmp_path / "c.toml"
    path.write_text(cfgmod.commented_toml(c))
    assert cfgmod.load(path) == c


def test_printed_configuration_says_which_keys_are_the_chosen_models(tmp_path, recwarn):
    """`netsim config` marks the keys a section's model reads as that model's own (a user
    who named another model and left them was warned at every run, though the file had
    written them as if anyone's); printed for another model, the file loads with no warning."""
    text = cfgmod.commented_toml()
    mobility = text.split("[mobility]")[1].split("[channel]")[0]
    assert mobility.index('model = "random_waypoint"') < mobility.index("random_waypoint's own keys follow")
    assert mobility.index("random_waypoint's own keys follow") < mobility.index("speed_min_mps = 0.5")
    other = cfgmod.load(None, ["mobility.model=gauss_markov"])
    (tmp_path / "g.toml").write_text(cfgmod.commented_toml(other))
    assert "gauss_markov's own keys follow" in (tmp_path / "g.toml").read_text()
    assert cfgmod.load(tmp_path / "g.toml") == other
    assert [str(w.message) for w in recwarn] == []


def test_a_configuration_error_crosses_a_process_pool_whole():
    """A ConfigError raised in a worker (a sweep's, an experiment's pool) is pickled back to
    the parent: it must come back as itself, key, value and message, not as a broken pool."""
    import pickle
    from concurrent.futures import ProcessPoolExecutor

    err = ConfigError("coverage.fade_margin_db", -1.0, "must be >= 0")
    err.add_note("in the sweep's point 3")
    back = pickle.loads(pickle.dumps(err))
    assert back.__notes__ == ["in the sweep's point 3"]
    assert (type(back), back.key, back.value, back.allowed, str(back)) == (
        ConfigError,
        err.key,
        err.value,
        err.allowed,
        str(err),
    )
    with ProcessPoolExecutor(1) as pool, pytest.raises(ConfigError, match="duration_s = inf: must be finite"):
        pool.submit(cfgmod.load, None, ["duration_s=inf"]).result()


def test_a_configuration_error_raised_in_a_simpy_process_reaches_the_caller_whole():
    """SimPy re-raises a process's error as ``type(e)(*e.args)``: a ConfigError raised in a
    motion process (a robot on a map that sees no destination) must come out as itself,
    not as a TypeError of its constructor (a traceback, exit 1)."""
    import simpy

    def proc(env):
        yield env.timeout(1.0)
        raise ConfigError("world.map", "closet.yaml", "robot 0 sees no free destination")

    env = simpy.Environment()
    env.process(proc(env))
    with pytest.raises(ConfigError) as err:
        env.run()
    assert (err.value.key, err.value.value, err.value.allowed) == (
        "world.map",
        "closet.yaml",
        "robot 0 sees no free destination",
    )
    assert str(err.value) == "world.map = 'closet.yaml': robot 0 sees no free destination"


def test_coverage_disks_wider_than_the_area_cover_it_whole():
    """A coverage radius of 1e300 m (a traceback of shapely's union) covers the whole area,
    exactly, as any disk past the area's diagonal does."""
    from netsim.run import execute

    keys = ["coverage.enabled=true", 'mobility.model="static"', "world.side_m=100", "world.n_robots=3"]
    res = execute(cfgmod.load(None, [*keys, "duration_s=12", "coverage.radius_m=1e300"]))
    covered = res.frames["coverage"]["covered_fraction_all"]
    assert len(covered) >= 2 and (covered == 1.0).all()


def test_the_oracle_through_walls_needs_the_links_tracked_during_the_run():
    """With events.runtime_links = "off" the oracle could not see the links walls or
    shadowing decide (it fell back to range circles and bounced messages): refused by name.
    On a plain log-distance radio the links are the implied range's disks: allowed."""
    keys = ['channel.propagation="log_distance"', 'protocol.routing="oracle"', 'events.runtime_links="off"']
    with pytest.raises(ConfigError) as err:
        cfgmod.load(None, [*keys, 'world.map="office"', 'world.bounds_m="map"'])
    assert err.value.key == "events.runtime_links" and "protocol.routing = 'oracle'" in str(err.value)
    with pytest.raises(ConfigError):
        cfgmod.load(None, [*keys, "channel.shadowing_sigma_db=4"])
    assert cfgmod.load(None, keys).protocol.routing == "oracle"


def test_a_coverage_margin_at_the_range_is_refused_and_a_start_after_the_end_told():
    """Kept links stay coverage.margin_m inside the range: at the range or past it no link
    can be kept and no robot moves (it ran silently); a control start at or after the run's
    end makes no step, and is told."""
    base = ["coverage.enabled=true", "mobility.model=static", "channel.range_m=100"]
    for margin in ("100", "inf"):
        with pytest.raises(ConfigError) as err:
            cfgmod.load(None, [*base, f"coverage.margin_m={margin}"])
        assert err.value.key == "coverage.margin_m" and "below the smallest range (100 m)" in str(err.value)
    late = r"^coverage.start_s = 1000: at or after the run's end \(duration_s = 30\)"
    with pytest.warns(cfgmod.ConfigWarning, match=late):
        cfgmod.load(None, [*base, "duration_s=30", "coverage.start_s=1000"])


def test_a_wall_loss_without_a_map_is_warned_of(tmp_path):
    """A wall loss set where no map puts walls (a `netsim calibrate --map` fit run in open
    space) is one warning naming it; its default (as a run's own config.toml writes it),
    and any value on a map, are not."""
    import warnings

    overrides = ['channel.propagation="log_distance"', "channel.wall_loss_db=7.5"]
    with pytest.warns(cfgmod.ConfigWarning, match=r"^channel.wall_loss_db = 7.5: no walls without a map"):
        config = cfgmod.load(None, overrides)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        # Taken out, as other ignored keys are: the run's config.toml read again says nothing.
        assert cfgmod.from_dict(cfgmod.to_dict(config)).channel.radio.wall_loss_db == 5.0
        cfgmod.load(None, ['channel.propagation="log_distance"', "channel.wall_loss_db=5.0"])
        cfgmod.load(None, [*overrides, 'world.map="office"', 'world.bounds_m="map"', "world.n_robots=10"])


@pytest.mark.parametrize(
    "name, read_as", [("s.movements", "bonnmotion"), ("s.movements.gz", "bonnmotion"), ("s.db3", "rosbag2")]
)
def test_scenario_generate_refuses_a_name_read_back_as_another_format(tmp_path, capsys, monkeypatch, name, read_as):
    """`netsim scenario generate` writes ns-2; a file named .movements would be read back
    as BonnMotion (and fail on its first line), one named .db3 as a bag's storage: refused
    in one line, exit 2, nothing written."""
    monkeypatch.chdir(tmp_path)
    argv = ["scenario", "generate", "--n", "3", "--side", "100", "--speed-max", "2", "--duration", "5", "-o", name]
    assert main(argv) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert lines == [
        f"netsim: error: -o {name}: writes ns-2, and a name so is read back as {read_as}; give another name "
        "(netsim export writes a run in the other formats)"
    ]
    assert list(tmp_path.iterdir()) == []


def test_the_placements_named_by_a_word_are_the_ones_the_engine_places():
    """A name the configuration keeps as given (not a file's path to make absolute) is one
    the engine places by: the two lists cannot drift apart."""
    from netsim.placement import PLACEMENTS

    assert set(cfgmod.NAMED_PLACEMENTS) == set(PLACEMENTS) | {"connected"}


# -- rules a mutation audit found no test for ------------------------------------------------
@pytest.mark.parametrize(
    "sets, line",
    [
        (
            ["world.torus=true", "world.bounds_m=[0.0, 0.0, 500.0, 500.0]"],
            "world.bounds_m = [0.0, 0.0, 500.0, 500.0]: cannot be set with world.torus = true",
        ),
        (["world.n_robots=2", "channel.range_m=[0.0, 5.0]"], "channel.range_m[0] = 0.0: must be a finite number > 0"),
        # A range of half the side: a robot would meet its own image's links.
        (
            ["world.torus=true", "world.side_m=100", "channel.range_m=50"],
            "world.side_m = 100.0: on a torus must exceed twice the largest range_m",
        ),
        (
            ["events.runtime_links=off", "events.live_topology=true"],
            "events.live_topology = true: needs link events during the run",
        ),
        (["duration_s=2", "channel.latency_s=2"], "channel.latency_s = 2.0: must be shorter than duration_s = 2 s"),
        (["world.start_m=[2000.0, 10.0]"], "world.start_m = [2000.0, 10.0]: is outside the area"),
    ],
)
def test_a_rule_between_keys_is_one_line_and_nothing_written(tmp_path, capsys, sets, line):
    code, err = _cli(tmp_path, capsys, *[a for s in sets for a in ("--set", s)])
    assert code == 2
    (said,) = err.strip().splitlines()
    assert said.startswith(f"netsim: error: {line}")
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(
    "tree",
    [
        {"world": {"side_m": 300.0, "placement": "centre", "centre_side_m": 300.0}},
        {"channel": {"range_m": 0.01}},
        {"channel": {"range_m": 1e12}},
        {"world": {"side_m": 100.0, "torus": True}, "channel": {"range_m": 49.0}},
    ],
)
def test_a_value_at_the_edge_of_its_rule_is_accepted(tree):
    """Each bound is the last value allowed: a central square as wide as the area, the
    shortest and longest ranges, a torus just over twice the range."""
    cfgmod.from_dict(tree)


def test_a_section_given_a_value_is_one_line_and_nothing_written(tmp_path, capsys):
    f = tmp_path / "s.toml"
    f.write_text("world = 5\n")
    code, err = _cli(tmp_path, capsys, str(f))
    assert code == 2
    assert err.strip().splitlines() == [f"netsim: error: {f}: world = 5: must be a table ([world])"]
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(
    ("sets", "named"),
    [([], True), (["world.n_robot=3"], False), (["world.side_m=500"], True)],
)
def test_an_error_in_a_key_the_file_sets_names_the_file(tmp_path, sets, named):
    """A bad key or value the scenario file sets (and no --set) names the file first, so the
    user knows where to look; the same key given by --set does not (it is the command
    line's)."""
    f = tmp_path / "typo.toml"
    f.write_text("duration_s = 5.0\n[world]\nn_robot = 30\n")
    with pytest.raises(ConfigError) as err:
        cfgmod.load(f, sets)
    assert str(err.value).startswith(f"{f}: world.n_robot = ") is named
    assert "unknown key (did you mean 'n_robots'?)" in str(err.value)


def test_a_model_name_that_is_no_text_is_one_line_and_nothing_written(tmp_path, capsys):
    code, err = _cli(tmp_path, capsys, "--set", "mobility.model=5")
    assert code == 2
    assert err.strip().splitlines() == ["netsim: error: mobility.model = 5: must be a string"]
    assert not (tmp_path / "out").exists()


def test_a_range_the_radios_law_overrides_is_said_to_be_ignored():
    with pytest.warns(
        cfgmod.ConfigWarning, match=r"^channel.range_m: not used by channel.propagation = 'log_distance'"
    ):
        config = cfgmod.from_dict({"channel": {"propagation": "log_distance", "range_m": 80.0}})
    assert "range_m" not in cfgmod.to_dict(config, derived=False)["channel"]


def test_a_bridge_table_in_a_scenario_points_to_netsim_bridge(tmp_path, capsys):
    f = tmp_path / "s.toml"
    f.write_text("[bridge]\nrate_hz = 10.0\n")
    code, err = _cli(tmp_path, capsys, str(f))
    assert code == 2
    (line,) = err.strip().splitlines()
    assert line.startswith("netsim: error: [bridge]: a table of `netsim bridge`")
    assert not (tmp_path / "out").exists()


def test_set_under_the_seed_blames_the_set_not_the_file(tmp_path, capsys):
    """The file's `seed = 3` is right: `--set seed.x=1` names a key as if it were a section."""
    f = tmp_path / "s.toml"
    f.write_text("seed = 3\n")
    code, err = _cli(tmp_path, capsys, str(f), "--set", "seed.x=1")
    assert code == 2
    assert err.strip().splitlines() == ["netsim: error: --set = 'seed.x=1': seed is a key, not a section"]
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(
    "value, what",
    [("[grid", "list"), ("[1.0,\n2.0]", "list")],
)
def test_a_set_value_that_opens_a_list_or_spans_lines_is_refused_not_taken_as_text(tmp_path, capsys, value, what):
    """A value that starts like a list, or breaks a line, is a mistyped TOML value: read as
    a bare word it would be a placement file named `[grid`."""
    code, err = _cli(tmp_path, capsys, "--set", f"world.placement={value}")
    assert code == 2
    (line,) = err.strip().splitlines()
    assert line.startswith(f"netsim: error: world.placement = {value!r}: is not a valid TOML {what}")
    assert not (tmp_path / "out").exists()


def test_a_set_bare_word_is_taken_without_the_spaces_around_it():
    assert cfgmod.load(None, ["world.placement = grid "]).world.placement == "grid"


def test_overrides_given_as_one_string_are_refused_as_such():
    """Iterated, the string's characters would each be refused as a key=value."""
    with pytest.raises(TypeError, match=r"^overrides = 'world.n_robots=5': must be a list of 'key=value' strings"):
        cfgmod.load(None, "world.n_robots=5")


def test_a_section_of_the_wrong_kind_made_in_python_is_refused():
    with pytest.raises(ConfigError, match=r"^world = 5: must be a WorldParams$"):
        cfgmod.Config(world=5)


@pytest.mark.parametrize(
    ("sets", "said"),
    [
        (["world.placement=center"], "or the path of an existing CSV file (did you mean 'centre'?)"),
        (["world.map=ofice"], "(no such file) (did you mean 'office'?)"),
        (["world.map=Cave"], "(no such file) (did you mean 'cave'?)"),
        (["world.map=office"], ': set world.side_m to at most 200, or world.bounds_m = "map" for the whole map'),
    ],
)
def test_a_misspelt_value_or_a_map_smaller_than_the_area_says_what_was_meant(tmp_path, capsys, sets, said):
    """A placement or an example map's name misspelt (an American spelling, a capital) names
    the one meant, as a misspelt key does; a map smaller than the area says which keys fit it
    (each was refused without a word of what to set)."""
    code = main(["run", "--quiet", *(a for s in sets for a in ("--set", s)), "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and err[0].endswith(said), err
    assert not (tmp_path / "o").exists()
