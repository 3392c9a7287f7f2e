"""The crossings of a pair's relative path with a disk, solved with numpy: the reference
the link kernels (netsim/links/_kernels.py) are compared with, bit for bit.

Vectorised over pairs, image by image on a torus; crossings are handed to an ``emit``
callback as ``(t, a, b, kind, phase)``. Independent of the kernels' loops; only the
constants (the edge tolerance, the phases) are shared.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from netsim.links._kernels import EDGE_S, PHASE_END, PHASE_START


def roots(d: np.ndarray, w: np.ndarray, radius: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Entry and exit times (relative) of ``|d + w t| = radius``; NaN when none."""
    A = np.einsum("ij,ij->i", w, w)
    B = 2.0 * np.einsum("ij,ij->i", d, w)
    C = np.einsum("ij,ij->i", d, d) - radius * radius
    disc = B * B - 4.0 * A * C
    ok = (A > 0) & (disc > 0)
    sq = np.sqrt(np.where(ok, disc, 0.0))
    # The numerically stable pair of roots: q / A and C / q.
    q = -0.5 * (B + np.copysign(sq, B))
    with np.errstate(divide="ignore", invalid="ignore"):
        r1 = np.where(ok, q / np.where(A > 0, A, 1.0), np.nan)
        r2 = np.where(ok & (q != 0), C / np.where(q != 0, q, 1.0), np.nan)
    r2 = np.where(ok & (q == 0), -r1, r2)
    return np.fmin(r1, r2), np.fmax(r1, r2)


def solve_piece(
    d: np.ndarray,
    w: np.ndarray,
    radius: np.ndarray,
    origin: float | np.ndarray,
    t_start: float | np.ndarray,
    length: float | np.ndarray,
    a: np.ndarray,
    b: np.ndarray,
    emit: Callable[..., None],
    box: float | None = None,
) -> None:
    """Crossings within ``[t_start, t_start + length]`` of pairs whose relative position is
    ``d + w (t - origin)`` (``origin <= t_start``); on a torus, of every image the path can
    reach (``d`` the nearest one at ``origin``).

    The roots are solved from ``origin``, not from ``t_start``: callers pass the later of the
    two robots' leg starts, so that a crossing's time depends on the pair's legs alone, not
    on where a solver's windows happen to fall. The post-hoc and the runtime solver then
    find the very same floats."""
    if len(d) == 0:
        return
    n = len(d)
    origin = np.broadcast_to(np.asarray(origin, float), (n,))
    length = np.broadcast_to(np.asarray(length, float), (n,))
    t_start = np.broadcast_to(np.asarray(t_start, float), (n,))
    if box is None:
        _solve_image(d, w, radius, origin, t_start, length, a, b, emit)
        return
    # An image k is reachable when |d - box k| <= R + |w| span (span: from origin to the end);
    # with d the nearest image, |k_x|, |k_y| <= 1/2 + (R + |w| span) / box.
    reach = radius + np.hypot(w[:, 0], w[:, 1]) * (t_start + length - origin)
    K = int(np.floor(0.5 + float(reach.max()) / box))
    for kx in range(-K, K + 1):
        for ky in range(-K, K + 1):
            dk = d - box * np.array([kx, ky], float)
            nearest = kx == ky == 0
            sel = slice(None) if nearest else np.hypot(dk[:, 0], dk[:, 1]) <= reach * (1 + 1e-9)
            _solve_image(
                dk[sel], w[sel], radius[sel], origin[sel], t_start[sel], length[sel], a[sel], b[sel], emit, nearest
            )


def _solve_image(
    d: np.ndarray,
    w: np.ndarray,
    radius: np.ndarray,
    origin: np.ndarray,
    t_start: np.ndarray,
    length: np.ndarray,
    a: np.ndarray,
    b: np.ndarray,
    emit: Callable[..., None],
    nearest: bool = True,
) -> None:
    if len(d) == 0:
        return
    at_in, at_out = crossing_times(d, w, radius, origin, nearest)
    clip_crossings(at_in, at_out, t_start, length, a, b, emit)


def crossing_times(
    d: np.ndarray, w: np.ndarray, radius: np.ndarray, origin: np.ndarray, nearest: bool = True
) -> tuple[np.ndarray, np.ndarray]:
    """The instants the relative path ``d + w (t - origin)`` enters and leaves the disk of
    ``radius`` (NaN when it does not cross it): ``origin`` plus the roots. A pair at rest
    (``w = 0``) within ``radius`` of its nearest image enters at ``origin``."""
    t_in, t_out = roots(d, w, radius)
    at_rest_in = nearest & (w[:, 0] == 0) & (w[:, 1] == 0) & (np.hypot(d[:, 0], d[:, 1]) <= radius)
    return origin + np.where(at_rest_in, 0.0, t_in), origin + t_out


def clip_crossings(
    at_in: np.ndarray,
    at_out: np.ndarray,
    t_start: np.ndarray,
    length: np.ndarray,
    a: np.ndarray,
    b: np.ndarray,
    emit: Callable[..., None],
) -> None:
    """Hand ``emit`` the crossings ``at_in`` (up) and ``at_out`` (down) that fall within
    ``[t_start, t_start + length]``, with the phase that orders them at a piece's edge."""
    end = t_start + length
    # A crossing on a piece's edge is looked for by both pieces, with a little slack, so
    # that rounding cannot hide it from both; the duplicate is dropped later. A crossing
    # near a piece's start sorts after one near the previous piece's end at the same
    # instant (and after the state set at a jump there).
    for at, kind in ((at_in, 1), (at_out, -1)):
        hit = (at >= t_start - EDGE_S) & (at <= end + EDGE_S)
        t_ev = np.minimum(np.maximum(at[hit], t_start[hit]), end[hit])
        phase = np.where(t_ev - t_start[hit] <= 0.5 * length[hit], PHASE_START, PHASE_END)
        emit(t_ev, a[hit], b[hit], kind, phase)


def in_range(pos: np.ndarray, a: np.ndarray, b: np.ndarray, radius: np.ndarray, box: float | None) -> np.ndarray:
    """Whether robots ``a[k]`` and ``b[k]`` are within ``radius[k]`` (``hypot <= radius``,
    nearest image on a torus)."""
    d = pos[a] - pos[b]
    if box is not None:
        d = d - box * np.round(d / box)
    return np.hypot(d[:, 0], d[:, 1]) <= radius
