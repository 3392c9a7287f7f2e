import numpy as np
import pandas as pd
import pytest

from netsim.errors import NetsimInputError
from netsim.tools import figures, sweep, sweep_figure
from tests.fixtures import keep_figures


@pytest.fixture
def drawn(monkeypatch):
    """The figures sweep_figure draws, kept open to be read."""
    kept = keep_figures(monkeypatch, sweep_figure)
    yield kept
    for fig in kept:
        figures.pyplot().close(fig)


def _runs() -> pd.DataFrame:
    rng = np.random.default_rng(3)
    rows = [
        {"pause": pause, "speed": speed, "leaders": 10 + speed + pause + rng.normal(), "tenure": 50 - speed}
        for pause in (0.0, 30.0)
        for speed in (5.0, 1.0, 10.0)
        for _ in range(4)
    ]
    return pd.DataFrame(rows)


def test_draw_aggregate_plots_each_series_mean_and_interval(tmp_path, drawn):
    # Rows out of order: the lines still run along x.
    agg = sweep.aggregate(_runs(), ["pause", "speed"], ["leaders", "tenure"]).iloc[::-1]
    path = sweep_figure.draw_aggregate(
        agg,
        "speed",
        "pause",
        {"leaders": "leaders", "tenure": "tenure (s)"},
        tmp_path / "f.png",
        "t",
        series_label=lambda p: f"pause {p:g} s",
    )
    assert path.is_file()
    (fig,) = drawn
    ax = fig.axes[0]
    assert ax.get_ylabel() == "leaders" and fig.axes[1].get_ylabel() == "tenure (s)"
    assert [c.get_label() for c in ax.containers] == ["pause 0 s", "pause 30 s"]
    for container, (_, g) in zip(ax.containers, agg.groupby("pause")):
        g = g.sort_values("speed")
        x, y = container.lines[0].get_data()
        np.testing.assert_array_equal(x, g["speed"])
        np.testing.assert_array_equal(y, g["leaders_mean"])
        (bars,) = container.lines[2]
        ends = np.array([seg[:, 1] for seg in bars.get_segments()])
        np.testing.assert_allclose(ends[:, 0], g["leaders_ci_low"])
        np.testing.assert_allclose(ends[:, 1], g["leaders_ci_high"])


def test_draw_aggregate_one_replication_draws_no_bar(tmp_path, drawn):
    agg = sweep.aggregate(_runs().groupby(["pause", "speed"]).head(1), ["pause", "speed"], ["leaders"])
    assert agg["leaders_ci_low"].isna().all()
    sweep_figure.draw_aggregate(agg, "speed", "pause", {"leaders": "leaders"}, tmp_path / "f.png", "t")
    (fig,) = drawn
    for container in fig.axes[0].containers:
        (bars,) = container.lines[2]
        assert all(seg[0, 1] == seg[1, 1] for seg in bars.get_segments())


def test_draw_aggregate_refuses_a_table_not_aggregated(tmp_path):
    with pytest.raises(NetsimInputError, match="no column leaders_mean, leaders_ci_low, leaders_ci_high"):
        sweep_figure.draw_aggregate(_runs(), "speed", "pause", {"leaders": "leaders"}, tmp_path / "f.png", "t")
    assert not (tmp_path / "f.png").exists()
