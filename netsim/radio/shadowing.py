"""Log-normal shadowing per pair: reciprocal, still while the pair is still, decorrelating with motion.

The model
---------
Each unordered pair ``{i, j}`` has its own shadowing ``X_ij`` in dB, Gaussian with mean 0
and standard deviation ``sigma``, the same in both directions (reciprocity). ``X_ij`` is a
function of the pair's *travel* ``s_ij(t)``: the sum of the two robots' path lengths since
t = 0. It is an Ornstein-Uhlenbeck process in ``s`` (Gudmundson's exponential model):

    corr(X(s), X(s + delta)) = exp(-delta / d_corr)

so it is constant while neither robot moves, and forgets as either one travels. Why the sum
of path lengths and not, say, the change of the pair's geometry: shadowing comes from the
obstacles around each end of the link; either robot moving among them changes it, even when
both move in parallel and their separation stays the same. And ``s`` only grows, so the
process is well defined whatever the order in which it is looked at.

Sampling
--------
:class:`PairShadowing` keeps, per pair seen so far, the last value and the travel at which
it was drawn. Looked at again at travel ``s'``, the pair moves on by the exact conditional
law of the process, ``X' = rho X + sigma sqrt(1 - rho^2) Z`` with
``rho = exp(-(s' - s) / d_corr)``, one standard normal ``Z`` per pair from the generator
handed in. Because the process is Markov, the values seen at any sequence of travels have
exactly the joint law of the process at those travels: the correlation is
``exp(-delta / d_corr)`` whatever the schedule (every Ack, every 10 s, or irregular). A
pair seen for the first time draws from the stationary law ``N(0, sigma^2)``. With
``sigma = 0`` nothing is drawn at all and the links are exactly the unit disk of the implied
range.

The value returned is clipped to +-4 sigma (``TRUNCATION_SIGMAS``; the stored state is not
clipped, so the dynamics stay exact): the neighbour search then has a finite radius, and the
probability that a pair at distance ``d`` links is exactly
``Phi((P_t - PL(d) - sensitivity) / sigma)`` wherever that lies in ``[3.2e-5, 1 - 3.2e-5]``
(0 and 1 outside).

Link events under shadowing
---------------------------
Two ways to say when a link is up, with their exactness:

- **Evaluated at each transmission** (``step_m = 0``, the default). ``X`` is drawn where
  the channel needs it, at send time, for the pairs within reach. Every reception decision
  is exact for the process above. Between two transmissions of a pair the process is not
  looked at, so "when did the link come up" has no exact answer, only "which frames got
  through"; a link table is then a record of receptions (or of decisions at send time).
- **Piecewise constant in travel** (``step_m > 0``, e.g. ``d_corr / 10``). ``X_ij`` only
  changes when ``s_ij`` crosses a multiple of ``step_m``; between such steps (and between
  changes of the walls crossed) a link is the distance threshold
  :func:`~netsim.radio.propagation.effective_range_m` of the pair's ``X`` and walls. The
  values at consecutive steps are the process sampled every ``step_m``: correlation exactly
  ``exp(-m step / d_corr)`` at ``m`` steps, and between grid points the linear interpolation
  of the exponential (at ``step_m = d_corr / 10``, within 0.0012 of ``exp(-delta / d_corr)``).
  A solver and the channel see the same ``X`` when they ask the same :class:`PairShadowing`
  in time order (the solver for a time window before the channel sends in it).

Memory: one entry per pair ever looked at (16 bytes of state and a key). :meth:`forget`
drops pairs that have travelled more than ``horizon`` decorrelation lengths since they were
last seen (correlation below ``exp(-horizon)``, by default 2e-9): on their next look they
draw afresh from the stationary law, which is the exact law up to that correlation.
"""

from __future__ import annotations

import numpy as np

from netsim.compiled import load
from netsim.errors import ConfigError
from netsim.radio._kernels import Clocks, Drawn, Shadow, ShadowLaw

# Shadowing is used clipped to +-4 sigma (its state is not: see PairShadowing), so that no
# pair beyond a finite distance can ever link; the link probability then follows the closed
# form exactly wherever it lies between 3.2e-5 and 1 - 3.2e-5.
TRUNCATION_SIGMAS = 4.0

# Standard normals drawn at once (see PairShadowing.normals).
NORMALS_BLOCK = 4096

# Above this many robots pairs get slots as they are first seen (see PairShadowing).
DENSE_MAX_ROBOTS = 3000


def pair_keys(a, b, n_robots: int | None = None) -> np.ndarray:
    """One int64 key per unordered pair: ``min << 32 | max`` (robot ids below 2**31), the
    key a frame's decision gives the pair (:func:`netsim.radio._kernels.pair_key`), for a
    team of ``n_robots`` (None: one per pair).

    >>> pair_keys([5, 0], [3, 9]).tolist() == [(3 << 32) | 5, 9]
    True
    """
    a, b = np.broadcast_arrays(np.asarray(a, dtype=np.int64), np.asarray(b, dtype=np.int64))
    flat_a, flat_b = np.ascontiguousarray(a).reshape(-1), np.ascontiguousarray(b).reshape(-1)
    out = np.empty(flat_a.shape[0], np.int64)
    load("netsim.radio._kernels", n_robots, values=flat_a.shape[0]).pair_keys_of(flat_a, flat_b, out)
    return out.reshape(a.shape)


def split_keys(keys: np.ndarray, n_robots: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The two robots of each key, lower id first (:func:`netsim.radio._kernels.pair_of`)."""
    keys = np.ascontiguousarray(keys, dtype=np.int64).reshape(-1)
    low, high = np.empty_like(keys), np.empty_like(keys)
    load("netsim.radio._kernels", n_robots, values=keys.shape[0]).pairs_of(keys, low, high)
    return low, high


class PairShadowing:
    """Shadowing of every pair, sampled on demand in non-decreasing travel.

    Parameters
    ----------
    sigma_db : standard deviation of ``X`` (dB); 0 turns shadowing off (nothing drawn).
    decorrelation_m : Gudmundson's decorrelation distance ``d_corr`` (metres of pair travel).
    rng : the component's own generator (e.g. ``sim.streams.get("shadowing")``).
    step_m : 0 to evaluate the process at each look; > 0 for a process piecewise constant
        in travel, changing at multiples of ``step_m`` (see the module notes).
    n_robots : the run's robots (its update loop then compiled or plain Python as
        :func:`netsim.compiled.load` decides; None, outside a run: as for a large one).
        When given and at most ``DENSE_MAX_ROBOTS``, every pair's slot is made at
        once (unseen: NaN), so that a pair seen for the first time costs a lookup, not an
        insertion into the sorted table (which copies it: ruinous when a run of a thousand
        robots meets new pairs at every transmission). Memory: 24 bytes per pair.
    """

    def __init__(
        self,
        sigma_db: float,
        decorrelation_m: float,
        rng: np.random.Generator,
        step_m: float = 0.0,
        n_robots: int | None = None,
    ):
        if not (np.isfinite(sigma_db) and sigma_db >= 0):
            raise ConfigError("channel.shadowing_sigma_db", sigma_db, "must be a finite number >= 0 (dB)")
        if not (np.isfinite(decorrelation_m) and decorrelation_m > 0):
            raise ConfigError("channel.shadowing_decorrelation_m", decorrelation_m, "must be a finite number > 0 (m)")
        if not (np.isfinite(step_m) and step_m >= 0):
            raise ConfigError("channel.shadowing_step_m", step_m, "must be a finite number >= 0 (m)")
        self.sigma_db = float(sigma_db)
        self.decorrelation_m = float(decorrelation_m)
        self.step_m = float(step_m)
        self.rng = rng
        self.n_robots = n_robots
        kernels = load("netsim.radio._kernels", n_robots)
        self._step, self._anchors, self._slots = kernels.shadow_step, kernels.anchors, kernels.slots
        self._records = kernels.records
        self._states, self._terms = kernels.stored_states, kernels.shadow_terms
        self.clip_db = TRUNCATION_SIGMAS * self.sigma_db
        self._keys = np.empty(0, dtype=np.int64)
        self._x = np.empty(0)
        self._s = np.empty(0)
        self.dense = n_robots is not None and 1 < n_robots <= DENSE_MAX_ROBOTS
        # Robots whose pairs all have slots (their place then computed, not searched); 0: none.
        self.dense_n = int(n_robots or 0) if self.dense else 0
        if self.dense:
            self._keys = np.empty(self.dense_n * (self.dense_n - 1) // 2, np.int64)
            kernels.dense_keys(self.dense_n, self._keys)  # ascending: lower id major
            self._x = np.full(len(self._keys), np.nan)
            self._s = np.zeros(len(self._keys))
        self.draws = 0
        # Normals drawn ahead from ``rng`` and handed out in order: the same sequence as
        # drawing each batch when needed (a Generator's normals do not depend on how many are
        # asked for at once), one draw call per block instead of one per frame.
        self._normals = np.empty(0)
        self._next = 0

    def normals(self, k: int) -> np.ndarray:
        """At least ``k`` standard normals, the next ones of the stream (not consumed:
        :meth:`consume` says how many were used)."""
        if self._next + k > len(self._normals):
            rest = self._normals[self._next :]
            self._normals = np.concatenate([rest, self.rng.standard_normal(max(k, NORMALS_BLOCK))])
            self._next = 0
        return self._normals[self._next :]

    def consume(self, k: int) -> None:
        """Mark the next ``k`` normals used."""
        self._next += k
        self.draws += k

    def __len__(self) -> int:
        """Pairs seen so far (and not forgotten)."""
        return int(np.count_nonzero(~np.isnan(self._x)))

    def table(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The pairs' records as a compiled pass reads and updates them in place: keys
        (:func:`pair_keys`, ascending), stored values ``X`` (unclipped; NaN: not seen, or
        forgotten) and anchor travels. New pairs go in through :meth:`insert`."""
        return self._keys, self._x, self._s

    def anchor(self, travel_m: np.ndarray) -> np.ndarray:
        """The travel a pair's value is taken at: ``travel_m`` down to a whole step (the
        kernel :func:`netsim.radio._kernels.anchored`, as a frame's pass takes it)."""
        travel = np.asarray(travel_m, dtype=float)
        flat = travel.reshape(-1)
        out = np.empty(flat.shape[0])
        self._anchors(flat, self.step_m, out)
        return out.reshape(travel.shape)

    def state(self, a, b) -> tuple[np.ndarray, np.ndarray]:
        """Stored (unclipped) value and anchor travel of each pair; NaN for pairs never seen."""
        keys = pair_keys(a, b, self.n_robots)
        x, s = np.empty(len(keys)), np.empty(len(keys))
        table_keys, table_x, table_s = self.table()
        self._states(table_keys, table_x, table_s, self.dense_n, keys, x, s)
        return x, s

    def loss_terms(self, x_db) -> np.ndarray:
        """Stored shadowing values as a pair's loss takes them, clipped to ``+-clip_db``
        (:func:`netsim.radio._kernels.shadow_term`)."""
        x = np.ascontiguousarray(x_db, dtype=float)
        out = np.empty(len(x))
        self._terms(x, self.clip_db, out)
        return out

    def sample(self, a, b, travel_m) -> np.ndarray:
        """``X`` (dB, clipped to +-4 sigma) of pairs ``(a[k], b[k])`` at pair travels ``travel_m[k]``.

        A pair's travel must not decrease from one look to the next (it is a sum of path
        lengths); a pair may appear twice in a batch (both directions) only at the same
        travel. One standard normal is drawn per item of the batch; a pair moves on with the
        draw of its first appearance.
        """
        a = np.asarray(a, dtype=np.int64)
        k = len(a)
        if self.sigma_db == 0.0 or k == 0:
            return np.zeros(k)
        keys = pair_keys(a, b, self.n_robots)
        s_new = self.anchor(np.array(np.broadcast_to(np.asarray(travel_m, dtype=float), (k,))))
        z = self.normals(k)[:k]
        self.consume(k)
        x = np.empty(k)
        new = np.empty(k, dtype=np.bool_)
        used = np.empty(k)
        law = tuple(ShadowLaw(self.sigma_db, self.decorrelation_m, self.dense_n, self.clip_db))
        shadow = tuple(Shadow(self._keys, self._x, self._s, z))
        self._step(shadow, law, tuple(Clocks(keys, s_new)), tuple(Drawn(x, new, used)))
        if new.any():
            # A pair new twice in the batch keeps the draw of its first appearance.
            idx = np.flatnonzero(new)
            uniq, first, inverse = np.unique(keys[idx], return_index=True, return_inverse=True)
            used[idx] = used[idx[first]][inverse]
            self.insert(uniq, x[idx[first]], s_new[idx[first]])
        return used

    def insert(self, keys, x, s) -> None:
        """Record pairs seen for the first time (``keys`` ascending, none recorded yet)."""
        keys = np.ascontiguousarray(keys, np.int64)
        if self.dense:
            x, s = np.ascontiguousarray(x, float), np.ascontiguousarray(s, float)
            self._records(self._keys, self._x, self._s, self.dense_n, keys, x, s)
            return
        at = np.empty(len(keys), np.int64)
        self._slots(self._keys, self.dense_n, keys, at)
        self._keys = np.insert(self._keys, at, keys)
        self._x = np.insert(self._x, at, x)
        self._s = np.insert(self._s, at, s)
