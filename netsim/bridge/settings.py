"""The ``[bridge]`` table of a scenario and the checks of ``netsim bridge``'s input.

The table is the bridge's, not the run's: it is taken out of the scenario before the rest
is read as any run's configuration (:func:`load`), and written next to the run's tables
(``bridge.toml``). Every check here runs before DDS is loaded or anything is written.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from typing import Any

from netsim import config as cfgmod
from netsim.errors import ConfigError, NetsimInputError
from netsim.params import refuse_events

# DDS maps a domain id to UDP ports (7400 + 250 x id, and up): ids above 232 overflow them.
DOMAIN_ID_MAX = 232
# A ROS 2 topic name's token: what `rt/robot_i/tx/<name>` may end with.
_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]*(/[A-Za-z][A-Za-z0-9_]*)*")
_KEYS = ("domain_id", "odom_hz", "relay")


@dataclass(frozen=True)
class Relay:
    """One relayed topic: robots publish on ``/robot_i/tx/<name>``, the channel's
    receivers get it on ``/robot_j/rx/<name>``; ``msgtype`` as ``pkg/msg/Type``."""

    name: str
    msgtype: str


@dataclass(frozen=True)
class BridgeSettings:
    domain_id: int = 0
    odom_hz: float = 10.0
    relay: tuple[Relay, ...] = field(default_factory=tuple)

    def as_dict(self) -> dict:
        return {
            "domain_id": self.domain_id,
            "odom_hz": self.odom_hz,
            "relay": [{"name": r.name, "type": r.msgtype} for r in self.relay],
        }


def typestore() -> Any:
    """The ROS 2 message definitions the bridge knows (those of rosbags' Humble store)."""
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_HUMBLE)


def ros_type(name: str) -> str:
    """``pkg/Type`` or ``pkg/msg/Type`` as ``pkg/msg/Type``."""
    parts = name.split("/")
    if len(parts) == 2:
        return f"{parts[0]}/msg/{parts[1]}"
    return name


def _relay(k: int, entry: Any, known: Any) -> Relay:
    key = f"bridge.relay[{k}]"
    if not isinstance(entry, dict) or set(entry) != {"name", "type"}:
        raise ConfigError(key, entry, 'must be a table {name = "chat", type = "std_msgs/msg/String"}')
    name, msgtype = entry["name"], entry["type"]
    if not isinstance(name, str) or not _NAME.fullmatch(name):
        raise ConfigError(f"{key}.name", name, "must be a topic name: letters, digits, _ and /, from a letter")
    if not isinstance(msgtype, str) or ros_type(msgtype) not in known:
        raise ConfigError(
            f"{key}.type", msgtype, "unknown ROS 2 message type (give pkg/msg/Type, one of rosbags' ROS 2 types)"
        )
    return Relay(name, ros_type(msgtype))


def settings(raw: Any) -> BridgeSettings:
    """The ``[bridge]`` table as :class:`BridgeSettings`, or a :class:`ConfigError`."""
    if not isinstance(raw, dict):
        raise ConfigError("bridge", raw, "must be a table ([bridge])")
    for key in raw:
        if key not in _KEYS:
            raise ConfigError(f"bridge.{key}", raw[key], "unknown key; allowed: " + ", ".join(_KEYS))
    domain = raw.get("domain_id", 0)
    if isinstance(domain, bool) or not isinstance(domain, int) or not 0 <= domain <= DOMAIN_ID_MAX:
        raise ConfigError("bridge.domain_id", domain, f"must be an integer from 0 to {DOMAIN_ID_MAX}")
    hz = raw.get("odom_hz", 10.0)
    if isinstance(hz, bool) or not isinstance(hz, int | float) or not (math.isfinite(hz) and hz > 0):
        raise ConfigError("bridge.odom_hz", hz, "must be a positive number, Hz")
    entries = raw.get("relay", [])
    if not isinstance(entries, list):
        raise ConfigError("bridge.relay", entries, "must be a list of tables [[bridge.relay]]")
    known = typestore().fielddefs if entries else {}
    relay = tuple(_relay(k, e, known) for k, e in enumerate(entries))
    names = [r.name for r in relay]
    if len(set(names)) != len(names):
        raise ConfigError("bridge.relay", names, "each topic name may be relayed once")
    return BridgeSettings(domain, float(hz), relay)


# The [bridge] keys as `netsim config` explains them (docs/ros2.md).
KEY_DOCS = {
    "domain_id": f"the DDS domain of your ROS 2 nodes (ROS_DOMAIN_ID), 0 to {DOMAIN_ID_MAX}",
    "odom_hz": "bridge steps per simulated second: odometry, /clock and the network topics each step, Hz",
    "relay": 'topics relayed through the network: {name = "...", type = "pkg/msg/Type"}',
}


def commented(bridge: BridgeSettings | None) -> str:
    """The ``[bridge]`` table with every key explained: ``bridge``'s values, or, without
    it, the defaults commented out (a run's scenario has no such table)."""
    import tomli_w

    values = (bridge or BridgeSettings()).as_dict()
    head = "# read by `netsim bridge` alone (docs/ros2.md)"
    out = ["", head, "[bridge]" if bridge else "# [bridge]"]
    for key in _KEYS:
        if key == "relay":
            items = ", ".join(f"{{name = {r['name']!r}, type = {r['type']!r}}}" for r in values[key])
            line = f"relay = [{items}]".replace("'", '"')
        else:
            line = tomli_w.dumps({key: values[key]}).strip()
        out += [f"# {KEY_DOCS[key]}", line if bridge else f"# {line}"]
    return "\n".join(out) + "\n"


def check_rate(rate: float) -> float:
    if not (math.isfinite(rate) and rate > 0):
        raise NetsimInputError(f"--rate {rate:g}: must be a positive number of simulated seconds per wall second")
    return rate


def read(path: str | None, overrides: list[str]) -> tuple[cfgmod.Config, BridgeSettings | None]:
    """The run's configuration and, when the scenario has a ``[bridge]`` table (or
    ``bridge.*`` overrides), the bridge's settings, each checked."""
    raw = cfgmod.read_tree(path, overrides)
    bridge = settings(raw.pop("bridge")) if "bridge" in raw else None
    return cfgmod.from_dict(raw), bridge


# ROS 2's builtin_interfaces/Time counts whole seconds in an int32.
STAMP_LIMIT_S = 2.0**31


def load(path: str | None, overrides: list[str]) -> tuple[cfgmod.Config, BridgeSettings]:
    """The run's configuration and the bridge's settings from a scenario file and
    ``--set`` overrides (``bridge.*`` keys included)."""
    config, bridge = read(path, overrides)
    if config.mobility.model != "external":
        raise ConfigError(
            "mobility.model", config.mobility.model, "the bridge moves robots as ROS 2 nodes tell: must be 'external'"
        )
    settings = bridge or BridgeSettings()
    if not config.duration_s < STAMP_LIMIT_S:
        why = "the bridge stamps its messages in ROS 2's Time, whose seconds are a 32-bit integer: must be below 2^31 s"
        raise ConfigError("duration_s", config.duration_s, why)
    # A key that schedules events, as those of the configuration (netsim.params.check_schedules).
    duration_s = config.duration_s
    refuse_events(
        "bridge.odom_hz", settings.odom_hz, duration_s * settings.odom_hz, duration_s, "the run", "duration_s"
    )
    return config, settings
