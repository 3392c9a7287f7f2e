"""Reference oracles for the radio's and the world's kernels: the same rules in numpy
operations, written independently of the loops (no production code imports them).

The tests run each kernel plain (``importlib.import_module``) and compiled
(:func:`netsim.compiled.compiled_copy`) and compare both with these, bit for bit.
"""

from __future__ import annotations

import numpy as np

from netsim.world.los import VERTEX_TOLERANCE_CELLS


# -- the range index (netsim._kernels.within, within_alive, neighbour_lists) -------------
def _wrap(d: np.ndarray, side: float) -> np.ndarray:
    return (d.real - side * np.round(d.real / side)) + 1j * (d.imag - side * np.round(d.imag / side))


def positions(st, t: float, idx=None, fold: bool = True) -> np.ndarray:
    """Every robot's (or rows ``idx``') position at ``t`` on its current leg, in numpy
    operations: ``origin + velocity * (t - t0)``, folded onto the torus by ``np.mod`` into
    ``[0, side)`` (a remainder that rounds up to the side is 0)."""
    if idx is None:
        p = st.origin_m + st.velocity_mps * (t - st.t0_s)[:, None]
    else:
        p = st.origin_m[idx] + st.velocity_mps[idx] * (t - st.t0_s[idx])[..., None]
    if not (st.torus and fold):
        return p
    p = np.mod(p, st.side_m)
    return np.where(p >= st.side_m, 0.0, p)


def within(st, t: float, i: int, r: float, cand: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The candidates within ``r`` of robot ``i`` at ``t`` and their distances (``hypot``:
    the engine's one pair distance, the channel's unicast and the radio's pairs too)."""
    x, y = st.position(i, t)
    d = st.origin_c.take(cand) + st.velocity_c.take(cand) * (t - st.t0_s.take(cand)) - complex(x, y)
    if st.torus:
        d = _wrap(d, st.side_m)
    dist = np.hypot(d.real, d.imag)
    keep = dist <= r
    return cand[keep], dist[keep]


def neighbour_lists(pairs: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Both directions of the ``pairs`` as lists per robot, ascending: ``(indptr, indices)``."""
    rows = np.concatenate([pairs[:, 0], pairs[:, 1]])
    cols = np.concatenate([pairs[:, 1], pairs[:, 0]])
    order = np.lexsort((cols, rows))
    indptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(rows, minlength=n), out=indptr[1:])
    return indptr, cols[order].astype(np.int64)


# -- the shared medium (netsim.radio._mac_kernels.end_frame) -----------------------------
def end_frame(medium, frame, out):
    """A frame's end: the same arguments, updated and filled the same way; returns how many
    robots are newly idle."""
    cover, transmitting, tx_seq, cover_seq, busy_s, busy_since = medium
    i, seq, now, disturbed, rx, hd_start, col_start, by_power, sinr_db, capture_db = frame
    hd, col, newly = out
    cover[disturbed] -= 1
    transmitting[i] = False
    hd[: len(rx)] = hd_start | (tx_seq[rx] > seq)
    lost = (sinr_db < capture_db) if by_power else (col_start | (cover_seq[rx] != seq))
    col[: len(rx)] = ~hd[: len(rx)] & lost
    cand = np.append(disturbed, i)
    idle = cand[(cover[cand] == 0) & ~transmitting[cand]]
    newly[: len(idle)] = idle
    busy_s[idle] += now - busy_since[idle]
    return len(idle)


# -- the link record (netsim.radio._kernels.link_changes, link_touches) ------------------
def link_changes(up, sender, receivers, linked, scratch, changed) -> int:
    now = np.zeros(up.shape[0], dtype=bool)
    now[receivers[linked]] = True
    found = np.flatnonzero(up[sender] != now)
    changed[: len(found)] = found
    return len(found)


def link_touches(up, sender, receivers, linked, t0, last_t, every, touched) -> int:
    heard = receivers[linked]
    heard = heard[up[sender, heard]]
    p = np.maximum(last_t[sender], last_t[heard])
    found = heard[every | (t0[sender] >= p) | (t0[heard] >= p)]
    touched[: len(found)] = found
    return len(found)


# -- shadowing (netsim.radio._kernels.shadow_step, through PairShadowing.sample) ---------
def shadow_sample(sh, a, b, travel_m) -> np.ndarray:
    """:meth:`~netsim.radio.shadowing.PairShadowing.sample` of ``sh`` in numpy operations
    (``sh``'s records and stream updated the same way)."""
    from netsim.radio.shadowing import pair_keys

    a = np.asarray(a, dtype=np.int64)
    k = len(a)
    if sh.sigma_db == 0.0 or k == 0:
        return np.zeros(k)
    keys = pair_keys(a, b)
    s_new = sh.anchor(np.array(np.broadcast_to(np.asarray(travel_m, dtype=float), (k,))))
    z = sh.normals(k)[:k]
    sh.consume(k)
    order = np.argsort(keys, kind="stable")
    sk = keys[order]
    first = np.r_[True, sk[1:] != sk[:-1]]
    uniq = sk[first]
    inverse = np.empty(len(keys), dtype=np.int64)
    inverse[order] = np.cumsum(first) - 1
    lead = order[first]  # each pair's first appearance in the batch
    zu, su = z[lead], s_new[lead]
    table_keys, table_x, table_s = sh.table()
    n_old = len(table_keys)
    pos = np.searchsorted(table_keys, uniq)
    if n_old:
        at_ = np.minimum(pos, n_old - 1)
        found = (table_keys[at_] == uniq) & ~np.isnan(table_x[at_])
    else:
        found = np.zeros(len(uniq), dtype=bool)
    x = sh.sigma_db * zu
    if found.any():
        at = pos[found]
        delta = np.maximum(su[found] - table_s[at], 0.0)
        rho = np.exp(-delta / sh.decorrelation_m)
        x[found] = rho * table_x[at] + sh.sigma_db * np.sqrt(1.0 - rho * rho) * zu[found]
        table_x[at] = x[found]
        table_s[at] = np.maximum(su[found], table_s[at])
    if (~found).any():
        sh.insert(uniq[~found], x[~found], su[~found])
    return np.clip(x[inverse], -sh.clip_db, sh.clip_db)


# -- the world's traversal (netsim.world._kernels.trace) ---------------------------------
def _snap(g: np.ndarray) -> np.ndarray:
    r = np.rint(g)
    return np.where(np.abs(g - r) <= VERTEX_TOLERANCE_CELLS, r, g)


def trace(blocked: np.ndarray, resolution_m: float, origin_m, p, q, first: bool = False, snap: bool = False):
    """Walls crossed by each segment ``p[k] -> q[k]`` (and, with ``first``, the parameter in
    ``[0, 1]`` at which it first meets a blocked cell, ``inf`` if never), all segments in
    one set of array operations; with ``snap``, ends within the vertex tolerance of a grid
    line put on it."""
    p = np.asarray(p, dtype=float).reshape(-1, 2)
    q = np.asarray(q, dtype=float).reshape(-1, 2)
    k = len(p)
    h, w = blocked.shape
    flat = blocked.ravel()
    origin = np.asarray(origin_m, dtype=float)
    g0 = (p - origin) / resolution_m
    g1 = (q - origin) / resolution_m
    if snap:
        g0, g1 = _snap(g0), _snap(g1)
    # Rows 0..k-1 cross vertical lines, rows k..2k-1 horizontal ones (coordinates swapped).
    G0 = np.concatenate([g0, g0[:, ::-1]])
    G1 = np.concatenate([g1, g1[:, ::-1]])
    c0 = np.floor(G0).astype(np.int64)
    c1 = np.floor(G1).astype(np.int64)
    start = flat[np.minimum(np.maximum(c0[:k, 1], 0), h - 1) * w + np.minimum(np.maximum(c0[:k, 0], 0), w - 1)]
    n = np.abs(c1[:, 0] - c0[:, 0])
    total = int(n.sum())
    if total == 0:
        walls = start.astype(np.int64)
        return (walls, np.where(start, 0.0, np.inf)) if first else walls

    seg = np.repeat(np.arange(2 * k), n)
    step = np.arange(total) - np.repeat(np.cumsum(n) - n, n)
    d = G1 - G0
    fwd = (c1[:, 0] > c0[:, 0])[seg]
    line = c0[seg, 0] + np.where(fwd, step + 1, -step)
    dp, ds = d[seg, 0], d[seg, 1]
    t = (line - G0[seg, 0]) / dp
    sc = G0[seg, 1] + t * ds
    s_lo = np.minimum(c0[seg, 1], c1[seg, 1])
    s_hi = np.maximum(c0[seg, 1], c1[seg, 1])
    s_cell = np.minimum(np.maximum(np.floor(sc).astype(np.int64), s_lo), s_hi)
    p_after = line - ~fwd
    p_before = line - fwd
    half1 = seg >= k
    p_max = np.where(half1, h - 1, w - 1)
    s_max = np.where(half1, w - 1, h - 1)

    def index(pc, sc_, sel=slice(None)):
        pc = np.minimum(np.maximum(pc, 0), p_max[sel])
        sc_ = np.minimum(np.maximum(sc_, 0), s_max[sel])
        return np.where(half1[sel], pc * w + sc_, sc_ * w + pc)

    y = np.rint(sc)
    length = np.hypot(d[:, 0], d[:, 1])[seg]
    vertex = (np.abs(sc - y) * np.abs(dp) <= VERTEX_TOLERANCE_CELLS * length) & (y > s_lo) & (y <= s_hi)
    if vertex.any():
        yi = y.astype(np.int64)
        up = ds > 0
        s_before = np.where(vertex, yi - up, s_cell)
        s_after = np.where(vertex, yi - ~up, s_cell)
    else:
        s_before = s_after = s_cell
    occ_before = flat[index(p_before, s_before)]
    hit = flat[index(p_after, s_after)]
    if vertex.any():
        vx = np.flatnonzero(vertex & ~half1)
        sides = flat[index(p_after[vx], s_before[vx], vx)] | flat[index(p_before[vx], s_after[vx], vx)]
        hit[vx] |= sides
    rise = hit & ~occ_before
    if vertex.any():
        rise[vertex & half1] = False
    seg0 = seg - k * half1
    walls = start + np.bincount(seg0, weights=rise, minlength=k).astype(np.int64)
    if not first:
        return walls
    first_t = np.where(start, 0.0, np.inf)
    np.minimum.at(first_t, seg0[hit], t[hit])
    return walls, first_t


# -- destinations on a map (netsim.world._kernels.free_destinations) ---------------------
def draw_destinations(m, rng, here_m, area, batch: int = 64, max_rounds: int = 100) -> np.ndarray:
    """Random waypoints as sample_free draws and legs_free checks them, batch by batch."""
    from netsim.world.free_space import legs_free, sample_free

    here = np.asarray(here_m, dtype=float).reshape(-1, 2)
    k = len(here)
    out = np.empty((k, 2))
    todo = np.arange(k)
    for _ in range(max_rounds):
        if len(todo) == 0:
            break
        cand = sample_free(m, rng, len(todo) * batch, area)
        ok = legs_free(m, np.repeat(here[todo], batch, axis=0), cand).reshape(len(todo), batch)
        got = ok.any(axis=1)
        pick = np.argmax(ok, axis=1)
        out[todo[got]] = cand.reshape(len(todo), batch, 2)[got, pick[got]]
        todo = todo[~got]
    return out


# -- legs of a trajectory (netsim._kernels.legs_at) --------------------------------
def leg_index(L, robots: np.ndarray, times: np.ndarray) -> np.ndarray:
    """The leg of ``robots[k]`` current at ``times[k]``, by one sort of legs and queries."""
    robots = np.asarray(robots, np.int64)
    times = np.asarray(times, float)
    leg_robot = np.repeat(np.arange(len(L.first)), L.end - L.first)
    k, m = len(robots), len(L.t)
    key_robot = np.r_[leg_robot, robots]
    key_t = np.r_[L.t, times]
    is_query = np.r_[np.zeros(m, np.int8), np.ones(k, np.int8)]
    order = np.lexsort((is_query, key_t, key_robot))
    legs_before = np.cumsum(is_query[order] == 0)
    where = np.empty(m + k, np.int64)
    where[order] = legs_before - 1
    return np.maximum(where[m:], L.first[robots])


# -- the odometer (netsim.state.RobotState.travelled_m) -----------------------------------
def distance_travelled(legs, until_s: float) -> np.ndarray:
    """Each robot's path length over ``[0, until_s]`` from its legs table: the sum, leg by
    leg in time order, of ``|v|`` (numpy's complex abs) times the leg's time within the run."""
    legs = legs.sort_values(["robot", "t_s"], kind="stable")
    t = legs["t_s"].to_numpy(float)
    robot = legs["robot"].to_numpy(np.int64)
    nxt = np.where(np.r_[robot[1:] != robot[:-1], True], until_s, np.r_[t[1:], until_s])
    dur = np.clip(np.minimum(nxt, until_s) - np.minimum(t, until_s), 0, None)
    v = np.ascontiguousarray(legs[["vx_mps", "vy_mps"]].to_numpy(float))
    speed = np.abs(v.view(np.complex128)[:, 0])
    return np.bincount(robot, weights=speed * dur, minlength=int(robot.max()) + 1 if len(robot) else 0)
