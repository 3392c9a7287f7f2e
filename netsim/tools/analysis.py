"""Analysis of results in pandas: link lifetimes with censoring handled (the estimators
are the engine's, :mod:`netsim.survival`, which the run's summary uses too), across a
sweep, and the closed forms the validation compares with.
"""

from __future__ import annotations

import math
from statistics import NormalDist

import numpy as np
import pandas as pd

from netsim.plugins import RoleLabels
from netsim.survival import kaplan_meier, lifetime_summary, link_durations, median, no_lifetimes, restricted_mean

__all__ = [
    "acks_until_leader_loss",
    "acks_waited",
    "compare_lifetimes",
    "expected_acks_until_spurious_timeout",
    "kaplan_meier",
    "lifetime_summary",
    "link_durations",
    "mean_acks_until_leader_loss",
    "median",
    "restricted_mean",
    "spurious_timeout_window",
    "torus_link_duration_mean",
]


def compare_lifetimes(runs: pd.DataFrame, links: pd.DataFrame, by: list[str]) -> pd.DataFrame:
    """Lifetime summary per parameter combination across a sweep: ``runs`` is
    :func:`netsim.tools.sweep.load`, ``links`` is :func:`netsim.tools.sweep.load_table` of ``links``;
    replications are pooled."""
    joined = links.merge(runs[["run_id", *by]], on="run_id") if len(links) else None
    rows = []
    for key, _ in runs.groupby(by, sort=True):
        key = key if isinstance(key, tuple) else (key,)
        g = None if joined is None else joined[(joined[by] == pd.Series(key, index=by)).all(axis=1)]
        # A combination whose runs saw no link (a sparse team) has its row, without figures.
        rows.append({**dict(zip(by, key)), **(no_lifetimes() if g is None or g.empty else lifetime_summary(g))})
    return pd.DataFrame(rows)


def torus_link_duration_mean(range_m: float, speed_mps: float) -> float:
    """Mean link lifetime for robots moving at the same constant speed in uniform random
    directions on a torus: ``pi^2 R / (8 v)`` (docs/validation.md item 6)."""
    return math.pi**2 * range_m / (8.0 * speed_mps)


def acks_until_leader_loss(roles: pd.DataFrame, tau_s: float, period_s: float, labels: RoleLabels) -> np.ndarray:
    """For each robot that became a member and lost its leader in the run, the number of
    its leader's Acks from the one it joined on to its first rule-3 timeout: the trials
    until ``k`` consecutive losses (docs/validation.md item 9); :func:`acks_waited`'s
    ``acks`` of the robots that did."""
    waited = acks_waited(roles, tau_s, period_s, labels)
    return waited["acks"].to_numpy(float)


def acks_waited(
    roles: pd.DataFrame, tau_s: float, period_s: float, labels: RoleLabels, end_s: float | None = None
) -> pd.DataFrame:
    """For each robot that became a member, ``acks``: its leader's Acks from the one it
    joined on to its first rule-3 timeout, and ``lost`` True; for one still waiting at
    ``end_s`` (the run's end; None: left out), the Acks after its joining one by then, and
    ``lost`` False (right-censored: its wait is longer). Assumes static robots and periodic
    Acks without jitter, so that every leader loss is spurious and the timeout comes
    ``tau`` after the last Ack heard: the count is ``floor((t_timeout - t_join - tau) /
    period) + k``, with ``k`` the number of Ack instants in the ``tau`` window, its end
    included (:func:`spurious_timeout_window`). ``labels``: how the run's protocol writes
    roles and the leader's loss (its plugin's ``role_labels``)."""
    k = spurious_timeout_window(tau_s, period_s)
    rows = []
    for _, rec in roles.groupby("robot"):
        joins = rec[rec["role"] == labels.member]
        if joins.empty:
            continue
        t_join = joins["t_s"].iloc[0]
        lost = rec[(rec["cause"] == labels.leader_lost) & (rec["t_s"] > t_join)]
        if len(lost):
            rows.append((math.floor((lost["t_s"].iloc[0] - t_join - tau_s) / period_s + 1e-9) + k, True))
        elif end_s is not None:
            rows.append((math.floor((end_s - t_join) / period_s + 1e-9), False))
    return pd.DataFrame({"acks": [float(a) for a, _ in rows], "lost": [bool(b) for _, b in rows]})


def mean_acks_until_leader_loss(waited: pd.DataFrame, level: float = 0.95) -> tuple[float, float, float]:
    """The mean wait of :func:`acks_waited` with the waits still running at the end
    counted (a mean of the completed ones alone leaves the long waits out, and falls short):
    every Ack waited over the leader losses seen, the maximum-likelihood mean of a
    memoryless wait, which the wait for ``k`` consecutive losses nearly is once it is much
    longer than ``k``. Its interval is that of an exponential wait's mean, ``mean
    exp(-+z / sqrt(losses))``. NaN without a loss."""
    losses = int(waited["lost"].sum())
    if losses == 0:
        return math.nan, math.nan, math.nan
    mean = float(waited["acks"].sum()) / losses
    z = NormalDist().inv_cdf(0.5 + level / 2)
    return mean, mean * math.exp(-z / math.sqrt(losses)), mean * math.exp(z / math.sqrt(losses))


def spurious_timeout_window(tau_s: float, period_s: float) -> int:
    """``k``: Ack instants in a window of ``tau`` after an Ack, its end included: an Ack
    due exactly ``tau`` later still counts (docs/model.md 4.2), so with ``tau`` a whole
    number of periods the member waits for that many losses, not one fewer."""
    return math.floor(tau_s / period_s + 1e-9)


def expected_acks_until_spurious_timeout(p: float | np.ndarray, k: int) -> float | np.ndarray:
    """``(1 - p^k) / ((1 - p) p^k)``: mean Acks until ``k`` consecutive losses, at a loss
    probability ``p`` in [0, 1) (a number, or an array of them). At ``p = 0`` no Ack is lost
    and the wait never ends: ``inf``, the formula's limit as ``p`` falls to 0."""
    q = np.asarray(p, dtype=float)
    with np.errstate(divide="ignore"):
        mean = (1 - q**k) / ((1 - q) * q**k)
    return float(mean) if mean.ndim == 0 else mean
