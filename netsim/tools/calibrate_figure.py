"""The figure of a calibration (``netsim calibrate --plot FILE``): the log beside the law
fitted to it.

- Left, each received frame's power against its distance (a log scale; distances within
  the reference distance at it), walls taken out at the fitted loss per wall when a map
  gave them; the frames sent but not received as ticks along the bottom; the fitted law
  with its band of two shadowing deviations; the least-squares line through the received
  frames alone (the naive fit the printout sets beside it); the sensitivity.
- Right, when the log lists frames the radio never heard: the share of frames the radio heard at
  each distance (with its 95 % Wilson interval) beside the share the fit predicts, the
  probability that the law plus shadowing clears the sensitivity, averaged over the same
  frames. A fit that bends the law to the survivors misses these points.

At most :data:`SHOWN` frames of each kind are drawn (an even sample, the same every time);
the fit and the shares use them all.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy import stats

from netsim.tools.calibrate import Calibration
from netsim.tools.figures import pyplot
from netsim.tools.output import write_atomically

SHOWN = 20_000
DISTANCE_BINS = 16


def _shown(rows: np.ndarray) -> np.ndarray:
    """Indices of at most SHOWN of ``rows`` (a mask), evenly spread."""
    idx = np.flatnonzero(rows)
    if len(idx) <= SHOWN:
        return idx
    return idx[np.linspace(0, len(idx) - 1, SHOWN).astype(np.int64)]


def wilson(heard: np.ndarray, total: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The 95 % Wilson score interval of ``heard / total`` (scipy's), per bin."""
    ends = [stats.binomtest(int(k), int(n)).proportion_ci(0.95, method="wilson") for k, n in zip(heard, total)]
    p = heard / total
    # It holds the share; rounding at 0 or 1 must not leave the share outside.
    return np.minimum([e.low for e in ends], p), np.maximum([e.high for e in ends], p)


def _frames(c: Calibration) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each fitted frame's distance (as the law reads it: ``max(d, d0)``), whether the
    radio heard it (received, or lost after it heard it), and whether it was received."""
    d = c.design
    assert d is not None
    distance = c.reference_distance_m * 10.0 ** (d.g_db / 10.0)
    heard = d.received if d.above is None else d.received | d.above
    return distance, heard, d.received


def heard_by_distance(c: Calibration) -> dict[str, np.ndarray]:
    """Per distance bin (of equal widths along the log of the distance; those without a
    frame left out): the bin's median distance, its frames, those the radio heard
    (received, or lost after it heard them), their share's 95 % interval, and the share
    the fit predicts."""
    distance, heard, _ = _frames(c)
    sigma = c.fit.shadowing_sigma_db.value
    predicted = stats.norm.sf((c.sensitivity_dbm - c.fit.mean_dbm(c.design)) / sigma)
    log_d = np.log(distance)
    edges = np.linspace(log_d.min(), log_d.max(), DISTANCE_BINS + 1)  # a fit has frames at two distances
    which = np.clip(np.searchsorted(edges, log_d, side="right") - 1, 0, len(edges) - 2)
    total = np.bincount(which, minlength=len(edges) - 1).astype(float)
    keep = total > 0
    count = np.bincount(which, heard, len(edges) - 1)[keep]
    total = total[keep]
    low, high = wilson(count, total)
    middle = np.array([np.median(distance[which == k]) for k in np.flatnonzero(keep)])
    return {
        "distance_m": middle,
        "frames": total,
        "heard": count,
        "low": low,
        "high": high,
        "predicted": np.bincount(which, predicted, len(edges) - 1)[keep] / total,
    }


def draw_calibration(c: Calibration, path: str | Path, where: str) -> Path:
    """Draw the calibration ``c`` of the log ``where`` and write it to ``path`` (its
    suffix gives the format: .png, .svg or .pdf)."""
    d = c.design
    assert d is not None
    distance, heard, seen = _frames(c)
    failed = ~heard
    fit, naive = c.fit, c.naive
    walls = d.walls is not None and fit.wall_loss_db is not None
    power = d.y_dbm + (fit.wall_loss_db.value * d.walls if walls else 0.0)  # type: ignore[union-attr,operator]
    plt = pyplot()
    panels = 2 if failed.any() else 1
    fig, axes = plt.subplots(1, panels, figsize=(6.4 * panels, 6.2), constrained_layout=True, squeeze=False)
    ax = axes[0][0]
    shown = _shown(seen)
    note = f" ({len(shown):,} of {int(seen.sum()):,})" if len(shown) < seen.sum() else ""
    dots = {"s": 3, "alpha": 0.25, "color": "C0", "lw": 0, "rasterized": True}
    ax.scatter(distance[shown], power[shown], label=f"received{note}", **dots)
    grid = np.geomspace(distance.min(), distance.max(), 200)
    sigma, law = fit.shadowing_sigma_db.value, c.law_dbm(fit, grid)
    ax.plot(grid, law, color="C3", lw=2, label=_named(f"fit ({fit.likelihood})", fit))
    band = {"color": "C3", "alpha": 0.12, "lw": 0, "label": "fit ± 2 sigma"}
    ax.fill_between(grid, law - 2 * sigma, law + 2 * sigma, **band)
    naive_line = {"color": "0.2", "lw": 1.2, "ls": "--", "label": _named("least squares, received only", naive)}
    ax.plot(grid, c.law_dbm(naive, grid), **naive_line)
    ax.axhline(c.sensitivity_dbm, color="C2", lw=1, ls=":", label=f"sensitivity {c.sensitivity_dbm:.4g} dBm")
    if failed.any():
        lost = _shown(failed)
        bottom = min(np.nanmin(power), c.sensitivity_dbm) - 4 * sigma
        note = f" ({len(lost):,} of {int(failed.sum()):,})" if len(lost) < failed.sum() else ""
        ticks = {"color": "0.5", "ms": 8, "alpha": 0.3, "label": f"not received{note}"}
        ax.plot(distance[lost], np.full(len(lost), bottom), "|", **ticks)
    _distance_axis(ax)
    ax.set_ylabel("received power, walls taken out (dBm)" if walls else "received power (dBm)")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize="small", loc="upper center", bbox_to_anchor=(0.5, -0.13))
    if panels == 2:
        share = heard_by_distance(c)
        right = axes[0][1]
        ratio = share["heard"] / share["frames"]
        err = [ratio - share["low"], share["high"] - ratio]
        right.errorbar(share["distance_m"], ratio, yerr=err, fmt="o", capsize=3, label="heard (95 %)")
        right.plot(share["distance_m"], share["predicted"], color="C3", lw=2, label="the fit predicts")
        _distance_axis(right)
        right.set_ylim(-0.02, 1.02)
        right.set_ylabel("frames the radio heard")
        right.grid(alpha=0.3, which="both")
        right.legend(fontsize="small")
    fig.suptitle(f"netsim calibrate {where}: {c.frames:,} frames of {c.pairs:,} pairs", fontsize="medium")
    path = Path(path)
    try:
        write_atomically(path, lambda tmp: fig.savefig(tmp, dpi=120, format=path.suffix.lstrip(".").lower()))
    finally:
        plt.close(fig)
    return path


def _distance_axis(ax) -> None:
    """A log scale of distances labelled in plain metres at 1, 2 and 5 of each decade."""
    from matplotlib import ticker

    ax.set_xscale("log")
    ax.xaxis.set_major_locator(ticker.LogLocator(subs=(1.0, 2.0, 5.0)))
    ax.xaxis.set_major_formatter(ticker.FormatStrFormatter("%g"))
    ax.xaxis.set_minor_formatter(ticker.NullFormatter())
    ax.set_xlabel("distance (m)")


def _named(what: str, f) -> str:
    walls = f" w {f.wall_loss_db.value:.3g} dB" if f.wall_loss_db is not None else ""
    return (
        f"{what}: PL(d0) {f.reference_loss_db.value:.4g} dB, n {f.path_loss_exponent.value:.3g},"
        f"{walls} sigma {f.shadowing_sigma_db.value:.3g} dB"
    )
