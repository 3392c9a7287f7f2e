"""Routing compared: delivery, latency and control overhead against speed, for the
clustering's backbone flooding and oracle shortest paths, and the aodv, olsr and greedy
protocols (docs/routing.md).

A random-waypoint team; ``--flows`` flows between fixed pairs (robot k to robot n-1-k) of
``--packet-bytes`` every ``--interval`` s from ``--warmup`` s (after the protocols have
settled) to the end. Per protocol and maximum speed, over ``--reps`` replications: the
packets' delivery ratio, their median latency, their paths' stretch (a delivered packet's
hops over the shortest path's between its ends when it was sent, packets.parquet's
``hops / shortest_hops``, averaged over the packets that had a path then), and control
frames per robot per second (the clustering's Acks for backbone and oracle, which the
backbone needs and the oracle does not: for it, none), each with a 95 % confidence
interval (Student's t over the replications).

Writes ``routing_compare.csv`` (one row per protocol and speed) and
``routing_compare.png`` (the four figures against speed).

    python experiments/routing_compare.py
    python experiments/routing_compare.py --speeds 1 5 10 --reps 5 --n 30
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np
import pandas as pd
from netsim.protocols.flows import packet_delivery

from netsim.errors import NetsimInputError
from netsim.tools import sweep as sweepmod
from netsim.tools.args import Parser
from netsim.tools.figures import pyplot

PROTOCOLS = {
    "backbone": {"model": "clustering", "routing": "backbone", "message_rate_hz": 0.0},
    "oracle": {"model": "clustering", "routing": "oracle", "message_rate_hz": 0.0},
    "aodv": {"model": "aodv"},
    "olsr": {"model": "olsr"},
    "greedy": {"model": "greedy"},
}


def ci95(values, within: tuple[float, float] = (-np.inf, np.inf)) -> tuple[float, float, float]:
    """Mean and the ends of a 95 % Student's t interval (NaN with one value), cut to
    ``within``, where the mean must lie (a ratio's [0, 1]): a few replications give the t
    interval ends a ratio cannot have, and cutting them off keeps its coverage."""
    mean, _sd, low, high = sweepmod.t_interval([x for x in values if np.isfinite(x)])
    # max and min keep a NaN given first
    return mean, max(low, float(within[0])), min(high, float(within[1]))


def per_run(runs: pd.DataFrame, packets: pd.DataFrame, control: pd.DataFrame | None, n: int, duration_s: float):
    """Per run: delivery ratio, median latency of the delivered packets, their mean path
    stretch (over those that had a path when sent), control frames per robot per second."""
    out = []
    for _, run in runs.iterrows():
        pk = packets[packets.run_id == run.run_id]
        got = pk[pk["delivered"]]
        # The run's summary figures of its packets (netsim.protocols.flows.packet_delivery).
        figures = packet_delivery({"packets": pk})
        if control is not None:
            frames = float(control[control.run_id == run.run_id]["sent"].sum())
        else:
            frames = float(run.get("acks_sent", 0.0)) if run["protocol.routing"] == "backbone" else 0.0
        out.append(
            {
                "speed_mps": run["mobility.speed_max_mps"],
                "delivery_ratio": figures.get("packet_delivery_ratio", np.nan),
                "latency_p50_s": float(got["latency_s"].median()) if len(got) else np.nan,
                "stretch": figures.get("packet_path_stretch", np.nan),
                "control_per_robot_per_s": frames / (n * duration_s),
            }
        )
    return pd.DataFrame(out)


def main(argv=None) -> None:
    p = Parser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--n", type=int, default=40)
    p.add_argument("--side", type=float, default=600.0)
    p.add_argument("--range", type=float, default=150.0)
    p.add_argument("--duration", type=float, default=200.0)
    p.add_argument("--warmup", type=float, default=30.0, help="flows start then, s")
    p.add_argument("--speeds", type=float, nargs="+", default=[1.0, 5.0, 10.0, 20.0])
    p.add_argument("--flows", type=int, default=4)
    p.add_argument("--interval", type=float, default=1.0, help="between two packets of a flow, s")
    p.add_argument("--packet-bytes", type=int, default=512)
    p.add_argument("--protocols", nargs="+", default=list(PROTOCOLS), choices=list(PROTOCOLS))
    sweepmod.add_runner_arguments(p, "routing_compare", reps=3)
    args = p.parse_args(argv)
    if args.flows < 1:
        raise NetsimInputError(f"--flows {args.flows}: at least 1 (a run without packets measures nothing)")
    if not (args.interval > 0 and math.isfinite(args.interval)):
        raise NetsimInputError(f"--interval {args.interval:g}: must be > 0 s")
    # A value given twice is one point, run once.
    args.speeds, args.protocols = (list(dict.fromkeys(v)) for v in (args.speeds, args.protocols))
    out = Path(args.out)
    rate = args.packet_bytes * 8 / args.interval
    flows = [
        {
            "src": k,
            "dst": args.n - 1 - k,
            "start_s": args.warmup,
            "stop_s": args.duration,
            "rate_bps": rate,
            "packet_bytes": args.packet_bytes,
        }
        for k in range(args.flows)
    ]
    sweeps = {}
    for name in args.protocols:
        base = {
            "seed": args.seed,
            "duration_s": args.duration,
            "world": {"n_robots": args.n, "side_m": args.side},
            "channel": {"range_m": args.range},
            "protocol": PROTOCOLS[name],
            "traffic": {"flows": flows},
            "output": {"position_interval_s": 0.0},
        }
        tables = ["packets"] if PROTOCOLS[name]["model"] == "clustering" else ["packets", "control"]
        grid = {"mobility.speed_max_mps": args.speeds}
        sweeps[name] = sweepmod.parse(
            {"name": name, "replications": args.reps, "tables": tables, "base": base, "grid": grid}
        )
    # Every point of every protocol checked before the first run: a bad one met later left the
    # protocols before it written.
    for sweep in sweeps.values():
        sweep.runs(here=args.scheduler is None)
    rows = []
    for name, sweep in sweeps.items():
        clustering = PROTOCOLS[name]["model"] == "clustering"
        print(sweepmod.run_sweep(sweep, out / name, workers=args.workers, scheduler=args.scheduler).text())
        runs = sweepmod.load(out / name)
        if clustering:
            runs["protocol.routing"] = PROTOCOLS[name]["routing"]
        control = None if clustering else sweepmod.load_table(out / name, "control")
        figures = per_run(runs, sweepmod.load_table(out / name, "packets"), control, args.n, args.duration)
        for speed, g in figures.groupby("speed_mps"):
            row = {"protocol": name, "speed_mps": speed, "runs": len(g)}
            for col, within in (
                ("delivery_ratio", (0.0, 1.0)),
                ("latency_p50_s", (0.0, np.inf)),
                ("stretch", (0.0, np.inf)),
                ("control_per_robot_per_s", (0.0, np.inf)),
            ):
                row[col], row[f"{col}_ci_low"], row[f"{col}_ci_high"] = ci95(g[col], within)
            rows.append(row)
    table = pd.DataFrame(rows)
    out.mkdir(parents=True, exist_ok=True)
    table.to_csv(out / "routing_compare.csv", index=False)
    print(table.to_string(index=False, float_format=lambda v: f"{v:.3g}"))
    figure(table).savefig(out / "routing_compare.png", dpi=120)
    print(f"wrote {out / 'routing_compare.csv'} and {out / 'routing_compare.png'}")


def figure(table: pd.DataFrame):
    """Delivery ratio, median latency, path stretch and control frames against speed, a
    line per protocol."""
    plt = pyplot()
    fig, axes = plt.subplots(1, 4, figsize=(17, 3.8))
    for ax, col, label in zip(
        axes,
        ("delivery_ratio", "latency_p50_s", "stretch", "control_per_robot_per_s"),
        ("delivery ratio", "median latency, s", "path stretch (hops over shortest)", "control frames per robot per s"),
    ):
        for name, g in table.groupby("protocol", sort=False):
            low = (g[col] - g[f"{col}_ci_low"]).fillna(0)
            high = (g[f"{col}_ci_high"] - g[col]).fillna(0)
            ax.errorbar(g["speed_mps"], g[col], yerr=[low, high], marker="o", capsize=3, label=name)
        ax.set_xlabel("maximum speed, m/s")
        ax.set_ylabel(label)
        # The axis spans 0.9 to 1 at least for a ratio and starts at 0 for the others, and
        # each tick is its value: values alike but for their last bits (a hop's latency
        # each, summed in another order) are drawn flat, where the axis zoomed into those
        # bits and, against an offset ("1e-15+1e-3"), showed a steep fall.
        low, high = ax.get_ylim()
        if col == "delivery_ratio":
            ax.set_ylim(min(low, 0.9), 1.02)
        elif col == "stretch":
            # A path is seldom shorter than the shortest one when it was sent (only if the
            # team moved while the packet waited): the axis starts at 1 unless one is.
            ax.set_ylim(min(low, 1.0), max(high, 1.1))
        else:
            ax.set_ylim(0.0, 1.05 * high if high > 0 else 1.0)
        ax.ticklabel_format(axis="y", useOffset=False)
    axes[0].legend()
    fig.tight_layout()
    return fig


if __name__ == "__main__":
    sweepmod.run_script(main, resumable=True)
