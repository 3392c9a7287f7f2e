"""Stamps (netsim.stamps): one rounding of a simulated instant for every output that
carries one (the bridge's messages, the live view, a bag)."""

import pytest

from netsim.stamps import ns, sec_nanosec


@pytest.mark.parametrize(
    ("t_s", "expected"),
    [
        (0.0, (0, 0)),
        (0.30000000000000004, (0, 300_000_000)),
        (12.5, (12, 500_000_000)),
        # Within half a nanosecond of a whole second: the nanoseconds carry. (The bridge's
        # stamps said 2 s 999,999,999 ns, the live scene's 2 s 0 ns: a second back.)
        (2.9999999999, (3, 0)),
        (2.99999999949, (2, 999_999_999)),
    ],
)
def test_a_stamp_carries_its_nanoseconds_into_the_seconds(t_s, expected):
    assert sec_nanosec(t_s) == expected
    sec, nanosec = expected
    assert ns(t_s) == sec * 1_000_000_000 + nanosec


def test_every_stamped_output_uses_the_one_rounding():
    """The bridge's Time, the live scene's Timestamp and a bag's Time of one instant agree."""
    pytest.importorskip("cyclonedds")
    pytest.importorskip("foxglove")
    from netsim.bridge.messages import stamp
    from netsim.formats import rosbag2

    t_s = 2.9999999999
    bridge = stamp(t_s)
    bag = rosbag2._stamp(rosbag2._typestore(), t_s)
    assert (bridge.sec, bridge.nanosec) == (bag.sec, bag.nanosec) == (3, 0)
