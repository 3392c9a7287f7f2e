"""The figure of a run's packets (``fig_packets.png``, drawn by ``netsim figures`` beside
the paper's when the run wrote ``packets.parquet``): how routing carried its traffic.

- the share of the packets sent so far that arrived, against the time they were sent
  (a packet counts once sent, delivered or not yet: in a run that ends, the last ones
  sent are still in flight); a route being found shows as a rise, a route breaking as a
  fall;
- each flow's latency, the delivered packets' distribution (ECDF);
- the extra hops a delivered packet took over the shortest path when it was sent
  (``hops - shortest_hops``; packets sent with no path left out);
- where the others went: the packets dropped by cause, and those still in flight at
  the end.

One line per flow (random pairs' messages: ``pairs``), up to :data:`MOST_FLOWS`; more
flows are drawn as one line, ``all packets``.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from matplotlib.ticker import MaxNLocator

from netsim.traffic import pathed_deliveries

MOST_FLOWS = 8
IN_FLIGHT = "in_flight"


def _series(packets: pd.DataFrame) -> list[tuple[str, pd.DataFrame]]:
    flows = sorted(packets["flow"].unique())
    if len(flows) > MOST_FLOWS:
        return [("all packets", packets)]
    return [("pairs" if f < 0 else f"flow {f}", packets[packets["flow"] == f]) for f in flows]


def delivered_so_far(packets: pd.DataFrame) -> tuple[np.ndarray, np.ndarray]:
    """The send times in order, and the share of the packets sent by each that arrived."""
    order = np.argsort(packets["t_sent_s"].to_numpy(), kind="stable")
    t = packets["t_sent_s"].to_numpy()[order]
    got = packets["delivered"].to_numpy(bool)[order]
    return t, np.cumsum(got) / np.arange(1, len(got) + 1)


def extra_hops(packets: pd.DataFrame) -> np.ndarray:
    """``hops - shortest_hops`` of the delivered packets that had a path when sent."""
    got = pathed_deliveries(packets)
    return (got["hops"].to_numpy(float) - got["shortest_hops"].to_numpy(float)).astype(np.int64)


def not_delivered(packets: pd.DataFrame) -> pd.Series:
    """The packets not delivered, by cause (``in_flight`` for those the run's end caught)."""
    lost = packets[~packets["delivered"].to_numpy(bool)]
    return lost["drop_cause"].fillna(IN_FLIGHT).value_counts().sort_index()


def draw_packets(ax_row, packets: pd.DataFrame) -> None:
    """Draw the four panels on the four axes ``ax_row``."""
    share, latency, stretch, lost = ax_row
    got_all = packets.loc[packets["delivered"].to_numpy(bool), "latency_s"].to_numpy(float)
    for label, p in _series(packets):
        t, so_far = delivered_so_far(p)
        share.step(t, so_far, where="post", label=label)
        got = np.sort(p.loc[p["delivered"].to_numpy(bool), "latency_s"].to_numpy(float))
        if len(got):
            latency.step(got, np.arange(1, len(got) + 1) / len(got), where="post", label=label)
    share.set(xlabel="time sent (s)", ylabel="delivered, of the packets sent so far", ylim=(-0.02, 1.02))
    share.legend(fontsize="small")
    # A log scale spreads latencies over decades; a channel without latency gives zeros.
    scale = "log" if len(got_all) and got_all.min() > 0 else "linear"
    latency.set(xlabel="latency (s)", ylabel="share of the delivered packets", xscale=scale)
    extra = extra_hops(packets) if "shortest_hops" in packets else None
    if extra is None:
        stretch.set_title("the run wrote no shortest_hops (written before them)", fontsize="small")
    elif len(extra):
        counts = np.bincount(extra - extra.min())
        stretch.bar(np.arange(extra.min(), extra.min() + len(counts)), counts, color="C2")
        stretch.xaxis.set_major_locator(MaxNLocator(integer=True))
        stretch.set_title(f"{len(extra):,} delivered with a path when sent", fontsize="small")
    stretch.set(xlabel="hops beyond the shortest path", ylabel="packets")
    causes = not_delivered(packets)
    if len(causes):
        lost.barh(causes.index.astype(str), causes.to_numpy(), color="C3")
    lost.set(xlabel="packets not delivered")
    lost.set_title(f"{int(packets['delivered'].sum()):,} of {len(packets):,} delivered", fontsize="small")
    for ax in ax_row:
        ax.grid(alpha=0.3)
