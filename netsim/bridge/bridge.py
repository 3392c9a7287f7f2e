"""The run as ROS 2 nodes see it (docs/ros2.md): commands in, odometry, clock, network
and relayed messages out, on the topics below (``i`` a robot id).

| topic | type | way |
| --- | --- | --- |
| ``/robot_i/cmd_vel`` | geometry_msgs/msg/Twist | in |
| ``/robot_i/odom`` | nav_msgs/msg/Odometry | out |
| ``/robot_i/neighbours`` | std_msgs/msg/Int32MultiArray | out |
| ``/clock`` | rosgraph_msgs/msg/Clock | out |
| ``/network/links`` | visualization_msgs/msg/MarkerArray | out, ``LINKS_HZ`` per simulated s |
| ``/robot_i/tx/<name>`` | the relay's type | in |
| ``/robot_i/rx/<name>`` | the relay's type | out |

Robots have no heading: a Twist's ``linear.x`` and ``linear.y`` are the world frame's
(east and north, m/s), its other fields are ignored; odometry is in the frame ``world``
(the run's area), its orientation the identity.
"""

from __future__ import annotations

import math
import warnings
from typing import Any

import numpy as np

from netsim.bridge.look import LINK_RGBA, link_line_list, robot_diameter_m, robot_rgba
from netsim.bridge.messages import idl_type, stamp, zero
from netsim.bridge.node import CLOCK_QOS, QOS_POLICIES, Node, Template, serialized, take_all, write_bytes
from netsim.bridge.relay import ChannelRelay
from netsim.bridge.settings import BridgeSettings
from netsim.config import world_bounds
from netsim.geometry import drivable

FRAME = "world"
TWIST = "geometry_msgs/msg/Twist"
ODOM = "nav_msgs/msg/Odometry"
CLOCK = "rosgraph_msgs/msg/Clock"
NEIGHBOURS = "std_msgs/msg/Int32MultiArray"
MARKERS = "visualization_msgs/msg/MarkerArray"
LINKS_TOPIC = "/network/links"
# The links' markers per simulated second (at most one per step): Cyclone's Python
# serializer takes longer over a MarkerArray than over everything else a step publishes.
LINKS_HZ = 2.0


def links_period(t_s: float) -> int:
    """Which of the periods of ``1 / LINKS_HZ`` s the instant ``t_s`` falls in: the links go
    out at a run's first step and at the first step of each period after (every step when
    steps are longer than a period), so LINKS_HZ times a simulated second whatever
    ``odom_hz``. Rounded first, so that a step's end a rounding error short of a period's
    start (3 x 0.1 s is 0.30000000000000004) counts as reaching it."""
    return math.floor(round(t_s * LINKS_HZ, 9))


def _set(path: str) -> Any:
    """A function that sets the field at the dotted ``path`` of a message."""
    *parents, leaf = path.split(".")

    def set_field(message: Any, value: Any) -> None:
        for p in parents:
            message = getattr(message, p)
        setattr(message, leaf, value)

    return set_field


def unmatched_warning(topic: str, policy_id: int) -> str:
    why = QOS_POLICIES.get(policy_id, f"its QoS policy {policy_id}; publish it with ROS 2's default QoS")
    return f"{topic}: a node publishes it with a QoS netsim cannot match, so none of its messages is taken ({why})"


def odometry(writer: Any, robot: int) -> Template:
    """Robot ``robot``'s odometry, its stamp, position and velocity patched at each write."""
    msg = zero(ODOM)
    msg.header.frame_id, msg.child_frame_id = FRAME, f"robot_{robot}"
    msg.pose.pose.orientation.w = 1.0
    fields = {
        "sec": ("<i", _set("header.stamp.sec")),
        "nanosec": ("<I", _set("header.stamp.nanosec")),
        "x": ("<d", _set("pose.pose.position.x")),
        "y": ("<d", _set("pose.pose.position.y")),
        "vx": ("<d", _set("twist.twist.linear.x")),
        "vy": ("<d", _set("twist.twist.linear.y")),
    }
    return Template(writer, msg, fields)


class RosBridge:
    """Publishes and takes a run's topics on one DDS participant."""

    def __init__(self, sim: Any, settings: BridgeSettings):
        self.sim, self.settings = sim, settings
        n = sim.state.n
        self.node = node = Node(settings.domain_id)
        self.cmd = [node.reader(f"/robot_{i}/cmd_vel", TWIST) for i in range(n)]
        self.odom = [odometry(node.writer(f"/robot_{i}/odom", ODOM), i) for i in range(n)]
        self.neigh = [node.writer(f"/robot_{i}/neighbours", NEIGHBOURS) for i in range(n)]
        # Each robot's neighbours as last serialized: a list is serialized again only when it changes.
        self._neigh_sent: list[tuple[tuple[int, ...], bytes] | None] = [None] * n
        self.clock = node.writer("/clock", CLOCK, qos=CLOCK_QOS)
        self.links = node.writer(LINKS_TOPIC, MARKERS)
        self.relay = ChannelRelay(sim, [r.name for r in settings.relay])
        self.tx = {
            r.name: [node.reader(f"/robot_{i}/tx/{r.name}", r.msgtype) for i in range(n)] for r in settings.relay
        }
        self.rx = {
            r.name: [node.writer(f"/robot_{i}/rx/{r.name}", r.msgtype) for i in range(n)] for r in settings.relay
        }
        self.topology = sim.live_topology() if sim.config.events.runtime_links != "off" else None
        self.commands = 0
        self.refused = 0
        self._links_period: int | None = None  # the period the links last went out in
        self._types = {name: idl_type(name) for name in (ODOM, CLOCK, NEIGHBOURS, MARKERS)}

    # -- in ------------------------------------------------------------------------------
    def take(self, t_s: float) -> None:
        """Apply the commands and send the messages that came since the last call."""
        for topic, policy_id in self.node.unmatched():
            warnings.warn(unmatched_warning(topic, policy_id), stacklevel=2)
        robots, vel = [], []
        for i, reader in enumerate(self.cmd):
            got = take_all(reader)
            self.commands += len(got)
            # The latest command holds; one that is not a finite velocity below light speed is
            # dropped (counted), as a robot cannot be driven at it (NaN fails the comparison).
            good = [(float(c.linear.x), float(c.linear.y)) for c in got]
            good = [v for v in good if drivable(v)[0]]
            self.refused += len(got) - len(good)
            if good:
                robots.append(i)
                vel.append(good[-1])
        if robots:
            self.sim.drive(robots, np.array(vel, dtype=float))
        for name, readers in self.tx.items():
            for i, reader in enumerate(readers):
                for message in take_all(reader):
                    self.relay.send(i, name, message, len(message.serialize()))

    # -- out -----------------------------------------------------------------------------
    def publish(self, t_s: float) -> None:
        sim = self.sim
        now = stamp(t_s)
        self.clock.write(self._types[CLOCK](clock=now))
        pos = sim.positions()
        vel = sim.state.velocity_mps
        sec, nanosec = now.sec, now.nanosec
        for i, (x, y), (vx, vy) in zip(range(len(pos)), pos.tolist(), vel.tolist(), strict=True):
            self.odom[i].write(sec=sec, nanosec=nanosec, x=x, y=y, vx=vx, vy=vy)
        if sim.neighbour_view is not None:
            for i, writer in enumerate(self.neigh):
                ids = tuple(int(j) for j in sim.neighbours(i))
                sent = self._neigh_sent[i]
                if sent is None or sent[0] != ids:
                    msg = zero(NEIGHBOURS)
                    msg.data = list(ids)
                    sent = self._neigh_sent[i] = (ids, serialized(writer, msg))
                write_bytes(writer, sent[1])
        period = links_period(t_s)
        if period != self._links_period:
            self.links.write(self._markers(now, pos))
            self._links_period = period
        for robot, name, message in self.relay.take():
            self.rx[name][robot].write(message)

    def _markers(self, now: Any, pos: np.ndarray) -> Any:
        point = idl_type("geometry_msgs/msg/Point")
        colour = idl_type("std_msgs/msg/ColorRGBA")
        robots = zero("visualization_msgs/msg/Marker")
        robots.header.stamp, robots.header.frame_id = now, FRAME
        robots.ns, robots.id, robots.type = "robots", 0, 7  # SPHERE_LIST
        robots.pose.orientation.w = 1.0
        # Sized to the area, as in the Foxglove scene: seen when the whole area is in view.
        size = robot_diameter_m(world_bounds(self.sim.config.world))
        robots.scale.x = robots.scale.y = robots.scale.z = size
        robots.points = [point(x=float(x), y=float(y), z=0.0) for x, y in pos.tolist()]
        robots.colors = [colour(r=r, g=g, b=b, a=a) for r, g, b, a in robot_rgba(self.sim.groups, len(pos))]
        links = zero("visualization_msgs/msg/Marker")
        links.header.stamp, links.header.frame_id = now, FRAME
        links.ns, links.id, links.type = "links", 1, 5  # LINE_LIST
        links.pose.orientation.w = 1.0
        links.scale.x = size / 5.0
        r, g, b, a = LINK_RGBA
        links.color = colour(r=r, g=g, b=b, a=a)
        if self.topology is not None:
            pairs = [(int(a), int(b)) for a, b in self.topology.graph.edges]
            links.points = [point(x=x, y=y, z=0.0) for x, y in link_line_list(pos, pairs, self.sim.state.torus_side_m)]
        out = self._types[MARKERS](markers=[robots, links])
        return out
