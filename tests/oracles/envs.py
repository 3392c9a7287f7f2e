"""Reference oracles of what the environments score at every step
(:mod:`netsim.envs._kernels`), written with numpy: the covered fraction of the run's area on
a grid, the number of components of the network of the links, and the nearest told
neighbours of the observations. The tests compare the kernels, plain and compiled, with
them."""

from __future__ import annotations

import numpy as np


def covered_fraction_grid(
    centres_m: np.ndarray, radius_m: float, x0_m: float, y0_m: float, width_m: float, height_m: float, cells: int
) -> float:
    """Fraction of the ``cells x cells`` grid of cell centres of the rectangle ``[x0, x0 +
    width] x [y0, y0 + height]`` that lie within ``radius_m`` of some centre
    (:func:`netsim.metrics.covered_fraction` on the same grid, without a search tree: each
    disk marks, in each grid row it reaches, the run of cells it covers, and a running sum
    along the rows counts them).

    >>> round(covered_fraction_grid(np.array([[50.0, 50.0]]), 10.0, 0.0, 0.0, 100.0, 100.0, 500), 3)
    0.031
    >>> covered_fraction_grid(np.empty((0, 2)), 10.0, 0.0, 0.0, 100.0, 100.0, 10)
    0.0
    """
    p = np.asarray(centres_m, dtype=float).reshape(-1, 2) - np.array([x0_m, y0_m])
    if len(p) == 0:
        return 0.0
    hx, hy = width_m / cells, height_m / cells
    lo = np.clip(np.ceil((p[:, 1] - radius_m) / hy - 0.5), 0, cells).astype(np.int64)
    hi = np.clip(np.floor((p[:, 1] + radius_m) / hy - 0.5), -1, cells - 1).astype(np.int64)
    rows = np.maximum(hi - lo + 1, 0)
    disk = np.repeat(np.arange(len(p)), rows)
    row = np.repeat(lo - np.cumsum(rows) + rows, rows) + np.arange(int(rows.sum()))
    dy = (row + 0.5) * hy - p[disk, 1]
    half = np.sqrt(np.maximum(radius_m * radius_m - dy * dy, 0.0))
    x = p[disk, 0]
    first = np.clip(np.ceil((x - half) / hx - 0.5), 0, cells).astype(np.int64)
    last = np.clip(np.floor((x + half) / hx - 0.5), -1, cells - 1).astype(np.int64)
    keep = first <= last
    row, first, last = row[keep], first[keep], last[keep]
    width = cells + 1
    marks = np.bincount(row * width + first, minlength=cells * width) - np.bincount(
        row * width + last + 1, minlength=cells * width
    )
    covered = np.cumsum(marks.reshape(cells, width)[:, :cells], axis=1) > 0
    return float(covered.mean())


def component_count(n: int, a: np.ndarray, b: np.ndarray) -> int:
    """Connected components of the network of ``n`` robots whose links are the pairs
    ``(a[k], b[k])`` (the links a run's channel makes: its link solver's ``up_pairs()``).
    Each robot's label becomes the least label in reach, halving paths, until none changes.

    >>> component_count(4, np.array([0, 2]), np.array([1, 3]))
    2
    >>> component_count(3, np.empty(0, np.int64), np.empty(0, np.int64))
    3
    """
    a = np.asarray(a, dtype=np.int64)
    b = np.asarray(b, dtype=np.int64)
    labels = np.arange(n)
    while True:
        new = labels.copy()
        np.minimum.at(new, a, labels[b])
        np.minimum.at(new, b, labels[a])
        new = new[new]
        if (new == labels).all():
            return int(np.count_nonzero(labels == np.arange(n)))
        labels = new


def nearest_told(
    out: np.ndarray,
    start: int,
    pos: np.ndarray,
    ids: np.ndarray,
    told: np.ndarray,
    heard_s: np.ndarray,
    now: float,
    k: int,
    age_max_s: float,
) -> None:
    """Write into ``out[i, start:start + 4 min(k, slots)]`` robot ``i``'s ``k`` nearest live
    table entries by told position (ties: the lower slot first): ``dx, dy`` (told position
    minus ``pos[i]``), the age of the Ack that told it (``now - heard_s``) and 1; zeros where
    fewer are live. ``ids, told, heard_s``: a :class:`netsim.cosim.NeighbourView`'s arrays."""
    n, slots = ids.shape
    live = ids >= 0
    rel = told - pos[:, None, :]
    d2 = np.where(live, (rel * rel).sum(axis=2), np.inf)
    take = min(k, slots)
    order = np.argsort(d2, axis=1, kind="stable")[:, :take]
    rows = np.arange(n)[:, None]
    block = np.zeros((n, take, 4))
    block[:, :, 0:2] = rel[rows, order]
    block[:, :, 2] = np.minimum(now - heard_s[rows, order], age_max_s)
    block[:, :, 3] = 1.0
    block[~live[rows, order]] = 0.0
    out[:, start : start + 4 * take] = block.reshape(n, -1)


def strongest_heard(
    out: np.ndarray,
    start: int,
    ids: np.ndarray,
    power_dbm: np.ndarray,
    heard_s: np.ndarray,
    now: float,
    k: int,
    low_dbm: float,
    high_dbm: float,
    age_max_s: float,
) -> None:
    """Write into ``out[i, start:start + 3 k]`` robot ``i``'s ``k`` strongest live
    table entries with a power (ties: the lower slot first): the power clipped to
    ``[low_dbm, high_dbm]``, the age of the Ack and 1; ``(low_dbm, 0, 0)`` where fewer are live."""
    n, slots = ids.shape
    valid = (ids >= 0) & ~np.isnan(power_dbm)
    key = np.where(valid, -np.nan_to_num(power_dbm), np.inf)
    take = min(k, slots)
    order = np.argsort(key, axis=1, kind="stable")[:, :take]
    rows = np.arange(n)[:, None]
    block = np.zeros((n, take, 3))
    block[:, :, 0] = np.clip(power_dbm[rows, order], low_dbm, high_dbm)
    block[:, :, 1] = np.minimum(now - heard_s[rows, order], age_max_s)
    block[:, :, 2] = 1.0
    block[~valid[rows, order]] = (low_dbm, 0.0, 0.0)
    out[:, start : start + 3 * take] = block.reshape(n, -1)
    out[:, start + 3 * take : start + 3 * k] = np.tile((low_dbm, 0.0, 0.0), k - take)
