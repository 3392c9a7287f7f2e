"""Connected coverage against the number of robots and the force law.

A sweep (``netsim.sweep``) of ``world.n_robots`` x ``coverage.law``: every run starts from
a dense random static deployment in the middle of the area (``world.placement =
"centre"``, as the paper's Fig. 6), forms groups, then lets the leaders spread by virtual
forces. Writes to ``--out``:

- ``coverage_vs_n.csv``: per point, the mean, standard deviation and 95 % confidence
  interval over replications of: the final covered fraction (disks around leaders, and
  around all robots), the fraction of runs connected at the start and at the end, whether
  connectivity was kept (never more components during control than at the start), the
  median nearest-leader spacing over ``sqrt(3) r_c``, the mean distance travelled per
  robot, and two references for the ``L`` leaders of each run: the hexagonal bound
  ``L (3 sqrt(3) / 2) r^2 / A``, what ``L`` disks cover as cells of Kershner's optimal
  hexagonal covering of the plane (a finite team's outer disks cover a little more), and
  ``L pi r^2 / A``, disks that do not overlap at all (a true upper bound);
- ``coverage_vs_n.png``: those against N, one line per law.

Killed, it resumes where it stopped: finished runs are kept in ``--out/sweep``.

    python experiments/coverage_vs_n.py
    python experiments/coverage_vs_n.py --n 20 40 80 160 --reps 10 --workers 2
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from netsim import sweep as sweepmod  # noqa: E402

METRICS = {
    "covered_fraction_leaders_final": "covered fraction (disks around leaders)",
    "covered_fraction_all_final": "covered fraction (disks around all robots)",
    "connected_final": "fraction of runs connected at the end",
    "connectivity_kept": "fraction of runs that kept connectivity",
    "distance_mean_m": "distance travelled per robot (m)",
}
EXTRA = [
    "connected_start",
    "components_max_during_control",
    "spacing_median_ratio_final",
    "hex_bound",
    "disjoint_bound",
    "leaders_final",
]


def plot(agg, path: Path, title: str) -> None:
    fig, axes = plt.subplots(1, len(METRICS), figsize=(4.3 * len(METRICS), 3.8), constrained_layout=True)
    for ax, (metric, label) in zip(axes, METRICS.items()):
        for law, g in agg.groupby("coverage.law"):
            g = g.sort_values("world.n_robots")
            low, high = g[f"{metric}_ci_low"], g[f"{metric}_ci_high"]
            if metric in ("connected_final", "connectivity_kept"):
                low, high = low.clip(0, 1), high.clip(0, 1)
            err = [g[f"{metric}_mean"] - low, high - g[f"{metric}_mean"]]
            ax.errorbar(g["world.n_robots"], g[f"{metric}_mean"], yerr=err, marker="o", capsize=3, label=law)
        ref = agg.groupby("world.n_robots")[["hex_bound_mean", "disjoint_bound_mean", "connected_start_mean"]].mean()
        if metric == "covered_fraction_leaders_final":
            ax.plot(ref.index, ref["hex_bound_mean"], ls=":", color="k", lw=1, label="hexagonal bound")
            ax.plot(ref.index, ref["disjoint_bound_mean"], ls="--", color="0.5", lw=1, label="disjoint disks")
        if metric == "connected_final":
            ax.plot(ref.index, ref["connected_start_mean"], ls=":", color="k", lw=1, label="connected at start")
            ax.legend(fontsize=8)
        ax.set_xlabel("robots N")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.suptitle(title)
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--n", type=int, nargs="+", default=[20, 40, 80, 120], help="numbers of robots")
    p.add_argument("--laws", nargs="+", default=["spring", "repulsion", "inverse_square"])
    p.add_argument("--side", type=float, default=1000.0, help="side of the area, m")
    p.add_argument("--start-side", type=float, default=300.0, help="side of the central start square, m")
    p.add_argument("--range", type=float, default=100.0, help="communication range r_c, m")
    p.add_argument("--duration", type=float, default=300.0, help="simulated seconds per run")
    p.add_argument("--knowledge", default="acks", choices=["acks", "global"])
    sweepmod.add_runner_arguments(p, "coverage_vs_n", reps=3)
    args = p.parse_args(argv)
    sweep = sweepmod.parse(
        {
            "name": "coverage_vs_n",
            "replications": args.reps,
            "base": {
                "seed": args.seed,
                "duration_s": args.duration,
                "world": {"side_m": args.side, "placement": "centre", "centre_side_m": args.start_side},
                "mobility": {"model": "static"},
                "channel": {"range_m": args.range},
                "protocol": {"model": "clustering", "message_rate_hz": 0.0},
                "coverage": {"enabled": True, "knowledge": args.knowledge},
                "output": {"position_interval_s": 0.0},
            },
            "grid": {"world.n_robots": args.n, "coverage.law": args.laws},
        }
    )
    out = Path(args.out)
    report = sweepmod.run_sweep(sweep, out / "sweep", workers=args.workers, scheduler=args.scheduler)
    print(report.text())
    runs = sweepmod.load(out / "sweep")
    runs["connected_final"] = runs["connected_final"].astype(float)
    runs["connected_start"] = (runs["components_start"] == 1).astype(float)
    runs["connectivity_kept"] = (runs["components_max_during_control"] <= runs["components_start"]).astype(float)
    area = args.side**2
    runs["hex_bound"] = (runs["leaders_final"] * 1.5 * math.sqrt(3) * args.range**2 / area).clip(upper=1.0)
    runs["disjoint_bound"] = (runs["leaders_final"] * math.pi * args.range**2 / area).clip(upper=1.0)
    agg = sweepmod.aggregate(runs, ["coverage.law", "world.n_robots"], list(METRICS) + EXTRA)
    agg.to_csv(out / "coverage_vs_n.csv", index=False)
    plot(
        agg,
        out / "coverage_vs_n.png",
        f"range {args.range:g} m, {args.side:g} m square, start in the central {args.start_side:g} m, "
        f"{args.knowledge} knowledge, {args.reps} replications, 95 % CI",
    )
    print(f"wrote {out / 'coverage_vs_n.csv'} and {out / 'coverage_vs_n.png'}")


if __name__ == "__main__":
    main()
