"""Logs of frames made with netsim's own channel physics and known parameters, for the tests
of ``netsim calibrate``; run as a module it prints the maximum-likelihood and the naive fits
beside the truth (the numbers quoted in docs/radio.md)::

    python -m tests.calibration_logs [--seeds 3]
    python -m tests.calibration_logs --write site.csv    # the received-only log of seed 0

Robots move by random waypoint (straight legs, no pause) in a square; every ``step_s`` one
robot, in turn, sends a frame to all the others. The power is the log-distance law of
:mod:`netsim.radio.propagation` with the pair's shadowing drawn by netsim's own
:class:`~netsim.radio.shadowing.PairShadowing` at the pair's travel (both robots' path length),
and the walls the line crosses on a map; a frame is received iff its power clears the
sensitivity. The truncated log keeps the received rows; the censored one keeps every frame,
``rssi_dbm`` empty for those not received.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from netsim.errors import NetsimInputError
from netsim.radio.propagation import LogDistanceParams, path_loss_db
from netsim.radio.shadowing import PairShadowing
from netsim.tools.args import Parser
from netsim.tools.cli import check_out_file

TRUTH = LogDistanceParams(
    tx_power_dbm=20.0,
    reference_loss_db=40.0,
    path_loss_exponent=3.0,
    sensitivity_dbm=-80.0,
    shadowing_sigma_db=6.0,
    shadowing_decorrelation_m=10.0,
    wall_loss_db=5.0,
)


def waypoint_tracks(rng, n_robots, side_m, duration_s, speed_mps=(0.5, 1.5), low_m=0.0):
    """Each robot's random-waypoint legs: arrival times, positions and odometer at each waypoint."""
    tracks = []
    for _ in range(n_robots):
        t, p, odo = [0.0], [rng.uniform(low_m, low_m + side_m, 2)], [0.0]
        while t[-1] < duration_s:
            q = rng.uniform(low_m, low_m + side_m, 2)
            length = float(np.hypot(*(q - p[-1])))
            t.append(t[-1] + length / rng.uniform(*speed_mps))
            p.append(q)
            odo.append(odo[-1] + length)
        tracks.append((np.array(t), np.array(p), np.array(odo)))
    return tracks


def at(tracks, robot, t_s):
    """Position and odometer of ``robot`` at times ``t_s`` (exact: motion is linear on a leg)."""
    t, p, odo = tracks[robot]
    return np.column_stack([np.interp(t_s, t, p[:, 0]), np.interp(t_s, t, p[:, 1])]), np.interp(t_s, t, odo)


def synth_log(
    seed: int,
    params: LogDistanceParams = TRUTH,
    censored: bool = False,
    n_robots: int = 12,
    side_m: float = 150.0,
    duration_s: float = 900.0,
    step_s: float = 0.25,
    occupancy=None,
) -> pd.DataFrame:
    """A log of frames (columns t_s, src, dst, positions, distance_m, rssi_dbm, received)."""
    root = np.random.SeedSequence(seed)
    motion_rng, shadow_rng = (np.random.default_rng(s) for s in root.spawn(2))
    tracks = waypoint_tracks(motion_rng, n_robots, side_m, duration_s)
    times = np.arange(step_s, duration_s, step_s)
    pos = np.empty((n_robots, len(times), 2))
    odo = np.empty((n_robots, len(times)))
    for i in range(n_robots):
        pos[i], odo[i] = at(tracks, i, times)
    shadowing = PairShadowing(params.shadowing_sigma_db, params.shadowing_decorrelation_m, shadow_rng)
    cols: dict[str, list] = {c: [] for c in ("t_s", "src", "dst", "p", "q", "distance_m", "rssi_dbm")}
    for k, t in enumerate(times):
        src = k % n_robots
        dst = np.delete(np.arange(n_robots), src)
        a = np.full(len(dst), src)
        p, q = pos[a, k], pos[dst, k]
        d = np.hypot(*(q - p).T)
        x = shadowing.sample(a, dst, odo[a, k] + odo[dst, k])
        power = params.tx_power_dbm - path_loss_db(d, params) - x
        if occupancy is not None:
            from netsim.world.los import walls_crossed

            power = power - params.wall_loss_db * walls_crossed(occupancy, p, q)
        for c, v in zip(cols, (np.full(len(dst), t), a, dst, p, q, d, power), strict=True):
            cols[c].append(v)
    v = {c: np.concatenate(parts) for c, parts in cols.items()}
    log = pd.DataFrame(
        {
            "t_s": v["t_s"],
            "src": v["src"],
            "dst": v["dst"],
            "src_x_m": v["p"][:, 0],
            "src_y_m": v["p"][:, 1],
            "dst_x_m": v["q"][:, 0],
            "dst_y_m": v["q"][:, 1],
            "distance_m": v["distance_m"],
            "rssi_dbm": v["rssi_dbm"],
        }
    )
    log["received"] = log["rssi_dbm"] >= params.sensitivity_dbm
    if censored:
        log.loc[~log["received"], "rssi_dbm"] = np.nan
        return log
    return log[log["received"]].reset_index(drop=True)


KEYS = ("reference_loss_db", "path_loss_exponent", "shadowing_sigma_db", "shadowing_decorrelation_m")


def comparison(seeds: int) -> str:
    """The ML fit (with its interval) and the naive least squares beside the truth, per log."""
    from netsim.tools.calibrate import calibrate_frame

    lines = [f"{'log':<10} {'seed':>4}  {'fit':<9}" + "".join(f"{k:>28}" for k in KEYS)]
    lines.append(f"{'':<10} {'':>4}  {'truth':<9}" + "".join(f"{getattr(TRUTH, k):>28g}" for k in KEYS))
    for censored in (False, True):
        for seed in range(seeds):
            result = calibrate_frame(synth_log(seed, censored=censored), sensitivity_dbm=TRUTH.sensitivity_dbm)
            for name, fit in (("ML", result.fit), ("naive LS", result.naive)):
                cells = []
                for k in KEYS:
                    if k == "shadowing_decorrelation_m":
                        e = result.decorrelation.estimate if name == "ML" else None
                    else:
                        e = getattr(fit, k)
                    if e is None:
                        cells.append("-")
                    elif name == "ML":
                        cells.append(f"{e.value:.2f} [{e.low:.2f}, {e.high:.2f}]")
                    else:
                        cells.append(f"{e.value:.2f}")
                kind = "censored" if censored else "truncated"
                lines.append(f"{kind:<10} {seed:>4}  {name:<9}" + "".join(f"{c:>28}" for c in cells))
    return "\n".join(lines)


def coverage(seeds: int, durations_s: tuple[float, ...]) -> str:
    """How often each ML interval holds the truth, over the truncated logs of ``seeds``
    seeds of each duration (seeds 0, 1, ...): the intervals' real coverage against 95 %."""
    from netsim.tools.calibrate import calibrate_frame

    lines = [f"{'duration_s':>10} {'seeds':>5}" + "".join(f"{k:>28}" for k in KEYS)]
    for duration_s in durations_s:
        held = dict.fromkeys(KEYS, 0)
        fitted = dict.fromkeys(KEYS, 0)
        for seed in range(seeds):
            log = synth_log(seed, duration_s=duration_s)
            result = calibrate_frame(log, sensitivity_dbm=TRUTH.sensitivity_dbm)
            for k in KEYS:
                e = result.decorrelation.estimate if k == "shadowing_decorrelation_m" else getattr(result.fit, k)
                if e is not None:
                    fitted[k] += 1
                    held[k] += e.covers(getattr(TRUTH, k))
        cells = [f"{held[k] / fitted[k]:.2f} of {fitted[k]}" if fitted[k] else "-" for k in KEYS]
        lines.append(f"{duration_s:>10g} {seeds:>5}" + "".join(f"{c:>28}" for c in cells))
    return "\n".join(lines)


def main(argv=None) -> None:
    ap = Parser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=3, help="logs of each kind to fit (seeds 0, 1, ...)")
    ap.add_argument("--write", metavar="FILE.csv", help="only write the received-only log of seed 0 as CSV")
    ap.add_argument(
        "--coverage",
        type=float,
        nargs="+",
        metavar="DURATION_S",
        help="instead: how often the intervals hold the truth over --seeds truncated logs of each duration",
    )
    args = ap.parse_args(argv)
    if args.seeds < 1:
        ap.error(f"--seeds {args.seeds}: at least 1")
    if args.write:
        try:
            check_out_file(Path(args.write), "--write")
        except NetsimInputError as exc:
            ap.error(str(exc))
        synth_log(0).to_csv(args.write, index=False)
        print(f"wrote {args.write}")
        return
    if args.coverage:
        print(coverage(args.seeds, tuple(args.coverage)))
        return
    print(comparison(args.seeds))


if __name__ == "__main__":
    main()
