"""The statistics of ``netsim calibrate``: the log-distance law fitted to logged powers.

The model (:mod:`netsim.radio.propagation`, :mod:`netsim.radio.shadowing`): a frame's power is

    y = P_t - PL(d0) - n g - w k + X,    g = 10 log10(max(d, d0) / d0),

``k`` the walls crossed, ``X ~ N(0, sigma^2)`` the pair's shadowing, and the frame is
received iff ``y >= S`` (the sensitivity). A robot logs only what it received, so:

- with only received rows, each row's power follows the normal *truncated* at ``S``
  (:func:`fit_truncated`);
- when the log also lists frames sent but not received (power unknown), those rows say only
  ``y < S``: a *censored* regression, Tobit's (:func:`fit_censored`); a frame lost after the
  radio heard it (to a loss model or a collision) with no power logged says ``y >= S``.

The rows of one pair are not independent (a pair's shadowing is an Ornstein-Uhlenbeck
process in its travel), so the likelihood above is a composite one: still consistent, but
its intervals come from the cluster-robust (sandwich) covariance with the pair as cluster,
``H^-1 (sum_g s_g s_g') H^-1 G / (G - 1)``, not from the inverse information alone, which
would treat a pair's hundred correlated frames as a hundred independent ones.

The decorrelation distance is fitted on the residuals of consecutive frames of one pair,
where the process is Markov: ``r' | r ~ N(rho r, sigma^2 (1 - rho^2))`` with
``rho = exp(-delta_s / d_corr)`` and ``delta_s`` the pair's travel between them
(:func:`fit_decorrelation`). Only frames whose predicted power lies far above ``S`` are used,
so that which frames were received hardly depends on ``X``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import optimize, special, stats

from netsim.compiled import load

Z95 = float(stats.norm.ppf(0.975))

# Frames whose predicted power is this many sigma above the sensitivity are received with
# probability 1 - 1.3e-3: their residuals are, for the decorrelation fit, untruncated.
CLEAR_SIGMAS = 3.0


@dataclass(frozen=True)
class Estimate:
    """A fitted value with its 95 % interval (``low``, ``high``)."""

    value: float
    low: float
    high: float

    def covers(self, truth: float) -> bool:
        return self.low <= truth <= self.high


@dataclass(frozen=True)
class Design:
    """What the fits read: one row per frame.

    ``y_dbm`` is the logged power (NaN: sent, not received), ``g_db`` the distance term
    ``10 log10(max(d, d0) / d0)``, ``walls`` the walls crossed (None: no map), ``cluster``
    an integer per unordered pair; ``above`` (None: none) the rows without a power known to
    have cleared the sensitivity (lost after the radio heard them).
    """

    y_dbm: np.ndarray
    g_db: np.ndarray
    walls: np.ndarray | None
    cluster: np.ndarray
    tx_power_dbm: float
    above: np.ndarray | None = None

    @property
    def received(self) -> np.ndarray:
        return ~np.isnan(self.y_dbm)

    def received_only(self) -> Design:
        """The rows of the frames that were received."""
        seen = self.received
        walls = None if self.walls is None else self.walls[seen]
        return Design(self.y_dbm[seen], self.g_db[seen], walls, self.cluster[seen], self.tx_power_dbm)

    def columns(self) -> np.ndarray:
        """Regressors of the loss: ``1`` (``PL(d0)``), ``g`` (``n``) and the walls (``w``)."""
        cols = [np.ones_like(self.g_db), self.g_db]
        if self.walls is not None:
            cols.append(self.walls.astype(float))
        return np.column_stack(cols)


@dataclass(frozen=True)
class ChannelFit:
    """Fitted ``reference_loss_db``, ``path_loss_exponent``, ``wall_loss_db`` (None
    without a map) and ``shadowing_sigma_db``."""

    reference_loss_db: Estimate
    path_loss_exponent: Estimate
    wall_loss_db: Estimate | None
    shadowing_sigma_db: Estimate
    likelihood: str  # "truncated", "censored" or "least squares"

    def mean_dbm(self, design: Design) -> np.ndarray:
        """Predicted power of every row (without shadowing)."""
        beta = [self.reference_loss_db.value, self.path_loss_exponent.value]
        if self.wall_loss_db is not None:
            beta.append(self.wall_loss_db.value)
        return design.tx_power_dbm - design.columns() @ np.asarray(beta)


def _loglik_and_scores(theta, design: Design, sensitivity_dbm: float, censored: bool):
    """Per-row log-likelihood and scores (rows x parameters) at ``theta = (beta, log sigma)``."""
    x = design.columns()
    beta, u = theta[:-1], theta[-1]
    sigma = np.exp(u)
    mu = design.tx_power_dbm - x @ beta
    c = (sensitivity_dbm - mu) / sigma
    seen = design.received
    ll = np.empty(len(mu))
    a_mu = np.empty(len(mu))  # d ll / d mu
    a_sigma = np.empty(len(mu))  # d ll / d sigma
    z = (design.y_dbm[seen] - mu[seen]) / sigma
    ll[seen] = stats.norm.logpdf(z) - u
    a_mu[seen] = z / sigma
    a_sigma[seen] = (z * z - 1.0) / sigma
    if censored:
        above = np.zeros(len(mu), bool) if design.above is None else design.above & ~seen
        below = ~seen & ~above
        cm = c[below]
        log_cdf = special.log_ndtr(cm)
        mills = np.exp(stats.norm.logpdf(cm) - log_cdf)
        ll[below] = log_cdf
        a_mu[below] = -mills / sigma
        a_sigma[below] = -mills * cm / sigma
        # Known to have cleared the sensitivity, power not logged: P(y >= S).
        ca = c[above]
        log_sf = special.log_ndtr(-ca)
        hazard = np.exp(stats.norm.logpdf(ca) - log_sf)
        ll[above] = log_sf
        a_mu[above] = hazard / sigma
        a_sigma[above] = hazard * ca / sigma
    elif np.isfinite(sensitivity_dbm):
        cs = c[seen]
        log_sf = special.log_ndtr(-cs)
        hazard = np.exp(stats.norm.logpdf(cs) - log_sf)
        ll[seen] -= log_sf
        a_mu[seen] -= hazard / sigma
        a_sigma[seen] -= hazard * cs / sigma
    scores = np.column_stack([-a_mu[:, None] * x, a_sigma * sigma])
    return ll, scores


def sandwich(scores: np.ndarray, hessian: np.ndarray, cluster: np.ndarray) -> np.ndarray:
    """Cluster-robust covariance ``H^-1 B H^-1 G / (G - 1)``, ``B`` the outer products of
    the clusters' summed scores and ``H`` the observed information."""
    _, inverse = np.unique(cluster, return_inverse=True)
    g = int(inverse.max()) + 1
    sums = np.zeros((g, scores.shape[1]))
    np.add.at(sums, inverse, scores)
    bread = np.linalg.inv(hessian)
    return bread @ (sums.T @ sums) @ bread * (g / (g - 1))


def _information(total_score, theta: np.ndarray) -> np.ndarray:
    """Observed information: minus the Jacobian of the total score, by central differences."""
    k = len(theta)
    h = np.empty((k, k))
    for j in range(k):
        step = 1e-5 * max(1.0, abs(theta[j]))
        up, down = theta.copy(), theta.copy()
        up[j] += step
        down[j] -= step
        h[:, j] = -(total_score(up) - total_score(down)) / (2 * step)
    return (h + h.T) / 2


def _estimates(theta: np.ndarray, cov: np.ndarray, walls: bool, likelihood: str) -> ChannelFit:
    se = np.sqrt(np.maximum(np.diag(cov), 0.0))

    def wald(j, floor=-np.inf):
        low = max(floor, theta[j] - Z95 * se[j])
        return Estimate(float(theta[j]), float(low), float(theta[j] + Z95 * se[j]))

    u, su = theta[-1], se[-1]
    # sigma's interval from log sigma's: it stays positive and is closer to its real coverage.
    sigma = Estimate(float(np.exp(u)), float(np.exp(u - Z95 * su)), float(np.exp(u + Z95 * su)))
    # A wall takes power, it gives none: the wall loss and its interval are held at 0 or more.
    return ChannelFit(wald(0), wald(1), wald(2, floor=0.0) if walls else None, sigma, likelihood)


def fit_naive(design: Design) -> ChannelFit:
    """Least squares through the received rows, as if nothing had been lost: biased (the
    frames that survive at long range are those shadowing favoured). Intervals cluster-robust."""
    seen = design.received
    x, y = design.columns()[seen], design.tx_power_dbm - design.y_dbm[seen]
    beta, *_ = np.linalg.lstsq(x, y, rcond=None)
    resid = y - x @ beta
    sigma = float(np.sqrt(np.mean(resid**2)))
    # Scores of the normal likelihood, which least squares maximises.
    theta = np.r_[beta, np.log(sigma)]
    return _ml(design.received_only(), theta, -np.inf, censored=False, likelihood="least squares", optimise=False)


def _ml(
    design: Design, start: np.ndarray, sensitivity_dbm: float, censored: bool, likelihood: str, optimise: bool = True
) -> ChannelFit:
    def negll(theta):
        ll, scores = _loglik_and_scores(theta, design, sensitivity_dbm, censored)
        return -ll.sum(), -scores.sum(axis=0)

    theta = np.asarray(start, dtype=float)
    if optimise:
        res = optimize.minimize(negll, theta, jac=True, method="BFGS", options={"gtol": 1e-8, "maxiter": 2000})
        theta = res.x
        if design.walls is not None and theta[2] < 0.0:
            # The likelihood's peak lies at a wall that gives power (walls that barely take
            # any, and the shadowing's scatter): the maximum over the walls there are is at 0.
            bounds = [(None, None), (None, None), (0.0, None), (None, None)]
            at_zero = np.r_[theta[:2], 0.0, theta[3:]]
            res = optimize.minimize(
                negll, at_zero, jac=True, method="L-BFGS-B", bounds=bounds, options={"ftol": 1e-15, "gtol": 1e-8}
            )
            theta = res.x
        if not np.all(np.isfinite(theta)) or not np.isfinite(res.fun):
            raise FitError("the maximum-likelihood fit did not converge")

    def total_score(t):
        return _loglik_and_scores(t, design, sensitivity_dbm, censored)[1].sum(axis=0)

    info = _information(total_score, theta)
    _, scores = _loglik_and_scores(theta, design, sensitivity_dbm, censored)
    try:
        cov = sandwich(scores, info, design.cluster)
    except np.linalg.LinAlgError:
        raise FitError("the fit is singular: the log does not determine every parameter") from None
    if not np.all(np.isfinite(cov)):
        raise FitError("the fit's intervals cannot be computed: the log does not determine every parameter")
    return _estimates(theta, cov, design.walls is not None, likelihood)


class FitError(ValueError):
    """The log does not determine the parameters (the command says so in one line)."""


def _start(design: Design) -> np.ndarray:
    naive = fit_naive(design)
    beta = [naive.reference_loss_db.value, naive.path_loss_exponent.value]
    if naive.wall_loss_db is not None:
        beta.append(naive.wall_loss_db.value)
    return np.r_[beta, np.log(max(naive.shadowing_sigma_db.value, 1e-3))]


def fit_truncated(design: Design, sensitivity_dbm: float) -> ChannelFit:
    """Maximum likelihood of the normal truncated at ``sensitivity_dbm`` (received rows only)."""
    sub = design.received_only()
    return _ml(sub, _start(sub), sensitivity_dbm, censored=False, likelihood="truncated")


def fit_censored(design: Design, sensitivity_dbm: float) -> ChannelFit:
    """Tobit: received rows by their density, the others by ``P(y < S)``."""
    return _ml(design, _start(design), sensitivity_dbm, censored=True, likelihood="censored")


@dataclass(frozen=True)
class Decorrelation:
    """The fitted decorrelation distance, from ``steps`` consecutive-frame steps of ``pairs``
    pairs; ``estimate`` None with ``reason`` when the log cannot tell it."""

    estimate: Estimate | None
    steps: int
    pairs: int
    reason: str = ""


MIN_STEPS = 30
MIN_STEP_PAIRS = 5


def ar1_steps(residual_db, travel_m, cluster, usable):
    """Consecutive usable frames of each pair (rows sorted by pair, then travel): the
    residual before and after, the travel between (> 0 only) and the pair."""
    idx = np.flatnonzero(usable)
    order = idx[np.lexsort((travel_m[idx], cluster[idx]))]
    same = cluster[order[1:]] == cluster[order[:-1]]
    a, b = order[:-1][same], order[1:][same]
    delta = travel_m[b] - travel_m[a]
    moved = delta > 1e-9
    a, b, delta = a[moved], b[moved], delta[moved]
    return residual_db[a], residual_db[b], delta, cluster[a]


def _ar1_loglik(theta, r0, r1, delta):
    sigma, d = np.exp(theta[0]), float(np.exp(theta[1]))
    # The correlation the channel draws shadowing by (netsim._kernels.shadow_correlation).
    rho, renewal = np.empty(len(delta)), np.empty(len(delta))
    load("netsim._kernels", None, values=len(delta)).shadow_steps(delta, d, rho, renewal)
    var = sigma**2 * renewal
    return -0.5 * (np.log(2 * np.pi * var) + (r1 - rho * r0) ** 2 / var)


def fit_decorrelation(residual_db, travel_m, cluster, usable, sigma_db: float) -> Decorrelation:
    """Maximum likelihood of the AR(1) in travel over consecutive frames of each pair;
    interval from the cluster-robust covariance of ``log d_corr`` (pairs as clusters)."""
    r0, r1, delta, pair = ar1_steps(residual_db, travel_m, cluster, usable)
    n_pairs = len(np.unique(pair))
    if len(delta) < MIN_STEPS or n_pairs < MIN_STEP_PAIRS:
        return Decorrelation(
            None,
            len(delta),
            n_pairs,
            f"too few steps between frames of a pair that moved (need {MIN_STEPS} from {MIN_STEP_PAIRS} pairs)",
        )
    scale = float(np.median(delta))
    lo, hi = np.log(scale * 1e-3), np.log(scale * 1e4)

    def negll(theta):
        return -_ar1_loglik(theta, r0, r1, delta).sum()

    start = np.array([np.log(max(sigma_db, 1e-3)), np.log(scale * 10)])
    res = optimize.minimize(negll, start, method="L-BFGS-B", bounds=[(None, None), (lo, hi)])
    theta = res.x
    if not res.success or not np.all(np.isfinite(theta)) or min(theta[1] - lo, hi - theta[1]) < 1e-3:
        return Decorrelation(
            None,
            len(delta),
            n_pairs,
            "not determined by this log (the pairs' travel between frames is far shorter or far longer than it)",
        )

    def per_step_scores(t):
        k = len(t)
        out = np.empty((len(delta), k))
        for j in range(k):
            up, down = t.copy(), t.copy()
            up[j] += 1e-5
            down[j] -= 1e-5
            out[:, j] = (_ar1_loglik(up, r0, r1, delta) - _ar1_loglik(down, r0, r1, delta)) / 2e-5
        return out

    info = _information(lambda t: per_step_scores(t).sum(axis=0), theta)
    cov = sandwich(per_step_scores(theta), info, pair)
    se = float(np.sqrt(max(cov[1, 1], 0.0)))
    v = float(np.exp(theta[1]))
    est = Estimate(v, float(np.exp(theta[1] - Z95 * se)), float(np.exp(theta[1] + Z95 * se)))
    return Decorrelation(est, len(delta), n_pairs)
