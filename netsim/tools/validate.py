"""``netsim validate``: the closed-form results of docs/validation.md, checked on real runs.

Each check builds runs from configurations (models by name, as ``netsim run`` does),
measures from their outputs, and compares with theory within a stated tolerance: four
standard errors for statistical checks unless said otherwise. The same results are
tested, at other sizes and seeds, by the test suite.
"""

from __future__ import annotations

import math
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from netsim.config import from_dict
from netsim.groups import in_a_group, leads_itself
from netsim.links.lifetimes import link_lifetimes
from netsim.metrics import MEAN_LEG_UNIT_SQUARE
from netsim.run import build, collect
from netsim.tools import analysis
from netsim.topology import geometric_pairs
from netsim.trajectory import distance_travelled


@dataclass
class Check:
    item: str
    result: str
    theory: float
    measured: float
    tolerance: float
    unit: str = ""

    @property
    def passed(self) -> bool:
        return bool(abs(self.measured - self.theory) <= self.tolerance)


def _config(**tree):
    tree.setdefault("output", {"position_interval_s": 0.0})
    tree.setdefault("protocol", {"model": "none"})
    return from_dict(tree)


def rwp_density(x: float, y: float) -> float:
    """Exact stationary density of random waypoint on the unit square (Hyytiä et al. 2006)."""
    from scipy import integrate

    def border(phi):
        c, s = math.cos(phi), math.sin(phi)
        ts = [
            t
            for t in (
                (1 - x) / c if c > 0 else None,
                -x / c if c < 0 else None,
                (1 - y) / s if s > 0 else None,
                -y / s if s < 0 else None,
            )
            if t is not None
        ]
        return min(ts)

    corners = sorted(math.atan2(cy - y, cx - x) % math.pi for cx in (0, 1) for cy in (0, 1))
    value = integrate.quad(
        lambda p: (lambda a, b: a * b * (a + b))(border(p), border(p + math.pi)), 0, math.pi, points=corners, limit=200
    )[0]
    return value / MEAN_LEG_UNIT_SQUARE


def completed_leg_lengths(legs: pd.DataFrame) -> np.ndarray:
    """Lengths of the moving legs that ended within the run, each robot's first leg (length-biased
    by the stationary start) left out."""
    t, r = legs["t_s"].to_numpy(), legs["robot"].to_numpy()
    same = r[1:] == r[:-1]
    speed = np.hypot(legs["vx_mps"], legs["vy_mps"]).to_numpy()[:-1]
    first = np.r_[True, r[1:-1] != r[:-2]]
    lengths = (speed * np.diff(t))[same & ~first & (speed > 0)]
    return lengths


def check_rwp() -> list[Check]:
    side, vmin, vmax, n, T = 200.0, 1.0, 4.0, 400, 600.0
    out = []
    for pause in (0.0, 20.0):
        sim = build(
            _config(
                seed=5,
                duration_s=T,
                world={"n_robots": n, "side_m": side},
                mobility={"speed_min_mps": vmin, "speed_max_mps": vmax, "pause_s": pause},
            )
        )
        sim.run()
        legs = sim.state.legs()
        per_robot = distance_travelled(legs, T) / T
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
    # Many legs per robot: the unfinished last leg (length-biased, left out) must not matter.
    side = 100.0
    sim = build(
        _config(
            seed=6,
            duration_s=2000.0,
            world={"n_robots": 300, "side_m": side},
            mobility={"speed_min_mps": 2.0, "speed_max_mps": 5.0, "pause_s": 0.0},
        )
    )
    sim.run()
    lengths = completed_leg_lengths(sim.state.legs())
    out.append(
        Check(
            "2",
            "RWP mean leg length",
            MEAN_LEG_UNIT_SQUARE * side,
            lengths.mean(),
            4 * lengths.std() / math.sqrt(len(lengths)),
            "m",
        )
    )
    return out


def check_stationary_start() -> list[Check]:
    n, h = 100_000, 0.05
    sim = build(
        _config(
            seed=3,
            duration_s=1.0,
            world={"n_robots": n, "side_m": 1.0},
            mobility={"speed_min_mps": 0.01, "speed_max_mps": 0.05, "pause_s": 0.0},
        )
    )
    sim.env.run(until=1e-9)  # the robots' processes set their first legs at t = 0
    p = sim.state.positions_at(0.0)
    out = []
    for pt in ((0.5, 0.5), (0.1, 0.1)):
        offsets = (np.arange(5) + 0.5) / 5 * h - h / 2
        mass = np.mean([rwp_density(pt[0] + dx, pt[1] + dy) for dx in offsets for dy in offsets]) * h * h
        count = int(((np.abs(p[:, 0] - pt[0]) < h / 2) & (np.abs(p[:, 1] - pt[1]) < h / 2)).sum())
        out.append(
            Check(
                "3, 4",
                f"RWP stationary density at t = 0 near {pt}",
                mass / h**2,
                count / (n * h * h),
                4 * math.sqrt(n * mass) / (n * h * h),
                "per unit area",
            )
        )
    speeds = np.hypot(*sim.state.velocity_mps.T)
    out.append(
        Check(
            "1, 4",
            "stationary start mean speed [0.01, 0.05]",
            0.04 / math.log(5),
            speeds.mean(),
            4 * speeds.std() / math.sqrt(n),
            "m/s",
        )
    )
    return out


def check_unit_disk() -> list[Check]:
    rng = np.random.default_rng(1)
    pos = rng.uniform(0, 100, (400, 2))
    i, j, _ = geometric_pairs(pos, 12.0)
    d = np.hypot(*(pos[:, None, :] - pos[None, :, :]).transpose(2, 0, 1))
    truth = {(a, b) for a, b in zip(*np.nonzero(np.triu(d <= 12.0, 1)))}
    wrong = len(truth ^ set(zip(i.tolist(), j.tolist())))
    return [Check("5", "unit disk: linked iff distance <= R (pairs wrong)", 0.0, float(wrong), 0.0)]


def check_torus_links() -> list[Check]:
    R, v, T = 10.0, 1.0, 1000.0
    sim = build(
        _config(
            seed=11,
            duration_s=T,
            world={"n_robots": 200, "side_m": 200.0, "torus": True},
            channel={"range_m": R},
            mobility={"model": "random_direction", "speed_min_mps": v, "speed_max_mps": v},
        )
    )
    sim.run()
    links = collect(sim)["links"]
    born = links[(links.t_up_s > 0) & (links.t_up_s < T / 2)]
    theory = math.pi**2 * R / (8 * v)
    return [
        Check(
            "6",
            "link duration, torus, equal speeds: pi^2 R / (8 v) (5 %)",
            theory,
            float((born.t_down_s - born.t_up_s).mean()),
            0.05 * theory,
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


def check_exact_links() -> list[Check]:
    """Item 7 on random trajectories, against brute force: plain, with jumps (sampled also
    just before and after every jump), and on the smallest torus allowed (side just above
    twice the range, where other images come into range within a piece)."""
    from netsim.links.lifetimes import jump_times
    from netsim.trajectory import LegTable

    out = []
    sim = build(
        _config(
            seed=4,
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
            la, lb = table.leg_at(a, t), table.leg_at(b, t)
            d = table.p[la] + table.v[la] * (t - table.t[la]) - table.p[lb] - table.v[lb] * (t - table.t[lb])
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
    times = np.sort(np.random.default_rng(4).uniform(0, 120.0, 2000))
    out.append(
        Check(
            "7",
            "link events vs brute force, 30 robots (pairs wrong at 2,000 instants)",
            0.0,
            float(brute_force_mismatches(legs, links, np.full(30, 40.0), times)),
            0.0,
        )
    )
    rng = np.random.default_rng(7)
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


def check_discovery_delay() -> list[Check]:
    pairs, p = 1000, 0.3
    n = 2 * pairs
    sim = build(
        _config(
            seed=8,
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
            4 * float(np.nanstd(delay)) / math.sqrt(pairs),
            "s",
        )
    ]


def check_spurious_timeouts() -> list[Check]:
    pairs, p, tau, k = 400, 0.3, 2.5, 2
    pos = np.zeros((2 * pairs, 2))
    pos[0::2, 0] = pos[1::2, 0] = np.arange(pairs) * 100.0
    pos[1::2, 1] = 5.0
    with tempfile.TemporaryDirectory() as tmp:
        csv = Path(tmp) / "pairs.csv"
        pd.DataFrame(pos, columns=["x_m", "y_m"]).to_csv(csv, index=False)
        sim = build(
            _config(
                seed=9,
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
    return [
        Check(
            "9",
            f"Acks until a spurious timeout, p = {p}, k = {k}",
            theory,
            counts.mean(),
            4 * counts.std() / math.sqrt(len(counts)),
            "Acks",
        )
    ]


def check_delivery_ratio() -> list[Check]:
    p = 0.25
    sim = build(
        _config(
            seed=3,
            duration_s=60.0,
            world={"n_robots": 60, "side_m": 400.0},
            channel={"loss_probability": p, "range_m": 100.0},
            protocol={"model": "ack"},
        )
    )
    sim.run()
    acks = collect(sim)["acks"]
    received, lost = acks.received.sum(), acks.dropped_loss.sum()
    n = received + lost
    return [Check("10", f"delivered fraction of Acks, loss {p}", 1 - p, received / n, 4 * math.sqrt(p * (1 - p) / n))]


def check_random_geometric() -> list[Check]:
    n, r, reps = 100, 0.1, 300
    degrees = []
    for rep in range(reps):
        sim = build(
            _config(seed=1, world={"n_robots": n, "side_m": 1.0}, mobility={"model": "static"}, channel={"range_m": r}),
            run=rep,
        )
        degrees.append(2 * len(geometric_pairs(sim.state.positions_at(0.0), r)[0]) / n)
    theory = (n - 1) * (math.pi * r**2 - 8 * r**3 / 3 + r**4 / 2)
    out = [
        Check(
            "11",
            "mean degree, unit square with border",
            theory,
            float(np.mean(degrees)),
            4 * float(np.std(degrees)) / math.sqrt(reps),
        )
    ]
    n, r, reps = 50, 0.16, 600
    ok = 0
    for rep in range(reps):
        sim = build(
            _config(
                seed=2,
                world={"n_robots": n, "side_m": 1.0, "torus": True},
                mobility={"model": "static"},
                channel={"range_m": r},
            ),
            run=rep,
        )
        i, j, _ = geometric_pairs(sim.state.positions_at(0.0), r, side_m=1.0)
        ok += bool(np.bincount(np.r_[i, j], minlength=n).min() >= 1)
    theory = (1 - (1 - math.pi * r**2) ** (n - 1)) ** n
    out.append(
        Check("12", "P(no isolated robot), torus", theory, ok / reps, 4 * math.sqrt(theory * (1 - theory) / reps))
    )
    return out


def check_clustering_invariants() -> list[Check]:
    bad = 0
    for seed in (1, 2, 3):
        n = 150
        side = 10.0 * math.sqrt(n * math.pi / 6)
        sim = build(
            _config(
                seed=seed,
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


def check_radio_unit_disk() -> list[Check]:
    """17: log-distance without shadowing links exactly as a unit disk of the implied range:
    the same links table and the same Ack receptions, on the same moving team."""
    base = {"seed": 17, "duration_s": 120.0, "world": {"n_robots": 100, "side_m": 800.0}, "protocol": {"model": "ack"}}
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


def check_radio_link_probability() -> list[Check]:
    """18: shadowing sigma on a static uniform deployment: the fraction of pairs the channel
    links at distance d is Phi((P_t - PL(d) - sensitivity) / sigma), in every distance bin."""
    from scipy.spatial import cKDTree

    from netsim.radio.propagation import LogDistanceParams, reach_m
    from netsim.tools.radio_checks import Z, link_probability

    sigma, n, side = 4.0, 1000, 1000.0
    params = LogDistanceParams(shadowing_sigma_db=sigma)
    sim, frames = _radio_run(
        seed=18,
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
    d = np.hypot(*(pos[i] - pos[j]).T)
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


def check_radio_correlation() -> list[Check]:
    """19: a moving pair's shadowing has correlation exp(-delta / d_corr) at travel separation
    delta, whatever the instants it was looked at in between (the channel's PairShadowing)."""
    from netsim.tools.radio_checks import check_shadowing_correlation

    return [Check("19", c.result, c.theory, c.measured, c.tolerance, c.unit) for c in check_shadowing_correlation()]


def check_radio_walls() -> list[Check]:
    """20: across a wall two robots do not link under the unit disk, through a doorway they
    do; under log-distance each wall crossed costs wall_loss_db."""
    from netsim.radio.maps import save_map
    from netsim.tools.radio_checks import check_walls, wall_test_map

    m = wall_test_map()
    out = []
    with tempfile.TemporaryDirectory() as tmp:
        path = save_map(Path(tmp) / "walls.yaml", m.occupied, m.free, m.resolution_m)
        for what, y, expected in (("across a wall", 15.0, 0.0), ("through a doorway", 3.0, 1.0)):
            csv = Path(tmp) / "pos.csv"
            pd.DataFrame({"x_m": [15.0, 25.0], "y_m": [y, y]}).to_csv(csv, index=False)
            sim, frames = _radio_run(
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
def check_medium() -> list[Check]:
    """Items 21-24: ALOHA against its closed forms, CSMA against Bianchi, hidden terminals."""
    from netsim.tools import mac_checks as m

    out = []
    for item, c in (("21", m.aloha_periodic()), ("22", m.aloha_poisson())):
        out.append(Check(item, c.item + ": reception success", c.theory, c.measured, c.tolerance))
    for n in (5, 10, 20, 50):
        c = m.csma_saturation(n)
        out.append(Check("23", c.item + ": throughput (share of time)", c.theory, c.measured, c.tolerance))
    for c in m.hidden_terminals():
        out.append(Check("24", c.item, c.theory, c.measured, c.tolerance))
    return out


MAC_NONE_RECORD = "tests/data/mac_none_724cc35.json"


def mac_none_record() -> dict | None:
    """The integer tables of a small clustering run recorded on the code before the medium
    existed (commit 724cc35; ``tests/data/record_mac_none.py``), or None outside a source
    checkout."""
    import json

    path = Path(__file__).resolve().parents[2] / MAC_NONE_RECORD
    return json.loads(path.read_text()) if path.is_file() else None


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


def check_medium_none() -> list[Check]:
    """Item 25: channel.mac = "none" reproduces the channel before the medium existed: a
    clustering run's Ack counts, role changes and table sizes equal those recorded at commit
    724cc35 (benchmarks/output_digest.py checks every table of 38 scenarios, byte for byte,
    against a digest recorded on the branch point)."""
    record = mac_none_record()
    label = 'channel.mac = "none": Ack counts, role changes and row counts as recorded before the medium'
    if record is None:
        return [Check("25", label + f" ({MAC_NONE_RECORD} not found: needs a source checkout)", 1.0, math.nan, 0.0)]
    tree = {k: dict(v) if isinstance(v, dict) else v for k, v in record["config"].items()}
    tree["channel"]["mac"] = "none"
    sim = build(from_dict(tree))
    sim.run()
    same = float(not mac_none_mismatches(record, collect(sim)))
    return [Check("25", label, 1.0, same, 0.0)]


CHECKS: list[Callable[[], list[Check]]] = [
    check_rwp,
    check_stationary_start,
    check_unit_disk,
    check_torus_links,
    check_exact_links,
    check_discovery_delay,
    check_spurious_timeouts,
    check_delivery_ratio,
    check_random_geometric,
    check_clustering_invariants,
    check_radio_unit_disk,
    check_radio_link_probability,
    check_radio_correlation,
    check_radio_walls,
    check_medium,
    check_medium_none,
]


def run_all(progress: bool = True) -> list[Check]:
    from netsim.progress import progress_bar

    results = []
    with progress_bar(len(CHECKS), "netsim validate", "check", enabled=progress, lines=5, leave=False) as bar:
        for check in CHECKS:
            results.extend(check())
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
