"""fig_packets.png: a run's packets as routing carried them (netsim.tools.packet_figure)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from netsim.tools import figures, packet_figure
from netsim.tools.cli import main

PNG = b"\x89PNG\r\n\x1a\n"


def _packets(**columns) -> pd.DataFrame:
    n = len(next(iter(columns.values())))
    base = {
        "flow": np.zeros(n, int),
        "t_sent_s": np.arange(n, dtype=float),
        "delivered": np.ones(n, bool),
        "latency_s": np.full(n, 0.01),
        "hops": np.ones(n),
        "shortest_hops": np.ones(n),
        "drop_cause": pd.Series([None] * n, dtype=object),
    }
    return pd.DataFrame({**base, **columns})


def test_delivered_so_far_counts_by_the_time_sent():
    p = _packets(t_sent_s=[3.0, 1.0, 2.0], delivered=[True, False, True])
    t, share = packet_figure.delivered_so_far(p)
    np.testing.assert_array_equal(t, [1.0, 2.0, 3.0])
    np.testing.assert_allclose(share, [0.0, 0.5, 2 / 3])


def test_extra_hops_of_the_delivered_packets_that_had_a_path():
    p = _packets(
        delivered=[True, True, False, True, True],
        hops=[4.0, 3.0, 9.0, 2.0, 2.0],
        shortest_hops=[2.0, 3.0, 1.0, np.inf, 3.0],
    )
    np.testing.assert_array_equal(packet_figure.extra_hops(p), [2, 0, -1])


def test_not_delivered_by_cause_with_the_run_end_as_in_flight():
    causes = pd.Series([None, "no_route", None, "ttl", "no_route"], dtype=object)
    p = _packets(delivered=[True, False, False, False, False], drop_cause=causes)
    assert packet_figure.not_delivered(p).to_dict() == {"in_flight": 1, "no_route": 2, "ttl": 1}


def test_flows_drawn_one_line_each_up_to_the_most_then_as_one():
    few = _packets(flow=[-1, 0, 1, 1])
    assert [label for label, _ in packet_figure._series(few)] == ["pairs", "flow 0", "flow 1"]
    many = _packets(flow=np.arange(packet_figure.MOST_FLOWS + 1))
    ((label, rows),) = packet_figure._series(many)
    assert label == "all packets" and len(rows) == len(many)


def test_a_table_without_shortest_hops_is_drawn_and_says_so():
    plt = figures.pyplot()
    fig, axes = plt.subplots(1, 4)
    try:
        packet_figure.draw_packets(axes, _packets(hops=[1.0, 2.0]).drop(columns="shortest_hops"))
        assert "no shortest_hops" in axes[2].get_title()
        assert not axes[2].patches
    finally:
        plt.close(fig)


@pytest.mark.slow
def test_figures_of_a_routing_run_draw_its_packets(tmp_path, capsys):
    run = tmp_path / "run"
    sets = ['protocol.model="aodv"', "protocol.message_rate_hz=2", "world.n_robots=12", "duration_s=20"]
    assert main(["run", "--quiet", "--no-progress", "--out", str(run), *[a for s in sets for a in ("--set", s)]]) == 0
    assert main(["figures", str(run), "--out", str(tmp_path / "f")]) == 0
    assert capsys.readouterr().out.splitlines()[-1] == f"wrote {tmp_path / 'f' / 'fig_packets.png'}"
    assert (tmp_path / "f" / "fig_packets.png").read_bytes()[:8] == PNG


def test_latencies_of_zero_are_drawn_on_a_linear_scale():
    """A channel without latency (`channel.latency_s = 0`) delivers in no time: a log
    scale would have nothing to draw; a linear one shows them."""
    plt = figures.pyplot()
    for latency, scale in ((0.0, "linear"), (0.01, "log")):
        fig, axes = plt.subplots(1, 4)
        try:
            packet_figure.draw_packets(axes, _packets(latency_s=[latency] * 3))
            assert axes[1].get_xscale() == scale
        finally:
            plt.close(fig)
