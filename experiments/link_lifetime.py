"""Link lifetime against speed and pause, with censoring handled (Kaplan-Meier).

Two sweeps on ``netsim.tools.sweep``:

- random waypoint, maximum speed x pause (speeds uniform on ``[spread v, v]``): mean
  (restricted) and median link lifetime with 95 % confidence intervals;
- random direction on a torus at constant speed, where the closed form of docs/validation.md
  item 6, ``pi^2 R / (8 v)``, applies and is drawn as the theory line.

Writes ``link_lifetime.csv`` (one row per model, speed and pause) and
``link_lifetime.png`` (left: survival curves at each speed, no pause; right: mean
lifetime against speed, with the theory line).

    python experiments/link_lifetime.py
    python experiments/link_lifetime.py --speeds 1 2 5 10 --pauses 0 20 --reps 3
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pandas as pd

from netsim.tools import analysis
from netsim.tools import sweep as sweepmod
from netsim.tools.args import Parser
from netsim.tools.figures import pyplot


def sweep_of(name, base, grid, reps):
    return sweepmod.parse({"name": name, "replications": reps, "tables": ["links"], "base": base, "grid": grid})


def run(sweep, out, args):
    print(sweepmod.run_sweep(sweep, out / sweep.name, workers=args.workers, scheduler=args.scheduler).text())
    return sweepmod.load(out / sweep.name), sweepmod.load_table(out / sweep.name, "links")


def main(argv=None) -> None:
    p = Parser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--n", type=int, default=100)
    p.add_argument("--side", type=float, default=1000.0)
    p.add_argument("--range", type=float, default=100.0)
    p.add_argument("--duration", type=float, default=600.0)
    p.add_argument("--speeds", type=float, nargs="+", default=[1.0, 2.0, 5.0, 10.0])
    p.add_argument("--pauses", type=float, nargs="+", default=[0.0, 30.0])
    p.add_argument("--spread", type=float, default=0.5, help="random waypoint speeds uniform on [spread v, v]")
    sweepmod.add_runner_arguments(p, "link_lifetime", reps=2)
    args = p.parse_args(argv)
    # A value given twice is one point, run once (each added its rows to the table again).
    args.speeds, args.pauses = (list(dict.fromkeys(v)) for v in (args.speeds, args.pauses))
    out = Path(args.out)
    common = {
        "seed": args.seed,
        "duration_s": args.duration,
        "channel": {"range_m": args.range},
        "protocol": {"model": "none"},
        "output": {"position_interval_s": 0.0},
    }
    sweeps = {}
    for v in args.speeds:
        base = {
            **common,
            "world": {"n_robots": args.n, "side_m": args.side},
            "mobility": {"speed_min_mps": args.spread * v, "speed_max_mps": v},
        }
        torus = {
            **common,
            "world": {"n_robots": args.n, "side_m": args.side, "torus": True},
            "mobility": {"model": "random_direction", "speed_min_mps": v, "speed_max_mps": v},
        }
        sweeps[v] = (
            sweep_of(f"rwp_v{v:g}", base, {"mobility.pause_s": args.pauses}, args.reps),
            sweep_of(f"torus_v{v:g}", torus, {"mobility.pause_s": [0.0]}, args.reps),
        )
    # Every point of every sweep checked before the first run: a bad one met later left the
    # sweeps before it written.
    for sweep in (sweep for pair in sweeps.values() for sweep in pair):
        sweep.runs(here=args.scheduler is None)
    rows, curves = [], {}
    for v, (rwp, on_torus) in sweeps.items():
        runs, links = run(rwp, out, args)
        for pause, g in analysis.compare_lifetimes(runs, links, ["mobility.pause_s"]).groupby("mobility.pause_s"):
            rows.append({"model": "random_waypoint", "speed_mps": v, "pause_s": pause, **g.iloc[0].to_dict()})
        chosen = runs[runs["mobility.pause_s"] == args.pauses[0]].run_id
        ld = analysis.link_durations(links[links.run_id.isin(chosen)])
        curves[v] = analysis.kaplan_meier(ld.duration_s, ld.observed)
        runs, links = run(on_torus, out, args)
        summary = analysis.compare_lifetimes(runs, links, ["mobility.pause_s"]).iloc[0].to_dict()
        rows.append(
            {
                "model": "random_direction_torus",
                "speed_mps": v,
                "pause_s": 0.0,
                **summary,
                "theory_mean_s": analysis.torus_link_duration_mean(args.range, v),
            }
        )
    df = pd.DataFrame(rows).drop(columns=["mobility.pause_s"])
    df.to_csv(out / "link_lifetime.csv", index=False)

    plt = pyplot()
    fig, (left, right) = plt.subplots(1, 2, figsize=(10, 4), constrained_layout=True)
    for v, km in curves.items():
        left.step(km.t_s, km.survival, where="post", label=f"v_max {v:g} m/s")
        left.fill_between(km.t_s, km.ci_low, km.ci_high, step="post", alpha=0.2)
    left.set(
        xlabel="link lifetime (s)",
        ylabel="survival P(T > t)",
        title=f"random waypoint, pause {args.pauses[0]:g} s (Kaplan-Meier, 95 % CI)",
    )
    # A short or sparse run may see no link end: its curves are empty, and a log axis of
    # nothing cannot be drawn.
    if any((km.t_s > 0).any() for km in curves.values()):
        left.set_xscale("log")
        left.legend()
    else:
        left.text(0.5, 0.5, "no link ended within the runs", ha="center", transform=left.transAxes)
    for (model, pause), g in df.groupby(["model", "pause_s"]):
        err = [g.mean_s - g.mean_ci_low_s, g.mean_ci_high_s - g.mean_s]
        right.errorbar(g.speed_mps, g.mean_s, yerr=err, marker="o", capsize=3, label=f"{model}, pause {pause:g} s")
    vs = np.linspace(min(args.speeds), max(args.speeds), 100)
    right.plot(
        vs, [analysis.torus_link_duration_mean(args.range, v) for v in vs], "k--", label="theory, torus: pi^2 R / (8 v)"
    )
    right.set(
        xlabel="speed (m/s)",
        ylabel="mean link lifetime, restricted to the run (s)",
        xscale="log",
        yscale="log" if (df.mean_s > 0).any() else "linear",
        title=f"{args.n} robots, range {args.range:g} m",
    )
    right.legend(fontsize=8)
    fig.savefig(out / "link_lifetime.png", dpi=120)
    print(df[["model", "speed_mps", "pause_s", "links", "mean_s", "median_s"]].round(2).to_string(index=False))
    print(f"wrote {out / 'link_lifetime.csv'} and {out / 'link_lifetime.png'}")


if __name__ == "__main__":
    sweepmod.run_script(main, resumable=True)
