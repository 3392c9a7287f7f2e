"""The live view (``netsim run --live``, ``netsim bridge --live``): a Foxglove WebSocket
server that a client on the loopback connects to, sees the channels advertised on, and
gets the run's messages from as they happen."""

import json
import struct
import subprocess
import sys
from pathlib import Path

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
