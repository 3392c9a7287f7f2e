"""``netsim bridge`` (docs/ros2.md) driven from another process as a ROS 2 node would: this
test process, with Cyclone DDS and its own structures under ROS 2's type names, on the
loopback and a DDS domain of each test's own."""

import json
import os
import signal
import subprocess
import sys
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

cyclonedds = pytest.importorskip("cyclonedds")  # the extra "ros" (installed with "test")

import cyclonedds.idl.annotations as annotate  # noqa: E402
from cyclonedds.core import Policy, Qos  # noqa: E402
from cyclonedds.domain import DomainParticipant  # noqa: E402
from cyclonedds.idl import IdlStruct  # noqa: E402
from cyclonedds.idl.types import array, float64, int32, uint32  # noqa: E402
from cyclonedds.internal import InvalidSample  # noqa: E402
from cyclonedds.pub import DataWriter  # noqa: E402
from cyclonedds.sub import DataReader  # noqa: E402
from cyclonedds.topic import Topic  # noqa: E402
from cyclonedds.util import duration  # noqa: E402

COMMAND = str(Path(sys.executable).with_name("netsim"))
RELIABLE = Qos(
    Policy.Reliability.Reliable(duration(milliseconds=100)), Policy.Durability.Volatile, Policy.History.KeepLast(10)
)
CLOCK_QOS = Qos(Policy.Reliability.BestEffort, Policy.Durability.Volatile, Policy.History.KeepLast(1))


# -- ROS 2 messages, written here as a ROS 2 node's would be (rosidl's DDS names) -----------
@dataclass
@annotate.final
class Time(IdlStruct, typename="builtin_interfaces::msg::dds_::Time_"):
    sec: int32
    nanosec: uint32


@dataclass
@annotate.final
class Clock(IdlStruct, typename="rosgraph_msgs::msg::dds_::Clock_"):
    clock: Time


@dataclass
@annotate.final
class Vector3(IdlStruct, typename="geometry_msgs::msg::dds_::Vector3_"):
    x: float64
    y: float64
    z: float64


@dataclass
@annotate.final
class Twist(IdlStruct, typename="geometry_msgs::msg::dds_::Twist_"):
    linear: Vector3
    angular: Vector3


@dataclass
@annotate.final
class String(IdlStruct, typename="std_msgs::msg::dds_::String_"):
    data: str


@dataclass
@annotate.final
class Header(IdlStruct, typename="std_msgs::msg::dds_::Header_"):
    stamp: Time
    frame_id: str


@dataclass
@annotate.final
class Point(IdlStruct, typename="geometry_msgs::msg::dds_::Point_"):
    x: float64
    y: float64
    z: float64


@dataclass
@annotate.final
class Quaternion(IdlStruct, typename="geometry_msgs::msg::dds_::Quaternion_"):
    x: float64
    y: float64
    z: float64
    w: float64


@dataclass
@annotate.final
class Pose(IdlStruct, typename="geometry_msgs::msg::dds_::Pose_"):
    position: Point
    orientation: Quaternion


@dataclass
@annotate.final
class PoseWithCovariance(IdlStruct, typename="geometry_msgs::msg::dds_::PoseWithCovariance_"):
    pose: Pose
    covariance: array[float64, 36]


@dataclass
@annotate.final
class TwistWithCovariance(IdlStruct, typename="geometry_msgs::msg::dds_::TwistWithCovariance_"):
    twist: Twist
    covariance: array[float64, 36]


@dataclass
@annotate.final
class Odometry(IdlStruct, typename="nav_msgs::msg::dds_::Odometry_"):
    header: Header
    child_frame_id: str
    pose: PoseWithCovariance
    twist: TwistWithCovariance


def seconds(t: Time) -> float:
    return t.sec + t.nanosec * 1e-9


# -- the bridge in a process of its own, on the loopback --------------------------------------
LOOPBACK_XML = """<CycloneDDS><Domain Id="any"><General><Interfaces><NetworkInterface name="lo"/></Interfaces>
<AllowMulticast>false</AllowMulticast></General><Discovery><ParticipantIndex>auto</ParticipantIndex>
<MaxAutoParticipantIndex>40</MaxAutoParticipantIndex><Peers><Peer address="127.0.0.1"/></Peers></Discovery>
</Domain></CycloneDDS>"""

# Each test its own domain: bridges of tests run side by side never meet.
DOMAINS = {
    "twist": 61,
    "clock": 62,
    "relay": 63,
    "ctrl_c": 64,
    "bytes": 65,
    "markers": 66,
    "bad_uri": 67,
    "burst": 68,
    "save": 69,
    "node": 70,
    "live": 71,
    "rate": 72,
    "best_effort": 73,
}


@pytest.fixture(autouse=True)
def loopback_dds(tmp_path, monkeypatch):
    """Cyclone DDS on the loopback alone, with unicast discovery (no multicast needed)."""
    xml = tmp_path / "cyclonedds.xml"
    xml.write_text(LOOPBACK_XML)
    monkeypatch.setenv("CYCLONEDDS_URI", xml.as_uri())


def scenario(tmp_path: Path, domain: int, extra: str = "", n: int = 3, duration_s: float = 4.0) -> Path:
    path = tmp_path / "bridge.toml"
    path.write_text(
        f"duration_s = {duration_s}\n"
        f"[world]\nn_robots = {n}\nside_m = 400\nplacement = 'centre'\ncentre_side_m = 10\n"
        "[channel]\nrange_m = 40\n"
        "[mobility]\nmodel = 'external'\n"
        "[protocol]\nmessage_rate_hz = 0\n"
        f"[bridge]\ndomain_id = {domain}\nodom_hz = 10\n{extra}"
    )
    return path


def start_bridge(config: Path, out: Path, *flags: str) -> subprocess.Popen:
    return subprocess.Popen(
        [COMMAND, "bridge", str(config), "--out", str(out), "--quiet", *flags],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def finish(proc: subprocess.Popen, timeout_s: float = 120) -> str:
    """Wait for the bridge to end; its standard error."""
    out, err = proc.communicate(timeout=timeout_s)
    assert proc.returncode == 0, err
    return err


def take(reader: DataReader) -> list:
    """The samples with data waiting in ``reader`` (a writer that leaves sends one without)."""
    return [s for s in reader.take(N=100) if s is not None and not isinstance(s, InvalidSample)]


def wait_for(reader: DataReader, proc: subprocess.Popen, what: str, timeout_s: float = 60) -> list:
    """Samples from ``reader`` as soon as there are any (the bridge is up)."""
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        got = take(reader)
        if got:
            return got
        assert proc.poll() is None, f"the bridge ended before {what}: {proc.communicate()[1]}"
        time.sleep(0.02)
    raise AssertionError(f"no {what} within {timeout_s} s")


@pytest.mark.slow
def test_twist_on_cmd_vel_moves_robot_at_that_velocity(tmp_path):
    """A Twist on /robot_0/cmd_vel moves robot 0 at its linear.x, linear.y (world frame, m/s)
    from the simulated instant the bridge takes it: its odometry tells that velocity and
    positions that advance by it, and legs.parquet holds the commanded leg. A Twist that is
    not a finite velocity (robot 1's), or is faster than light (robot 2's; it ended the
    session, every table lost), is dropped and counted, and the session goes on."""
    config = scenario(tmp_path, DOMAINS["twist"], duration_s=6.0)
    proc = start_bridge(config, tmp_path / "out", "--rate", "2")
    dp = DomainParticipant(DOMAINS["twist"])
    odom = DataReader(dp, Topic(dp, "rt/robot_0/odom", Odometry), qos=RELIABLE)
    cmd = DataWriter(dp, Topic(dp, "rt/robot_0/cmd_vel", Twist), qos=RELIABLE)
    cmd_1 = DataWriter(dp, Topic(dp, "rt/robot_1/cmd_vel", Twist), qos=RELIABLE)
    cmd_2 = DataWriter(dp, Topic(dp, "rt/robot_2/cmd_vel", Twist), qos=RELIABLE)
    wait_for(odom, proc, "odometry")
    cmd_1.write(Twist(linear=Vector3(x=float("nan"), y=1.0, z=0.0), angular=Vector3(x=0.0, y=0.0, z=0.0)))
    cmd_2.write(Twist(linear=Vector3(x=4e8, y=0.0, z=0.0), angular=Vector3(x=0.0, y=0.0, z=0.0)))
    twist = Twist(linear=Vector3(x=1.5, y=-0.5, z=0.0), angular=Vector3(x=0.0, y=0.0, z=0.0))
    moving: list[Odometry] = []
    while proc.poll() is None and len(moving) < 5:
        cmd.write(twist)
        time.sleep(0.05)
        moving += [s for s in take(odom) if s.twist.twist.linear.x == 1.5]
    finish(proc)
    assert len(moving) >= 2, "robot 0's odometry never told the commanded velocity"
    first, last = moving[0], moving[-1]
    assert (first.twist.twist.linear.x, first.twist.twist.linear.y) == (1.5, -0.5)
    dt = seconds(last.header.stamp) - seconds(first.header.stamp)
    dx = last.pose.pose.position.x - first.pose.pose.position.x
    dy = last.pose.pose.position.y - first.pose.pose.position.y
    assert dt > 0
    assert dx == pytest.approx(1.5 * dt, abs=1e-6) and dy == pytest.approx(-0.5 * dt, abs=1e-6)
    assert first.header.frame_id == "world" and first.child_frame_id == "robot_0"
    legs = pd.read_parquet(tmp_path / "out" / "legs.parquet")
    commanded = legs[(legs["robot"] == 0) & (legs["cause"] == "command")]
    assert len(commanded) == 1
    assert commanded[["vx_mps", "vy_mps"]].iloc[0].tolist() == [1.5, -0.5]
    assert not len(legs[(legs["robot"] != 0) & (legs["cause"] == "command")])
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["bridge_commands_refused"] == 2


@pytest.mark.slow
def test_clock_advances_at_the_rate_asked(tmp_path):
    """/clock (ROS 2's clock QoS) steps by one control period of simulated time and, at
    --rate R, never runs ahead of R simulated seconds per wall second."""
    rate = 4.0
    config = scenario(tmp_path, DOMAINS["clock"], duration_s=8.0)
    proc = start_bridge(config, tmp_path / "out", "--rate", str(rate))
    dp = DomainParticipant(DOMAINS["clock"])
    clock = DataReader(dp, Topic(dp, "rt/clock", Clock), qos=CLOCK_QOS)
    seen: list[tuple[float, float]] = []  # (wall, simulated)
    for s in wait_for(clock, proc, "/clock"):
        seen.append((time.monotonic(), seconds(s.clock)))
    while proc.poll() is None:
        seen += [(time.monotonic(), seconds(s.clock)) for s in take(clock)]
        time.sleep(0.01)
    finish(proc)
    sim = [t for _, t in seen]
    assert sim == sorted(sim) and sim[-1] == pytest.approx(8.0)
    steps = {round(b - a, 9) for a, b in zip(sim, sim[1:], strict=False)}
    assert steps and all(abs(s / 0.1 - round(s / 0.1)) < 1e-6 for s in steps)  # whole control periods
    (w0, t0), (w1, t1) = seen[0], seen[-1]
    # Read late by this busy process, the first message can shorten the span seen: a
    # quarter of it is slack (a bridge that does not wait for the wall clock takes a
    # fraction of it for 3 robots).
    assert w1 - w0 >= 0.75 * (t1 - t0) / rate
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["bridge_rate"] == rate and summary["bridge_lag_max_s"] >= 0


@pytest.mark.slow
def test_relayed_message_arrives_with_the_channel_latency_while_the_link_is_up_and_not_after(tmp_path):
    """A message robot 0 publishes on /robot_0/tx/chat reaches /robot_1/rx/chat while the
    channel links them, channel.latency_s later (relay.parquet), and none sent after the
    link broke arrives."""
    relay = "relay = [{name = 'chat', type = 'std_msgs/msg/String'}]\n"
    config = scenario(tmp_path, DOMAINS["relay"], extra=relay, n=2, duration_s=10.0)
    text = config.read_text().replace("range_m = 40", "range_m = 40\nlatency_s = 0.25")
    config.write_text(text)
    proc = start_bridge(config, tmp_path / "out", "--rate", "2")
    dp = DomainParticipant(DOMAINS["relay"])
    tx = DataWriter(dp, Topic(dp, "rt/robot_0/tx/chat", String), qos=RELIABLE)
    rx = DataReader(dp, Topic(dp, "rt/robot_1/rx/chat", String), qos=RELIABLE)
    clock = DataReader(dp, Topic(dp, "rt/clock", Clock), qos=CLOCK_QOS)
    cmd = DataWriter(dp, Topic(dp, "rt/robot_0/cmd_vel", Twist), qos=RELIABLE)
    wait_for(clock, proc, "/clock")
    got: list[str] = []
    k, away = 0, False
    while proc.poll() is None:
        tx.write(String(data=f"m{k}"))
        k += 1
        got += [s.data for s in take(rx)]
        now = max((seconds(s.clock) for s in take(clock)), default=0.0)
        if now > 3.0 and not away:
            # 20 m/s east: robot 0 leaves robot 1's 40 m range within about 2.5 s.
            cmd.write(Twist(linear=Vector3(x=20.0, y=0.0, z=0.0), angular=Vector3(x=0.0, y=0.0, z=0.0)))
            away = True
        time.sleep(0.05)
    finish(proc)
    out = tmp_path / "out"
    rows = pd.read_parquet(out / "relay.parquet")
    links = pd.read_parquet(out / "links.parquet")
    summary = json.loads((out / "summary.json").read_text())
    assert len(links) == 1 and not links["censored_end"].iloc[0], "the link must break during the run"
    t_down = float(links["t_down_s"].iloc[0])
    to_1 = rows[rows["dst"] == 1]
    assert len(to_1) > 0
    assert (to_1["t_received_s"] - to_1["t_sent_s"]).tolist() == pytest.approx([0.25] * len(to_1))
    assert (to_1["t_sent_s"] <= t_down).all()
    assert summary["bridge_relayed_sent"] > len(to_1), "messages sent after the break must have been lost"
    # Every reception the channel decided was published on /robot_1/rx/chat, once.
    assert len(got) == len(set(got)) == len(to_1)


@pytest.mark.slow
def test_every_message_a_node_sends_in_one_step_is_taken_past_ten(tmp_path):
    """A node that sends 30 messages to relay and 15 commands at once, within one step, has
    every one taken: 30 relayed (rows of relay.parquet for the robot in range) and 15
    commands counted. (netsim's readers kept the last 10: 20 messages were dropped
    uncounted.)"""
    relay = "relay = [{name = 'chat', type = 'std_msgs/msg/String'}]\n"
    config = scenario(tmp_path, DOMAINS["burst"], extra=relay, n=2, duration_s=3.0)
    proc = start_bridge(config, tmp_path / "out", "--rate", "2")
    dp = DomainParticipant(DOMAINS["burst"])
    keep_all = Qos(Policy.Reliability.Reliable(duration(seconds=1)), Policy.Durability.Volatile, Policy.History.KeepAll)
    tx = DataWriter(dp, Topic(dp, "rt/robot_0/tx/chat", String), qos=keep_all)
    cmd = DataWriter(dp, Topic(dp, "rt/robot_1/cmd_vel", Twist), qos=keep_all)
    clock = DataReader(dp, Topic(dp, "rt/clock", Clock), qos=CLOCK_QOS)
    wait_for(clock, proc, "/clock")
    for k in range(30):
        tx.write(String(data=f"m{k}"))
    for k in range(15):
        cmd.write(Twist(linear=Vector3(x=0.01 * k, y=0.0, z=0.0), angular=Vector3(x=0.0, y=0.0, z=0.0)))
    finish(proc)
    out = tmp_path / "out"
    summary = json.loads((out / "summary.json").read_text())
    assert summary["bridge_relayed_sent"] == 30 and summary["bridge_commands"] == 15, summary
    rows = pd.read_parquet(out / "relay.parquet")
    assert sorted(rows.loc[rows["dst"] == 1, "msg_id"]) == list(range(30))


@pytest.mark.slow
def test_ctrl_c_ends_the_bridge_with_every_table_written(tmp_path):
    """SIGINT (Ctrl-C) ends a bridge (here with its live view) before duration_s with exit
    status 0 and the run's tables written up to that instant."""
    config = scenario(tmp_path, DOMAINS["ctrl_c"], duration_s=600.0)
    out = tmp_path / "out"
    proc = start_bridge(config, out, "--rate", "1", "--live", "0")
    dp = DomainParticipant(DOMAINS["ctrl_c"])
    clock = DataReader(dp, Topic(dp, "rt/clock", Clock), qos=CLOCK_QOS)
    wait_for(clock, proc, "/clock")
    proc.send_signal(signal.SIGINT)
    assert "live view: Foxglove WebSocket on ws://127.0.0.1:" in finish(proc)
    summary = json.loads((out / "summary.json").read_text())
    assert 0 < summary["duration_s"] < 600
    for table in ("legs", "links", "positions", "roles", "relay"):
        assert (out / f"{table}.parquet").is_file()
    positions = pd.read_parquet(out / "positions.parquet")
    assert positions["t_s"].max() <= summary["duration_s"]


@pytest.mark.slow
def test_a_second_ctrl_c_while_the_session_is_saved_loses_nothing(tmp_path, monkeypatch, capfd):
    """Ctrl-C pressed again while the session's tables are being written (people press it
    twice) is taken as the first was: the save goes on whole, exit status 0. (It raised
    the command's interrupt: nothing written, status 130, the whole session lost.)"""
    import netsim.run
    from netsim.tools.cli import main

    collect = netsim.run.collect

    def collect_pressed_again(sim, emit=None, progress=False):
        signal.raise_signal(signal.SIGINT)
        return collect(sim, emit, progress)

    monkeypatch.setattr(netsim.run, "collect", collect_pressed_again)
    out = tmp_path / "out"
    code = main(["bridge", str(scenario(tmp_path, DOMAINS["save"], duration_s=1.0)), "--out", str(out), "--quiet"])
    assert code == 0, capfd.readouterr().err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["duration_s"] == 1.0 and summary["bridge_steps"] == 10
    assert (out / "bridge.toml").is_file() and (out / "positions.parquet").is_file()


def test_odometry_bytes_are_the_serializers_own():
    """The odometry the bridge writes as patched bytes is byte for byte what Cyclone's
    serializer makes of the same message (stamp, position, velocity, frames)."""
    from netsim.bridge.bridge import odometry
    from netsim.bridge.node import Node, serialized

    node = Node(DOMAINS["bytes"])
    writer = node.writer("/robot_3/odom", "nav_msgs/msg/Odometry")
    template = odometry(writer, 3)
    got = template.fill(sec=12, nanosec=500_000_000, x=101.25, y=-3.5, vx=1.5, vy=-0.25)
    msg = Odometry(
        header=Header(stamp=Time(sec=12, nanosec=500_000_000), frame_id="world"),
        child_frame_id="robot_3",
        pose=PoseWithCovariance(
            pose=Pose(position=Point(x=101.25, y=-3.5, z=0.0), orientation=Quaternion(x=0.0, y=0.0, z=0.0, w=1.0)),
            covariance=[0.0] * 36,
        ),
        twist=TwistWithCovariance(
            twist=Twist(linear=Vector3(x=1.5, y=-0.25, z=0.0), angular=Vector3(x=0.0, y=0.0, z=0.0)),
            covariance=[0.0] * 36,
        ),
    )
    assert got == serialized(writer, msg)
    assert Odometry.deserialize(got) == msg


@pytest.mark.parametrize("odom_hz", [1.0, 3.0, 4.0, 10.0, 20.0])
def test_the_links_go_out_twice_a_simulated_second_whatever_the_steps(odom_hz):
    """``/network/links`` goes out at the first step and the first step of each half
    second: twice in every simulated second when steps are at most half a second, every
    step when they are longer. (It went out every round(odom_hz / 2) steps: 1.5 times a
    second at 3 Hz.)"""
    from netsim.bridge.bridge import links_period

    steps = [k / odom_hz for k in range(1, int(6 * odom_hz) + 1)]
    sent, last = [], None
    for t in steps:
        if links_period(t) != last:
            sent.append(t)
            last = links_period(t)
    per_second = [sum(k <= t < k + 1 for t in sent) for k in range(1, 6)]
    assert per_second == [min(2, int(odom_hz))] * 5, sent


def test_link_markers_colour_robots_by_role_and_size_them_to_the_area():
    """The bridge's ``robots`` marker colours a leader (``alpha``) red, a member (``beta``)
    blue, as the live view's scene does, and sizes the spheres to the area so that they
    show in a view of the whole area."""
    from netsim.bridge.bridge import RosBridge
    from netsim.bridge.look import ROLE_RGBA
    from netsim.bridge.settings import BridgeSettings
    from netsim.run import build
    from tests.fixtures import make_config

    config = make_config(
        seed=3,
        duration_s=30,
        world={"n_robots": 12, "side_m": 300.0, "placement": "centre", "centre_side_m": 150.0},
        mobility={"model": "external"},
        channel={"range_m": 80},
    )
    sim = build(config)
    ros = RosBridge(sim, BridgeSettings(domain_id=DOMAINS["markers"]))
    sim.run(until_s=20)
    from netsim.bridge.messages import stamp

    robots, _links = ros._markers(stamp(20.0), sim.positions()).markers
    names = [sim.groups.role_names[int(c)] for c in sim.groups.role]
    assert {"alpha", "beta"} <= set(names)
    got = [(c.r, c.g, c.b, c.a) for c in robots.colors]
    assert got == [tuple(np.float32(v) for v in ROLE_RGBA[r]) for r in names]
    assert robots.scale.x == 3.0  # 1/100 of the 300 m side


# -- bad input: one line, exit status 2, nothing written, before DDS is loaded --------------
@pytest.mark.parametrize(
    ("sets", "flags", "message"),
    [
        (["bridge.relay=[{name='chat', type='std_msgs/msg/Nope'}]"], [], "bridge.relay[0].type = 'std_msgs/msg/Nope'"),
        (["bridge.domain_id=233"], [], "bridge.domain_id = 233: must be an integer from 0 to 232"),
        (["bridge.domain_id=-1"], [], "bridge.domain_id = -1"),
        ([], ["--rate", "0"], "--rate 0: must be a positive"),
        ([], ["--rate", "-2"], "--rate -2: must be a positive"),
        (["mobility.model=random_waypoint"], [], "mobility.model = 'random_waypoint'"),
        (["events.runtime_links=off"], [], "events.runtime_links = 'off': netsim bridge draws the links as they"),
        (["events.runtime_links=off"], ["--live", "0"], "events.runtime_links = 'off': netsim bridge draws the links"),
        (
            ["bridge.odom_hz=1e9"],
            [],
            "bridge.odom_hz = 1000000000.0: the run would make 3e+11 events of it in duration_s = 300 s",
        ),
        (
            ["duration_s=3e9", "bridge.odom_hz=1e-9", "protocol.model=none", "output.position_interval_s=0"],
            ["--rate", "1e9"],
            "duration_s = 3000000000.0: the bridge stamps its messages in ROS 2's Time",
        ),
    ],
    ids=[
        "unknown_relay_type",
        "domain_id_too_large",
        "domain_id_negative",
        "rate_zero",
        "rate_negative",
        "not_external",
        "no_runtime_links",
        "no_runtime_links_live",
        "odom_hz_too_many_steps",
        "duration_past_a_stamp",
    ],
)
def test_bad_bridge_input_is_one_line_and_exit_2(tmp_path, capsys, sets, flags, message):
    """An unknown relay type, a domain id outside 0..232, a --rate not positive, a mobility
    model other than external, no link solved during the run (/network/links drew none;
    with --live it was refused late, blaming a hook): one line on standard error, exit
    status 2, nothing written."""
    from netsim.tools.cli import main

    args = ["bridge", "--out", str(tmp_path / "out")]
    # External motion unless the case sets another model (a key given twice is warned of).
    own_model = any(s.startswith("mobility.model=") for s in sets)
    for s in [*([] if own_model else ["mobility.model=external"]), *sets]:
        args += ["--set", s]
    code = main(args + flags)
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1 and err.startswith("netsim: error: ") and message in err
    assert not (tmp_path / "out").exists()


@pytest.mark.slow
def test_netsim_run_loads_neither_dds_nor_foxglove(tmp_path):
    """``netsim run`` (no --live) imports neither cyclonedds nor foxglove: the bridge costs
    nothing when not used."""
    code = (
        "import sys\n"
        "from netsim.tools.cli import main\n"
        f"assert main(['run', '--out', {str(tmp_path / 'o')!r}, '--quiet', '--set', 'duration_s=5',"
        " '--set', 'mobility.model=external']) == 0\n"
        "print(sorted(m for m in sys.modules if m.split('.')[0] in ('cyclonedds', 'foxglove', 'netsim')"
        " and (m.startswith('netsim.bridge') or not m.startswith('netsim'))))\n"
    )
    env = {k: v for k, v in os.environ.items() if k != "NETSIM_COMPILED"}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env)
    assert out.stdout.strip().splitlines()[-1] == "[]"


def test_a_cyclone_configuration_that_does_not_parse_is_refused_naming_it(tmp_path, monkeypatch):
    """CYCLONEDDS_URI naming a file Cyclone cannot parse: the bridge ends with one line of
    its own naming that variable (after Cyclone's own line), exit 2, nothing written (it was
    a traceback)."""
    broken = tmp_path / "broken.xml"
    broken.write_text("<CycloneDDS><Domain\n")
    monkeypatch.setenv("CYCLONEDDS_URI", broken.as_uri())
    run = subprocess.run(
        [COMMAND, "bridge", str(scenario(tmp_path, DOMAINS["bad_uri"])), "--out", str(tmp_path / "out"), "--quiet"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert run.returncode == 2, run.stderr
    last = run.stderr.strip().splitlines()[-1]
    assert last.startswith(f"netsim: error: CYCLONEDDS_URI = '{broken.as_uri()}': Cyclone DDS cannot start on domain")
    assert "Traceback" not in run.stderr
    assert not (tmp_path / "out").exists()


# -- rules a mutation audit found no test for ------------------------------------------------
def test_the_highest_dds_domain_is_taken_and_a_boolean_is_no_domain():
    from netsim.bridge.settings import DOMAIN_ID_MAX, settings
    from netsim.errors import ConfigError

    assert settings({"domain_id": DOMAIN_ID_MAX}).domain_id == DOMAIN_ID_MAX
    with pytest.raises(ConfigError, match=f"^bridge.domain_id = true: must be an integer from 0 to {DOMAIN_ID_MAX}$"):
        settings({"domain_id": True})


def test_topics_are_ros_2s_under_rt():
    from netsim.bridge.node import Node, dds_topic

    assert dds_topic("/robot_0/odom") == "rt/robot_0/odom"
    node = Node(DOMAINS["node"])
    assert node.writer("/robot_0/odom", "nav_msgs/msg/Odometry").topic.name == "rt/robot_0/odom"


def test_a_serialized_message_is_padded_to_four_bytes_as_the_writer_pads_it():
    from netsim.bridge.messages import zero
    from netsim.bridge.node import Node, serialized

    writer = Node(DOMAINS["node"]).writer("/chat", "std_msgs/msg/String")
    msg = zero("std_msgs/msg/String")
    msg.data = "ab"  # 4 + 4 + 3 bytes
    assert serialized(writer, msg) == msg.serialize(use_version_2=writer._use_version_2) + b"\0"
    assert len(serialized(writer, msg)) == 12


def test_a_template_field_whose_sentinel_is_found_twice_is_refused():
    from netsim.bridge.messages import zero
    from netsim.bridge.node import Node, Template

    writer = Node(DOMAINS["node"]).writer("/v", "geometry_msgs/msg/Vector3")

    def both(m, v):  # a setter that writes two fields: the sentinel cannot name one place
        m.x = m.y = v

    with pytest.raises(RuntimeError, match="^cannot place the field x in the message's bytes$"):
        Template(writer, zero("geometry_msgs/msg/Vector3"), {"x": ("<d", both)})


def test_clock_has_ros_2s_clock_qos_and_the_inbox_keeps_all():
    from netsim.bridge.node import CLOCK_QOS, INBOX_QOS

    assert Policy.Reliability.BestEffort in CLOCK_QOS and Policy.History.KeepLast(1) in CLOCK_QOS
    assert Policy.History.KeepAll in INBOX_QOS


def test_take_all_takes_every_sample_waiting_past_one_batch():
    from netsim.bridge.messages import idl_type
    from netsim.bridge.node import INBOX_QOS, Node, take_all

    node = Node(DOMAINS["node"])
    reader = node.reader("/robot_0/tx/chat", "std_msgs/msg/String")
    writer = node.writer("/robot_0/tx/chat", "std_msgs/msg/String", qos=INBOX_QOS)
    msg = idl_type("std_msgs/msg/String")
    for k in range(100):
        writer.write(msg(data=f"m{k}"))
    assert [s.data for s in take_all(reader)] == [f"m{k}" for k in range(100)]
    writer.dispose(msg(data="m0"))
    assert take_all(reader) == []


def test_a_bridge_with_a_live_view_sends_it_every_step(tmp_path, monkeypatch):
    from netsim.bridge.live_view import LiveView
    from netsim.tools.cli import main

    sent: list[float] = []
    monkeypatch.setattr(LiveView, "publish", lambda self, t_s: sent.append(t_s))
    config = scenario(tmp_path, DOMAINS["live"], duration_s=0.5)
    assert main(["bridge", str(config), "--out", str(tmp_path / "out"), "--quiet", "--rate", "1e3", "--live", "0"]) == 0
    assert sent == pytest.approx([0.1, 0.2, 0.3, 0.4, 0.5])


def test_the_bridge_paces_the_run_at_the_rate_given(tmp_path, monkeypatch):
    """``--rate R`` is the pacer's: R simulated seconds per wall second, as the summary
    reports it (a bridge that paced at 1 whatever it was asked reported R all the same)."""
    import netsim.tools.bridge
    from netsim.bridge.loop import Pacer
    from netsim.tools.cli import main

    rates: list[float] = []

    class Recorded(Pacer):
        def __init__(self, sim, period_s, rate, *rest):
            rates.append(rate)
            super().__init__(sim, period_s, rate, *rest)

    monkeypatch.setattr(netsim.tools.bridge, "Pacer", Recorded)
    config = scenario(tmp_path, DOMAINS["rate"], duration_s=0.5)
    assert main(["bridge", str(config), "--out", str(tmp_path / "out"), "--quiet", "--rate", "250"]) == 0
    assert rates == [250.0]
    assert json.loads((tmp_path / "out" / "summary.json").read_text())["bridge_rate"] == 250.0


@pytest.mark.slow
def test_a_best_effort_publisher_that_netsim_cannot_match_is_warned_of_once():
    """A node publishing /robot_1/cmd_vel best effort never matches netsim's reliable reader,
    so none of its commands arrives: the bridge's step warns naming the topic, once (a
    reliable publisher beside it is not named), and goes on."""
    from netsim.bridge.bridge import RosBridge
    from netsim.bridge.settings import BridgeSettings
    from netsim.run import build
    from tests.fixtures import make_config

    sim = build(make_config(duration_s=5, world={"n_robots": 2}, mobility={"model": "external"}))
    ros = RosBridge(sim, BridgeSettings(domain_id=DOMAINS["best_effort"]))
    dp = DomainParticipant(DOMAINS["best_effort"])
    writers = [  # kept: a writer no one holds is deleted
        DataWriter(dp, Topic(dp, "rt/robot_0/cmd_vel", Twist), qos=RELIABLE),
        DataWriter(dp, Topic(dp, "rt/robot_1/cmd_vel", Twist), qos=CLOCK_QOS),  # best effort
    ]
    said: list[str] = []
    end = time.monotonic() + 30
    while not said and time.monotonic() < end:  # discovery is asynchronous
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            ros.take(0.0)
        said += [str(w.message) for w in caught]
        time.sleep(0.02)
    assert len(said) == 1 and len(writers) == 2
    assert said[0] == (
        "/robot_1/cmd_vel: a node publishes it with a QoS netsim cannot match, so none of its messages is taken "
        "(best effort: netsim reads reliably; publish it reliable, ROS 2's default)"
    )
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        ros.take(0.0)
    assert caught == []  # once
