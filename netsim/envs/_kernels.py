"""What an environment step measures and observes, written as loops (kernels: compiled or
plain Python, :func:`netsim.compiled.load`): the covered fraction of the run's area on a
grid, and each robot's nearest told neighbours and strongest heard ones. One item at a
time: for tens of robots numpy's cost per call, not the arithmetic, is what a step costs.
The tests compare them with numpy oracles (tests/oracles/envs.py)."""

from __future__ import annotations

import numpy as np

from netsim._kernels import grid_nearest_m, share_within
from netsim.compiled import jit


@jit(nogil=True)
def covered_fraction_grid(p, radius_m, x0_m, y0_m, width_m, height_m, cells):
    """Fraction of the ``cells x cells`` grid of cell centres of the rectangle ``[x0, x0 +
    width] x [y0, y0 + height]`` that lie within ``radius_m`` of some centre of ``p``
    (:func:`netsim._kernels.grid_nearest_m`, the rule of :func:`netsim.metrics.covered_fraction`)."""
    nearest = grid_nearest_m(p, radius_m, x0_m, y0_m, width_m, height_m, cells, 0.0, True)
    return share_within(nearest.ravel(), radius_m)


@jit(nogil=True)
def nearest_told(out, start, pos, ids, told, heard_s, now, k, age_max_s):
    """Write into ``out[i, start:start + 4 min(k, slots)]`` robot ``i``'s ``k`` nearest live
    table entries by told position (ties: the lower slot first): ``dx, dy`` (told position
    minus ``pos[i]``), the age of the Ack that told it (``now - heard_s``, at most
    ``age_max_s``: tau, the observation's bound, which an entry outlives by the instants that
    round into its deadline) and 1; zeros where fewer are live. ``ids, told, heard_s``: a
    :class:`netsim.cosim.NeighbourView`'s arrays."""
    n, slots = ids.shape
    d2 = np.empty(slots)
    for i in range(n):
        for s in range(slots):
            if ids[i, s] >= 0:
                dx = told[i, s, 0] - pos[i, 0]
                dy = told[i, s, 1] - pos[i, 1]
                d2[s] = dx * dx + dy * dy
            else:
                d2[s] = np.inf
        order = np.argsort(d2, kind="mergesort")
        for m in range(min(k, slots)):
            s = order[m]
            c = start + 4 * m
            if ids[i, s] >= 0:
                out[i, c] = told[i, s, 0] - pos[i, 0]
                out[i, c + 1] = told[i, s, 1] - pos[i, 1]
                out[i, c + 2] = min(now - heard_s[i, s], age_max_s)
                out[i, c + 3] = 1.0
            else:
                out[i, c] = 0.0
                out[i, c + 1] = 0.0
                out[i, c + 2] = 0.0
                out[i, c + 3] = 0.0


@jit(nogil=True)
def strongest_heard(out, start, ids, power_dbm, heard_s, now, k, low_dbm, high_dbm, age_max_s):
    """Write into ``out[i, start:start + 3 k]`` robot ``i``'s ``k`` strongest live
    table entries by the power it got their last Acks at (ties: the lower slot first;
    entries without a power left out): that power (dBm, kept within ``[low_dbm,
    high_dbm]``, the observation's bounds, against float32's rounding there), the age of
    the Ack (``now - heard_s``, at most ``age_max_s``, as in :func:`nearest_told`) and 1;
    where fewer are live, ``low_dbm`` (nothing heard: the floor, inside the bounds), 0 and
    0. ``ids, power_dbm, heard_s``: a :class:`netsim.cosim.LinkQualityView`'s arrays."""
    n, slots = ids.shape
    key = np.empty(slots)
    for i in range(n):
        for s in range(slots):
            p = power_dbm[i, s]
            key[s] = -p if ids[i, s] >= 0 and not np.isnan(p) else np.inf
        order = np.argsort(key, kind="mergesort")
        for m in range(min(k, slots)):
            s = order[m]
            c = start + 3 * m
            if key[s] < np.inf:
                out[i, c] = min(max(power_dbm[i, s], low_dbm), high_dbm)
                out[i, c + 1] = min(now - heard_s[i, s], age_max_s)
                out[i, c + 2] = 1.0
            else:
                out[i, c] = low_dbm
                out[i, c + 1] = 0.0
                out[i, c + 2] = 0.0
        # Places past the table's slots (a table grows as it needs): nothing heard.
        for m in range(min(k, slots), k):
            c = start + 3 * m
            out[i, c] = low_dbm
            out[i, c + 1] = 0.0
            out[i, c + 2] = 0.0
