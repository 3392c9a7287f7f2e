"""The live view: a Foxglove WebSocket server (``foxglove-sdk``) that streams a run as it
happens, for the Foxglove app (``Open connection`` > ``Foxglove WebSocket``,
``ws://127.0.0.1:PORT``).

Channels (every message's log time is its simulated instant, and the server tells the
app the simulated time):

- ``/netsim/scene``: ``foxglove.SceneUpdate``, a sphere per robot coloured by role and the
  links as lines, frame ``world``; every step;
- ``/netsim/poses``: JSON ``{t_s, x_m, y_m, vx_mps, vy_mps}`` (lists by robot); every step;
- ``/netsim/roles``: JSON ``{t_s, robot, role, leader, cause}``; at each role change;
- ``/netsim/links``: JSON ``{t_s, a, b, up}``; as each link comes up or goes down;
- ``/netsim/messages``: JSON ``{t_s, msg_id, src, dst, hops, delivered, latency_s,
  cause}``; as each protocol message is delivered or dropped end to end (``latency_s``
  null for a dropped one: JSON has no NaN, and a client's strict parser refuses it).

A step is ``1 / bridge.odom_hz`` simulated seconds in ``netsim bridge``, 0.1 s in
``netsim run --live``.
"""

from __future__ import annotations

import logging
from typing import Any

import foxglove
from foxglove.channels import SceneUpdateChannel
from foxglove.messages import (
    Color,
    LinePrimitive,
    LinePrimitiveLineType,
    Point3,
    Pose,
    Quaternion,
    SceneEntity,
    SceneUpdate,
    SpherePrimitive,
    Timestamp,
    Vector3,
)

from netsim.bridge.look import LINK_RGBA, link_line_list, robot_diameter_m, robot_rgba
from netsim.config import world_bounds
from netsim.errors import NetsimInputError
from netsim.stamps import ns, sec_nanosec

# Links are drawn in screen pixels: in metres they would vanish when the whole area is in view.
LINK_WIDTH_PX = 2.0

_NUMBERS = {"type": "array", "items": {"type": "number"}}
POSES_SCHEMA = {
    "type": "object",
    "properties": {"t_s": {"type": "number"}, "x_m": _NUMBERS, "y_m": _NUMBERS, "vx_mps": _NUMBERS, "vy_mps": _NUMBERS},
}
ROLES_SCHEMA = {
    "type": "object",
    "properties": {
        "t_s": {"type": "number"},
        "robot": {"type": "integer"},
        "role": {"type": "string"},
        "leader": {"type": "integer"},
        "cause": {"type": "string"},
    },
}
LINKS_SCHEMA = {
    "type": "object",
    "properties": {
        "t_s": {"type": "number"},
        "a": {"type": "integer"},
        "b": {"type": "integer"},
        "up": {"type": "boolean"},
    },
}
MESSAGES_SCHEMA = {
    "type": "object",
    "properties": {
        "t_s": {"type": "number"},
        "msg_id": {"type": "integer"},
        "src": {"type": "integer"},
        "dst": {"type": "integer"},
        "hops": {"type": "integer"},
        "delivered": {"type": "boolean"},
        "latency_s": {"type": ["number", "null"]},
        "cause": {"type": "string"},
    },
}


def _colour(rgba: tuple[float, float, float, float]) -> Color:
    r, g, b, a = rgba
    return Color(r=r, g=g, b=b, a=a)


# The Foxglove SDK's log (Python's logging) of what a connected client's socket does.
CLIENT_LOG = "foxglove.websocket.connected_client"


class LiveView:
    """The server and its channels, fed by the run's events and by :meth:`publish`."""

    def __init__(self, sim: Any, port: int, host: str = "127.0.0.1"):
        self.sim = sim
        # A viewer that goes without closing its connection (a tab closed, a laptop asleep)
        # is no fault of the run: the server's log of it is not shown.
        logging.getLogger(CLIENT_LOG).setLevel(logging.CRITICAL)
        try:
            self.server = foxglove.start_server(
                name="netsim", host=host, port=port, capabilities=[foxglove.Capability.Time]
            )
        except RuntimeError as exc:  # the port taken, or not ours to bind
            raise NetsimInputError(f"--live {port}: cannot serve on {host}:{port} ({exc})") from None
        self.port = self.server.port
        self.scene = SceneUpdateChannel("/netsim/scene")
        self.poses = foxglove.Channel("/netsim/poses", schema=POSES_SCHEMA)
        self.roles = foxglove.Channel("/netsim/roles", schema=ROLES_SCHEMA)
        self.links = foxglove.Channel("/netsim/links", schema=LINKS_SCHEMA)
        self.messages = foxglove.Channel("/netsim/messages", schema=MESSAGES_SCHEMA)
        self.up: set[tuple[int, int]] = set()
        self.robot_m = robot_diameter_m(world_bounds(sim.config.world))
        ev = sim.events
        ev.on("link_up", self._link_up)
        ev.on("link_down", self._link_down)
        ev.on("role_change", self._role)
        ev.on("message_delivered", self._delivered)
        ev.on("message_dropped", self._dropped)

    # -- as they happen --------------------------------------------------------------
    def _link_up(self, e: Any) -> None:
        self.up.add((e.a, e.b))
        self.links.log({"t_s": e.t_s, "a": e.a, "b": e.b, "up": True}, log_time=ns(e.t_s))

    def _link_down(self, e: Any) -> None:
        self.up.discard((e.a, e.b))
        self.links.log({"t_s": e.t_s, "a": e.a, "b": e.b, "up": False}, log_time=ns(e.t_s))

    def _role(self, e: Any) -> None:
        t = float(e.t_s)
        row = {"t_s": t, "robot": int(e.robot), "role": str(e.role), "leader": int(e.leader), "cause": str(e.cause)}
        self.roles.log(row, log_time=ns(t))

    def _delivered(self, e: Any) -> None:
        row = {"t_s": e.t_s, "msg_id": e.msg_id, "src": e.src, "dst": e.dst, "hops": e.hops, "delivered": True}
        row.update(latency_s=e.latency_s, cause="")
        self.messages.log(row, log_time=ns(e.t_s))

    def _dropped(self, e: Any) -> None:
        row = {"t_s": e.t_s, "msg_id": e.msg_id, "src": e.src, "dst": e.dst, "hops": e.hops, "delivered": False}
        row.update(latency_s=None, cause=e.cause)
        self.messages.log(row, log_time=ns(e.t_s))

    # -- every step ------------------------------------------------------------------
    def publish(self, t_s: float) -> None:
        sim, t_ns = self.sim, ns(t_s)
        pos = sim.positions()
        vel = sim.state.velocity_mps
        self.server.broadcast_time(t_ns)
        self.poses.log(
            {
                "t_s": t_s,
                "x_m": pos[:, 0].tolist(),
                "y_m": pos[:, 1].tolist(),
                "vx_mps": vel[:, 0].tolist(),
                "vy_mps": vel[:, 1].tolist(),
            },
            log_time=t_ns,
        )
        rgba = robot_rgba(sim.groups, len(pos))
        stamp = Timestamp(*sec_nanosec(t_s))
        d = self.robot_m
        size = Vector3(x=d, y=d, z=d)
        spheres = [
            SpherePrimitive(
                pose=Pose(position=Vector3(x=x, y=y, z=0.0), orientation=Quaternion(w=1.0)), size=size, color=_colour(c)
            )
            for (x, y), c in zip(pos.tolist(), rgba, strict=True)
        ]
        points = [Point3(x=x, y=y, z=0.0) for x, y in link_line_list(pos, sorted(self.up), sim.state.torus_side_m)]
        lines = [
            LinePrimitive(
                type=LinePrimitiveLineType.LineList,
                thickness=LINK_WIDTH_PX,
                scale_invariant=True,
                points=points,
                color=_colour(LINK_RGBA),
                pose=Pose(position=Vector3(), orientation=Quaternion(w=1.0)),
            )
        ]
        entities = [
            SceneEntity(timestamp=stamp, frame_id="world", id="robots", spheres=spheres),
            SceneEntity(timestamp=stamp, frame_id="world", id="links", lines=lines),
        ]
        self.scene.log(SceneUpdate(entities=entities), log_time=t_ns)

    def close(self) -> None:
        self.server.stop()
