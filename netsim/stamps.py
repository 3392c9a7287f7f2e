"""Simulated instants as ROS 2 and Foxglove stamp them: whole nanoseconds, or seconds and
the nanoseconds past them (``builtin_interfaces/Time``). One rounding for every output that
carries a stamp (the bridge's messages, the live view, a bag), so that they name the same
instant the same way, and the nanoseconds carry into the seconds (2.9999999999 s is 3 s
0 ns, not 2 s 999,999,999 ns or 2 s 0 ns)."""

from __future__ import annotations

NS_PER_S = 1_000_000_000


def ns(t_s: float) -> int:
    """``t_s`` seconds in whole nanoseconds (rounded to the nearest)."""
    return int(round(t_s * 1e9))


def sec_nanosec(t_s: float) -> tuple[int, int]:
    """``(sec, nanosec)`` of ``t_s``: the whole seconds and the nanoseconds past them."""
    sec, nanosec = divmod(ns(t_s), NS_PER_S)
    return sec, nanosec
