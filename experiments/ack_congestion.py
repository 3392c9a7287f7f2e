"""The Ack flood on a shared medium: what the clustering protocol pays when the channel fills.

Static robots, uniform on a torus (no border), range 100 m, the square's side chosen for
``D`` robots in range on average (``N pi R^2 / side^2 = D``). The clustering protocol with
its message traffic (``--message-rate`` messages per second, network-wide) runs on each
medium, ``channel.mac`` = none, aloha, csma (802.11 DCF), for every Ack period ``t``
(jitter ``0.05 t``, ``tau = 3 t``) and density ``D``, with replications.

The robots stand still: once the groups have formed (``--warmup`` seconds) every role
change is spurious, caused by Acks that did not arrive. Per point: the Ack delivery ratio,
spurious role changes per robot per minute, the time-mean number of leaders, the message
delivery ratio, the channel utilisation and collision ratio, and the offered Ack load
``G = (D + 1) T / t`` (``T``: an Ack's airtime), the share of time the Acks of a robot and
its neighbours would occupy the medium, and the carried Ack load ``G x`` the Ack delivery
ratio. The channel saturates where the carried load stops growing with the offered load:
for each medium, the points at or beyond the offered load of its largest carried load are
marked ``saturated`` (dashed line in the figure), unless that largest load is the grid's
last point (the carried load still rises there). Queue overflows are counted too
(``frames_dropped_queue_full``): broadcast frames, never retried, rarely overflow CSMA's
queues; they collide instead.

Writes ``ack_congestion.csv`` and ``ack_congestion.png``.

    python experiments/ack_congestion.py
    python experiments/ack_congestion.py --densities 10 30 --periods 1 0.1 --reps 3
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np
import pandas as pd
from netsim.protocols.ack import AckParams

from netsim.errors import NetsimInputError
from netsim.radio.mac import airtime_s
from netsim.radio.mac_models import CsmaParams
from netsim.tools import sweep as sweepmod
from netsim.tools.args import Parser
from netsim.tools.figures import pyplot

RANGE_M = 100.0
MACS = ("none", "aloha", "csma")
METRICS = {
    "ack_delivery_ratio": "Ack delivery ratio",
    "spurious_role_changes_per_robot_per_min": "spurious role changes / robot / min",
    "leaders_time_mean": "leaders (time mean)",
    "message_delivery_ratio": "message delivery ratio",
}


def side_for(n: int, density: float) -> float:
    return RANGE_M * math.sqrt(n * math.pi / density)


def spurious_changes(roles: pd.DataFrame, run_ids, n: int, warmup_s: float, duration_s: float) -> pd.Series:
    """Role changes after the warm-up per robot per minute, for each run."""
    late = roles[roles.t_s >= warmup_s]
    counts = late.groupby("run_id").size().reindex(run_ids, fill_value=0)
    return counts / (n * (duration_s - warmup_s) / 60.0)


def knees(df: pd.DataFrame) -> dict[str, float]:
    """Each medium's knee: the offered load at which the carried load peaks, where it falls
    past it within the grid; ``inf`` where it still rises at the grid's last point (or the
    grid has one point): no point is saturated then."""
    out = {}
    for mac, g in df.sort_values("offered_ack_load").groupby("mac"):
        top = int(np.argmax(g.carried_ack_load.to_numpy()))
        out[mac] = float(g.offered_ack_load.iloc[top]) if top < len(g) - 1 else math.inf
    return out


def main(argv=None) -> None:
    p = Parser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--n", type=int, default=80, help="robots")
    p.add_argument("--densities", type=float, nargs="+", default=[10.0, 25.0, 50.0], help="robots in range D")
    p.add_argument("--periods", type=float, nargs="+", default=[1.0, 0.25, 0.1, 0.05, 0.025], help="Ack periods t, s")
    p.add_argument("--macs", nargs="+", default=list(MACS), choices=MACS)
    p.add_argument("--duration", type=float, default=40.0)
    p.add_argument("--warmup", type=float, default=10.0, help="s before role changes count as spurious")
    p.add_argument("--message-rate", type=float, default=2.0, help="messages per second, network-wide")
    sweepmod.add_runner_arguments(p, "ack_congestion", reps=2)
    args = p.parse_args(argv)
    for density in args.densities:
        if not (density > 0 and math.isfinite(density)):
            raise NetsimInputError(f"--densities {density:g}: each must be > 0 (robots in range)")
    if max(args.densities) >= args.n * math.pi / 4:
        raise NetsimInputError(f"--densities must stay below n pi / 4 = {args.n * math.pi / 4:g}")
    if not 0 <= args.warmup < args.duration:
        raise NetsimInputError(f"--warmup {args.warmup:g}: must be at least 0 and shorter than --duration")
    # A value given twice is one point, run once (each would add the same runs again).
    args.densities, args.periods, args.macs = (
        list(dict.fromkeys(v)) for v in (args.densities, args.periods, args.macs)
    )
    sweeps = {}
    for period in args.periods:
        name = f"period_{period:g}"
        sweeps[name] = (
            period,
            sweepmod.parse(
                {
                    "name": f"ack_congestion_{name}",
                    "replications": args.reps,
                    "tables": ["roles"],
                    "base": {
                        "seed": args.seed,
                        "duration_s": args.duration,
                        "world": {"n_robots": args.n, "torus": True},
                        "mobility": {"model": "static"},
                        "channel": {"range_m": RANGE_M},
                        "protocol": {
                            "model": "clustering",
                            "ack_period_s": period,
                            "ack_jitter_s": 0.05 * period,
                            "message_rate_hz": args.message_rate,
                        },
                        "output": {"position_interval_s": 0.0},
                    },
                    "grid": {
                        "channel.mac": list(args.macs),
                        "world.side_m": [side_for(args.n, d) for d in args.densities],
                    },
                }
            ),
        )
    # Every point of every period checked before the first run: a bad one met later left the
    # periods before it written.
    for _, sweep in sweeps.values():
        sweep.runs(here=args.scheduler is None)
    scheduler = sweepmod.connect(args.scheduler) if args.scheduler else None
    out = Path(args.out)
    frames, roles = [], []
    for name, (period, sweep) in sweeps.items():
        print(sweepmod.run_sweep(sweep, out / name, workers=args.workers, scheduler=scheduler).text())
        runs = sweepmod.load(out / name)
        runs["ack_period_s"] = period
        frames.append(runs)
        roles.append(sweepmod.load_table(out / name, "roles"))
    runs = pd.concat(frames, ignore_index=True)
    role_rows = pd.concat(roles, ignore_index=True)
    runs["robots_in_range"] = args.n * math.pi * RANGE_M**2 / runs["world.side_m"] ** 2
    runs["spurious_role_changes_per_robot_per_min"] = spurious_changes(
        role_rows, runs.run_id, args.n, args.warmup, args.duration
    ).to_numpy()
    # The air's defaults, which every medium of the sweep shares.
    channel = CsmaParams()
    ack_airtime = airtime_s(AckParams().ack_bytes, channel.data_rate_bps, channel.preamble_s)
    rows = []
    for (mac, period, _side), g in runs.groupby(["channel.mac", "ack_period_s", "world.side_m"]):
        density = float(g.robots_in_range.iloc[0])
        row = {
            "mac": mac,
            "ack_period_s": period,
            "robots_in_range": round(density, 3),
            "offered_ack_load": (density + 1) * ack_airtime / period,
            "replications": len(g),
        }
        for col in [*METRICS, "channel_utilisation", "collision_ratio", "frames_dropped_queue_full"]:
            values = g[col].astype(float) if col in g else pd.Series([np.nan] * len(g))
            row[col] = values.mean()
            if col in METRICS:
                # Student's t with n - 1 degrees of freedom: a few replications need it.
                mean, _sd, _low, high = sweepmod.t_interval(values.dropna())
                row[col + "_ci95"] = high - mean
        rows.append(row)
    df = pd.DataFrame(rows).sort_values(["mac", "offered_ack_load"]).reset_index(drop=True)
    df["carried_ack_load"] = df.offered_ack_load * df.ack_delivery_ratio
    knee = knees(df)
    df["saturated"] = [mac != "none" and load >= knee[mac] for mac, load in zip(df.mac, df.offered_ack_load)]
    df.to_csv(out / "ack_congestion.csv", index=False)

    panels = {**METRICS, "carried_ack_load": "carried Ack load G x delivery ratio"}
    plt = pyplot()
    fig, axes = plt.subplots(2, 3, figsize=(15, 8), constrained_layout=True)
    # One colour per medium, one marker per density: along a line only the Ack period changes.
    colours = {mac: f"C{k}" for k, mac in enumerate(MACS)}
    markers = dict(zip(sorted(df.robots_in_range.unique()), "osD^v<>p"))
    panels["channel_utilisation"] = "channel utilisation"
    for ax, (metric, label) in zip(axes.flat, panels.items()):
        for (mac, density), g in df.groupby(["mac", "robots_in_range"]):
            if metric == "channel_utilisation" and mac == "none":
                continue
            yerr = g[metric + "_ci95"] if metric + "_ci95" in g else None
            ax.errorbar(
                g.offered_ack_load,
                g[metric],
                yerr=yerr,
                fmt=markers[density] + "-",
                color=colours[mac],
                capsize=3,
                alpha=0.8,
                label=f"{mac}, D = {density:g}",
            )
        for mac in knee:
            if df[df.mac == mac].saturated.any():
                ax.axvline(knee[mac], color=colours[mac], ls="--", lw=1)
        ax.set(xscale="log", xlabel="offered Ack load G = (D + 1) T / t", ylabel=label)
    axes.flat[0].legend(fontsize="small", ncol=2)
    fig.suptitle(
        f"{args.n} static robots, D = {', '.join(f'{d:g}' for d in args.densities)} in range, "
        f"t = {', '.join(f'{t:g}' for t in args.periods)} s; dashed: saturation (largest carried load)"
    )
    fig.savefig(out / "ack_congestion.png", dpi=120)
    print(df.drop(columns=[c for c in df if c.endswith("_ci95")]).round(3).to_string(index=False))
    print(f"wrote {out / 'ack_congestion.csv'} and {out / 'ack_congestion.png'}")


if __name__ == "__main__":
    sweepmod.run_script(main, resumable=True)
