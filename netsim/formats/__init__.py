"""The mobility formats robot teams use, in and out: BonnMotion movements and ROS 2 bags
(ns-2 movement files: :mod:`netsim.formats.ns2`). Each reader gives :class:`~netsim.formats.waypoints.Waypoints`,
each robot's track as timed positions, linear in between; each writer takes a run's tables."""

BONNMOTION_NAMES = (".movements", ".movements.gz")
BAG_STORAGE_NAMES = (".mcap", ".db3")  # a bag's storage file, inside its folder


def format_of_name(name: str) -> str:
    """The format a file is read as by its name alone: ``"bonnmotion"``, ``"rosbag2"`` (a
    bag's storage file) or ``"ns2"``; a folder is a bag whatever its name (the caller, who
    can look, says so)."""
    if name.endswith(BONNMOTION_NAMES):
        return "bonnmotion"
    if name.endswith(BAG_STORAGE_NAMES):
        return "rosbag2"
    return "ns2"
