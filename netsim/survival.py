"""Link lifetimes with censoring handled: the Kaplan-Meier estimator and the restricted
mean lifetime, the figures the run's summary leads with and ``netsim.tools.analysis``
offers for sweeps.

A link still up when the run ends has an unknown lifetime, only a lower bound: dropping
such links, or counting them as ended, biases the lifetime down, more so for long links.
The Kaplan-Meier estimator uses them correctly (right-censored). Links already up at
t = 0 have an unknown birth and are left out.
"""

from __future__ import annotations

import math
from statistics import NormalDist

import numpy as np
import numpy.typing as npt
import pandas as pd


def _z(level: float) -> float:
    """The standard normal quantile of a two-sided interval at ``level``."""
    return NormalDist().inv_cdf(0.5 + level / 2)


def link_durations(links: pd.DataFrame) -> pd.DataFrame:
    """Lifetimes of the links born during the run: ``duration_s`` and ``observed`` (False
    when the link was still up at the end, a right-censored lifetime)."""
    born = links[~links["censored_start"]] if "censored_start" in links else links
    return pd.DataFrame(
        {
            "duration_s": (born["t_down_s"] - born["t_up_s"]).to_numpy(float),
            "observed": ~born["censored_end"].to_numpy(bool),
        }
    )


def kaplan_meier(durations: npt.ArrayLike, observed: npt.ArrayLike, level: float = 0.95) -> pd.DataFrame:
    """Kaplan-Meier survival curve: ``t_s, at_risk, events, survival, ci_low, ci_high``.

    One row per distinct time with an observed end; the confidence band is pointwise,
    from Greenwood's variance on the log(-log) scale (it stays inside [0, 1]).

    >>> km = kaplan_meier([1, 2, 2, 3, 4, 5], [1, 1, 0, 1, 0, 1])
    >>> km["survival"].round(4).tolist()
    [0.8333, 0.6667, 0.4444, 0.0]
    """
    d = np.asarray(durations, dtype=float)
    e = np.asarray(observed, dtype=bool)
    if len(d) != len(e):
        raise ValueError("durations and observed must have the same length")
    times, ends = np.unique(d[e], return_counts=True)
    # Lifetimes at least t long, ended or not, for every t at once (a summary's many links).
    at_risk = (len(d) - np.searchsorted(np.sort(d), times, "left")).astype(float)
    events = ends.astype(float)
    survival = np.cumprod(1.0 - events / at_risk)
    with np.errstate(divide="ignore", invalid="ignore"):
        greenwood = np.cumsum(events / (at_risk * (at_risk - events)))
        z = _z(level)
        log_s = np.log(survival)
        se = np.sqrt(greenwood) / np.abs(log_s)
        low = survival ** np.exp(z * se)
        high = survival ** np.exp(-z * se)
    low = np.where(survival > 0, np.nan_to_num(low, nan=0.0), 0.0)
    high = np.where(survival > 0, np.nan_to_num(high, nan=1.0), 0.0)
    high = np.where(survival >= 1, 1.0, high)
    return pd.DataFrame(
        {
            "t_s": times,
            "at_risk": at_risk.astype(int),
            "events": events.astype(int),
            "survival": survival,
            "ci_low": low,
            "ci_high": high,
        }
    )


def restricted_mean(
    km: pd.DataFrame,
    durations: npt.ArrayLike,
    observed: npt.ArrayLike,
    horizon_s: float | None = None,
    level: float = 0.95,
) -> tuple[float, float, float]:
    """Mean lifetime restricted to ``horizon_s`` (default: the longest duration), the area
    under the survival curve, with its confidence interval (Klein and Moeschberger).

    Equals the plain mean when nothing is censored.

    Returns ``(mean, ci_low, ci_high)``.
    """
    d = np.asarray(durations, dtype=float)
    tau = float(d.max()) if horizon_s is None else float(horizon_s)
    t = km["t_s"].to_numpy()
    s = km["survival"].to_numpy()
    keep = t <= tau
    t, s = t[keep], s[keep]
    knots = np.r_[0.0, t, tau]
    levels = np.r_[1.0, s]
    areas = np.diff(knots) * levels
    mean = float(areas.sum())
    # Area beyond each event time, for the variance.
    beyond = np.cumsum(areas[::-1])[::-1][1:]
    n, ev = km["at_risk"].to_numpy(float)[keep], km["events"].to_numpy(float)[keep]
    with np.errstate(divide="ignore", invalid="ignore"):
        terms = np.where(n > ev, beyond**2 * ev / (n * (n - ev)), 0.0)
    half = _z(level) * math.sqrt(float(terms.sum()))
    return mean, mean - half, mean + half


def median(km: pd.DataFrame) -> tuple[float, float, float]:
    """Median lifetime and its confidence interval, where the survival curve and its band
    cross one half (NaN where they never do)."""

    def first_below(col: str) -> float:
        hit = km.loc[km[col] <= 0.5, "t_s"]
        return float(hit.iloc[0]) if len(hit) else float("nan")

    return first_below("survival"), first_below("ci_low"), first_below("ci_high")


def no_lifetimes(links: int = 0, censored: int = 0) -> dict:
    """:func:`lifetime_summary` of links none of which ended: counts, and no figure."""
    figures = ("mean_s", "mean_ci_low_s", "mean_ci_high_s", "median_s", "median_ci_low_s", "median_ci_high_s")
    return {"links": links, "censored": censored, **dict.fromkeys(figures, math.nan)}


def lifetime_summary(links: pd.DataFrame, level: float = 0.95) -> dict:
    """Mean (restricted) and median link lifetime with confidence intervals, and counts."""
    ld = link_durations(links)
    if ld.empty or not ld["observed"].any():
        return no_lifetimes(len(ld), int((~ld["observed"]).sum()))
    km = kaplan_meier(ld["duration_s"], ld["observed"], level)
    mean, lo, hi = restricted_mean(km, ld["duration_s"], ld["observed"], level=level)
    med, med_lo, med_hi = median(km)
    return {
        "links": len(ld),
        "censored": int((~ld["observed"]).sum()),
        "mean_s": mean,
        "mean_ci_low_s": lo,
        "mean_ci_high_s": hi,
        "median_s": med,
        "median_ci_low_s": med_lo,
        "median_ci_high_s": med_hi,
    }
