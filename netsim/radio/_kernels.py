"""The radio's loops (compiled or plain, :func:`netsim.compiled.load`): the passes over a
frame's pairs (:mod:`netsim.radio.fast`), the shadowing's update
(:mod:`netsim.radio.shadowing`), the links' record and the legs' lookup, one item at a
time; and the log-distance law itself (:func:`path_loss_db`), which every place that needs
a loss calls. The tests check them against numpy oracles (tests/oracles/radio.py) and the
loss chain's own path on whole arrays.

The loops take their arrays as records, each a :class:`~typing.NamedTuple` defined here and
read by field name: :class:`Shadow`, :class:`ShadowLaw`, :class:`Clocks`, :class:`Drawn`,
:class:`PathLoss`, :class:`Points`, :class:`Decided`, :class:`Robots` (and the robots'
:class:`netsim._kernels.Motion`).
numba types a named tuple passed from Python by a slower path than a plain one, on every
call: so the callers pass each as a plain tuple of its fields, built by its record
(``tuple(Points(g0, g1))``), and a loop names it on entry (``Points(*points)``, free in
compiled code). The run's constants are a one-row record (:data:`netsim.radio.fast.FRAME`).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from netsim._kernels import Motion, innovation_scale, lower_bound, pair_travel, position, reaches, shadow_correlation
from netsim.compiled import jit
from netsim.world._kernels import NO_LIMIT, on_grid, walls_one


class Shadow(NamedTuple):
    """The shadowing's records (:meth:`~netsim.radio.shadowing.PairShadowing.table`) and
    the standard normals of this call, taken in order."""

    table_keys: np.ndarray  # each stored pair's key, ascending
    table_x: np.ndarray  # its shadowing, dB (NaN: listed, never seen)
    table_s: np.ndarray  # the pair's travel at that value, m
    normals: np.ndarray


class ShadowLaw(NamedTuple):
    """The shadowing's law: sigma (dB), decorrelation distance (m), the robots whose
    every pair has a slot (0: none), and the bound of ``|X|`` in a loss (dB)."""

    sigma_db: float
    decorrelation_m: float
    dense_n: int
    clip_db: float


class Clocks(NamedTuple):
    """Pairs by key, and each pair's travel now (its shadowing's clock), m."""

    keys: np.ndarray
    s_new: np.ndarray


class Drawn(NamedTuple):
    """Filled: each pair's shadowing, dB (a new pair's first draw where it is new), whether
    the pair is new (not stored), and the shadowing as a loss uses it (:func:`shadow_term`)."""

    x: np.ndarray
    new: np.ndarray
    used: np.ndarray


class PathLoss(NamedTuple):
    """Each pair's path loss, dB, and whether the terms after it could let it through."""

    loss: np.ndarray
    alive: np.ndarray


class Points(NamedTuple):
    """The ends of each pair in grid units (rows ``(u, v)``): sender, receiver."""

    g0: np.ndarray
    g1: np.ndarray


class Decided(NamedTuple):
    """A frame's pairs: their keys and travels (read, or filled by :func:`log_frame`), and,
    filled, a new pair's shadowing, whether it is new, and whether it is received."""

    keys: np.ndarray
    s_new: np.ndarray
    x_new: np.ndarray
    new: np.ndarray
    receivable: np.ndarray


class Robots(NamedTuple):
    """The robots' legs and odometers: what a pair's shadowing clock and a map's grid
    points are computed from (``speed_mps``: ``|v|`` as numpy computes it)."""

    odometer_m: np.ndarray
    speed_mps: np.ndarray
    t0_s: np.ndarray
    origin_m: np.ndarray
    velocity_mps: np.ndarray


@jit(nogil=True, inline="always")
def dense_slot(i, j, dense_n):
    """The slot of the pair ``(i, j)``, ``i < j``, in a table that lists every pair of
    ``dense_n`` robots, lower id major."""
    return i * dense_n - (i * (i + 1)) // 2 + (j - i - 1)


@jit(nogil=True)
def dense_keys(dense_n, out):
    """Every pair's key (:func:`pair_key`) of ``dense_n`` robots, each at its
    :func:`dense_slot`, into ``out``."""
    for i in range(dense_n):
        for j in range(i + 1, dense_n):
            out[dense_slot(i, j, dense_n)] = pair_key(i, j)


@jit(nogil=True)
def slot(table_keys, dense_n, key):
    """Where ``key`` is (or would go) in the table: computed when every pair of ``dense_n``
    robots has its slot (keys in ascending order, lower id major), else a binary search."""
    if dense_n > 0:
        i, j = pair_of(key)
        return dense_slot(i, j, dense_n)
    return lower_bound(table_keys, 0, table_keys.shape[0], key)


@jit(nogil=True)
def slots(table_keys, dense_n, keys, out):
    """:func:`slot` of every key, into ``out``."""
    for k in range(keys.shape[0]):
        out[k] = slot(table_keys, dense_n, keys[k])


@jit(nogil=True, inline="always")
def record(table_keys, table_x, table_s, dense_n, key, x, s):
    """Record the pair ``key`` seen for the first time, its shadowing ``x`` at travel ``s``,
    in its slot of a table that lists every pair (``dense_n`` > 0)."""
    pos = slot(table_keys, dense_n, key)
    table_x[pos] = x
    table_s[pos] = s


@jit(nogil=True)
def records(table_keys, table_x, table_s, dense_n, keys, x, s):
    """:func:`record` of every pair ``keys[k]``."""
    for k in range(keys.shape[0]):
        record(table_keys, table_x, table_s, dense_n, keys[k], x[k], s[k])


@jit(nogil=True, inline="always")
def stored_slot(table_keys, table_x, dense_n, key):
    """The slot of the pair ``key`` in the table when the pair has a stored value, else the
    table's length. A slot holding NaN is a pair listed in advance but never seen yet; with
    every pair listed (``dense_n > 0``) the slot is the pair's, and its key need not be read."""
    n = table_keys.shape[0]
    pos = slot(table_keys, dense_n, key)
    if pos < n and (dense_n > 0 or table_keys[pos] == key) and not np.isnan(table_x[pos]):
        return pos
    return n


@jit(nogil=True, inline="always")
def moved_on(table_x, table_s, pos, s_new, sigma, decorrelation_m, z):
    """The pair in slot ``pos`` moved on to travel ``s_new``: its shadowing correlated with
    the stored value by ``exp(-travel / decorrelation)`` (Gudmundson), the innovation ``z``
    (a standard normal) scaled to keep the variance ``sigma^2``; the slot updated in place."""
    rho = shadow_correlation(s_new - table_s[pos], decorrelation_m)
    v = rho * table_x[pos] + sigma * innovation_scale(rho) * z
    table_x[pos] = v
    table_s[pos] = max(s_new, table_s[pos])
    return v


@jit(nogil=True, inline="always")
def look(table_keys, table_x, table_s, dense_n, key, s_new, sigma, decorrelation_m, z):
    """The pair ``key`` looked at at travel ``s_new`` with the standard normal ``z``: its
    stored value moved on (:func:`moved_on`), or, for a pair not stored, a draw of the
    stationary law ``sigma z`` (not stored here: the caller records it). Returns the value
    and whether the pair is new."""
    pos = stored_slot(table_keys, table_x, dense_n, key)
    if pos < table_keys.shape[0]:
        return moved_on(table_x, table_s, pos, s_new, sigma, decorrelation_m, z), False
    return sigma * z, True


@jit(nogil=True, inline="always")
def shadow_term(x, clip_db):
    """The shadowing ``x`` (dB) as a pair's loss takes it: clipped to ``+-clip_db`` (the
    stored state is not clipped, so the process stays exact)."""
    return min(max(x, -clip_db), clip_db)


@jit(nogil=True)
def shadow_terms(x, clip_db, out):
    """:func:`shadow_term` of every value of ``x`` (1-d), into ``out``."""
    for m in range(x.shape[0]):
        out[m] = shadow_term(x[m], clip_db)


@jit(nogil=True)
def stored_states(table_keys, table_x, table_s, dense_n, keys, x, s):
    """Each pair's stored (unclipped) shadowing and anchor travel, looked up as a frame
    looks it up (:func:`stored_slot`), into ``x`` and ``s``; NaN for a pair never seen."""
    n = table_keys.shape[0]
    for m in range(keys.shape[0]):
        pos = stored_slot(table_keys, table_x, dense_n, keys[m])
        x[m] = table_x[pos] if pos < n else np.nan
        s[m] = table_s[pos] if pos < n else np.nan


@jit(nogil=True)
def shadow_step(shadow, law, pairs, out):
    """Look at the pairs ``pairs.keys`` at travels ``pairs.s_new`` (:func:`look`; stored
    pairs move on in place): their values to ``out.x``, clipped to ``out.used``
    (:func:`shadow_term`), the new ones flagged in ``out.new``. ``shadow``: :class:`Shadow`;
    ``law``: :class:`ShadowLaw` (``clip_db``: :func:`shadow_term`'s bound); ``pairs``:
    :class:`Clocks`; ``out``: :class:`Drawn`."""
    sh = Shadow(*shadow)
    lw = ShadowLaw(*law)
    pc = Clocks(*pairs)
    dr = Drawn(*out)
    table_keys, table_x, table_s, z = sh.table_keys, sh.table_x, sh.table_s, sh.normals
    sigma, decorrelation_m, dense_n, clip_db = lw.sigma_db, lw.decorrelation_m, lw.dense_n, lw.clip_db
    keys, s_new = pc.keys, pc.s_new
    for m in range(keys.shape[0]):
        v, is_new = look(table_keys, table_x, table_s, dense_n, keys[m], s_new[m], sigma, decorrelation_m, z[m])
        dr.x[m] = v
        dr.new[m] = is_new
        dr.used[m] = shadow_term(v, clip_db)


@jit(nogil=True)
def received_dbm(tx_dbm, loss_db):
    """The power a frame arrives with, ``P_t - loss`` (dBm): one expression for a number
    or an array of them (:meth:`netsim.radio.chain.Radio.received_dbm` calls it too)."""
    return tx_dbm - loss_db


@jit(nogil=True)
def shadowing_of(tx_dbm, path_loss_db, received_dbm):
    """The shadowing a frame had that arrived with ``received_dbm`` after ``path_loss_db``:
    :func:`received_dbm`'s law solved for it, ``P_t - PL - P_r`` (dB). One expression for a
    number or an array."""
    return tx_dbm - path_loss_db - received_dbm


@jit(nogil=True)
def above_sensitivity_db(received_dbm, sensitivity_dbm):
    """How far above the sensitivity a frame arrives with ``received_dbm`` (dB; negative:
    not heard). One expression for a number or an array: the margin a robot measures on
    an Ack (the local plan) and, by :func:`margin_db`, the one a loss gives."""
    return received_dbm - sensitivity_dbm


@jit(nogil=True)
def margin_db(tx_dbm, loss_db, sensitivity_dbm):
    """A frame's margin after ``loss_db``: :func:`above_sensitivity_db` of its power
    (:func:`received_dbm`). The radio hears it exactly when the margin is not negative
    (:func:`heard`: the sign of a rounded difference is the difference's), so a plan that
    keeps links by their margin and the channel never disagree at the edge."""
    return above_sensitivity_db(received_dbm(tx_dbm, loss_db), sensitivity_dbm)


@jit(nogil=True)
def heard(tx_dbm, loss_db, sensitivity_dbm):
    """The radio's decision: a frame after ``loss_db`` is received when its margin
    (:func:`margin_db`) is not negative, its power at least the sensitivity. One expression
    for a number or an array (a frame's pass, and :meth:`netsim.radio.chain.Radio.hears`
    for every other caller)."""
    return margin_db(tx_dbm, loss_db, sensitivity_dbm) >= 0.0


@jit(nogil=True)
def with_slack(budget_db):
    """The budget a pair is dropped against before its last terms are added: ``budget_db``
    and a slack of its rounding, so that dropping a pair early never disagrees with the
    decision (:func:`heard`) the whole sum would give."""
    return budget_db + 1e-9 * (1.0 + abs(budget_db))


@jit(nogil=True)
def may_be_heard(loss_db, rest_db, slack_budget_db):
    """The early drop: whether a pair whose terms so far cost ``loss_db`` can still be heard
    when the terms left add at least ``rest_db`` (``slack_budget_db``: :func:`with_slack`).
    One expression for a number or an array (a frame's compiled pass, and the loss chain
    term by term, :meth:`netsim.radio.chain.LossChain.receivable`)."""
    return loss_db + rest_db <= slack_budget_db


@jit(nogil=True)
def through_walls_db(loss_db, wall_db, walls):
    """A pair's loss after the walls its segment crosses, ``wall_db`` each: one expression
    for a number or an array (a frame's passes, the chain's wall term,
    :meth:`netsim.radio.propagation.LogDistanceParams.loss_db` for the plans, and the inverse
    law :func:`netsim.radio.propagation.effective_range_m`)."""
    return loss_db + wall_db * walls


@jit(nogil=True)
def path_loss_db(distance_m, d0_m, pl0_db, n10):
    """The log-distance law, the one place it is computed: ``PL(d0) + 10 n log10(d / d0)``,
    and ``PL(d0)`` below ``d0`` (at ``d = 0`` too); ``n10`` is ``10 n``."""
    return pl0_db + n10 * math.log10(max(distance_m, d0_m) / d0_m)


@jit(nogil=True)
def path_losses_db(distance_m, d0_m, pl0_db, n10, out):
    """:func:`path_loss_db` of every distance of ``distance_m`` (1-d), written to ``out``."""
    for m in range(distance_m.shape[0]):
        out[m] = path_loss_db(distance_m[m], d0_m, pl0_db, n10)


@jit(nogil=True)
def path_loss_pass(frame, d, loss, alive):
    """Path loss of each pair, and whether the terms after it could still let it through
    (``frame``: the run's constants, :data:`netsim.radio.fast.FRAME`)."""
    c = frame[0]
    d0, pl0, n10, rest_db, budget_slack = c.d0_m, c.pl0_db, c.n10, -c.clip_db, c.budget_slack
    count = 0
    for m in range(d.shape[0]):
        loss[m] = 0.0 + path_loss_db(d[m], d0, pl0, n10)
        ok = may_be_heard(loss[m], rest_db, budget_slack)
        alive[m] = ok
        if ok:
            count += 1
    return count


@jit(nogil=True)
def budget_pass(frame, sigma, path, shadow, flat, points, pairs):
    """Shadowing (when ``sigma`` > 0) and walls (when the run has a wall loss) for the pairs
    still alive, then the decision ``tx - loss >= sensitivity``: the loss chain in one pass.
    ``frame``: the run's constants; ``path``: :func:`path_loss_pass`'s :class:`PathLoss`;
    ``shadow``: :class:`Shadow`; ``flat``: the map's occupied cells; ``points``:
    :class:`Points`; ``pairs``: :class:`Decided`, the keys and travels read (shadowing),
    the rest filled."""
    c = frame[0]
    pl = PathLoss(*path)
    sh = Shadow(*shadow)
    ends = Points(*points)
    dec = Decided(*pairs)
    loss, alive = pl.loss, pl.alive
    table_keys, table_x, table_s, z = sh.table_keys, sh.table_x, sh.table_s, sh.normals
    g0, g1 = ends.g0, ends.g1
    keys, s_new, x_new, new, receivable = dec.keys, dec.s_new, dec.x_new, dec.new, dec.receivable
    decorrelation_m, clip_db, wall_db, dense_n = c.decorrelation_m, c.clip_db, c.wall_db, c.dense_n
    cells, eps, budget_slack = (flat, c.map_h, c.map_w), c.eps, c.budget_slack
    tx_dbm, sensitivity_dbm = c.tx_dbm, c.sensitivity_dbm
    j = 0
    for m in range(loss.shape[0]):
        receivable[m] = False
        new[m] = False
        if not alive[m]:
            continue
        total = loss[m]
        if sigma > 0.0:
            v, is_new = look(table_keys, table_x, table_s, dense_n, keys[m], s_new[m], sigma, decorrelation_m, z[j])
            if is_new:
                new[m] = True
                x_new[m] = v
            j += 1
            total = total + shadow_term(v, clip_db)
        if wall_db > 0.0:
            if not may_be_heard(total, 0.0, budget_slack):
                continue
            # Counting stops two walls past what the margin affords: the pair is then out,
            # whatever rounding the division made.
            affordable = (budget_slack - total) / wall_db
            limit = np.int64(affordable) + 1 if affordable < 1e18 else np.iinfo(np.int64).max
            walls = walls_one(cells, g0[m, 0], g0[m, 1], g1[m, 0], g1[m, 1], eps, limit)
            total = through_walls_db(total, wall_db, walls)
        receivable[m] = heard(tx_dbm, total, sensitivity_dbm)


@jit(nogil=True)
def received_pass(frame, t, sender, receivers, d, x, motion, flat, out):
    """Power (dBm) at each of ``receivers`` of ``sender``'s frame at ``t``: ``P_t`` less the
    loss a decision sums, path loss (:func:`path_loss_db`) at ``d``, the pair's stored
    shadowing ``x`` (:func:`shadow_term`; NaN, a pair never seen: none) when the run has
    shadowing, and ``wall_db`` per wall the pair's segment crosses, all counted, when it has
    a wall loss (the robots placed by :func:`grid_points` from ``motion``, the state's
    :class:`Motion`; ``flat``: the map's occupied cells). ``frame``: the run's constants."""
    c = frame[0]
    k = receivers.shape[0]
    if c.wall_db > 0.0:
        ends = Points(np.empty((k, 2)), np.empty((k, 2)))
        grid_points(frame, t, sender, receivers, motion, ends)
    else:
        none = np.zeros((1, 2))
        ends = Points(none, none)
    for m in range(k):
        total = path_loss_db(d[m], c.d0_m, c.pl0_db, c.n10)
        if c.sigma_db > 0.0:
            total = total + (0.0 if np.isnan(x[m]) else shadow_term(x[m], c.clip_db))
        if c.wall_db > 0.0:
            g0, g1, no_limit = ends.g0, ends.g1, int(NO_LIMIT)
            walls = walls_one((flat, c.map_h, c.map_w), g0[m, 0], g0[m, 1], g1[m, 0], g1[m, 1], c.eps, no_limit)
            total = through_walls_db(total, c.wall_db, walls)
        out[m] = received_dbm(c.tx_dbm, total)


@jit(nogil=True, inline="always")
def in_disk(distance_m, range_m):
    """The unit disk's rule: a pair at ``distance_m`` links when within the range (the one
    "in range", :func:`netsim._kernels.reaches`, of a distance already known)."""
    return reaches(distance_m, 0.0, range_m, 0.0)


@jit(nogil=True)
def in_disks(distance_m, range_m, out):
    """:func:`in_disk` of each distance, one range for all, into ``out``."""
    for m in range(distance_m.shape[0]):
        out[m] = in_disk(distance_m[m], range_m)


@jit(nogil=True)
def disk_losses(distance_m, a, range_m, out):
    """The unit disk as a loss (dB) of each pair: 0 within the range of its sender
    (``range_m[a[m]]``, or ``range_m[0]`` for all when it has one item), infinite beyond."""
    per_robot = range_m.shape[0] > 1
    for m in range(distance_m.shape[0]):
        out[m] = 0.0 if in_disk(distance_m[m], range_m[a[m]] if per_robot else range_m[0]) else np.inf


@jit(nogil=True)
def disk_pass(frame, d, a, range_m, flat, points, receivable):
    """The unit disk (the sender's range: ``range_m[a]``, or ``range_m[0]`` for all), with
    line of sight on a map (``flat``, the ends in grid units ``points``: :class:`Points`)."""
    c = frame[0]
    ends = Points(*points)
    g0, g1 = ends.g0, ends.g1
    for m in range(d.shape[0]):
        ok = in_disk(d[m], range_m[a[m]] if c.per_robot else range_m[0])
        if ok and c.use_map:
            walls = walls_one((flat, c.map_h, c.map_w), g0[m, 0], g0[m, 1], g1[m, 0], g1[m, 1], c.eps, int(0))
            ok = walls == 0
        receivable[m] = ok


@jit(nogil=True, inline="always")
def anchored(travel_m, step_m):
    """The travel a pair's shadowing is taken at: ``travel_m`` down to a whole ``step_m``
    when ``step_m`` > 0 (a process piecewise constant in travel), else itself."""
    return np.floor(travel_m / step_m) * step_m if step_m > 0.0 else travel_m


@jit(nogil=True)
def anchors(travel_m, step_m, out):
    """:func:`anchored` of every travel of ``travel_m`` (1-d), written to ``out``."""
    for m in range(travel_m.shape[0]):
        out[m] = anchored(travel_m[m], step_m)


@jit(nogil=True, inline="always")
def pair_key(a, b):
    """The key of the unordered pair of robots ``a``, ``b``: the lower id in the high 32
    bits, the higher in the low ones (ids below 2**31)."""
    return (min(a, b) << 32) | max(a, b)


@jit(nogil=True, inline="always")
def pair_of(key):
    """The two robots of the pair ``key`` (:func:`pair_key`), lower id first."""
    return key >> 32, key & 0xFFFFFFFF


@jit(nogil=True)
def pairs_of(keys, a, b):
    """:func:`pair_of` of each key into ``a`` and ``b``."""
    for m in range(keys.shape[0]):
        a[m], b[m] = pair_of(keys[m])


@jit(nogil=True)
def pair_keys_of(a, b, out):
    """:func:`pair_key` of each pair ``(a[m], b[m])`` into ``out``
    (:func:`netsim.radio.shadowing.pair_keys`)."""
    for m in range(a.shape[0]):
        out[m] = pair_key(a[m], b[m])


@jit(nogil=True)
def pair_clock(sender, receivers, odometer, speed, t0, t, step_m, keys, s_new):
    """Each pair's key, and its shadowing clock: the pair's travel at ``t`` (the two robots'
    :func:`netsim._kernels.travel` summed, ``speed`` the state's ``speed_mps``), floored to
    a multiple of ``step_m`` when ``step_m`` > 0
    (:meth:`~netsim.radio.shadowing.PairShadowing.anchor`)."""
    for m in range(receivers.shape[0]):
        r = receivers[m]
        s_new[m] = anchored(pair_travel(odometer, speed, t0, sender, r, t), step_m)
        keys[m] = pair_key(sender, r)


@jit(nogil=True)
def link_changes(up, sender, receivers, linked, scratch, changed):
    """Robots whose link with ``sender`` differs from ``up[sender]`` once this decision is
    taken (heard: up; otherwise down), written to ``changed``; returns how many.
    ``scratch`` is all False on entry and on return."""
    for m in range(receivers.shape[0]):
        if linked[m]:
            scratch[receivers[m]] = True
    count = 0
    row = up[sender]
    for j in range(row.shape[0]):
        if row[j] != scratch[j]:
            changed[count] = j
            count += 1
    for m in range(receivers.shape[0]):
        scratch[receivers[m]] = False
    return count


@jit(nogil=True)
def link_touches(up, sender, receivers, linked, t0, last_t, every, touched):
    """Robots heard by ``sender`` whose link with it is already up and that may have left
    the reach since the pair's last decision: one of the two started a leg (or jumped) at or
    after it (``t0``; the last decision is the later of the two robots' last sends,
    ``last_t``), or ``every``. Written to ``touched``; returns how many."""
    count = 0
    own_t0 = t0[sender]
    own_last = last_t[sender]
    for m in range(receivers.shape[0]):
        if not linked[m]:
            continue
        r = receivers[m]
        if not up[sender, r]:
            continue
        p = max(own_last, last_t[r])
        if every or own_t0 >= p or t0[r] >= p:
            touched[count] = r
            count += 1
    return count


@jit(nogil=True)
def grid_points(frame, t, sender, receivers, motion, points):
    """Grid coordinates (:func:`~netsim.world._kernels.on_grid`, the map grid of ``frame``)
    of the sender (every row of ``g0``) and of each receiver (``g1``) at ``t``, ``points``:
    :class:`Points`, filled. The positions of :func:`netsim._kernels.position` (a map is
    never a torus); ``motion``: the state's :class:`Motion`."""
    c = frame[0]
    map_ox, map_oy, res = c.map_ox, c.map_oy, c.res_m
    mo = Motion(*motion)
    ends = Points(*points)
    origin_m, velocity_mps, t0 = mo.origin_m, mo.velocity_mps, mo.t0_s
    g0, g1 = ends.g0, ends.g1
    x0, y0 = position(origin_m, velocity_mps, t0, sender, t, False, 0.0)
    u0, v0 = on_grid(x0, map_ox, res), on_grid(y0, map_oy, res)
    for m in range(receivers.shape[0]):
        x, y = position(origin_m, velocity_mps, t0, receivers[m], t, False, 0.0)
        g0[m, 0] = u0
        g0[m, 1] = v0
        g1[m, 0] = on_grid(x, map_ox, res)
        g1[m, 1] = on_grid(y, map_oy, res)


@jit(nogil=True)
def pair_points(frame, pos_a, pos_b, points):
    """Grid coordinates (:func:`~netsim.world._kernels.on_grid`, the map grid of ``frame``)
    of the pairs' ends at ``pos_a`` and ``pos_b`` (metres), ``points``: :class:`Points`, filled."""
    c = frame[0]
    ends = Points(*points)
    for m in range(pos_a.shape[0]):
        ends.g0[m, 0] = on_grid(pos_a[m, 0], c.map_ox, c.res_m)
        ends.g0[m, 1] = on_grid(pos_a[m, 1], c.map_oy, c.res_m)
        ends.g1[m, 0] = on_grid(pos_b[m, 0], c.map_ox, c.res_m)
        ends.g1[m, 1] = on_grid(pos_b[m, 1], c.map_oy, c.res_m)


@jit(nogil=True)
def log_frame(frame, t, sender, receivers, distance_m, robots, shadow, flat, out):
    """One frame under log-distance path loss, with shadowing when the run's ``sigma_db`` >
    0 and walls when its ``wall_db`` > 0: :func:`pair_clock`, :func:`grid_points`,
    :func:`path_loss_pass` and :func:`budget_pass` in one call.

    ``frame``: the run's constants (:data:`netsim.radio.fast.FRAME`); ``robots``: the
    state's :class:`Robots`; ``shadow``: :class:`Shadow`, the normals taken in order;
    ``flat``: the map's occupied cells; ``out``: :class:`Decided`, filled. Pairs met for the
    first time get their slot at once when every pair has one (``dense_n`` > 0); otherwise
    they are left flagged in ``new`` for the caller to insert. Returns the number of normals
    used."""
    c = frame[0]
    rb = Robots(*robots)
    sh = Shadow(*shadow)
    dec = Decided(*out)
    table_keys, table_x, table_s = sh.table_keys, sh.table_x, sh.table_s
    keys, s_new, x_new, new = dec.keys, dec.s_new, dec.x_new, dec.new
    sigma, dense_n = c.sigma_db, c.dense_n
    k = receivers.shape[0]
    if sigma > 0.0:
        pair_clock(sender, receivers, rb.odometer_m, rb.speed_mps, rb.t0_s, t, c.step_m, keys, s_new)
    if c.wall_db > 0.0:
        points = Points(np.empty((k, 2)), np.empty((k, 2)))
        grid_points(frame, t, sender, receivers, Motion(rb.origin_m, rb.velocity_mps, rb.t0_s, False, 0.0), points)
    else:
        none = np.zeros((1, 2))
        points = Points(none, none)
    loss = np.empty(k)
    alive = np.empty(k, dtype=np.bool_)
    count = path_loss_pass(frame, distance_m, loss, alive)
    if count == 0:
        sigma = 0.0
    budget_pass(frame, sigma, PathLoss(loss, alive), sh, flat, points, dec)
    if dense_n > 0 and sigma > 0.0:
        for m in range(k):
            if new[m]:
                record(table_keys, table_x, table_s, dense_n, keys[m], x_new[m], s_new[m])
                new[m] = False
    return count if sigma > 0.0 else 0


@jit(nogil=True)
def disk_frame(frame, t, sender, receivers, distance_m, range_m, robots, flat, receivable):
    """One frame under the unit disk (the sender's range), with line of sight on a map:
    :func:`grid_points` and :func:`disk_pass` in one call. ``robots``: the state's
    :class:`Motion`."""
    c = frame[0]
    k = receivers.shape[0]
    if c.use_map:
        points = Points(np.empty((k, 2)), np.empty((k, 2)))
        grid_points(frame, t, sender, receivers, robots, points)
    else:
        none = np.zeros((1, 2))
        points = Points(none, none)
    senders = np.full(k, sender, dtype=np.int64)
    disk_pass(frame, distance_m, senders, range_m, flat, points, receivable)
