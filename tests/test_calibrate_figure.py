"""netsim calibrate --plot: the figure of a fit beside its log."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from netsim.tools import calibrate_figure, figures
from netsim.tools.calibrate import calibrate_frame
from netsim.tools.cli import main
from tests.calibration_logs import TRUTH, synth_log
from tests.fixtures import keep_figures

SMALL = {"n_robots": 8, "duration_s": 300.0, "step_s": 0.5}


@pytest.fixture(scope="module")
def censored():
    return synth_log(3, censored=True, **SMALL)


@pytest.fixture(scope="module")
def truncated():
    return synth_log(3, **SMALL)


@pytest.fixture
def drawn(monkeypatch):
    """The figures calibrate_figure draws, kept open to be read."""
    kept = keep_figures(monkeypatch, calibrate_figure)
    yield kept
    for fig in kept:
        figures.pyplot().close(fig)


def _line(ax, label_start: str):
    (line,) = [ln for ln in ax.get_lines() if ln.get_label().startswith(label_start)]
    return line


def test_plot_writes_the_figure_beside_the_fragment(tmp_path, capsys, censored):
    log, out, plot = tmp_path / "log.csv", tmp_path / "site.toml", tmp_path / "fit.png"
    censored.to_csv(log, index=False)
    assert main(["calibrate", str(log), "--out", str(out), "--plot", str(plot)]) == 0
    printed = capsys.readouterr().out
    assert f"wrote {plot}" in printed and f"wrote {out}" in printed
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fit.png", "log.csv", "site.toml"]


def test_plot_shows_every_frame_and_the_fitted_law(tmp_path, censored, drawn):
    """The received frames at their power and distance, the frames not received as ticks,
    the fitted law P_t - PL(d0) - 10 n log10(d / d0) and the naive line, and a second panel
    of the share heard."""
    c = calibrate_frame(censored)
    calibrate_figure.draw_calibration(c, tmp_path / "f.png", "log")
    (fig,) = drawn
    left, right = fig.axes[:2]
    received = censored["received"].to_numpy()
    (dots,) = left.collections[:1]
    assert len(dots.get_offsets()) == received.sum()
    assert len(_line(left, "not received").get_xdata()) == (~received).sum()
    for label, f in (("fit (censored)", c.fit), ("least squares", c.naive)):
        x, y = _line(left, label).get_data()
        want = c.tx_power_dbm - f.reference_loss_db.value - f.path_loss_exponent.value * 10 * np.log10(x)
        np.testing.assert_allclose(y, want)
    assert right.get_ylabel() == "frames the radio heard"


def test_plot_of_a_truncated_fit_has_no_share_heard(tmp_path, truncated, drawn):
    """A log of received frames alone has no share heard to show: one panel."""
    c = calibrate_frame(truncated, -80.0)
    calibrate_figure.draw_calibration(c, tmp_path / "f.png", "log")
    (fig,) = drawn
    assert len(fig.axes) == 1 and c.fit.likelihood == "truncated"


def test_plot_draws_an_even_sample_of_a_long_log(tmp_path, censored, drawn, monkeypatch):
    monkeypatch.setattr(calibrate_figure, "SHOWN", 100)
    c = calibrate_frame(censored)
    calibrate_figure.draw_calibration(c, tmp_path / "f.png", "log")
    (fig,) = drawn
    (dots,) = fig.axes[0].collections[:1]
    received = int(censored["received"].sum())
    assert len(dots.get_offsets()) == 100 and dots.get_label() == f"received (100 of {received:,})"


def test_share_heard_counts_every_frame_and_predicts_by_the_fit(censored):
    c = calibrate_frame(censored)
    share = calibrate_figure.heard_by_distance(c)
    assert share["frames"].sum() == len(censored)
    assert share["heard"].sum() == censored["received"].sum()
    assert (np.diff(share["distance_m"]) > 0).all()
    assert (share["low"] <= share["heard"] / share["frames"]).all()
    assert (share["heard"] / share["frames"] <= share["high"]).all()
    # The nearest bin: its frames' mean chance of clearing the sensitivity under the fit.
    d = np.maximum(censored["distance_m"].to_numpy(), 1.0)
    width = (np.log(d).max() - np.log(d).min()) / calibrate_figure.DISTANCE_BINS
    first = np.log(d) < np.log(d).min() + width
    mean = c.tx_power_dbm - c.fit.reference_loss_db.value - c.fit.path_loss_exponent.value * 10 * np.log10(d[first])
    chance = stats.norm.sf((c.sensitivity_dbm - mean) / c.fit.shadowing_sigma_db.value)
    assert share["predicted"][0] == pytest.approx(chance.mean())
    # A fit to netsim's own log predicts the shares it heard.
    inside = (share["low"] <= share["predicted"] + 0.02) & (share["predicted"] - 0.02 <= share["high"])
    assert inside.sum() >= len(inside) - 2
    assert TRUTH.sensitivity_dbm == pytest.approx(c.sensitivity_dbm, abs=1.0)


def test_wilson_interval_closed_form():
    low, high = calibrate_figure.wilson(np.array([0.0, 5.0]), np.array([10.0, 10.0]))
    z2 = stats.norm.ppf(0.975) ** 2
    assert low[0] == pytest.approx(0.0, abs=1e-15) and high[0] == pytest.approx(z2 / (10 + z2))
    assert (low[1] + high[1]) / 2 == pytest.approx(0.5) and low[1] == pytest.approx(0.2366, abs=1e-4)


@pytest.mark.parametrize(
    ("plot", "words"),
    [
        ("fit.txt", "--plot '{plot}': must end in one of .png, .svg, .pdf"),
        ("here.png", "--plot {plot}: exists already; give a new path"),
        ("no/such/dir/fit.png", "--plot {plot}: the directory {parent} does not exist"),
    ],
)
def test_a_bad_plot_path_is_one_line_exit_2_nothing_written(tmp_path, capsys, censored, plot, words):
    log = tmp_path / "log.csv"
    censored.to_csv(log, index=False)
    (tmp_path / "here.png").write_text("mine")
    plot_path = tmp_path / plot
    assert main(["calibrate", str(log), "--plot", str(plot_path)]) == 2
    captured = capsys.readouterr()
    err = captured.err.strip()
    assert err == "netsim: error: " + words.format(plot=plot_path, parent=plot_path.parent)
    assert captured.out == ""
    assert sorted(p.name for p in tmp_path.iterdir()) == ["here.png", "log.csv"]
    assert (tmp_path / "here.png").read_text() == "mine"


def test_share_heard_counts_frames_lost_after_the_radio_heard_them(tmp_path, censored, drawn):
    """A frame lost to a loss model cleared the sensitivity: it is heard, not missed, and
    not drawn among the frames not received."""
    log = censored[["t_s", "src", "dst", "distance_m", "rssi_dbm", "received"]]
    received = log["received"].to_numpy()
    lost = received & (np.random.default_rng(1).random(len(log)) < 0.3)
    log = log.assign(cause=np.where(received, "", "out_of_range"))
    log.loc[lost, ["received", "cause", "rssi_dbm"]] = [False, "loss", np.nan]
    c = calibrate_frame(log, TRUTH.sensitivity_dbm)
    share = calibrate_figure.heard_by_distance(c)
    assert share["heard"].sum() == received.sum()
    calibrate_figure.draw_calibration(c, tmp_path / "f.png", "log")
    (fig,) = drawn
    assert len(_line(fig.axes[0], "not received").get_xdata()) == (~received).sum()


def test_plot_on_a_map_takes_the_walls_out_at_the_fitted_loss(tmp_path, drawn):
    from netsim.radio.propagation import LogDistanceParams
    from netsim.tools.radio_checks import wall_test_map
    from netsim.world.los import walls_crossed

    m = wall_test_map()
    params = LogDistanceParams(
        reference_loss_db=40.0, path_loss_exponent=3.0, shadowing_sigma_db=4.0, wall_loss_db=6.0, sensitivity_dbm=-80.0
    )
    log = synth_log(6, params, side_m=40.0, duration_s=100.0, step_s=0.5, occupancy=m)
    xy = log[["src_x_m", "src_y_m", "dst_x_m", "dst_y_m"]].to_numpy()
    walls = walls_crossed(m, xy[:, :2], xy[:, 2:]).astype(float)
    c = calibrate_frame(log, -80.0, walls=walls)
    calibrate_figure.draw_calibration(c, tmp_path / "f.png", "log")
    (fig,) = drawn
    ax = fig.axes[0]
    (dots,) = ax.collections[:1]
    want = log["rssi_dbm"].to_numpy() + c.fit.wall_loss_db.value * walls
    assert walls.any() and c.fit.wall_loss_db.value > 0
    np.testing.assert_allclose(dots.get_offsets()[:, 1], want)
    assert ax.get_ylabel() == "received power, walls taken out (dBm)"


@pytest.mark.parametrize("suffix, magic", [(".svg", b"<?xml"), (".pdf", b"%PDF")])
def test_plot_writes_the_format_its_suffix_names(tmp_path, capsys, censored, suffix, magic):
    log, plot = tmp_path / "log.csv", tmp_path / f"fit{suffix}"
    censored.to_csv(log, index=False)
    assert main(["calibrate", str(log), "--plot", str(plot)]) == 0
    assert plot.read_bytes()[: len(magic)] == magic
