"""The live view (``netsim run --live``, ``netsim bridge --live``): a Foxglove WebSocket
server that a client on the loopback connects to, sees the channels advertised on, and
gets the run's messages from as they happen."""

import json
import struct
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import pytest

pytest.importorskip("foxglove")  # the extra "ros" (installed with "test")
client = pytest.importorskip("websockets.sync.client")

COMMAND = str(Path(sys.executable).with_name("netsim"))
# The Foxglove WebSocket protocol as foxglove-sdk serves it.
SUBPROTOCOL = "foxglove.sdk.v1"
CHANNELS = {"/netsim/scene", "/netsim/poses", "/netsim/roles", "/netsim/links", "/netsim/messages"}


def live_port(proc: subprocess.Popen) -> int:
    """The port the command says its server listens on (it was given 0: any free port)."""
    for line in proc.stderr:
        if line.startswith("live view:"):
            return int(line.rsplit(":", 1)[1])
    raise AssertionError(f"no live view line; the command ended with {proc.wait()}")


@pytest.mark.slow
def test_live_run_advertises_its_channels_and_streams_poses(tmp_path):
    """``netsim run --live 0`` serves Foxglove's WebSocket protocol on the loopback: a client
    gets the channels advertised (scene, poses, roles, links, messages) and, once
    subscribed, the robots' poses with the run's simulated time."""
    proc = subprocess.Popen(
        [COMMAND, "run", "--live", "0", "--quiet", "--out", str(tmp_path / "out")]
        + ["--set", "duration_s=8", "--set", "world.n_robots=6", "--set", "world.side_m=100"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        port = live_port(proc)
        with client.connect(f"ws://127.0.0.1:{port}", subprotocols=[SUBPROTOCOL], open_timeout=30) as ws:
            channels: dict[str, dict] = {}
            while not CHANNELS <= set(channels):
                msg = ws.recv(timeout=30)
                if isinstance(msg, str) and json.loads(msg).get("op") == "advertise":
                    channels.update({c["topic"]: c for c in json.loads(msg)["channels"]})
            poses = channels["/netsim/poses"]
            assert poses["encoding"] == "json"
            assert channels["/netsim/scene"]["schemaName"] == "foxglove.SceneUpdate"
            ws.send(json.dumps({"op": "subscribe", "subscriptions": [{"id": 7, "channelId": poses["id"]}]}))
            while True:
                msg = ws.recv(timeout=30)
                if isinstance(msg, bytes) and msg[0] == 1:  # a message data frame
                    sub, log_time_ns = struct.unpack_from("<IQ", msg, 1)
                    body = json.loads(msg[13:])
                    break
        assert sub == 7
        assert len(body["x_m"]) == len(body["y_m"]) == 6
        assert 0 < body["t_s"] <= 8 and log_time_ns == round(body["t_s"] * 1e9)
        assert all(0 <= x <= 100 for x in body["x_m"])
    finally:
        proc.communicate(timeout=120)
    assert proc.returncode == 0
    assert (tmp_path / "out" / "positions.parquet").is_file()


def _clustered_sim(side_m: float = 200.0):
    """Twelve static robots under the clustering protocol (run 20 s: leaders and members)."""
    from netsim.run import build
    from tests.fixtures import make_config

    config = make_config(
        seed=3,
        duration_s=30,
        world={"n_robots": 12, "side_m": side_m},
        mobility={"model": "static"},
        channel={"range_m": 80},
    )
    return build(config)


def test_live_scene_colours_leaders_members_and_undecided_robots():
    """The scene's sphere of a leader (role ``alpha``) is red, a member's (``beta``) blue, an
    undecided robot's (``gamma``) grey: the colours follow the protocol's role labels."""
    from netsim.bridge.look import GREY, robot_rgba

    sim = _clustered_sim()
    sim.run(until_s=20)
    names = [sim.groups.role_names[int(c)] for c in sim.groups.role]
    assert {"alpha", "beta"} <= set(names)
    expected = {"alpha": (0.85, 0.2, 0.2, 1.0), "beta": (0.2, 0.45, 0.85, 1.0), "gamma": GREY}
    assert robot_rgba(sim.groups, sim.state.n) == [expected[r] for r in names]


def test_live_scene_robots_and_links_show_with_the_whole_area_in_view():
    """A robot's sphere is 1/100 of the area's longer side across, and links are lines a
    fixed number of screen pixels wide, so both show when the app looks at the whole area."""
    from netsim.area import Bounds
    from netsim.bridge.live_view import LINK_WIDTH_PX, LiveView
    from netsim.bridge.look import robot_diameter_m

    assert robot_diameter_m(Bounds(0.0, 0.0, 1000.0, 400.0)) == 10.0
    sim = _clustered_sim(side_m=500.0)
    view = LiveView(sim, 0)
    try:
        sim.run(until_s=20)
        sent = []
        view.scene = SimpleNamespace(log=lambda msg, log_time: sent.append(repr(msg)))
        view.publish(sim.env.now)
    finally:
        view.close()
    assert "size: Some(Vector3 { x: 5.0, y: 5.0, z: 5.0 })" in sent[0]  # the 500 m area
    assert f"thickness: {LINK_WIDTH_PX}, scale_invariant: true" in sent[0]


def test_a_dropped_message_is_strict_json_on_the_messages_channel():
    """A dropped message has no latency: the channel says null, which JSON has and its
    schema allows, not NaN, which a client's strict parser (a browser's ``JSON.parse``, as
    the Foxglove app's) refuses: every drop was unreadable there."""
    from netsim.bridge.live_view import MESSAGES_SCHEMA, LiveView

    sim = _clustered_sim()
    view = LiveView(sim, 0)
    sent = []
    try:
        view.messages = SimpleNamespace(log=lambda row, log_time: sent.append(row))
        view._dropped(SimpleNamespace(t_s=1.5, msg_id=3, src=0, dst=4, hops=2, cause="ttl"))
    finally:
        view.close()
    (row,) = sent
    assert json.loads(json.dumps(row, allow_nan=False))["latency_s"] is None
    assert "null" in MESSAGES_SCHEMA["properties"]["latency_s"]["type"]


def test_live_views_draw_a_link_across_a_torus_seam_from_both_ends():
    """The live scene and the bridge's markers draw a link 3 m long across the seam of a
    100 m torus as two 3 m segments toward the border, not one 97 m across the area; on
    the plane a link is itself."""
    import numpy as np

    from netsim.bridge.look import link_line_list

    pos = np.array([[1.0, 50.0], [98.0, 50.0], [50.0, 10.0], [52.0, 10.0]])
    points = np.array(link_line_list(pos, [(0, 1), (2, 3)], 100.0)).reshape(-1, 2, 2)
    assert np.hypot(*(points[:, 1] - points[:, 0]).T).tolist() == [3.0, 2.0, 3.0]
    assert points.tolist() == [[[1, 50], [-2, 50]], [[50, 10], [52, 10]], [[101, 50], [98, 50]]]
    assert link_line_list(pos, [(0, 1)], None) == [(1.0, 50.0), (98.0, 50.0)]
    assert link_line_list(pos, [], 100.0) == []


def test_a_live_port_in_use_is_one_line_exit_2_nothing_written(tmp_path):
    """`--live PORT` on a port another server holds: one line naming it, exit 2, nothing
    written (it was a traceback from the WebSocket library)."""
    import socket

    holder = socket.socket()
    holder.bind(("127.0.0.1", 0))
    holder.listen()
    port = holder.getsockname()[1]
    try:
        out = tmp_path / "out"
        run = subprocess.run(
            [COMMAND, "run", "--quiet", "--live", str(port), "--set", "duration_s=2", "--out", str(out)],
            capture_output=True,
            text=True,
            timeout=120,
        )
    finally:
        holder.close()
    lines = run.stderr.strip().splitlines()
    assert run.returncode == 2, run.stderr
    assert len(lines) == 1 and lines[0].startswith(f"netsim: error: --live {port}: cannot serve on 127.0.0.1:{port}")
    assert not out.exists()


def test_live_without_runtime_links_is_refused_before_anything_starts(tmp_path, capsys):
    """`netsim run --live` with events.runtime_links = "off": one line saying the live view
    draws the links as they change, exit 2, nothing written, before the server starts (it
    was refused after, blaming a hook)."""
    from netsim.tools.cli import main

    out = tmp_path / "out"
    code = main(["run", "--live", "0", "--set", "events.runtime_links=off", "--set", "duration_s=2", "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1, err
    assert err.startswith("netsim: error: events.runtime_links = 'off': netsim run --live draws the links as they")
    assert not out.exists()


def test_robots_without_known_roles_are_grey():
    """A run without groups, or a protocol whose role labels are not the clustering
    protocol's, draws every such robot grey, one colour a robot."""
    from netsim.bridge.look import GREY, ROLE_RGBA, robot_rgba

    assert robot_rgba(None, 3) == [GREY] * 3
    groups = SimpleNamespace(role_names=("scout", "alpha"), role=[0, 1, 0])
    assert robot_rgba(groups, 3) == [GREY, ROLE_RGBA["alpha"], GREY]


def test_a_live_run_sends_the_scene_every_tenth_of_a_simulated_second(monkeypatch):
    from netsim.bridge.live_view import LiveView
    from netsim.tools.bridge import run_live
    from tests.fixtures import make_config

    sent: list[float] = []
    monkeypatch.setattr(LiveView, "publish", lambda self, t_s: sent.append(t_s))
    config = make_config(seed=1, duration_s=0.3, world={"n_robots": 3, "side_m": 50.0}, mobility={"model": "static"})
    run_live(config, 0, SimpleNamespace(table=lambda name, frame: None))
    assert sent == pytest.approx([0.1, 0.2, 0.3])


@pytest.mark.slow
def test_a_viewer_that_drops_its_connection_leaves_standard_error_clean(tmp_path):
    """A client that goes without closing the WebSocket (a closed tab: its socket reset) is
    no error of the run: the command's standard error holds its own lines only, none of the
    SDK's log of the client's socket."""
    import contextlib
    import socket

    proc = subprocess.Popen(
        [COMMAND, "run", "--live", "0", "--quiet", "--no-progress", "--out", str(tmp_path / "out")]
        + ["--set", "duration_s=8", "--set", "world.n_robots=6", "--set", "world.side_m=100"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    port = live_port(proc)
    # The client's own closing finds its socket gone: that is the point.
    with contextlib.suppress(OSError):
        with client.connect(f"ws://127.0.0.1:{port}", subprotocols=[SUBPROTOCOL], open_timeout=30) as ws:
            ws.recv(timeout=30)  # the server's hello: the connection is up
            # Gone with a reset (SO_LINGER 0), no closing handshake.
            ws.socket.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
            ws.socket.close()
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 0
    assert err.strip() == "", err
