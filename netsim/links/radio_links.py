"""Link lifetimes under a radio other than the plain unit disk: walls and shadowing.

How exact they are (docs/radio.md says the same for users):

- **Log-distance without shadowing or walls**: a link is the distance threshold of the
  implied range, solved exactly by :func:`netsim.links.lifetimes.link_lifetimes` (never here).
- **Walls, no shadowing** (unit disk with line of sight, or log-distance with
  ``wall_loss_db`` per wall): a link can only be up while the two robots are within the
  radio's largest range, and those intervals are solved exactly first (the *envelope*).
  Within each, the link is solved exactly along stretches in which both robots keep their
  legs: the walls crossed change only at instants solved in closed form
  (:mod:`netsim.world.sweep`), and between them the link is a distance threshold per
  count of walls (:mod:`netsim.links.wall_sweeps`, shared with the runtime solver
  :class:`netsim.links.walled_links.WalledLinks`: the same table, bit for bit).
- **Shadowing**: a link is random; its state is only defined where the channel looks at it,
  at transmissions (:class:`~netsim.radio.reception.LinkRecorder`). A link is up from the first
  transmission between the two robots (either way) that gets through while it is down to
  the first that does not; it goes down at the latest when the two leave the reach
  interval it came up in (solved exactly), and the next transmission that gets through
  after that cut brings it up again. So up times are send times, exact as the channel
  decided them, and a link between robots that never transmit is never seen.

Censoring follows :func:`netsim.links.lifetimes.link_lifetimes`: ``censored_start`` for a link up
at t = 0, ``censored_end`` for one still up at the end.
"""

from __future__ import annotations

from functools import partial

import numpy as np
import pandas as pd

from netsim.compiled import cores, side_by_side
from netsim.geometry import link_ranges_m
from netsim.links.lifetimes import COLUMNS, link_lifetimes
from netsim.links.wall_sweeps import Stretches, count_below, envelope_radii, map_radio
from netsim.progress import progress_bar
from netsim.trajectory import LegTable


def positions(L: LegTable, robots: np.ndarray, times: np.ndarray) -> np.ndarray:
    """Positions of ``robots[k]`` at ``times[k]`` (exact, from the legs), shape ``(k, 2)``."""
    times = np.asarray(times, float)
    leg = L.legs_at(robots, times)
    return L.at(leg, times)


def _frame(a, b, t_up, t_down, duration_s: float, open_end) -> pd.DataFrame:
    out = pd.DataFrame(
        {
            "a": np.asarray(a, np.int64),
            "b": np.asarray(b, np.int64),
            "t_up_s": np.asarray(t_up, float),
            "t_down_s": np.asarray(t_down, float),
        }
    )
    out["censored_start"] = out["t_up_s"].to_numpy() == 0.0
    out["censored_end"] = np.asarray(open_end, bool)
    out["censored"] = out["censored_start"] | out["censored_end"]
    return out[COLUMNS].sort_values(["t_up_s", "a", "b"], kind="stable").reset_index(drop=True)


def radio_link_lifetimes(
    reception, legs: pd.DataFrame, ranges_m, duration_s: float, side_m=None, torus=False, progress: bool = False
):
    """The links table (``links.parquet``) of a run whose channel decides receptions with
    ``reception`` (None: the unit disk of ``ranges_m``); whether or not link events were
    announced during the run, this is the table's one producer. ``progress``: a bar on a
    map's solve when it is long (:func:`walled_lifetimes`)."""
    n = len(ranges_m)
    if reception is not None and reception.recorder is not None:
        return recorded_lifetimes(reception.recorder, legs, n, reception.reach_m, duration_s, side_m, torus)
    if reception is None or reception.map is None:
        # The unit disk, or log-distance without shadowing or walls: the unit disk of the
        # implied range, exactly.
        return link_lifetimes(legs, ranges_m, duration_s, side_m, torus)
    return walled_lifetimes(reception, legs, ranges_m, duration_s, progress)


def recorded_lifetimes(recorder, legs, n: int, reach_m: float, duration_s: float, side_m=None, torus=False):
    """Decisions of the channel, cut where the pair leaves the reach.

    Each lifetime starts at a decision that brings the link up, or at a touch
    (:class:`~netsim.radio.reception.LinkRecorder`) on a link the reach has cut, and ends at the
    first decision that does not get through or where the pair leaves the reach interval
    (the envelope's) in which the lifetime began, whichever comes first. A start the
    envelope puts outside the reach (a decision at the range's edge, by rounding) is cut at
    once (``t_down_s = t_up_s``)."""
    rec = recorder.intervals(duration_s)
    if len(rec) == 0:
        return _frame([], [], [], [], duration_s, [])
    touches = recorder.touches()
    env = link_lifetimes(legs, np.full(n, reach_m), duration_s, side_m, torus)
    env = env.sort_values("t_up_s", kind="stable")
    # Candidate starts: each recorded interval's, then its touches (kept below when the
    # link was cut before them).
    raw = rec.set_index("id")
    ids = np.r_[rec["id"].to_numpy(np.int64), touches["id"].to_numpy(np.int64)]
    starts = pd.DataFrame(
        {
            "a": np.r_[rec["a"].to_numpy(np.int64), touches["a"].to_numpy(np.int64)],
            "b": np.r_[rec["b"].to_numpy(np.int64), touches["b"].to_numpy(np.int64)],
            "t_s": np.r_[rec["t_up_s"].to_numpy(float), touches["t_s"].to_numpy(float)],
            "first": np.r_[np.ones(len(rec), bool), np.zeros(len(touches), bool)],
            "id": ids,
            "end": raw.loc[ids, "t_down_s"].to_numpy(float),
            "open": raw.loc[ids, "open"].to_numpy(bool),
        }
    )
    starts = starts.sort_values("t_s", kind="stable")
    # The envelope interval in which each start falls.
    m = pd.merge_asof(
        starts,
        env[["a", "b", "t_up_s", "t_down_s", "censored_end"]].rename(
            columns={"t_up_s": "env_up", "t_down_s": "env_down", "censored_end": "env_open"}
        ),
        left_on="t_s",
        right_on="env_up",
        by=["a", "b"],
        direction="backward",
    )
    t_up = m["t_s"].to_numpy(float)
    env_down = m["env_down"].to_numpy(float)
    has_env = ~np.isnan(env_down)
    end = m["end"].to_numpy(float)
    # Outside the reach by the envelope's account (its last interval is over): cut at once.
    outside = has_env & (env_down < t_up)
    cut = has_env & ~outside & (env_down < end)
    t_down = np.where(outside, t_up, np.where(cut, env_down, end))
    open_end = np.where(outside, False, np.where(cut, m["env_open"].fillna(False).to_numpy(bool), m["open"]))
    open_end = open_end.astype(bool) & (t_down >= duration_s)
    # A touch opens a lifetime only once the reach has cut the previous one of its interval
    # (a lifetime the decisions end is over when its interval is).
    reach_end = np.where(outside, t_up, np.where(has_env & (env_down <= end), env_down, np.inf))
    order = np.lexsort((~m["first"].to_numpy(bool), t_up, m["id"].to_numpy(np.int64)))
    keep = np.zeros(len(m), bool)
    first = m["first"].to_numpy(bool)
    until = np.inf
    for k in order.tolist():
        if first[k] or t_up[k] >= until:
            keep[k] = True
            until = reach_end[k]
    return _frame(m["a"][keep], m["b"][keep], t_up[keep], t_down[keep], duration_s, open_end[keep])


# How much of a map's solve is held at once: a team large for its map has nearly every pair
# in range, and all their stretches (pairs times course changes) would not fit in memory. The
# blocks do not change the result: every stretch, and every chunk, is solved on its own.
BLOCK_STRETCHES = 200_000
BLOCK_CHUNKS = 500_000


def _blocks(sizes: np.ndarray, limit: int) -> list[tuple[int, int]]:
    """Consecutive ranges ``[lo, hi)`` of items whose ``sizes`` add up to at most ``limit``
    (an item larger than that alone)."""
    ends = np.cumsum(np.asarray(sizes, float))
    out, lo = [], 0
    while lo < len(ends):
        base = ends[lo - 1] if lo else 0.0
        hi = max(int(np.searchsorted(ends, base + limit, side="right")), lo + 1)
        out.append((lo, hi))
        lo = hi
    return out


def walled_lifetimes(
    reception, legs: pd.DataFrame, ranges_m, duration_s: float, progress: bool = False
) -> pd.DataFrame:
    """Links on a map without shadowing: solved along stretches within the exact envelope
    (:mod:`netsim.links.wall_sweeps`); the reference the runtime solver
    (:class:`netsim.links.walled_links.WalledLinks`) is tested against. ``progress``: a bar
    when the solve takes more than a block."""
    radii, _ = envelope_radii(reception, ranges_m)
    n = len(radii)
    env = link_lifetimes(legs, radii, duration_s)
    if len(env) == 0:
        return env
    L = LegTable(legs, n)
    a_env, b_env = env["a"].to_numpy(np.int64), env["b"].to_numpy(np.int64)
    t0, t1 = env["t_up_s"].to_numpy(float), env["t_down_s"].to_numpy(float)
    # Stretch starts: the envelope's start and every leg start of either robot before its end.
    before_end = np.nextafter(t1, -np.inf)
    first = [L.legs_at(robot, t0) for robot in (a_env, b_env)]
    count = [np.maximum(L.legs_at(robot, before_end) - f, 0) for robot, f in zip((a_env, b_env), first, strict=True)]
    blocks = _blocks(1 + count[0] + count[1], BLOCK_STRETCHES)
    radio = map_radio(reception)

    def solve(block: tuple[int, int]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        lo, hi = block
        part = slice(lo, hi)
        i, t_up, t_down = _solve_envelope(
            radio,
            L,
            n,
            radii,
            (a_env[part], b_env[part]),
            (t0[part], t1[part]),
            [f[part] for f in first],
            [c[part] for c in count],
        )
        return i + lo, t_up, t_down

    found: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
    # Two blocks at a time where there are two cores: their loops release the GIL.
    step = 2 if cores() >= 2 else 1
    with progress_bar(len(env), "links on the map", "pairs in range", enabled=progress and len(blocks) > 1) as bar:
        for k in range(0, len(blocks), step):
            now = blocks[k : k + step]
            found.extend(side_by_side(*(partial(solve, block) for block in now)) if len(now) == 2 else [solve(now[0])])
            bar.update(now[-1][1] - now[0][0])
    i, t_up, t_down = (np.concatenate(column) for column in zip(*found, strict=True))
    open_end = env["censored_end"].to_numpy(bool)[i] & (t_down >= t1[i])
    return _frame(a_env[i], b_env[i], t_up, t_down, duration_s, open_end)


def _solve_envelope(radio, L: LegTable, n: int, radii, pairs, span, first, count):
    """The lifetimes within envelope intervals ``pairs`` (``a, b``) over ``span`` (``t0,
    t1``), whose robots' legs at ``t0`` are ``first`` and which start ``count`` more legs
    before ``t1``: each lifetime's interval (an index into them), up and down."""
    a_env, b_env = pairs
    t0, t1 = span
    m = len(t0)
    starts_t, starts_iv = [t0], [np.arange(m)]
    for f, c in zip(first, count, strict=True):
        iv = np.repeat(np.arange(m), c)
        offset = np.arange(int(c.sum())) - np.repeat(np.cumsum(c) - c, c)
        starts_t.append(L.t[f[iv] + 1 + offset])
        starts_iv.append(iv)
    u, iv = np.concatenate(starts_t), np.concatenate(starts_iv)
    order = np.lexsort((u, iv))
    u, iv = u[order], iv[order]
    keep = np.r_[True, (iv[1:] != iv[:-1]) | (u[1:] != u[:-1])]
    u, iv = u[keep], iv[keep]
    e = np.where(np.r_[iv[1:] == iv[:-1], False], np.r_[u[1:], 0.0], t1[iv])
    a, b = a_env[iv], b_env[iv]
    la, lb = L.legs_at(a, u), L.legs_at(b, u)
    s = Stretches(a, b, u, L.p[la], L.v[la], L.t[la], L.p[lb], L.v[lb], L.t[lb], link_ranges_m(radii, a, b), n)
    k1 = np.minimum(np.maximum(count_below(u, s.h, e), 1.0), s.nc)
    solved = []
    for lo, hi in _blocks(k1, BLOCK_CHUNKS):
        rows = np.arange(lo, hi)
        solved.append(s.take(radio, rows, np.zeros(hi - lo), k1[lo:hi], None)[:4])
    row, t_chg, up_chg, s0 = (np.concatenate(column) for column in zip(*solved, strict=True))
    kept = t_chg <= e[row]
    row, t_chg, up_chg = row[kept], t_chg[kept], up_chg[kept]
    # Events in their order: by interval, stretch (rows are in time order), then the
    # stretch's start, its changes in order, and the envelope's end last.
    rows = np.arange(len(s))
    ev_iv = np.r_[iv, iv[row], np.arange(m)]
    ev_row = np.r_[rows, row, np.full(m, len(s))]
    ev_phase = np.r_[np.zeros(len(s)), np.ones(len(row)), np.full(m, 2)]
    ev_t = np.r_[u, t_chg, t1]
    ev_up = np.r_[s0, up_chg, np.zeros(m, bool)]
    order = np.lexsort((ev_t, ev_phase, ev_row, ev_iv))
    ev_t, ev_iv, ev_up = ev_t[order], ev_iv[order], ev_up[order]
    # Keep the events that change the state (each interval starts down).
    prev = np.r_[False, np.where(ev_iv[1:] == ev_iv[:-1], ev_up[:-1], False)]
    keep = ev_up != prev
    ev_t, ev_iv, ev_up = ev_t[keep], ev_iv[keep], ev_up[keep]
    ups = np.flatnonzero(ev_up)
    # After filtering, each up is followed by its down in the same interval.
    return ev_iv[ups], ev_t[ups], ev_t[ups + 1]
