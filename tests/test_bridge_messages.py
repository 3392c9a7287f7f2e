"""ROS 2 messages as Cyclone DDS structures (netsim.bridge.messages), without a DDS domain:
the type names a ROS 2 node matches and the bytes it reads."""

import pytest

pytest.importorskip("cyclonedds")  # the extra "ros" (installed with "test")

from netsim.bridge.messages import dds_name, idl_type, zero  # noqa: E402

CDR_HEADER = b"\x00\x01\x00\x00"  # little-endian plain CDR


def test_types_carry_the_dds_names_ros_2_gives_them():
    assert dds_name("geometry_msgs/msg/Twist") == "geometry_msgs::msg::dds_::Twist_"
    assert idl_type("geometry_msgs/msg/Twist").__idl_typename__ == "geometry_msgs::msg::dds_::Twist_"


@pytest.mark.parametrize(
    ("msgtype", "value", "payload"),
    [
        ("std_msgs/msg/Byte", 255, b"\xff"),
        ("std_msgs/msg/Char", 200, b"\xc8"),
        ("std_msgs/msg/UInt32", 2**32 - 1, b"\xff\xff\xff\xff"),
    ],
)
def test_unsigned_fields_take_their_whole_range(msgtype, value, payload):
    assert idl_type(msgtype)(data=value).serialize() == CDR_HEADER + payload


def test_a_bounded_string_longer_than_its_bound_is_refused():
    msg = zero("rmw_dds_common/msg/NodeEntitiesInfo")
    msg.node_name = "n" * 256
    msg.serialize()
    msg.node_name = "n" * 257
    with pytest.raises(Exception, match="node_name"):
        msg.serialize()


def test_a_bounded_sequence_longer_than_its_bound_is_refused():
    msg = zero("shape_msgs/msg/SolidPrimitive")
    msg.dimensions = [1.0] * 3
    msg.serialize()
    msg.dimensions = [1.0] * 4
    with pytest.raises(Exception, match="dimensions"):
        msg.serialize()


def test_a_zero_message_has_empty_strings_and_sequences():
    marker = zero("visualization_msgs/msg/Marker")
    assert marker.ns == "" and marker.header.frame_id == "" and marker.points == [] and marker.colors == []
    assert zero("std_msgs/msg/String").serialize() == CDR_HEADER + b"\x01\x00\x00\x00\x00"
