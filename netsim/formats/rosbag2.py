"""ROS 2 bags (rosbag2: SQLite3 or MCAP storage), read and written with the ``rosbags``
library: no ROS installation is needed.

In: each robot's poses from ``nav_msgs/msg/Odometry`` or ``geometry_msgs/msg/PoseStamped``
messages, one topic per robot: by default the topics ``/robot_<i>/...`` of those types (one
per robot), or the list ``mobility.topics`` (robot ``i`` follows ``topics[i]``). A robot
follows its poses in straight lines between their header stamps; times count from the
first stamp of all the robots' poses; a robot whose log starts later waits at its first
pose (:mod:`netsim.formats.waypoints`). Orientation and height are ignored. The robots'
poses must be in one frame (their headers' ``frame_id``), or in frames that transforms on
``/tf_static`` join under one, in which they are then placed (in the plane: the
transforms' translations and yaw): robots whose odometry starts each in its own frame at
its own origin would otherwise be placed on top of each other. Frames are told apart by
name (a namespaced ``/<ns>/tf_static`` is not read): robots that start at one point are
warned of.

Out: a run as a bag (SQLite3, the storage every ROS 2 distribution reads), stamps the
simulated time: ``geometry_msgs/msg/PoseStamped`` on ``/robot_<i>/pose`` for every sampled
position (``positions.parquet``), the links up at each sampling instant as one
``visualization_msgs/msg/MarkerArray`` on ``/links`` (a ``LINE_LIST`` marker), each role
change as ``std_msgs/msg/String`` on ``/robot_<i>/role`` and each message sent or delivered
on ``/messages`` (JSON text), each packet of ``packets.parquet`` sent or delivered on
``/packets`` (JSON text; a routing protocol's run has packets and no messages), all in
frame ``map``.
"""

from __future__ import annotations

import json
import math
import re
import warnings
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from netsim.errors import NetsimInputError, listed
from netsim.formats.waypoints import Waypoints
from netsim.metrics import links_up_at
from netsim.stamps import ns, sec_nanosec

POSE_TYPES = ("nav_msgs/msg/Odometry", "geometry_msgs/msg/PoseStamped")
_ROBOT_TOPIC = re.compile(r"^/robot_(\d+)/")
FRAME = "map"
TF_STATIC, TF_TYPE = "/tf_static", "tf2_msgs/msg/TFMessage"


def _typestore() -> Any:
    from rosbags.typesys import Stores, get_typestore  # imported when asked: an optional dependency

    return get_typestore(Stores.ROS2_HUMBLE)


def _natural(name: str) -> list:
    """A sort key that puts /robot_2 before /robot_10."""
    return [(0, int(part), "") if part.isdigit() else (1, 0, part) for part in re.split(r"(\d+)", name)]


def _robot_topics(connections: Any, topics: Sequence[str], source: str) -> dict[str, int]:
    """Which topic each robot follows: ``{topic: robot}``."""
    types = {c.topic: c.msgtype for c in connections}
    pose_topics = {t: ty for t, ty in types.items() if ty in POSE_TYPES}
    if topics:
        missing = [t for t in topics if t not in pose_topics]
        if missing:
            first = missing[0]
            if first in types:
                raise NetsimInputError(
                    f"{source}: topic {first!r} of mobility.topics holds {types[first]}, not {' or '.join(POSE_TYPES)}"
                )
            have = listed(sorted(pose_topics, key=_natural)) or "none"
            raise NetsimInputError(
                f"{source}: topic {first!r} of mobility.topics is not in the bag (pose topics in the bag: {have})"
            )
        return {t: i for i, t in enumerate(topics)}
    chosen: dict[int, list[str]] = {}
    for topic in pose_topics:
        if m := _ROBOT_TOPIC.match(topic):
            chosen.setdefault(int(m[1]), []).append(topic)
    # A robot whose topics hold no pose is not read: said, as the team's size then differs.
    posed = {int(m[1]) for t in types if (m := _ROBOT_TOPIC.match(t)) and t not in pose_topics} - set(chosen)
    if posed:
        others = sorted((t for t in types if (m := _ROBOT_TOPIC.match(t)) and int(m[1]) in posed), key=_natural)
        warnings.warn(
            f"{source}: robot(s) {sorted(posed)[:10]} have topics but none holding a pose ("
            + listed([f"{t}: {types[t]}" for t in others], 5)
            + f"; a pose is {' or '.join(POSE_TYPES)}): they are not read",
            stacklevel=3,
        )
    if not chosen:
        raise NetsimInputError(
            f"{source}: no pose topic /robot_<i>/... of type {' or '.join(POSE_TYPES)} "
            f"(topics: {listed(sorted(types, key=_natural)) or 'none'}); name them in mobility.topics"
        )
    twice = {i: t for i, t in chosen.items() if len(t) > 1}
    if twice:
        i, several = next(iter(sorted(twice.items())))
        raise NetsimInputError(
            f"{source}: robot {i} has several pose topics {sorted(several)}; name one per robot in mobility.topics"
        )
    lacking = sorted(set(range(max(chosen) + 1)) - set(chosen))
    if lacking:
        raise NetsimInputError(f"{source}: no pose topic for robot(s) {lacking[:10]} (robots are numbered from 0)")
    return {t[0]: i for i, t in chosen.items()}


def _messages(reader: Any, conns: list[Any], source: str, reader_error: type[Exception]) -> Iterator[Any]:
    """The bag's messages on ``conns``; a storage the library cannot read on is one line."""
    try:
        yield from reader.messages(connections=conns)
    except reader_error as exc:
        why = " ".join(str(exc).split())
        raise NetsimInputError(f"{source}: cannot be read as a rosbag2 bag ({why})") from None


def read(path: str | Path, topics: Sequence[str] = ()) -> Waypoints:
    """The robots' tracks recorded in the bag at ``path`` (module notes); one line naming
    the bag and what is wrong otherwise."""
    from rosbags.rosbag2 import Reader, ReaderError  # imported when asked: an optional dependency
    from rosbags.serde import SerdeError

    path = Path(path)
    source = str(path)
    if path.is_file() and path.suffix in (".mcap", ".db3"):
        if (path.parent / "metadata.yaml").is_file():
            raise NetsimInputError(f"{source}: the storage file of a bag; give the bag's folder, {path.parent}")
        raise NetsimInputError(
            f"{source}: a storage file alone, without the metadata.yaml of a rosbag2 folder; put it in a folder of "
            "its own and run `ros2 bag reindex FOLDER` (with `-s mcap` for MCAP), which writes it"
        )
    if not path.is_dir():
        raise NetsimInputError(f"{source!r}: not a rosbag2 folder (a folder with metadata.yaml)")
    if not (path / "metadata.yaml").is_file():
        raise NetsimInputError(f"{source}: a folder is read as a rosbag2 bag, and this one has no metadata.yaml")
    try:
        reader = Reader(path)
        reader.open()
    except Exception as exc:  # the library's errors name the problem; one line for the user
        why = " ".join(str(exc).split())  # a YAML parser's message spans lines
        raise NetsimInputError(f"{source}: cannot be read as a rosbag2 bag ({why})") from None
    try:
        which = _robot_topics(reader.connections, topics, source)
        store = _typestore()
        conns = [c for c in reader.connections if c.topic in which]
        robots, stamps, xs, ys = [], [], [], []
        frames: dict[int, set[str]] = {}
        for conn, _t, raw in _messages(reader, conns, source, ReaderError):
            msg = _deserialized(store, raw, conn, source, SerdeError)
            pose = msg.pose.pose if conn.msgtype == "nav_msgs/msg/Odometry" else msg.pose
            stamp = msg.header.stamp
            robots.append(which[conn.topic])
            stamps.append(stamp.sec * 1_000_000_000 + stamp.nanosec)
            xs.append(pose.position.x)
            ys.append(pose.position.y)
            frames.setdefault(which[conn.topic], set()).add(_frame(msg.header.frame_id))
        placed = _into_one_frame(frames, reader, store, source, ReaderError, SerdeError)
    finally:
        reader.close()
    if placed:
        robot_of = np.array(robots, dtype=np.int64)
        x, y = np.array(xs, dtype=float), np.array(ys, dtype=float)
        for i, transform in placed.items():
            mine = robot_of == i
            x[mine], y[mine] = _placed(x[mine], y[mine], *transform)
        xs, ys = x.tolist(), y.tolist()
    posed = set(robots)
    silent = sorted((i, t) for t, i in which.items() if i not in posed)
    if silent:
        # A robot with no pose has no position to start from.
        i, topic = silent[0]
        more = f" ({len(silent)} such topics)" if len(silent) > 1 else ""
        raise NetsimInputError(f"{source}: topic {topic!r} of robot {i} holds no pose message{more}")
    stamps_ns = np.array(stamps, dtype=np.int64)
    _warn_of_stamps(np.array(robots, dtype=np.int64), stamps_ns, source)
    t = (stamps_ns - stamps_ns.min()) / 1e9 if len(stamps_ns) else stamps_ns.astype(float)
    if len(xs) and not np.isfinite(np.r_[xs, ys]).all():
        raise NetsimInputError(f"{source}: a pose has a non-finite position")
    wp = Waypoints.of(robots, t, xs, ys, source)
    _warn_of_shared_starts(wp.initial_m(), source)
    return wp


def _warn_of_shared_starts(start_m: np.ndarray, source: str) -> None:
    """Say where two robots start at one point: frames are told apart by name, and robots
    whose odometry each starts at its own origin in frames of one name (``odom`` in each
    robot's namespace) read as one frame stand on top of each other."""
    _, first, count = np.unique(np.round(start_m, 6), axis=0, return_index=True, return_counts=True)
    if (count > 1).any():
        k = int(np.flatnonzero(count > 1)[0])
        x, y = start_m[first[k]]
        warnings.warn(
            f"{source}: {int(count[k])} robots start at ({x:g}, {y:g}): odometry from each robot's own origin, in "
            "frames of one name? The frames are told apart by name: give the poses in one frame (such as map)",
            stacklevel=3,
        )


def _deserialized(store: Any, raw: bytes, conn: Any, source: str, serde_error: type[Exception]) -> Any:
    try:
        return store.deserialize_cdr(raw, conn.msgtype)
    except serde_error as exc:
        why = " ".join(str(exc).split())
        raise NetsimInputError(f"{source}: a message on {conn.topic!r} is not a {conn.msgtype} ({why})") from None


def _frame(frame_id: str) -> str:
    """A frame's name as tf2 compares them (a leading slash is not part of it)."""
    return frame_id.lstrip("/")


def _into_one_frame(
    frames: dict[int, set[str]], reader: Any, store: Any, source: str, reader_error: type, serde_error: type
) -> dict[int, tuple[float, float, float]]:
    """Per robot, the planar transform ``(x, y, yaw)`` that takes its poses into the frame
    all the robots share through ``/tf_static``; empty when they are in one frame already.
    Poses in frames nothing joins are one line: placed as if in one frame, robots whose
    odometry starts at their own origins would stand on top of each other."""
    for i, names in sorted(frames.items()):
        if len(names) > 1:
            raise NetsimInputError(f"{source}: robot {i}'s poses are in several frames ({_frames_listed(names)})")
    frame_of = {i: next(iter(names)) for i, names in frames.items()}
    distinct = set(frame_of.values())
    if len(distinct) <= 1:
        return {}
    conns = [c for c in reader.connections if c.topic == TF_STATIC and c.msgtype == TF_TYPE]
    parent: dict[str, tuple[str, float, float, float]] = {}
    # (The reader takes no connections to mean all of them.)
    for conn, _t, raw in _messages(reader, conns, source, reader_error) if conns else ():
        for tf in _deserialized(store, raw, conn, source, serde_error).transforms:
            q, t = tf.transform.rotation, tf.transform.translation
            yaw = math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))
            parent[_frame(tf.child_frame_id)] = (_frame(tf.header.frame_id), t.x, t.y, yaw)
    rooted = {name: _to_root(name, parent, source) for name in sorted(distinct)}
    if len({root for root, *_ in rooted.values()}) > 1:
        raise NetsimInputError(
            f"{source}: the robots' poses are in {len(distinct)} frames ({_frames_listed(distinct)}) that no "
            f"transforms on {TF_STATIC} join under one: netsim places every robot in one frame; record the poses "
            "in one frame (such as map), or the static transforms from theirs to it"
        )
    return {i: rooted[name][1:] for i, name in frame_of.items()}


def _to_root(
    frame: str, parent: dict[str, tuple[str, float, float, float]], source: str
) -> tuple[str, float, float, float]:
    """The frame at the top of ``frame``'s chain of static transforms, and the planar
    transform ``(x, y, yaw)`` taking a point of ``frame`` into it (``p -> R(yaw) p + (x, y)``).
    A chain that comes back to a frame has no top: one line naming it."""
    x = y = yaw = 0.0
    chain = [frame]
    while frame in parent:
        up, tx, ty, turn = parent[frame]
        if up in chain:
            loop = " -> ".join(repr(f) for f in [*chain[chain.index(up) :], up])
            raise NetsimInputError(f"{source}: the transforms on {TF_STATIC} go round a cycle ({loop})")
        (x, y), yaw = _placed(x, y, tx, ty, turn), yaw + turn
        chain.append(up)
        frame = up
    return frame, x, y, yaw


def _placed(x: Any, y: Any, tx: float, ty: float, yaw: float) -> tuple[Any, Any]:
    """Points ``(x, y)`` of a frame placed in its parent by the planar transform ``(tx, ty,
    yaw)``: ``R(yaw) p + (tx, ty)``."""
    c, s = math.cos(yaw), math.sin(yaw)
    return c * x - s * y + tx, s * x + c * y + ty


def _frames_listed(names: set[str]) -> str:
    return listed([repr(n) if n else "none given" for n in sorted(names)], 5)


def _warn_of_stamps(robots: np.ndarray, stamps_ns: np.ndarray, source: str) -> None:
    """Say where a robot's header stamps, in the bag's order, go back or repeat: its poses
    are read in stamp order, and at a repeated stamp the last read puts it."""
    order = np.argsort(robots, kind="stable")
    same = robots[order][1:] == robots[order][:-1]
    step = np.diff(stamps_ns[order])
    back, repeated = int((same & (step < 0)).sum()), int((same & (step == 0)).sum())
    if back:
        warnings.warn(
            f"{source}: {back:,} pose(s) have a header stamp earlier than the pose before them on their robot's "
            "topic (in the bag's order): the poses are read in stamp order",
            stacklevel=3,
        )
    if repeated:
        warnings.warn(
            f"{source}: {repeated:,} pose(s) repeat the header stamp of the pose before them on their robot's "
            "topic: the robot is where the last of them puts it",
            stacklevel=3,
        )


def _make(store: Any, typename: str, **given: Any) -> Any:
    """A message of ``typename`` with the ``given`` fields and zero or empty defaults."""
    from rosbags.typesys.store import Nodetype  # imported when asked: an optional dependency

    _consts, fields = store.fielddefs[typename]
    kwargs = {}
    for name, (kind, spec) in fields:
        if name in given:
            kwargs[name] = given[name]
        elif kind == Nodetype.NAME:
            kwargs[name] = _make(store, spec)
        elif kind == Nodetype.BASE:
            base = spec[0]
            kwargs[name] = "" if base == "string" else False if base == "bool" else 0.0 if "float" in base else 0
        elif kind == Nodetype.ARRAY:
            (inner_kind, inner), size = spec
            kwargs[name] = np.zeros(size, dtype=_dtype(inner[0])) if inner_kind == Nodetype.BASE else []
        else:
            inner_kind, inner = spec[0]
            kwargs[name] = np.zeros(0, dtype=_dtype(inner[0])) if inner_kind == Nodetype.BASE else []
    return store.types[typename](**kwargs)


def _dtype(base: str) -> Any:
    return {"bool": bool, "byte": np.uint8, "char": np.uint8, "octet": np.uint8}.get(base, base)


def _stamp(store: Any, t_s: float) -> Any:
    sec, nanosec = sec_nanosec(t_s)
    return _make(store, "builtin_interfaces/msg/Time", sec=sec, nanosec=nanosec)


def write(out: str | Path, frames: dict[str, pd.DataFrame]) -> int:
    """The run's ``frames`` (its tables by name) as a bag in the new folder ``out``;
    returns the number of messages written."""
    from rosbags.rosbag2 import Writer  # imported when asked: an optional dependency

    store = _typestore()
    rows: list[tuple[int, str, str, object]] = []  # (stamp ns, topic, type, message)

    def header(t_s: float) -> Any:
        return _make(store, "std_msgs/msg/Header", stamp=_stamp(store, t_s), frame_id=FRAME)

    def point(x: float, y: float) -> Any:
        return _make(store, "geometry_msgs/msg/Point", x=float(x), y=float(y))

    positions = frames["positions"]
    for t, robot, x, y in positions[["t_s", "robot", "x_m", "y_m"]].to_numpy().tolist():
        pose = _make(
            store,
            "geometry_msgs/msg/Pose",
            position=point(x, y),
            orientation=_make(store, "geometry_msgs/msg/Quaternion", w=1.0),
        )
        msg = _make(store, "geometry_msgs/msg/PoseStamped", header=header(t), pose=pose)
        rows.append((ns(t), f"/robot_{int(robot)}/pose", "geometry_msgs/msg/PoseStamped", msg))

    links = frames.get("links")
    if links is not None:
        a, b = links["a"].to_numpy(), links["b"].to_numpy()
        up, down = links["t_up_s"].to_numpy(), links["t_down_s"].to_numpy()
        open_end = links["censored_end"].to_numpy(bool) if "censored_end" in links else np.zeros(len(links), bool)
        for t, at in positions.groupby("t_s", sort=True):
            t = float(t)  # type: ignore[arg-type]  # the group's key: a sampling instant
            xy = dict(zip(at["robot"].tolist(), zip(at["x_m"].tolist(), at["y_m"].tolist())))
            live = links_up_at(up, down, open_end, t)
            pts = [point(*xy[int(r)]) for pair in zip(a[live], b[live]) for r in pair if int(r) in xy]
            marker = _make(
                store,
                "visualization_msgs/msg/Marker",
                header=header(t),
                ns="links",
                type=5,  # LINE_LIST: one segment per pair of points
                pose=_make(
                    store, "geometry_msgs/msg/Pose", orientation=_make(store, "geometry_msgs/msg/Quaternion", w=1.0)
                ),
                scale=_make(store, "geometry_msgs/msg/Vector3", x=0.5),
                color=_make(store, "std_msgs/msg/ColorRGBA", r=0.2, g=0.4, b=0.9, a=1.0),
                points=pts,
            )
            rows.append(
                (
                    ns(t),
                    "/links",
                    "visualization_msgs/msg/MarkerArray",
                    _make(store, "visualization_msgs/msg/MarkerArray", markers=[marker]),
                )
            )

    def text(t: float, topic: str, payload: dict) -> None:
        rows.append(
            (ns(t), topic, "std_msgs/msg/String", _make(store, "std_msgs/msg/String", data=json.dumps(payload)))
        )

    roles = frames.get("roles")
    if roles is not None:
        for t, robot, role, leader, cause in (
            roles[["t_s", "robot", "role", "leader", "cause"]].to_numpy(object).tolist()
        ):
            text(t, f"/robot_{int(robot)}/role", {"role": str(role), "leader": int(leader), "cause": str(cause)})
    messages = frames.get("messages")
    if messages is not None:
        for m in messages.to_dict("records"):
            ids = {"msg_id": int(m["msg_id"]), "src": int(m["src"]), "dst": int(m["dst"])}
            text(float(m["t_sent_s"]), "/messages", {"event": "sent", **ids})
            if m["delivered"]:
                extra = {"hops": int(m["hops"]), "latency_s": float(m["latency_s"])}
                text(float(m["t_delivered_s"]), "/messages", {"event": "delivered", **ids, **extra})
    packets = frames.get("packets")
    if packets is not None:
        for m in packets.to_dict("records"):
            ids = {"flow": int(m["flow"]), "packet": int(m["packet"]), "src": int(m["src"]), "dst": int(m["dst"])}
            text(float(m["t_sent_s"]), "/packets", {"event": "sent", **ids})
            if m["delivered"]:
                extra = {"hops": int(m["hops"]), "latency_s": float(m["latency_s"])}
                text(float(m["t_delivered_s"]), "/packets", {"event": "delivered", **ids, **extra})

    rows.sort(key=lambda r: (r[0], r[1]))
    with Writer(Path(out), version=8) as writer:
        conns = {}
        for _ns, topic, typename, _msg in rows:
            if topic not in conns:
                conns[topic] = writer.add_connection(topic, typename, typestore=store)
        for stamp, topic, typename, msg in rows:
            writer.write(conns[topic], stamp, store.serialize_cdr(msg, typename))
    return len(rows)
