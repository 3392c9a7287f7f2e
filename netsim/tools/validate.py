"""``netsim validate``: the closed-form results of docs/validation.md, checked on real runs.

Each check builds runs from configurations (models by name, as ``netsim run`` does),
measures from their outputs, and compares with theory within a stated tolerance: four
standard errors for statistical checks unless said otherwise, counted over the outcomes
that are independent (frames, rounds or robots where receptions or legs go together). The
same results are tested, at other sizes and seeds, by the test suite.

The checks are listed in :data:`CHECKS`, one :class:`Item` each: the items of
docs/validation.md it covers, the check (a function of a seed: None for the seeds fixed
here, so that the default output does not change; ``netsim validate --seed N`` passes N,
and each check turns it into the seeds of its runs with :func:`derive`), and whether it is
statistical (it may then fail, rarely, on a correct model; a slow test runs each over 20
seeds). A new check is a function ``check_x(seed=None) -> list[Check]`` and a line in
:data:`CHECKS`.
"""

from __future__ import annotations

import math
import tempfile
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from netsim.config import from_dict
from netsim.errors import NetsimInputError
from netsim.geometry import speeds_mps
from netsim.groups import in_a_group, leads_itself
from netsim.links.lifetimes import link_lifetimes
from netsim.metrics import MEAN_LEG_UNIT_SQUARE, mean_distance_rectangle
from netsim.run import build, collect
from netsim.tools import analysis
from netsim.tools.check import Check
from netsim.topology import geometric_pairs


@dataclass(frozen=True)
class Item:
    """An entry of :data:`CHECKS`: ``check(seed)`` returns the rows of the items
    ``numbers`` of docs/validation.md; ``statistical``: its rows have a tolerance of
    standard errors (a correct model fails one rarely), not an exact one."""

    numbers: tuple[str, ...]
    check: Callable[..., list[Check]]
    statistical: bool
    # Units of the progress bar it takes: more than 1 for a check of several long runs,
    # which then takes ``tick``, called as each run ends, so that the bar moves meanwhile.
    parts: int = 1


def derive(seed: int | None, default: int) -> int:
    """The seed of a check's run (or generator) whose fixed seed is ``default``: ``default``
    itself without ``--seed``, else a seed drawn from ``(seed, default)``."""
    if seed is None:
        return default
    return int(np.random.SeedSequence([seed, default]).generate_state(1)[0])


def cluster_se(values: np.ndarray, groups: np.ndarray) -> float:
    """Standard error of ``values.mean()`` when values of one group (a robot's legs) may be
    correlated and groups are independent: the ratio estimator's, ``sum_g (S_g - m N_g)^2``
    over ``(sum N_g)^2``, times ``G / (G - 1)``."""
    _, inverse = np.unique(groups, return_inverse=True)
    sums = np.bincount(inverse, weights=values)
    counts = np.bincount(inverse)
    g = len(counts)
    m = sums.sum() / counts.sum()
    return float(math.sqrt(((sums - m * counts) ** 2).sum() * g / (g - 1)) / counts.sum())


def _config(**tree):
    tree.setdefault("output", {"position_interval_s": 0.0})
    tree.setdefault("protocol", {"model": "none"})
    return from_dict(tree)


def rwp_density(x: float, y: float, width: float = 1.0, height: float = 1.0) -> float:
    """Exact stationary density of random waypoint on the ``width x height`` rectangle
    ``[0, width] x [0, height]`` (Hyytiä et al. 2006): ``f = int_0^pi a b (a + b) dphi /
    (A^2 E[L])``, ``a`` and ``b`` the distances to the border both ways along ``phi``."""
    from scipy import integrate

    def border(phi):
        c, s = math.cos(phi), math.sin(phi)
        ts = [
            t
            for t in (
                (width - x) / c if c > 0 else None,
                -x / c if c < 0 else None,
                (height - y) / s if s > 0 else None,
                -y / s if s < 0 else None,
            )
            if t is not None
        ]
        return min(ts)

    corners = sorted(math.atan2(cy - y, cx - x) % math.pi for cx in (0, width) for cy in (0, height))
    value = integrate.quad(
        lambda p: (lambda a, b: a * b * (a + b))(border(p), border(p + math.pi)), 0, math.pi, points=corners, limit=200
    )[0]
    if width == height == 1.0:
        return value / MEAN_LEG_UNIT_SQUARE
    return value / ((width * height) ** 2 * mean_distance_rectangle(width, height))


def completed_leg_lengths(legs: pd.DataFrame) -> np.ndarray:
    """Lengths of the moving legs that ended within the run, each robot's first leg (length-biased
    by the stationary start) left out."""
    t, r = legs["t_s"].to_numpy(), legs["robot"].to_numpy()
    same = r[1:] == r[:-1]
    speed = speeds_mps(legs[["vx_mps", "vy_mps"]].to_numpy(float))[:-1]
    first = np.r_[True, r[1:-1] != r[:-2]]
    lengths = (speed * np.diff(t))[same & ~first & (speed > 0)]
    return lengths


def leg_lengths_from_third(legs: pd.DataFrame, before_s: float) -> tuple[np.ndarray, np.ndarray]:
    """``(lengths, robots)`` of the moving legs that start before ``before_s``, each robot's
    first two legs left out: its first is the stationary start's (length-biased); its second
    starts at the first's end, which is not uniform. Every later leg joins two uniform
    waypoints. ``before_s`` must leave time for any leg to end within the run (side times
    sqrt 2 over the lowest speed before its end): then which legs count does not depend on
    how long they are, as it would if legs were kept for having ended."""
    t, r = legs["t_s"].to_numpy(), legs["robot"].to_numpy()
    speed = speeds_mps(legs[["vx_mps", "vy_mps"]].to_numpy(float))
    same = np.r_[r[1:] == r[:-1], False]
    moving = same & (speed > 0)
    rank = pd.Series(moving.astype(int)).groupby(r).cumsum().to_numpy()
    keep = moving & (rank >= 3) & (t < before_s)
    lengths = (speed[:-1] * np.diff(t))[keep[:-1]]
    return lengths, r[:-1][keep[:-1]]


def check_rwp_speed(seed: int | None = None) -> list[Check]:
    side, vmin, vmax, n, T = 200.0, 1.0, 4.0, 400, 600.0
    out = []
    for pause in (0.0, 20.0):
        sim = build(
            _config(
                seed=derive(seed, 5),
                duration_s=T,
                world={"n_robots": n, "side_m": side},
                mobility={"speed_min_mps": vmin, "speed_max_mps": vmax, "pause_s": pause},
            )
        )
        sim.run()
        per_robot = sim.state.travelled_m(T, slice(None)) / T
        EL, EinvV = MEAN_LEG_UNIT_SQUARE * side, math.log(vmax / vmin) / (vmax - vmin)
        out.append(
            Check(
                "1",
                f"RWP time-average speed, pause {pause:g} s",
                EL / (EL * EinvV + pause),
                per_robot.mean(),
                4 * per_robot.std() / math.sqrt(n),
                "m/s",
            )
        )
    return out


def check_rwp_leg_length(seed: int | None = None) -> list[Check]:
    side, vmin, duration = 100.0, 2.0, 2000.0
    sim = build(
        _config(
            seed=derive(seed, 6),
            duration_s=duration,
            world={"n_robots": 300, "side_m": side},
            mobility={"speed_min_mps": vmin, "speed_max_mps": 5.0, "pause_s": 0.0},
        )
    )
    sim.run()
    # Two legs of a robot share a waypoint: the standard error is over robots.
    lengths, robots = leg_lengths_from_third(sim.state.legs(), duration - side * math.sqrt(2) / vmin)
    return [
        Check(
            "2",
            "RWP mean leg length",
            MEAN_LEG_UNIT_SQUARE * side,
            lengths.mean(),
            4 * cluster_se(lengths, robots),
            "m",
        )
    ]


def _box_check(p: np.ndarray, centre, h: float, density, label: str) -> Check:
    """Robots of ``p`` in the ``h``-square box at ``centre`` against ``density`` integrated
    over it (a 10 x 10 midpoint rule)."""
    n = len(p)
    offsets = (np.arange(10) + 0.5) / 10 * h - h / 2
    mass = np.mean([density(centre[0] + dx, centre[1] + dy) for dx in offsets for dy in offsets]) * h * h
    count = int(((np.abs(p[:, 0] - centre[0]) < h / 2) & (np.abs(p[:, 1] - centre[1]) < h / 2)).sum())
    return Check(
        "3, 4", label, mass / h**2, count / (n * h * h), 4 * math.sqrt(n * mass) / (n * h * h), "per unit area"
    )


# Boxes this large see the start's length bias (docs/validation.md, item 4), which boxes a
# quarter as wide let through.
DENSITY_BOX = 0.2


def check_stationary_start(seed: int | None = None) -> list[Check]:
    n, h = 100_000, DENSITY_BOX
    vmin, vmax = 0.01, 0.05
    sim = build(
        _config(
            seed=derive(seed, 3),
            duration_s=1.0,
            world={"n_robots": n, "side_m": 1.0},
            mobility={"speed_min_mps": vmin, "speed_max_mps": vmax, "pause_s": 0.0},
        )
    )
    sim.env.run(until=1e-9)  # the robots' processes set their first legs at t = 0
    p = sim.state.positions_at(0.0)
    out = [
        _box_check(p, pt, h, rwp_density, f"RWP stationary density at t = 0 in the box of side {h:g} at {pt}")
        for pt in ((0.5, 0.5), (0.1, 0.1))
    ]
    speeds = sim.state.speed_mps
    out.append(
        Check(
            "1, 4",
            "stationary start mean speed [0.01, 0.05]",
            (vmax - vmin) / math.log(vmax / vmin),
            speeds.mean(),
            4 * speeds.std() / math.sqrt(n),
            "m/s",
        )
    )
    # A rectangle across the origin (world.bounds_m = [-1, 0, 1, 1]): the same law, shifted and stretched.
    sim = build(
        _config(
            seed=derive(seed, 4),
            duration_s=1.0,
            world={"n_robots": n, "side_m": 1.0, "bounds_m": [-1.0, 0.0, 1.0, 1.0]},
            mobility={"speed_min_mps": vmin, "speed_max_mps": vmax, "pause_s": 0.0},
        )
    )
    sim.env.run(until=1e-9)
    p = sim.state.positions_at(0.0)
    for pt in ((0.0, 0.5), (-0.9, 0.1)):
        label = f"RWP stationary density at t = 0 in the box of side {h:g} at {pt}, area [-1, 0, 1, 1]"
        out.append(_box_check(p, pt, h, lambda x, y: rwp_density(x + 1, y, 2.0, 1.0), label))
    return out + _paused_start(seed, n, vmin, vmax)


def _paused_start(seed: int | None, n: int, vmin: float, vmax: float) -> list[Check]:
    """With a pause, a robot starts paused with the share of time robots spend paused, for
    a residual pause uniform on [0, pause], and the density mixes uniform (paused) and
    moving robots' (item 4)."""
    leg_s = MEAN_LEG_UNIT_SQUARE * math.log(vmax / vmin) / (vmax - vmin)
    pause = 20.0
    share = pause / (pause + leg_s)
    sim = build(
        _config(
            seed=derive(seed, 7),
            duration_s=pause + 1.0,
            world={"n_robots": n, "side_m": 1.0},
            mobility={"speed_min_mps": vmin, "speed_max_mps": vmax, "pause_s": pause},
        )
    )
    sim.env.run(until=1e-9)
    p = sim.state.positions_at(0.0)
    paused = sim.state.speed_mps == 0.0
    sim.env.run(until=pause + 1.0)
    legs = sim.state.legs()
    ends = legs[legs["cause"] == "pause_end"].groupby("robot")["t_s"].min()
    residual = ends.reindex(np.flatnonzero(paused)).to_numpy()
    mixed = lambda x, y: share + (1 - share) * rwp_density(x, y)  # noqa: E731
    return [
        Check(
            "1, 4",
            f"stationary start paused, pause {pause:g} s (share)",
            share,
            paused.mean(),
            4 * math.sqrt(share * (1 - share) / n),
        ),
        Check(
            "4",
            f"stationary start residual pause, pause {pause:g} s (mean)",
            pause / 2,
            float(np.mean(residual)) if len(residual) else math.nan,
            4 * pause / math.sqrt(12 * max(len(residual), 1)),
            "s",
        ),
        _box_check(
            p,
            (0.5, 0.5),
            DENSITY_BOX,
            mixed,
            f"RWP stationary density at t = 0, pause {pause:g} s, in the box of side {DENSITY_BOX:g} at (0.5, 0.5)",
        ),
    ]


def check_unit_disk(seed: int | None = None) -> list[Check]:
    rng = np.random.default_rng(derive(seed, 1))
    pos = rng.uniform(0, 100, (400, 2))
    i, j, _ = geometric_pairs(pos, 12.0)
    d = np.hypot(*(pos[:, None, :] - pos[None, :, :]).transpose(2, 0, 1))
    truth = {(a, b) for a, b in zip(*np.nonzero(np.triu(d <= 12.0, 1)))}
    wrong = len(truth ^ set(zip(i.tolist(), j.tolist())))
    return [Check("5", "unit disk: linked iff distance <= R (pairs wrong)", 0.0, float(wrong), 0.0)]


def capped_link_duration_s(range_m: float, speed_mps: float, cap_s: float) -> float:
    """Mean of ``min(T, cap_s)`` over links born in steady state between robots of equal
    speed ``v`` and uniform headings, ``T = 2 sqrt(R^2 - b^2) / v_r`` (docs/validation.md
    item 6): links are born at a rate proportional to ``v_r = 2 v sin(theta / 2)``,
    ``theta`` uniform on ``(0, pi)``, with ``b`` uniform on ``(-R, R)``. Without a cap it is
    ``pi^2 R / (8 v)``."""
    from scipy import integrate

    def weighted(theta: float) -> float:
        vr = 2.0 * speed_mps * math.sin(theta / 2.0)
        if vr == 0.0:
            return 0.0
        capped = integrate.quad(
            lambda b: min(2.0 * math.sqrt(max(range_m**2 - b * b, 0.0)) / vr, cap_s), -range_m, range_m, limit=200
        )[0]
        return vr * capped / (2.0 * range_m)

    near_zero = [1e-4, 1e-3, 1e-2, 0.05, 0.2]
    mean_vr = 4.0 * speed_mps / math.pi
    return integrate.quad(weighted, 0.0, math.pi, points=near_zero, limit=400)[0] / math.pi / mean_vr


def check_torus_links(seed: int | None = None) -> list[Check]:
    R, v, T = 10.0, 1.0, 1000.0
    sim = build(
        _config(
            seed=derive(seed, 11),
            duration_s=T,
            world={"n_robots": 200, "side_m": 200.0, "torus": True},
            channel={"range_m": R},
            mobility={"model": "random_direction", "speed_min_mps": v, "speed_max_mps": v},
        )
    )
    sim.run()
    links = collect(sim)["links"]
    # Links born in the first half, each seen for at least T/2: min(duration, T/2) is known
    # for every one of them, whereas their durations themselves would be cut at the run's end.
    born = links[(links.t_up_s > 0) & (links.t_up_s < T / 2)]
    capped = np.minimum((born.t_down_s - born.t_up_s).to_numpy(), T / 2)
    # A pair meets again on the torus at the same relative speed: its links' durations go
    # together, hence the standard error over pairs.
    pairs = (born.a * sim.state.n + born.b).to_numpy()
    return [
        Check(
            "6",
            f"link duration, torus, equal speeds, capped at {T / 2:g} s "
            f"(pi^2 R / (8 v) = {math.pi**2 * R / (8 * v):.4g} uncapped)",
            capped_link_duration_s(R, v, T / 2),
            float(capped.mean()),
            4 * cluster_se(capped, pairs),
            "s",
        )
    ]


def random_legs(rng: np.random.Generator, n: int, duration_s: float, side_m: float, speed_mps: float, jump_rate=0.0):
    """Random piecewise-linear trajectories as a leg log: course changes at exponential
    intervals (mean ``duration_s / 6``), Gaussian velocities; with ``jump_rate``, that
    fraction of the changes are jumps to a uniform position."""
    rows = []
    for r in range(n):
        t, p = 0.0, rng.uniform(0, side_m, 2)
        while t < duration_s:
            v = rng.normal(0, speed_mps, 2)
            rows.append((t, r, p[0], p[1], v[0], v[1]))
            dt = rng.exponential(duration_s / 6)
            t += dt
            p = rng.uniform(0, side_m, 2) if rng.random() < jump_rate else p + v * dt
    return pd.DataFrame(rows, columns=["t_s", "robot", "x_m", "y_m", "vx_mps", "vy_mps"])


def brute_force_mismatches(legs: pd.DataFrame, links: pd.DataFrame, ranges, times, side_m=None) -> int:
    """Pairs on which ``links`` and the distances sampled at ``times`` disagree (linked iff
    ``d <= min(r_a, r_b)``, on a torus by the nearest image), summed over the instants."""
    from netsim.trajectory import sample_positions

    ranges = np.asarray(ranges, float)
    n = len(ranges)
    times = np.sort(np.asarray(times, float))
    pos = sample_positions(legs, n, times)[["x_m", "y_m"]].to_numpy().reshape(len(times), n, 2)
    radius = np.minimum(ranges[:, None], ranges[None, :])
    a, b, up, down = (links[c].to_numpy() for c in ("a", "b", "t_up_s", "t_down_s"))
    wrong = 0
    for k, t in enumerate(times.tolist()):
        d = pos[k][:, None, :] - pos[k][None, :, :]
        if side_m is not None:
            d -= side_m * np.round(d / side_m)
        truth = np.triu(np.hypot(d[..., 0], d[..., 1]) <= radius, 1)
        claimed = np.zeros((n, n), bool)
        live = (up <= t) & (down > t)
        claimed[a[live], b[live]] = True
        wrong += int((truth ^ claimed).sum())
    return wrong


def check_exact_links(seed: int | None = None) -> list[Check]:
    """Item 7 on random trajectories, against brute force: plain, with jumps (sampled also
    just before and after every jump), and on the smallest torus allowed (side just above
    twice the range, where other images come into range within a piece)."""
    from netsim.links.lifetimes import jump_times
    from netsim.trajectory import LegTable

    out = []
    sim = build(
        _config(
            seed=derive(seed, 4),
            duration_s=120.0,
            world={"n_robots": 30, "side_m": 200.0},
            channel={"range_m": 40.0},
            mobility={"speed_min_mps": 1.0, "speed_max_mps": 8.0, "pause_s": 1.0},
        )
    )
    sim.run()
    legs = sim.state.legs()
    links = link_lifetimes(legs, 40.0, 120.0)
    # Time error of every up/down time: its distance error over the pair's radial speed.
    errors = []
    table = LegTable(legs, 30)
    for col, flag in (("t_up_s", "censored_start"), ("t_down_s", "censored_end")):
        done = links[~links[flag]]
        for t, a, b in zip(done[col].tolist(), done["a"].tolist(), done["b"].tolist()):
            la, lb = table.legs_at(np.array([a, b]), np.array([t, t]))
            pa, pb = table.at(np.array([la, lb]), t)
            d = pa - pb
            dist = math.hypot(*d)
            radial = abs(float(np.dot(d, table.v[la] - table.v[lb]))) / dist
            if radial > 0.01:  # a grazing pass has no well-defined time error
                errors.append(abs(dist - 40.0) / radial)
    out.append(
        Check(
            "7",
            f"link times solve |dp + dv t| = R, {len(errors)} random events (max error)",
            0.0,
            max(errors),
            1e-9,
            "s",
        )
    )
    times = np.sort(np.random.default_rng(derive(seed, 4)).uniform(0, 120.0, 2000))
    out.append(
        Check(
            "7",
            "link events vs brute force, 30 robots (pairs wrong at 2,000 instants)",
            0.0,
            float(brute_force_mismatches(legs, links, np.full(30, 40.0), times)),
            0.0,
        )
    )
    rng = np.random.default_rng(derive(seed, 7))
    n, duration, side = 20, 60.0, 80.0
    ranges = rng.uniform(10.0, 20.0, n)
    legs = random_legs(rng, n, duration, side, 3.0, jump_rate=0.4)
    links = link_lifetimes(legs, ranges, duration)
    jt, _ = jump_times(LegTable(legs, n))
    jt = jt[(jt > 0) & (jt < duration)]
    times = np.sort(np.r_[rng.uniform(0, duration, 2000), jt - 1e-7, jt + 1e-7])
    out.append(
        Check(
            "7",
            f"link events under {len(jt)} jumps vs brute force, also 1e-7 s around each (pairs wrong)",
            0.0,
            float(brute_force_mismatches(legs, links, ranges, times)),
            0.0,
        )
    )
    r, side = 10.0, 20.0 * (1 + 1e-6)
    legs = random_legs(rng, n, duration, side, 3.0)
    links = link_lifetimes(legs, r, duration, side_m=side, torus=True)
    times = np.sort(rng.uniform(0, duration, 2000))
    wrong = brute_force_mismatches(legs, links, np.full(n, r), times, side_m=side)
    out.append(
        Check(
            "7",
            f"link events on the smallest torus (side 2 r + {side - 2 * r:.0e} m) vs brute force (pairs wrong)",
            0.0,
            float(wrong),
            0.0,
        )
    )
    return out


def check_discovery_delay(seed: int | None = None) -> list[Check]:
    pairs, p = 1000, 0.3
    n = 2 * pairs
    sim = build(
        _config(
            seed=derive(seed, 8),
            duration_s=40.0,
            world={"n_robots": n, "side_m": 200_000.0},
            mobility={"model": "static"},
            channel={"range_m": 10.0, "loss_probability": p, "latency_s": 0.0},
            protocol={"model": "ack", "ack_jitter_s": 0.0},
        )
    )
    pos = np.zeros((n, 2))
    pos[:, 0] = np.tile(np.arange(pairs) * 100.0, 2)
    pos[pairs:, 1] = 5000.0
    sim.state.place(pos)
    first = np.full(n, np.nan)

    def listen(now, ack, receivers, hears_me):
        if ack.sender < pairs:
            r = receivers[receivers == ack.sender + pairs]
            first[r[np.isnan(first[r])]] = now

    def arrive():
        yield sim.env.timeout(10.0)
        for k in range(pairs):
            sim.state.set_leg(pairs + k, 10.0, (0.0, 0.0), start_m=(k * 100.0, 5.0))

    sim.models["protocol"].listeners.append(listen)  # the Ack beacon, built from protocol.model = "ack"
    sim.env.process(arrive())
    sim.run()
    delay = first[pairs:] - 10.0
    return [
        Check(
            "8",
            f"discovery delay T/2 + T p / (1 - p), p = {p}",
            0.5 + p / (1 - p),
            float(np.nanmean(delay)),
            4 * float(np.nanstd(delay)) / math.sqrt(int(np.isfinite(delay).sum())),
            "s",
        )
    ]


def check_spurious_timeouts(seed: int | None = None) -> list[Check]:
    # tau a whole number of periods: the Ack due exactly tau after the last one counts.
    return [_spurious_timeouts(seed, p, tau) for p, tau in ((0.3, 2.5), (0.5, 3.0))]


def _spurious_timeouts(seed: int | None, p: float, tau: float) -> Check:
    pairs, k = 400, analysis.spurious_timeout_window(tau, 1.0)
    pos = np.zeros((2 * pairs, 2))
    pos[0::2, 0] = pos[1::2, 0] = np.arange(pairs) * 100.0
    pos[1::2, 1] = 5.0
    with tempfile.TemporaryDirectory() as tmp:
        csv = Path(tmp) / "pairs.csv"
        pd.DataFrame(pos, columns=["x_m", "y_m"]).to_csv(csv, index=False)
        sim = build(
            _config(
                seed=derive(seed, 9),
                duration_s=200.0,
                world={"n_robots": 2 * pairs, "side_m": 1e5, "placement": str(csv)},
                mobility={"model": "static"},
                channel={"range_m": 10.0, "loss_probability": p},
                protocol={
                    "model": "clustering",
                    "ack_jitter_s": 0.0,
                    "tau_s": tau,
                    "election_policy": "none",
                    "message_rate_hz": 0.0,
                },
            )
        )
        sim.run()
    labels = sim.config.protocol.plugin.role_labels
    counts = analysis.acks_until_leader_loss(sim.trace.frame("roles"), tau, 1.0, labels)
    theory = analysis.expected_acks_until_spurious_timeout(p, k)
    return Check(
        "9",
        f"Acks until a spurious timeout, p = {p}, tau = {tau:g} periods, k = {k}",
        theory,
        counts.mean(),
        4 * counts.std() / math.sqrt(len(counts)),
        "Acks",
    )


def check_delivery_ratio(seed: int | None = None) -> list[Check]:
    p = 0.25
    sim = build(
        _config(
            seed=derive(seed, 3),
            duration_s=60.0,
            world={"n_robots": 60, "side_m": 400.0},
            channel={"loss_probability": p, "range_m": 100.0},
            protocol={"model": "ack"},
            output={"receptions": True},
        )
    )
    sim.run()
    frames = collect(sim)
    acks = frames["acks"]
    received, lost = acks.received.sum(), acks.dropped_loss.sum()
    n = received + lost
    # Each robot in range loses an Ack on its own: an Ack's receptions are binomial, their
    # variance m p (1 - p). One draw for all of an Ack's robots would give m times that.
    per_ack = frames["receptions"].groupby(["src", "t_s"])["received"].agg(["sum", "size"])
    m, got = per_ack["size"].to_numpy(float), per_ack["sum"].to_numpy(float)
    z2 = (got - m * (1 - p)) ** 2 / (m * p * (1 - p))
    return [
        Check("10", f"delivered fraction of Acks, loss {p}", 1 - p, received / n, 4 * math.sqrt(p * (1 - p) / n)),
        Check(
            "10",
            "an Ack's receptions: variance over the binomial's (independent losses)",
            1.0,
            float(z2.mean()),
            4 * float(z2.std()) / math.sqrt(len(z2)),
        ),
    ]


def check_mean_degree(seed: int | None = None) -> list[Check]:
    n, r, reps = 100, 0.1, 300
    degrees = []
    for rep in range(reps):
        sim = build(
            _config(
                seed=derive(seed, 1),
                world={"n_robots": n, "side_m": 1.0},
                mobility={"model": "static"},
                channel={"range_m": r},
            ),
            run=rep,
        )
        degrees.append(2 * len(geometric_pairs(sim.state.positions_at(0.0), r)[0]) / n)
    theory = (n - 1) * (math.pi * r**2 - 8 * r**3 / 3 + r**4 / 2)
    return [
        Check(
            "11",
            "mean degree, unit square with border",
            theory,
            float(np.mean(degrees)),
            4 * float(np.std(degrees)) / math.sqrt(reps),
        )
    ]


def check_no_isolated(seed: int | None = None) -> list[Check]:
    n, r, reps = 50, 0.16, 600
    ok = 0
    for rep in range(reps):
        sim = build(
            _config(
                seed=derive(seed, 2),
                world={"n_robots": n, "side_m": 1.0, "torus": True},
                mobility={"model": "static"},
                channel={"range_m": r},
            ),
            run=rep,
        )
        i, j, _ = geometric_pairs(sim.state.positions_at(0.0), r, side_m=1.0)
        ok += bool(np.bincount(np.r_[i, j], minlength=n).min() >= 1)
    theory = (1 - (1 - math.pi * r**2) ** (n - 1)) ** n
    return [Check("12", "P(no isolated robot), torus", theory, ok / reps, 4 * math.sqrt(theory * (1 - theory) / reps))]


def check_clustering_invariants(seed: int | None = None) -> list[Check]:
    bad = 0
    for fixed in (1, 2, 3):
        n = 150
        side = 10.0 * math.sqrt(n * math.pi / 6)
        sim = build(
            _config(
                seed=derive(seed, fixed),
                duration_s=40.0,
                world={"n_robots": n, "side_m": side},
                mobility={"model": "static"},
                channel={"range_m": 10.0},
                protocol={"model": "clustering", "message_rate_hz": 0.0},
            )
        )
        sim.run()
        i, j, _ = geometric_pairs(sim.state.positions_at(sim.now), 10.0)
        linked = set(zip(i.tolist(), j.tolist())) | set(zip(j.tolist(), i.tolist()))
        leader = sim.groups.leader  # each robot's leader: its own id for a leader, -1 for none
        is_leader = leads_itself(leader)
        bad += int((is_leader[i] & is_leader[j]).sum()) + int((leader < 0).sum())
        bad += sum((m, int(leader[m])) not in linked for m in np.flatnonzero(in_a_group(leader)).tolist())
    return [Check("13", "leaders independent and dominating, none undecided (violations)", 0.0, float(bad), 0.0)]


# -- the radio (channel.propagation, shadowing, walls) --------------------------------------
def _radio_run(**tree):
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = build(_config(**tree))
    sim.run()
    return sim, collect(sim)


def check_radio_unit_disk(seed: int | None = None) -> list[Check]:
    """17: log-distance without shadowing links exactly as a unit disk of the implied range:
    the same links table and the same Ack receptions, on the same moving team."""
    base = {
        "seed": derive(seed, 17),
        "duration_s": 120.0,
        "world": {"n_robots": 100, "side_m": 800.0},
        "protocol": {"model": "ack"},
    }
    radio, radio_frames = _radio_run(**base, channel={"propagation": "log_distance"})
    r = float(radio.state.range_m[0])
    disk, disk_frames = _radio_run(**base, channel={"range_m": r})
    a, b = radio_frames["links"], disk_frames["links"]
    rows = lambda f: set(map(tuple, f[["a", "b", "t_up_s", "t_down_s"]].to_numpy().tolist()))  # noqa: E731
    wrong = len(rows(a) ^ rows(b))
    heard = abs(
        int(radio.channel.counters_for("ack").received.sum()) - int(disk.channel.counters_for("ack").received.sum())
    )
    return [
        Check("17", f"log-distance, no shadowing = unit disk of {r:g} m: link lifetimes that differ", 0.0, wrong, 0.0),
        Check("17", "log-distance, no shadowing = unit disk: Ack receptions that differ", 0.0, float(heard), 0.0),
    ]


def check_radio_link_probability(seed: int | None = None) -> list[Check]:
    """18: shadowing sigma on a static uniform deployment: the fraction of pairs the channel
    links at distance d is Phi((P_t - PL(d) - sensitivity) / sigma), in every distance bin."""
    from scipy.spatial import cKDTree

    from netsim.radio.propagation import LogDistanceParams, reach_m
    from netsim.tools.radio_checks import Z, link_probability

    sigma, n, side = 4.0, 1000, 1000.0
    params = LogDistanceParams(shadowing_sigma_db=sigma)
    sim, frames = _radio_run(
        seed=derive(seed, 18),
        duration_s=1.2,
        world={"n_robots": n, "side_m": side},
        mobility={"model": "static"},
        channel={"propagation": "log_distance", "shadowing_sigma_db": sigma},
        protocol={"model": "ack"},
    )
    pos = sim.state.positions_at(0.0)
    reach = reach_m(params)
    pairs = cKDTree(pos).query_pairs(reach, output_type="ndarray")
    i, j = pairs.min(axis=1), pairs.max(axis=1)
    links = frames["links"]
    linked_keys = set((links.a * n + links.b).tolist())
    linked = np.isin(i * n + j, np.fromiter(linked_keys, np.int64, len(linked_keys)))
    d = np.hypot(*(pos[i] - pos[j]).T)  # measured apart from the engine's kernel: a reference
    p = link_probability(d, params)
    edges = np.linspace(0.0, reach, 11)
    which = np.clip(np.digitize(d, edges) - 1, 0, 9)
    out = []
    for k in range(10):
        sel = which == k
        m = int(sel.sum())
        theory = float(p[sel].mean())
        se = math.sqrt(float((p[sel] * (1 - p[sel])).sum())) / m
        out.append(
            Check(
                "18",
                f"shadowing {sigma:g} dB: linked fraction, d in [{edges[k]:.0f}, {edges[k + 1]:.0f}) m ({m} pairs)",
                theory,
                float(linked[sel].mean()),
                Z * se,
            )
        )
    return out


def check_radio_correlation(seed: int | None = None) -> list[Check]:
    """19: a moving pair's shadowing has correlation exp(-delta / d_corr) at travel separation
    delta, whatever the instants it was looked at in between (the channel's PairShadowing)."""
    from netsim.tools.radio_checks import check_shadowing_correlation

    rows = check_shadowing_correlation(seed=derive(seed, 1))
    return [Check("19", c.result, c.theory, c.measured, c.tolerance, c.unit) for c in rows]


def check_radio_pair_travel(seed: int | None = None) -> list[Check]:
    """27: the channel's shadowing of a pair whose robots both move decorrelates with the sum
    of their path lengths (side by side at 1 m/s: 2 m of pair travel per second)."""
    from netsim.tools.radio_checks import pair_travel_correlation

    table = pair_travel_correlation(seed=derive(seed, 27))
    return [
        Check(
            "27",
            f"shadowing of pairs moving side by side: correlation at {row.delta_m:g} m of the two robots' travel",
            row.theory,
            row.correlation,
            max(row.hi - row.theory, row.theory - row.lo),
        )
        for row in table.itertuples()
    ]


def check_radio_walls(seed: int | None = None) -> list[Check]:
    """20: across a wall two robots do not link under the unit disk, through a doorway they
    do; under log-distance each wall crossed costs wall_loss_db."""
    from netsim.tools.radio_checks import check_walls, wall_test_map
    from netsim.world.maps import save_map

    m = wall_test_map()
    out = []
    with tempfile.TemporaryDirectory() as tmp:
        path = save_map(Path(tmp) / "walls.yaml", m.occupied, m.free, m.resolution_m)
        for what, y, expected in (("across a wall", 15.0, 0.0), ("through a doorway", 3.0, 1.0)):
            csv = Path(tmp) / "pos.csv"
            pd.DataFrame({"x_m": [15.0, 25.0], "y_m": [y, y]}).to_csv(csv, index=False)
            sim, frames = _radio_run(
                seed=derive(seed, 1),
                duration_s=5.0,
                world={"n_robots": 2, "side_m": 40.0, "map": str(path), "placement": str(csv)},
                mobility={"model": "static"},
                channel={"range_m": 30.0},
                protocol={"model": "ack"},
            )
            heard = int(sim.channel.counters_for("ack").received.sum()) > 0
            out.append(Check("20", f"unit disk, robots 10 m apart {what}: linked", expected, float(heard), 0.0))
    for c in check_walls():
        if c.item == "W3":
            out.append(Check("20", c.result, c.theory, c.measured, c.tolerance, c.unit))
    return out


# -- the shared medium (channel.mac) ----------------------------------------------------------
def check_aloha_periodic(seed: int | None = None) -> list[Check]:
    """21: ALOHA, periodic frames at uniform phases, against (1 - 2T/t)^(n - 1); with two
    robots every loss is to half duplex (a robot sending cannot receive)."""
    from netsim.tools import mac_checks as m

    c = m.aloha_periodic(seed=derive(seed, 1))
    pair = m.half_duplex_pair(seed=derive(seed, 21))
    return [
        Check("21", c.item + ": reception success", c.theory, c.measured, c.tolerance),
        Check("21", pair.item + ": reception success", pair.theory, pair.measured, pair.tolerance),
    ]


def check_aloha_poisson(seed: int | None = None) -> list[Check]:
    """22: ALOHA, Poisson traffic, against e^(-2G)."""
    from netsim.tools import mac_checks as m

    c = m.aloha_poisson(seed=derive(seed, 1))
    return [Check("22", c.item + ": reception success", c.theory, c.measured, c.tolerance)]


def check_csma_saturation(seed: int | None = None) -> list[Check]:
    """23: CSMA saturation throughput against Bianchi (a model's tolerance, 5 %)."""
    from netsim.tools import mac_checks as m

    out = []
    for n in (5, 10, 20, 50):
        c = m.csma_saturation(n, seed=derive(seed, 1))
        out.append(Check("23", c.item + ": throughput (share of time)", c.theory, c.measured, c.tolerance))
    return out


def check_hidden_terminals(seed: int | None = None) -> list[Check]:
    """24: hidden terminals lose like an ALOHA pair; the control (in range) at most the bound."""
    from netsim.tools import mac_checks as m

    return [Check("24", c.item, c.theory, c.measured, c.tolerance) for c in m.hidden_terminals(seed=derive(seed, 1))]


def check_interference_sum(seed: int | None = None) -> list[Check]:
    """26: under log-distance the medium sums the interference of every frame on the air."""
    from netsim.tools import mac_checks as m

    c, receptions, differs = m.interference_sum(seed=derive(seed, 1))
    label = f"{c.item} ({differs} of {receptions} otherwise with the strongest alone)"
    return [Check("26", label, c.theory, c.measured, c.tolerance)]


MAC_NONE_RECORD = "tests/data/mac_none_724cc35.json"


def mac_none_record() -> dict | None:
    """The integer tables of a small clustering run recorded on the code before the medium
    existed (commit 724cc35; ``tests/data/record_mac_none.py``), or None outside a source
    checkout."""
    import json

    path = Path(__file__).resolve().parents[2] / MAC_NONE_RECORD
    return json.loads(path.read_text()) if path.is_file() else None


def mac_none_tree(record: dict) -> dict:
    """The configuration of :func:`mac_none_record`'s run, with ``channel.mac = "none"``, and
    rule 6 in that commit's order (``protocol.join_before_election``)."""
    tree = {k: dict(v) if isinstance(v, dict) else v for k, v in record["config"].items()}
    tree["channel"]["mac"] = "none"
    tree["protocol"]["join_before_election"] = True
    return tree


# The record's sampled tables have no sample at the run's end, which runs now take: their
# rows before the end are compared.
RECORDED_BEFORE_END = ("groups", "beliefs", "neighbour_beliefs")


def mac_none_mismatches(record: dict, frames: dict) -> list[str]:
    """Where a run's tables differ from ``record`` (:func:`mac_none_record`): its integer and
    label columns row by row, and the row count of each table it holds."""
    bad = []
    end_s = record["config"]["duration_s"]
    for name, counted in record["rows"].items():
        frame = frames.get(name, ())
        if name in RECORDED_BEFORE_END and len(frame):
            frame = frame[frame["t_s"] < end_s]
        if len(frame) != counted:
            bad.append(f"{name}: {len(frame)} rows, recorded {counted}")
    for name in ("acks", "roles"):
        for col, values in record[name].items():
            got = [v if isinstance(v, str) else int(v) for v in frames[name][col]] if col in frames[name] else None
            if got != values:
                bad.append(f"{name}.{col} differs")
    return bad


def check_medium_none(seed: int | None = None) -> list[Check]:
    """Item 25: channel.mac = "none" reproduces the channel before the medium existed: a
    clustering run's Ack counts, role changes and table sizes equal those recorded at commit
    724cc35 (benchmarks/output_digest.py checks every table of 38 scenarios, byte for byte,
    against a digest recorded on the branch point). The record fixes the run: ``seed`` is
    not used."""
    record = mac_none_record()
    label = 'channel.mac = "none": Ack counts, role changes and row counts as recorded before the medium'
    if record is None:
        return [Check("25", label + f" ({MAC_NONE_RECORD} not found: needs a source checkout)", 1.0, math.nan, 0.0)]
    sim = build(from_dict(mac_none_tree(record)))
    sim.run()
    same = float(not mac_none_mismatches(record, collect(sim)))
    return [Check("25", label, 1.0, same, 0.0)]


def ar1_mean_variance(alpha: float, k: int) -> float:
    """Variance of the mean of ``k`` successive values of a stationary AR(1) process of
    coefficient ``alpha``, over the process's variance: ``(1 + 2 sum_j (1 - j/k) alpha^j) / k``."""
    j = np.arange(1, k)
    return float(1.0 + 2.0 * ((1.0 - j / k) * alpha**j).sum()) / k


def ar1_autocorrelations(alpha: float, lags: Iterable[int], k: int) -> np.ndarray:
    """Expected sample autocorrelations (:func:`sample_autocorrelation`) at ``lags`` of ``k``
    successive values of a stationary Gaussian AR(1) process of coefficient ``alpha``:
    ``alpha^h`` less a bias of order ``1/k`` from the estimated mean and the ratio.

    The estimate is a ratio ``N / D`` of quadratic forms of the values ``x`` (covariance
    ``S = alpha^|i - j|``): with ``C`` the centring matrix and ``M = C S C``, ``E[D] =
    tr M``, ``Var D = 2 tr M^2``, ``E[N_h] = sum_i M[i, i + h]`` and ``Cov(N_h, D) = 2 sum_i
    M^2[i, i + h]``, and the second-order delta method gives ``E[N]/E[D] - Cov(N, D)/E[D]^2
    + E[N] Var(D)/E[D]^3`` (error of order ``1/k^2``)."""
    i = np.arange(k)
    cov = alpha ** np.abs(i[:, None] - i[None, :]).astype(float)
    m = cov - cov.mean(axis=0, keepdims=True) - cov.mean(axis=1, keepdims=True) + cov.mean()
    m2 = m @ m
    ed, vd = float(np.trace(m)), 2.0 * float(np.trace(m2))
    out = []
    for h in lags:
        en, cnd = float(np.trace(m, offset=h)), 2.0 * float(np.trace(m2, offset=h))
        out.append(en / ed - cnd / ed**2 + en * vd / ed**3)
    return np.array(out)


def sample_autocorrelation(x: np.ndarray, lag: int) -> float:
    """``sum (x_t - m)(x_(t+h) - m) / sum (x_t - m)^2``, ``m`` the mean of ``x``."""
    d = x - x.mean()
    return float((d[:-lag] * d[lag:]).sum() / (d * d).sum())


GM_LAGS = (1, 2, 4, 8)


def check_gauss_markov(seed: int | None = None) -> list[Check]:
    """Item 28: Gauss-Markov speed and direction at successive updates are stationary AR(1)
    processes: the speed's mean is ``mean_speed_mps``, the variances are ``speed_sigma_mps^2``
    and ``direction_sigma_rad^2`` and the autocorrelations ``alpha^h`` at lags ``h`` up to 8.
    The robots start near the centre of a square they cannot leave in the run (a row counts
    those whose path was long enough to reach a border: the borders turn a robot)."""
    alpha, mean, sigma, sigma_d, n, updates, skip = 0.7, 3.0, 0.5, 0.3, 60, 1500, 20
    side, centre = 20000.0, 2000.0
    sim = build(
        _config(
            seed=derive(seed, 28),
            duration_s=float(updates),
            world={"n_robots": n, "side_m": side, "placement": "centre", "centre_side_m": centre},
            mobility={
                "model": "gauss_markov",
                "alpha": alpha,
                "mean_speed_mps": mean,
                "speed_sigma_mps": sigma,
                "direction_sigma_rad": sigma_d,
            },
        )
    )
    sim.run()
    legs = sim.state.legs()
    start = legs.groupby("robot").first()[["x_m", "y_m"]].to_numpy()
    room = np.minimum(start, side - start).min(axis=1)
    legs = legs[legs["cause"].isin(["start", "turn"])]
    means, variances, corrs = [], {"speed": [], "direction": []}, {"speed": [], "direction": []}
    reach = []
    for _, g in legs.groupby("robot"):
        v = g[["vx_mps", "vy_mps"]].to_numpy()
        speeds = speeds_mps(v)
        reach.append(speeds.sum() * sim.config.mobility.update_interval_s)
        # The first updates leave the start at the means: the processes are stationary after.
        s = speeds[1:][skip:]
        d = np.unwrap(np.arctan2(v[:, 1], v[:, 0]))[1:][skip:]
        means.append(s.mean())
        for name, x in (("speed", s), ("direction", d)):
            variances[name].append(float(((x - x.mean()) ** 2).mean()))
            corrs[name].append([sample_autocorrelation(x, h) for h in GM_LAGS])
    k = len(s)
    means_a = np.array(means)
    out = [Check("28", "Gauss-Markov mean speed", mean, means_a.mean(), 4 * means_a.std(ddof=1) / math.sqrt(n), "m/s")]
    # Deviations from the sample mean fall short of the process's variance by the mean's.
    shrink = 1.0 - ar1_mean_variance(alpha, k)
    for name, sd, unit in (("speed", sigma, "(m/s)^2"), ("direction", sigma_d, "rad^2")):
        v = np.array(variances[name])
        out.append(
            Check(
                "28", f"Gauss-Markov {name} variance", sd**2 * shrink, v.mean(), 4 * v.std(ddof=1) / math.sqrt(n), unit
            )
        )
    expected = ar1_autocorrelations(alpha, GM_LAGS, k)
    for name in ("speed", "direction"):
        c = np.array(corrs[name])
        for col, h in enumerate(GM_LAGS):
            out.append(
                Check(
                    "28",
                    f"Gauss-Markov {name} autocorrelation at lag {h} (alpha^{h} = {alpha**h:.4g})",
                    float(expected[col]),
                    c[:, col].mean(),
                    4 * c[:, col].std(ddof=1) / math.sqrt(n),
                )
            )
    near = int((np.array(reach) >= room).sum())
    out.append(Check("28", "Gauss-Markov robots whose path could reach a border", 0, near, 0))
    return out


def check_rpgm(seed: int | None = None) -> list[Check]:
    """Item 29: group mobility as Hong et al. and BonnMotion define it. Exact: every member
    stays within ``group_radius_m`` of its group's reference point at every instant
    (checked where either changes course: both move in straight lines in between, so the
    distance is convex there), and no member is faster than ``speed_max_mps``. Statistical,
    on the reference legs where the speed bound cannot reject a new offset (``speed_max_mps``
    times the leg's time at least its length plus the disk's diameter): a member's new
    offset ``o'`` at the leg's end has a distance uniform on ``[0, R]`` (mean ``R / 2``), and
    is drawn afresh, independent of the old offset ``o``: ``o . o'`` has mean 0."""
    from netsim.trajectory import sample_positions

    radius, size, n, T, vmax = 40.0, 5, 60, 3000.0, 5.0
    sim = build(
        _config(
            seed=derive(seed, 29),
            duration_s=T,
            world={"n_robots": n, "side_m": 800.0},
            mobility={
                "model": "rpgm",
                "group_size": size,
                "group_radius_m": radius,
                "pause_s": 2.0,
                "speed_min_mps": 0.5,
                "speed_max_mps": vmax,
            },
        )
    )
    sim.run()
    frames = collect(sim)
    ref, legs = frames["reference_points"], frames["legs"]
    times = np.unique(np.r_[ref["t_s"].to_numpy(), T])
    times = times[times <= T]
    pos = sample_positions(legs, n, times)[["x_m", "y_m"]].to_numpy().reshape(len(times), n, 2)
    farther = 0
    distance, dot, member = [], [], []
    for g, track in ref.groupby("group"):
        # The log holds each reference leg as two rows: where it starts, where and when it ends.
        t0, t1 = track["t_s"].to_numpy()[0::2], track["t_s"].to_numpy()[1::2]
        p0, p1 = track[["x_m", "y_m"]].to_numpy()[0::2], track[["x_m", "y_m"]].to_numpy()[1::2]
        unique = track.drop_duplicates("t_s", keep="last").sort_values("t_s")
        rx = np.interp(times, unique["t_s"], unique["x_m"])
        ry = np.interp(times, unique["t_s"], unique["y_m"])
        within = t1 <= T
        free = within & (vmax * (t1 - t0) >= np.hypot(*(p1 - p0).T) + 2 * radius)
        k0, k1 = np.searchsorted(times, t0[free]), np.searchsorted(times, t1[free])
        for i in range(int(g) * size, min((int(g) + 1) * size, n)):
            d = np.hypot(pos[:, i, 0] - rx, pos[:, i, 1] - ry)
            farther += int((d > radius * (1 + 1e-9)).sum())
            old, new = pos[k0, i] - p0[free], pos[k1, i] - p1[free]
            distance.extend((np.hypot(*new.T) / radius).tolist())
            dot.extend(((old * new).sum(axis=1) / radius**2).tolist())
            member.extend([i] * len(new))
    speed = speeds_mps(legs[["vx_mps", "vy_mps"]].to_numpy(float))
    faster = int((speed > vmax * (1 + 1e-9)).sum())
    distance_a, dot_a, member_a = np.array(distance), np.array(dot), np.array(member)
    return [
        Check("29", f"RPGM: member-instants farther than {radius:g} m from the reference point", 0, farther, 0),
        Check("29", f"RPGM: member legs faster than speed_max_mps = {vmax:g} m/s", 0, faster, 0),
        # Each unconstrained leg's offset is a fresh draw: independent across legs and members.
        Check(
            "29",
            f"RPGM: new offset's distance over the radius, mean ({len(distance_a)} member-legs)",
            0.5,
            distance_a.mean(),
            4 * distance_a.std(ddof=1) / math.sqrt(len(distance_a)),
        ),
        # Consecutive legs of a member share an offset: the standard error is over members.
        Check(
            "29",
            "RPGM: old offset . new offset over radius^2, mean (fresh draws: 0)",
            0.0,
            dot_a.mean(),
            4 * cluster_se(dot_a, member_a),
        ),
    ]


# -- coverage on the radio the robots have (items 30, 31) ------------------------------------
# The targets of the covered fraction of min(1, U(N) / A) from a dense start, by plan
# (experiments/coverage_targets.py), and the floors item 31 holds every seed to: below what
# each plan reaches at N = 60 by a margin for the spread between seeds.
COVERAGE_FLOOR = {"global": 0.75, "local": 0.60}
VALIDATE_FLOOR = {"global": 0.85, "local": 0.60}
COVERAGE_RADIOS = {
    "unit disk": ["channel.range_m=100"],
    "shadowing 4 dB": ["channel.propagation=log_distance", "channel.shadowing_sigma_db=4"],
    "office, line of sight": ["world.map=office", "world.side_m=200", "channel.range_m=30"],
    "office, 5 dB a wall": [
        "world.map=office",
        "world.side_m=200",
        "channel.propagation=log_distance",
        "channel.wall_loss_db=5",
        "channel.sensitivity_dbm=-64.3",  # an implied range of 30 m
    ],
}


def coverage_settings(
    radio: str, plan: str, n: int, loss: float, seed: int, duration_s: float, extra: Sequence[str] = ()
) -> list[str]:
    """A coverage run from a dense start (a central square of side ``40 sqrt(N)`` m, about
    twenty neighbours each; 40 m on the office map) on an area large enough that a connected
    team cannot cover it (``500 sqrt(N)`` m a side in open space); ``extra``: ``KEY=VALUE``
    settings over these."""
    on_map = radio.startswith("office")
    return [
        f"seed={seed}",
        f"world.n_robots={n}",
        f"world.side_m={500 * math.sqrt(n):.1f}",
        "world.placement=centre",
        f"world.centre_side_m={40 if on_map else 40 * math.sqrt(n):.1f}",
        "mobility.model=static",
        "coverage.enabled=true",
        f"coverage.plan={plan}",
        "protocol.message_rate_hz=0",
        "output.position_interval_s=0",
        f"channel.loss_probability={loss}",
        f"duration_s={duration_s}",
        *COVERAGE_RADIOS[radio],
        *extra,
    ]


# How long the coverage targets' runs last (docs/model.md 5.2, validate's items 30 and 31).
COVERAGE_DURATION_S = 600.0


def cut_short(duration_s: float) -> str:
    """A line telling that runs of ``duration_s`` are shorter than the targets' (their teams
    cut while still spreading, so a verdict is not the targets'); empty when they are not."""
    if duration_s >= COVERAGE_DURATION_S:
        return ""
    return (
        f"note: --duration {duration_s:g} s is shorter than the targets' {COVERAGE_DURATION_S:g} s: the teams were"
        " cut while spreading, and these verdicts are not the targets'"
    )


def coverage_outcome(frames: dict[str, pd.DataFrame], summary: dict, n: int, start_s: float, end_s: float) -> dict:
    """What a coverage run showed: the components of the real network (``links.parquet``) at
    control start and their largest number at any link event after it, whether the
    coverage table's ``components`` equals that network's at every sample, the covered
    fraction of the bound at the end, and when the stopping rule ended control (NaN: the
    run ended first, the team still spreading)."""
    from netsim.metrics import components_in_links_table

    links, cov = frames["links"], frames["coverage"]
    times = np.unique(np.r_[start_s, links["t_up_s"].to_numpy(), links["t_down_s"].to_numpy()])
    times = times[(times >= start_s) & (times <= end_s)]
    comps = components_in_links_table(links, n, times)
    at_samples = components_in_links_table(links, n, cov["t_s"].to_numpy(float))
    return {
        "components_at_start": int(comps[0]),
        "components_max": int(comps.max()),
        "table_true": bool((cov["components"].to_numpy() == at_samples).all()),
        "of_bound": float(summary["covered_of_bound_all_final"]),
        "settled_s": float(summary["control_settled_s"]),
    }


def coverage_run(
    radio: str, plan: str, n: int, loss: float, seed: int, duration_s: float, extra: Sequence[str] = ()
) -> dict:
    """One coverage run (:func:`coverage_settings`) and its outcome (:func:`coverage_outcome`)."""
    from netsim.config import load
    from netsim.run import execute

    config = load(None, coverage_settings(radio, plan, n, loss, seed, duration_s, extra))
    result = execute(config)
    return coverage_outcome(result.frames, result.summary, n, config.coverage.start_s, duration_s)


def check_coverage(seed: int | None = None, tick: Callable[[], object] = lambda: None) -> list[Check]:
    """Items 30 and 31: under every radio and with both plans the real network never has
    more components after control starts than when it starts, and the coverage table
    reports it truly (30); on the unit disk at N = 60 each plan covers at least its floor of
    the bound (31). ``tick()`` as each run ends."""
    out = []
    for radio in COVERAGE_RADIOS:
        for plan in ("global", "local"):
            n = 40 if radio.startswith("office") else 60
            o = coverage_run(radio, plan, n, 0.0, derive(seed, 30), COVERAGE_DURATION_S)
            tick()
            grew = o["components_max"] - o["components_at_start"]
            out.append(Check("30", f"coverage, {radio}, {plan}: components above those at control start", 0, grew, 0))
            out.append(
                Check("30", f"coverage, {radio}, {plan}: table's components untrue", 0, int(not o["table_true"]), 0)
            )
            if radio == "unit disk":
                floor = VALIDATE_FLOOR[plan]
                # One-sided: the row passes when the fraction reaches the floor.
                shown = min(o["of_bound"], 1.0)
                out.append(
                    Check(
                        "31",
                        f"coverage at N = 60, {plan}: fraction of the bound (at least {floor:g})",
                        (1.0 + floor) / 2,
                        shown,
                        (1.0 - floor) / 2,
                    )
                )
    # Item 30's rows, then item 31's, as the table lists items.
    return sorted(out, key=lambda c: c.item)


CHECKS: list[Item] = [
    Item(("1",), check_rwp_speed, statistical=True),
    Item(("2",), check_rwp_leg_length, statistical=True),
    Item(("1", "3", "4"), check_stationary_start, statistical=True),
    Item(("5",), check_unit_disk, statistical=False),
    Item(("6",), check_torus_links, statistical=True),
    Item(("7",), check_exact_links, statistical=False),
    Item(("8",), check_discovery_delay, statistical=True),
    Item(("9",), check_spurious_timeouts, statistical=True),
    Item(("10",), check_delivery_ratio, statistical=True),
    Item(("11",), check_mean_degree, statistical=True),
    Item(("12",), check_no_isolated, statistical=True),
    Item(("13",), check_clustering_invariants, statistical=False),
    Item(("17",), check_radio_unit_disk, statistical=False),
    Item(("18",), check_radio_link_probability, statistical=True),
    Item(("19",), check_radio_correlation, statistical=True),
    Item(("20",), check_radio_walls, statistical=False),
    Item(("21",), check_aloha_periodic, statistical=True),
    Item(("22",), check_aloha_poisson, statistical=True),
    Item(("23",), check_csma_saturation, statistical=True),
    Item(("24",), check_hidden_terminals, statistical=True),
    Item(("25",), check_medium_none, statistical=False),
    Item(("26",), check_interference_sum, statistical=False),
    Item(("27",), check_radio_pair_travel, statistical=True),
    Item(("28",), check_gauss_markov, statistical=True),
    Item(("29",), check_rpgm, statistical=True),
    Item(("30", "31"), check_coverage, statistical=False, parts=2 * len(COVERAGE_RADIOS)),
]


def item_numbers(checks: Iterable[Item] | None = None) -> list[str]:
    """Every item number the checks cover, in numerical order."""
    numbers = {n for c in (CHECKS if checks is None else checks) for n in c.numbers}
    return sorted(numbers, key=int)


def parse_only(text: str) -> list[str]:
    """``--only``'s value, item numbers separated by commas (``"21,22"``), checked against
    :data:`CHECKS`: a :class:`NetsimInputError` naming the flag for anything else."""
    known = item_numbers()
    asked = [part.strip() for part in text.split(",")]
    for part in asked:
        if part not in known:
            shown = f"no item {part}" if part.isdigit() else f"{part!r} is not an item number"
            raise NetsimInputError(
                f"--only = {text!r}: {shown}; give item numbers separated by commas, from {_spans(known)}"
            )
    return asked


def _spans(numbers: list[str]) -> str:
    """``"1-13, 17-27"`` for the sorted item numbers ``numbers``."""
    values = [int(n) for n in numbers]
    runs: list[list[int]] = []
    for v in values:
        if runs and v == runs[-1][1] + 1:
            runs[-1][1] = v
        else:
            runs.append([v, v])
    return ", ".join(f"{a}" if a == b else f"{a}-{b}" for a, b in runs)


def parse_seed(text: str) -> int:
    """``--seed``'s value: a whole number >= 0, else a :class:`NetsimInputError` naming the flag."""
    try:
        seed = int(text)
    except ValueError:
        seed = -1
    if seed < 0:
        raise NetsimInputError(f"--seed = {text!r}: must be a whole number >= 0")
    return seed


def select(only: Iterable[str] | None = None, statistical: bool | None = None) -> list[Item]:
    """The checks covering any of the items ``only`` (all: None), the statistical ones alone
    if ``statistical`` is True (the exact ones if False)."""
    wanted = None if only is None else set(only)
    return [
        c
        for c in CHECKS
        if (wanted is None or wanted & set(c.numbers)) and (statistical is None or c.statistical == statistical)
    ]


def run_all(progress: bool = True, seed: int | None = None, only: Iterable[str] | None = None) -> list[Check]:
    """The rows of the checks covering the items ``only`` (all: None), their random draws
    from ``seed`` (None: the fixed seeds of the default table)."""
    from netsim.progress import progress_bar

    checks = select(only)
    results = []
    total = sum(c.parts for c in checks)
    with progress_bar(total, "netsim validate", "experiments", enabled=progress, lines=5, leave=False) as bar:
        for c in checks:
            if c.parts > 1:
                results.extend(c.check(seed, tick=lambda: bar.update(1)))
            else:
                results.extend(c.check(seed))
                bar.update(1)
    return results


def table(results: list[Check]) -> str:
    rows = [("item", "result", "theory", "measured", "tolerance", "pass")]
    for c in results:
        rows.append(
            (
                c.item,
                c.result,
                f"{c.theory:.6g}",
                f"{c.measured:.6g}",
                f"± {c.tolerance:.3g}",
                "yes" if c.passed else "NO",
            )
        )
    widths = [max(len(r[k]) for r in rows) for k in range(6)]
    lines = ["  ".join(cell.ljust(w) for cell, w in zip(r, widths)) for r in rows]
    lines.insert(1, "-" * len(lines[0]))
    return "\n".join(lines)
