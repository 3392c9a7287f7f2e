"""The link events a run announces, as the rows of a links table: what the tests compare
with ``links.parquet`` (the runtime solvers are the live feed, the table has one producer)."""

from __future__ import annotations

import numpy as np
import pandas as pd

from netsim.links.lifetimes import COLUMNS


class Feed:
    """Subscribes to ``link_up`` and ``link_down`` on ``events`` (before the run starts) and
    keeps every lifetime announced."""

    def __init__(self, events) -> None:
        self.up: dict[tuple[int, int], float] = {}
        self.rows: list[tuple[int, int, float, float]] = []
        events.on("link_up", self._up)
        events.on("link_down", self._down)

    def _up(self, event) -> None:
        assert (event.a, event.b) not in self.up, event
        self.up[(event.a, event.b)] = event.t_s

    def _down(self, event) -> None:
        t_up = self.up.pop((event.a, event.b))
        assert t_up == event.up_since_s, event
        self.rows.append((event.a, event.b, t_up, event.t_s))

    def table(self, sim, t_end: float) -> pd.DataFrame:
        """The announced lifetimes as a links table ending at ``t_end``. The changes due at
        the run's very end are not announced (the kernel stops before them) but applied to
        the solver's links (``sim.links.up``, after :func:`netsim.run.collect`): a link
        announced up that the solver no longer has went down then; one it has that was
        never announced came up then."""
        live = {divmod(key, max(sim.state.n, 1)) for key in sim.links.up}
        rows = list(self.rows)
        ended_at_end = [(a, b, t, t_end) for (a, b), t in self.up.items() if (a, b) not in live]
        still = [(a, b, t) for (a, b), t in self.up.items() if (a, b) in live]
        still += [(int(a), int(b), t_end) for a, b in live if (a, b) not in self.up]
        rows += ended_at_end
        a = np.array([r[0] for r in rows] + [r[0] for r in still], np.int64)
        b = np.array([r[1] for r in rows] + [r[1] for r in still], np.int64)
        out = pd.DataFrame(
            {
                "a": a,
                "b": b,
                "t_up_s": np.array([r[2] for r in rows] + [r[2] for r in still], float),
                "t_down_s": np.array([r[3] for r in rows] + [t_end] * len(still), float),
            }
        )
        out["censored_start"] = out["t_up_s"].to_numpy() == 0.0
        out["censored_end"] = np.r_[np.zeros(len(rows), bool), np.ones(len(still), bool)]
        out["censored"] = out["censored_start"] | out["censored_end"]
        return out[COLUMNS].sort_values(["t_up_s", "a", "b"], kind="stable").reset_index(drop=True)
