"""ROS 2 messages as Cyclone DDS structures, under the type names ROS 2 puts on the wire
(``pkg::msg::dds_::Type_``), so that nodes on ``rmw_cyclonedds_cpp`` match them.

The bridge's own types are built from the same definitions as the relayed ones: rosbags'
store of ROS 2 message definitions (:func:`idl_type`), one structure per type, nested
types first. So a relayed topic can be of any type the store knows.
"""

from __future__ import annotations

import dataclasses
import types as pytypes
import typing
from functools import cache
from typing import Any

import cyclonedds.idl.annotations as annotate
from cyclonedds.idl import IdlStruct
from cyclonedds.idl import types as t

from netsim.bridge.settings import typestore
from netsim.stamps import sec_nanosec

_BASE = {
    "bool": bool,
    "byte": t.uint8,
    "char": t.uint8,
    "int8": t.int8,
    "uint8": t.uint8,
    "int16": t.int16,
    "uint16": t.uint16,
    "int32": t.int32,
    "uint32": t.uint32,
    "int64": t.int64,
    "uint64": t.uint64,
    "float32": t.float32,
    "float64": t.float64,
    "string": str,
}


def dds_name(msgtype: str) -> str:
    """``geometry_msgs/msg/Twist`` -> ``geometry_msgs::msg::dds_::Twist_``."""
    pkg, kind, name = msgtype.split("/")
    return f"{pkg}::{kind}::dds_::{name}_"


def _field_type(node: tuple) -> Any:
    from rosbags.typesys.store import Nodetype

    kind, rest = node
    if kind == Nodetype.BASE:
        name, bound = rest
        if name == "string" and bound:
            return t.bounded_str[bound]  # type: ignore[misc]
        return _BASE[name]
    if kind == Nodetype.NAME:
        return idl_type(rest)
    sub, length = rest
    inner = _field_type(sub)
    if kind == Nodetype.ARRAY:
        return t.array[inner, length]  # type: ignore[misc]
    return t.sequence[inner, length] if length else t.sequence[inner]  # type: ignore[misc]


@cache
def idl_type(msgtype: str) -> type:
    """The Cyclone DDS structure of the ROS 2 message ``pkg/msg/Type`` (cached: one class
    per type, as DDS wants one type per name)."""
    _consts, fields = typestore().fielddefs[msgtype]
    annotations = {name: _field_type(node) for name, node in fields}
    if not annotations:  # an empty ROS 2 message carries one octet on the wire
        annotations = {"structure_needs_at_least_one_member": t.uint8}
    cls_name = msgtype.replace("/", "_")

    def body(ns: dict) -> None:
        ns["__annotations__"] = annotations
        ns["__module__"] = __name__

    cls = pytypes.new_class(cls_name, (IdlStruct,), {"typename": dds_name(msgtype)}, body)
    return dataclasses.dataclass(annotate.final(cls))


def zero(msgtype: str) -> Any:
    """A message of ``msgtype`` with every field at its zero."""
    cls = idl_type(msgtype)
    return cls(**{f.name: _zero(f.type) for f in dataclasses.fields(cls)})


def _zero(tp: Any) -> Any:
    if typing.get_origin(tp) is typing.Annotated:  # arrays, sequences, bounded strings
        tp = typing.get_args(tp)[1]
    if tp is bool:
        return False
    if tp is str or isinstance(tp, t.bounded_str):
        return ""
    if isinstance(tp, t.array):
        return [_zero(tp.subtype)] * tp.length
    if isinstance(tp, t.sequence):
        return []
    if isinstance(tp, type) and dataclasses.is_dataclass(tp):
        return tp(**{f.name: _zero(f.type) for f in dataclasses.fields(tp)})
    if tp in (t.float32, t.float64):
        return 0.0
    return 0


def stamp(t_s: float) -> Any:
    """builtin_interfaces/Time of ``t_s`` seconds."""
    sec, nanosec = sec_nanosec(t_s)
    return idl_type("builtin_interfaces/msg/Time")(sec=sec, nanosec=nanosec)
