"""A sweep's metrics against one parameter, one panel a metric, one line a series, each
point the replications' mean with its confidence interval (the columns
:func:`netsim.tools.sweep.aggregate` writes: ``<metric>_mean``, ``_ci_low``, ``_ci_high``)."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path

import pandas as pd

from netsim.errors import NetsimInputError
from netsim.tools.figures import pyplot
from netsim.tools.output import write_atomically


def draw_aggregate(
    agg: pd.DataFrame,
    x: str,
    series: str,
    metrics: Mapping[str, str],
    path: str | Path,
    title: str,
    *,
    xlabel: str | None = None,
    series_label: Callable[[object], str] = str,
) -> Path:
    """Draw ``metrics`` (column -> axis label) of ``agg`` against its column ``x``, a line
    for each value of its column ``series`` (named by ``series_label``), and write the PNG
    to ``path``. An interval the aggregate could not give (one replication: NaN) draws no
    bar."""
    missing = [f"{m}_{part}" for m in metrics for part in ("mean", "ci_low", "ci_high") if f"{m}_{part}" not in agg]
    missing += [c for c in (x, series) if c not in agg]
    if missing:
        raise NetsimInputError(
            f"the aggregate has no column {', '.join(missing)} (netsim.tools.sweep.aggregate writes them)"
        )
    plt = pyplot()
    fig, axes = plt.subplots(1, len(metrics), figsize=(4.2 * len(metrics), 3.6), constrained_layout=True, squeeze=False)
    for ax, (metric, label) in zip(axes[0], metrics.items()):
        for value, g in agg.groupby(series):
            g = g.sort_values(x)
            mean = g[f"{metric}_mean"]
            err = [(mean - g[f"{metric}_ci_low"]).fillna(0.0), (g[f"{metric}_ci_high"] - mean).fillna(0.0)]
            ax.errorbar(g[x], mean, yerr=err, marker="o", capsize=3, label=series_label(value))
        ax.set_xlabel(xlabel or x)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[0][0].legend()
    fig.suptitle(title)
    path = Path(path)
    try:
        write_atomically(path, lambda tmp: fig.savefig(tmp, dpi=120, format=path.suffix.lstrip(".").lower() or "png"))
    finally:
        plt.close(fig)
    return path
