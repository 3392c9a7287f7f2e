"""Connected coverage against the number of robots and the force law.

A sweep (``netsim.tools.sweep``) of ``world.n_robots`` x ``coverage.law``: every run starts from
a dense random static deployment in the middle of the area (``world.placement =
"centre"``, a square of side ``start_spacing x sqrt(N)``, so that the start is equally
dense, about 20 neighbours per robot, at every N), forms groups, then spreads by virtual
forces (``coverage.members``, ``"spread"`` by default) until the stopping rule ends
control. The area is large enough that a connected team cannot cover it all: the bound
``U(N) = r^2 (pi + 1.9132 (N - 1))`` (docs/validation.md item 16) stays below ``A``. Writes to
``--out``:

- ``coverage_vs_n.csv``: per point, the mean, standard deviation and 95 % confidence
  interval over replications of: the final covered fraction of the area (all robots'
  disks, exact), the same as a fraction of ``min(1, U(N) / A)``, the leaders' covered
  fraction, the fraction of runs connected at the end and of runs that kept their
  connectivity (never more components during control than at the start), the settling
  time (from the start of control to when the stopping rule ended it; ``settled`` is the
  fraction of runs where it did), the mean and largest distance travelled per robot, and
  the number of leaders at the end;
- ``coverage_vs_n.png``: those against N, one line per law, with the bound ``U(N) / A``
  and the 60 % target drawn.

Killed, it resumes where it stopped: finished runs are kept in ``--out/sweep``.

    python experiments/coverage_vs_n.py --workers 2
    python experiments/coverage_vs_n.py --n 20 80 200 --laws spring --reps 5 --members follow
"""

from __future__ import annotations

import argparse
import dataclasses
import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from netsim import metrics  # noqa: E402
from netsim.tools import sweep as sweepmod  # noqa: E402

METRICS = [
    "covered_fraction_all_final",
    "covered_of_bound_all_final",
    "covered_fraction_leaders_final",
    "connected_final",
    "connectivity_kept",
    "settling_s",
    "settled",
    "distance_mean_m",
    "distance_max_m",
    "leaders_final",
]
PANELS = {
    "covered_fraction_all_final": "covered fraction of the area (all robots' disks)",
    "covered_of_bound_all_final": "covered fraction of min(1, U(N) / A)",
    "settling_s": "settling time after control starts (s)",
    "distance_mean_m": "distance travelled per robot (m)",
    "connectivity_kept": "fraction of runs that kept connectivity",
}


def plot(agg, path: Path, side_m: float, range_m: float, title: str) -> None:
    fig, axes = plt.subplots(1, len(PANELS), figsize=(4.4 * len(PANELS), 4.0), constrained_layout=True)
    ns = np.arange(int(agg["world.n_robots"].min()), int(agg["world.n_robots"].max()) + 1)
    bound = np.array([metrics.bound_fraction(int(n), range_m, side_m) for n in ns])
    for ax, (metric, label) in zip(axes, PANELS.items()):
        for law, g in agg.groupby("coverage.law"):
            g = g.sort_values("world.n_robots")
            mean = g[f"{metric}_mean"]
            low, high = g[f"{metric}_ci_low"].fillna(mean), g[f"{metric}_ci_high"].fillna(mean)
            if metric == "connectivity_kept":
                low, high = low.clip(0, 1), high.clip(0, 1)
            ax.errorbar(g["world.n_robots"], mean, yerr=[mean - low, high - mean], marker="o", capsize=3, label=law)
        if metric == "covered_fraction_all_final":
            ax.plot(ns, bound, color="k", lw=1, label="bound min(1, U(N)/A)")
            ax.plot(ns, 0.6 * bound, color="k", lw=1, ls=":", label="60 % of the bound")
        if metric == "covered_of_bound_all_final":
            ax.axhline(1.0, color="k", lw=1, label="bound")
            ax.axhline(0.6, color="k", lw=1, ls=":", label="60 %")
            ax.set_ylim(0, 1.05)
        ax.set_xlabel("robots N")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle(title)
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--n", type=int, nargs="+", default=[20, 40, 80, 120, 160, 200], help="numbers of robots")
    p.add_argument("--laws", nargs="+", default=["spring", "repulsion", "inverse_square"])
    p.add_argument("--side", type=float, default=2500.0, help="side of the area, m")
    p.add_argument("--start-spacing", type=float, default=40.0, help="the start square's side is this x sqrt(N), m")
    p.add_argument("--range", type=float, default=100.0, help="communication range r_c, m")
    p.add_argument("--duration", type=float, default=900.0, help="simulated seconds per run")
    p.add_argument("--knowledge", default="acks", choices=["acks", "global"])
    p.add_argument("--members", default="spread", choices=["spread", "follow"])
    sweepmod.add_runner_arguments(p, "coverage_vs_n", reps=3)
    args = p.parse_args(argv)
    base = {
        "seed": args.seed,
        "duration_s": args.duration,
        "world": {"side_m": args.side, "placement": "centre"},
        "mobility": {"model": "static"},
        "channel": {"range_m": args.range},
        "protocol": {"model": "clustering", "message_rate_hz": 0.0},
        "coverage": {"enabled": True, "knowledge": args.knowledge, "members": args.members},
        "output": {"position_interval_s": 0.0},
    }
    points = tuple(
        {
            "world.n_robots": n,
            "world.centre_side_m": min(args.side, round(args.start_spacing * math.sqrt(n), 3)),
            "coverage.law": law,
        }
        for n in args.n
        for law in args.laws
    )
    sweep = sweepmod.parse(
        {"name": "coverage_vs_n", "replications": args.reps, "base": base, "grid": {"coverage.law": args.laws}}
    )
    sweep = dataclasses.replace(sweep, points=points)
    out = Path(args.out)
    report = sweepmod.run_sweep(sweep, out / "sweep", workers=args.workers, scheduler=args.scheduler)
    print(report.text())
    runs = sweepmod.load(out / "sweep")
    runs["connected_final"] = runs["connected_final"].astype(float)
    runs["connectivity_kept"] = (runs["components_max_during_control"] <= runs["components_start"]).astype(float)
    runs["settling_s"] = runs["control_settled_s"].astype(float) - runs["coverage.start_s"]
    runs["settled"] = runs["settling_s"].notna().astype(float)
    agg = sweepmod.aggregate(runs, ["coverage.law", "world.n_robots"], METRICS)
    agg.insert(2, "bound", [metrics.bound_fraction(int(n), args.range, args.side) for n in agg["world.n_robots"]])
    agg.to_csv(out / "coverage_vs_n.csv", index=False)
    plot(
        agg,
        out / "coverage_vs_n.png",
        args.side,
        args.range,
        f"members {args.members}, range {args.range:g} m, {args.side:g} m square, dense start "
        f"({args.start_spacing:g} m x sqrt(N)), {args.knowledge} knowledge, {args.reps} replications, 95 % CI",
    )
    show = ["coverage.law", "world.n_robots", "bound", "covered_fraction_all_final_mean"]
    show += ["covered_of_bound_all_final_mean", "settling_s_mean", "settled_mean", "distance_mean_m_mean"]
    show += ["connectivity_kept_mean"]
    print(agg[show].to_string(index=False, float_format=lambda x: f"{x:.3g}"))
    print(f"wrote {out / 'coverage_vs_n.csv'} and {out / 'coverage_vs_n.png'}")


if __name__ == "__main__":
    sweepmod.run_script(main)
