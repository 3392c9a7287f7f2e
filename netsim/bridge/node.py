"""The bridge's DDS participant, on ROS 2's wire conventions.

Topics are ROS 2's: ``/robot_0/odom`` is the DDS topic ``rt/robot_0/odom``; types carry
ROS 2's DDS names (:mod:`netsim.bridge.messages`). Every topic netsim publishes has ROS 2's default QoS
(reliable, volatile, keep last 10) but ``/clock``, which has ROS 2's clock QoS (best
effort, volatile, keep last 1), as ``rclcpp`` gives it to ``use_sim_time``; netsim reads
what nodes send reliably and keeps it all until it is taken (:data:`INBOX_QOS`).
"""

from __future__ import annotations

import os
import struct
from collections.abc import Callable
from typing import Any

from cyclonedds._clayer import ddspy_write
from cyclonedds.core import DDSException, Listener, Policy, Qos
from cyclonedds.domain import DomainParticipant
from cyclonedds.internal import InvalidSample
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from cyclonedds.util import duration

from netsim.bridge.messages import idl_type
from netsim.errors import NetsimInputError

DEFAULT_QOS = Qos(
    Policy.Reliability.Reliable(duration(milliseconds=100)),
    Policy.Durability.Volatile,
    Policy.History.KeepLast(10),
)
CLOCK_QOS = Qos(Policy.Reliability.BestEffort, Policy.Durability.Volatile, Policy.History.KeepLast(1))
# What nodes send netsim (commands, messages to relay) is taken once a step: a reader keeping
# the last 10 would drop, uncounted, what a node sent beyond 10 in one step. History is not
# matched between writer and reader, so any ROS 2 publisher still matches.
INBOX_QOS = Qos(
    Policy.Reliability.Reliable(duration(milliseconds=100)), Policy.Durability.Volatile, Policy.History.KeepAll
)


# The DDS ids (the specification's QosPolicyId) of the policies a writer can fail netsim's
# readers on, and how a node fixes it.
QOS_POLICIES = {
    11: "best effort: netsim reads reliably; publish it reliable, ROS 2's default",
    6: "exclusive ownership: netsim reads shared; publish it shared, ROS 2's default",
}


def dds_topic(name: str) -> str:
    """``/robot_0/odom`` -> ``rt/robot_0/odom``."""
    return "rt/" + name.lstrip("/")


class Node:
    """One DDS participant on ``domain_id``, its topics made once each."""

    def __init__(self, domain_id: int):
        try:
            self.participant = DomainParticipant(domain_id)
        except DDSException as exc:
            # Cyclone reads its configuration (CYCLONEDDS_URI) as the participant is made.
            uri = os.environ.get("CYCLONEDDS_URI")
            where = f"CYCLONEDDS_URI = {uri!r}" if uri else f"bridge.domain_id = {domain_id}"
            text = f"{where}: Cyclone DDS cannot start on domain {domain_id} with it: {exc}"
            raise NetsimInputError(text) from None
        self._topics: dict[str, Topic] = {}
        # Topics a node publishes with a QoS netsim's readers cannot match (appended on DDS's
        # own thread): nothing of such a publisher arrives, so the bridge says so.
        self._unmatched: list[tuple[str, int]] = []
        self._told: set[str] = set()

    def topic(self, name: str, msgtype: str) -> Topic:
        tp = self._topics.get(name)
        if tp is None:
            tp = self._topics[name] = Topic(self.participant, dds_topic(name), idl_type(msgtype))
        return tp

    def writer(self, name: str, msgtype: str, qos: Qos = DEFAULT_QOS) -> DataWriter:
        return DataWriter(self.participant, self.topic(name, msgtype), qos=qos)

    def reader(self, name: str, msgtype: str, qos: Qos = INBOX_QOS) -> DataReader:
        unmatched = Listener(
            on_requested_incompatible_qos=lambda _r, status: self._unmatched.append((name, status.last_policy_id))
        )
        return DataReader(self.participant, self.topic(name, msgtype), qos=qos, listener=unmatched)

    def unmatched(self) -> list[tuple[str, int]]:
        """The topics, not named before, that a node publishes with a QoS netsim's readers
        cannot match, each with the DDS id of the policy that did not (:data:`QOS_POLICIES`)."""
        new = {t: policy for t, policy in self._unmatched[:] if t not in self._told}
        self._told.update(new)
        return list(new.items())


def take_all(reader: DataReader) -> list[Any]:
    """Every sample waiting in ``reader``, oldest first (none blocks)."""
    out: list[Any] = []
    while True:
        got = reader.take(N=64)
        if not got:
            return out
        # A writer that goes away leaves a sample without data (InvalidSample).
        out.extend(s for s in got if s is not None and not isinstance(s, InvalidSample))


class Template:
    """A message of fixed layout written as CDR bytes, its numeric fields patched in place:
    Cyclone's Python serializer walks a message field by field, which for odometry at
    10 Hz for every robot is most of a step's time. The bytes are the serializer's own for
    a template message; each field to patch is found in them by a sentinel value."""

    def __init__(self, writer: DataWriter, message: Any, fields: dict[str, tuple[str, Callable[[Any, Any], None]]]):
        """``fields``: by name, the struct format of the field (``"<d"``, ``"<i"``...) and a
        function that sets it on ``message`` (each is set to its own sentinel here)."""
        self.writer = writer
        self.offsets: dict[str, tuple[str, int]] = {}
        sentinels = {}
        for k, (name, (fmt, set_field)) in enumerate(fields.items()):
            value = (0x5E17E1 + 7919 * k) if fmt[-1] in "iI" else 8.125e12 + 7919.0 * k
            set_field(message, value)
            sentinels[name] = struct.pack(fmt, value)
        data = serialized(writer, message)
        for name, pattern in sentinels.items():
            at = data.find(pattern)
            if at < 0 or data.find(pattern, at + 1) >= 0:
                raise RuntimeError(f"cannot place the field {name} in the message's bytes")
            self.offsets[name] = (fields[name][0], at)
        self.data = bytearray(data)

    def fill(self, **values: float) -> bytes:
        """The message's bytes with ``values`` in their fields (the others as last filled)."""
        data = self.data
        for name, value in values.items():
            fmt, at = self.offsets[name]
            struct.pack_into(fmt, data, at, value)
        return bytes(data)

    def write(self, **values: float) -> None:
        write_bytes(self.writer, self.fill(**values))


def serialized(writer: DataWriter, message: Any) -> bytes:
    """``message`` as ``writer`` would put it on the wire (padded to 4 bytes, as it does)."""
    data = message.serialize(use_version_2=writer._use_version_2)
    return data.ljust((len(data) + 3) & ~3, b"\0")


def write_bytes(writer: DataWriter, data: bytes) -> None:
    """Write a sample already serialized (:func:`serialized`)."""
    rc = ddspy_write(writer._ref, data)
    if rc < 0:
        raise RuntimeError(f"DDS refused a sample (return code {rc})")
