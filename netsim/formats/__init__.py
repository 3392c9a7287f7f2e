"""The mobility formats robot teams use, in and out: BonnMotion movements and ROS 2 bags
(ns-2 movement files: :mod:`netsim.formats.ns2`). Each reader gives :class:`~netsim.formats.waypoints.Waypoints`,
each robot's track as timed positions, linear in between; each writer takes a run's tables."""
