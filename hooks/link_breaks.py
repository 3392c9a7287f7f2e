"""Link breaks per robot per minute: an example of a hook that subscribes to run events.

Listed in ``[events] hooks = ["link_breaks"]``, it counts the ``link_down`` events of each
robot (a break counts for both ends) in every minute of the run, and writes them as
``link_breaks.parquet``: one row per robot per minute, ``minute, t_s`` (the minute's
start), ``robot, breaks``. Subscribing to ``link_down`` makes the run solve link events
as it goes (``events.runtime_links = "auto"``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping

import numpy as np
import pandas as pd

from netsim.events import LinkDown
from netsim.params import NoParams
from netsim.plugins import Parts, PluginSpec

MINUTE_S = 60.0
SCHEMA = {"minute": "int64", "t_s": "float64", "robot": "int64", "breaks": "int64"}


class LinkBreaks:
    """Counts of link breaks by robot and minute."""

    def __init__(self, n: int, duration_s: float, clock: Callable[[], float] | None = None):
        self.minutes = max(1, math.ceil(duration_s / MINUTE_S))
        self.counts = np.zeros((self.minutes, n), dtype=np.int64)
        # The run's clock: the table ends at the minute of now (collected before the end).
        self.clock = clock

    def on_link_down(self, ev: LinkDown) -> None:
        m = min(int(ev.t_s // MINUTE_S), self.minutes - 1)
        self.counts[m, ev.a] += 1
        self.counts[m, ev.b] += 1

    def frame(self) -> pd.DataFrame:
        counts = self.counts
        if self.clock is not None:
            counts = counts[: max(1, math.ceil(self.clock() / MINUTE_S))]
        minutes, n = counts.shape
        minute = np.repeat(np.arange(minutes, dtype=np.int64), n)
        return pd.DataFrame(
            {
                "minute": minute,
                "t_s": minute * MINUTE_S,
                "robot": np.tile(np.arange(n, dtype=np.int64), minutes),
                "breaks": counts.ravel(),
            }
        )

    def summary(self, frames: Mapping[str, pd.DataFrame], duration_s: float) -> dict:
        n = self.counts.shape[1]
        per = self.counts.sum() / (n * duration_s / MINUTE_S) if n and duration_s > 0 else math.nan
        return {"link_breaks_per_robot_per_minute": float(per)}


def build(params: NoParams, parts: Parts) -> LinkBreaks:
    env = parts.env
    hook = LinkBreaks(parts.state.n, parts.duration_s, lambda: env.now)
    parts.events.on("link_down", hook.on_link_down)
    parts.trace.add_frame("link_breaks", hook.frame)
    return hook


PLUGIN = PluginSpec(Params=NoParams, build=build, tables={"link_breaks": SCHEMA})
