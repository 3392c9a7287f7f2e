"""The bridge's DDS participant, on ROS 2's wire conventions.

Topics are ROS 2's: ``/robot_0/odom`` is the DDS topic ``rt/robot_0/odom``; types carry
ROS 2's DDS names (:mod:`netsim.bridge.messages`). Every topic has ROS 2's default QoS
(reliable, volatile, keep last 10) but ``/clock``, which has ROS 2's clock QoS (best
effort, volatile, keep last 1), as ``rclcpp`` gives it to ``use_sim_time``.
"""

from __future__ import annotations

from typing import Any

from cyclonedds.core import Policy, Qos
from cyclonedds.domain import DomainParticipant
from cyclonedds.internal import InvalidSample
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from cyclonedds.util import duration

from netsim.bridge.messages import idl_type

DEFAULT_QOS = Qos(
    Policy.Reliability.Reliable(duration(milliseconds=100)),
    Policy.Durability.Volatile,
    Policy.History.KeepLast(10),
)
CLOCK_QOS = Qos(Policy.Reliability.BestEffort, Policy.Durability.Volatile, Policy.History.KeepLast(1))


def dds_topic(name: str) -> str:
    """``/robot_0/odom`` -> ``rt/robot_0/odom``."""
    return "rt/" + name.lstrip("/")


class Node:
    """One DDS participant on ``domain_id``, its topics made once each."""

    def __init__(self, domain_id: int):
        self.participant = DomainParticipant(domain_id)
        self._topics: dict[str, Topic] = {}

    def topic(self, name: str, msgtype: str) -> Topic:
        tp = self._topics.get(name)
        if tp is None:
            tp = self._topics[name] = Topic(self.participant, dds_topic(name), idl_type(msgtype))
        return tp

    def writer(self, name: str, msgtype: str, qos: Qos = DEFAULT_QOS) -> DataWriter:
        return DataWriter(self.participant, self.topic(name, msgtype), qos=qos)

    def reader(self, name: str, msgtype: str, qos: Qos = DEFAULT_QOS) -> DataReader:
        return DataReader(self.participant, self.topic(name, msgtype), qos=qos)


def take_all(reader: DataReader) -> list[Any]:
    """Every sample waiting in ``reader``, oldest first (none blocks)."""
    out: list[Any] = []
    while True:
        got = reader.take(N=64)
        if not got:
            return out
        # A writer that goes away leaves a sample without data (InvalidSample).
        out.extend(s for s in got if s is not None and not isinstance(s, InvalidSample))
