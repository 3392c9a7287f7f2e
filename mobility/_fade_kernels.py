"""The fade-margin rule under shadowing (docs/model.md section 5, "Staying connected", and
5.1, "Radios"), one implementation for both plans: the global plan's link rules
(:mod:`netsim.mobility.keep`) and the local plan (:mod:`netsim.mobility.local`) call these
loops, compiled or plain (:func:`netsim.compiled.load`).

A link whose shadowing was measured at ``x`` (dB, the pair's value at that transmission)
may, over a pair travel ``delta`` since, have moved against the link by at most its drift
back to 0 from a favourable ``x`` and :data:`FADE_SIGMAS` standard deviations of its
spread: ``(1 - rho) max(-x, 0) + FADE_SIGMAS sigma sqrt(1 - rho^2)``, ``rho = exp(-delta /
d_corr)`` (:func:`plausible_change_db`). A budget ``B`` of power margin then allows a pair
travel :func:`fade_travel_m`, and a link kept at the length where its margin with ``x`` is
``B`` (:func:`netsim._kernels.range_at_loss_m`) stays up at every look of the channel over that travel unless
the shadowing moves by more.
"""

from __future__ import annotations

import math

from netsim._kernels import innovation_scale, shadow_correlation
from netsim.compiled import jit

# Standard deviations of the shadowing's change that a kept link's budget covers (a
# one-sided 4-sigma event has probability 3.2e-5 at each look of the channel).
FADE_SIGMAS = 4.0
# Bisection rounds of fade_travel_m: rho to 2^-60.
BISECTIONS = 60


@jit(nogil=True)
def change_within_sigmas_db(rho, x_db, sigma_db, sigmas):
    """``(1 - rho) max(-x, 0) + sigmas sigma sqrt(1 - rho^2)``: the change covered up to
    ``sigmas`` standard deviations (a kept link's budget covers :data:`FADE_SIGMAS`)."""
    drift = max(-x_db, 0.0)
    return (1.0 - rho) * drift + sigmas * sigma_db * innovation_scale(rho)


@jit(nogil=True)
def plausible_change_db(travel_m, x_db, sigma_db, decorrelation_m):
    """How far the shadowing measured at ``x_db`` plausibly moved against the link over a
    pair travel ``travel_m`` (module notes), within :data:`FADE_SIGMAS` standard deviations."""
    return plausible_change_within_db(travel_m, x_db, sigma_db, decorrelation_m, FADE_SIGMAS)


@jit(nogil=True)
def plausible_change_within_db(travel_m, x_db, sigma_db, decorrelation_m, sigmas):
    """:func:`plausible_change_db` covering ``sigmas`` standard deviations of the change in
    place of :data:`FADE_SIGMAS` (rule 1's detours, ``coverage.detour_sigmas``)."""
    return change_within_sigmas_db(shadow_correlation(travel_m, decorrelation_m), x_db, sigma_db, sigmas)


@jit(nogil=True)
def fade_travel_m(budget_db, x_db, sigma_db, decorrelation_m):
    """The largest pair travel over which the plausible change stays within ``budget_db``
    (0 for a budget <= 0; inf when even complete decorrelation stays within it). The change
    falls as ``rho`` grows: bisection for the smallest ``rho`` within the budget."""
    if not budget_db > 0:
        return 0.0
    if change_within_sigmas_db(0.0, x_db, sigma_db, FADE_SIGMAS) <= budget_db:
        return math.inf
    lo, hi = 0.0, 1.0
    for _ in range(BISECTIONS):
        mid = 0.5 * (lo + hi)
        if change_within_sigmas_db(mid, x_db, sigma_db, FADE_SIGMAS) <= budget_db:
            hi = mid
        else:
            lo = mid
    if hi <= 0.0:
        return math.inf
    return -decorrelation_m * math.log(hi)


@jit(nogil=True)
def plausible_change_many(travel_m, x_db, sigma_db, decorrelation_m, out):
    """:func:`plausible_change_db` for every row."""
    for k in range(out.shape[0]):
        out[k] = plausible_change_db(travel_m[k], x_db[k], sigma_db, decorrelation_m)


@jit(nogil=True)
def fade_travel_many(budget_db, x_db, sigma_db, decorrelation_m, out):
    """:func:`fade_travel_m` for every row."""
    for k in range(out.shape[0]):
        out[k] = fade_travel_m(budget_db[k], x_db[k], sigma_db, decorrelation_m)
