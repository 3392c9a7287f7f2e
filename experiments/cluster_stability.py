"""Cluster stability against speed and pause: how many leaders, how often roles change,
how long a leader lasts.

For a fixed number of robots and range, sweep ``mobility.speed_max_mps`` and
``mobility.pause_s`` with replications (same seed, advancing run number), and write

- ``cluster_stability.csv``: one row per run, every parameter, the seed, the replication
  and the metrics (long format, ready for pandas);
- ``cluster_stability.png``: each metric's mean against the maximum speed, one line per
  pause, with 95 % confidence intervals (Student t over replications).

    python experiments/cluster_stability.py                    # defaults below
    python experiments/cluster_stability.py --reps 10 --workers 2 --speeds 1 5 10 20
"""

from __future__ import annotations

import argparse
import os
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from scipy import stats  # noqa: E402
from tqdm.auto import tqdm  # noqa: E402

from netsim.config import from_dict  # noqa: E402
from netsim.run import execute  # noqa: E402

METRICS = {
    "leaders_time_mean": "leaders (time-weighted mean)",
    "role_changes_per_robot_per_min": "role changes per robot per minute",
    "mean_leader_tenure_s": "mean leader tenure (s)",
}


def one_run(job: dict) -> dict:
    tree = {
        "seed": job["seed"],
        "duration_s": job["duration_s"],
        "world": {"n_robots": job["n_robots"], "side_m": job["side_m"]},
        "mobility": {
            "speed_min_mps": job["speed_min_mps"],
            "speed_max_mps": job["speed_max_mps"],
            "pause_s": job["pause_s"],
        },
        "channel": {"range_m": job["range_m"]},
        "protocol": {"model": "clustering"},
        "output": {"position_interval_s": 0.0},
    }
    result = execute(from_dict(tree), run=job["rep"])
    return {**job, **{k: result.summary.get(k) for k in METRICS}, "wall_s": result.wall_s}


def confidence_interval(values: pd.Series, level: float = 0.95) -> float:
    """Half-width of the Student-t confidence interval of the mean."""
    v = values.dropna().to_numpy(float)
    if len(v) < 2:
        return float("nan")
    return float(stats.t.ppf(0.5 + level / 2, len(v) - 1) * v.std(ddof=1) / np.sqrt(len(v)))


def summarize(df: pd.DataFrame) -> pd.DataFrame:
    rows = []
    for (pause, speed), g in df.groupby(["pause_s", "speed_max_mps"]):
        row = {"pause_s": pause, "speed_max_mps": speed, "reps": len(g)}
        for m in METRICS:
            row[m] = g[m].mean()
            row[m + "_ci95"] = confidence_interval(g[m])
        rows.append(row)
    return pd.DataFrame(rows)


def plot(summary: pd.DataFrame, path: Path, title: str) -> None:
    fig, axes = plt.subplots(1, len(METRICS), figsize=(4.2 * len(METRICS), 3.6), constrained_layout=True)
    for ax, (metric, label) in zip(axes, METRICS.items()):
        for pause, g in summary.groupby("pause_s"):
            g = g.sort_values("speed_max_mps")
            ax.errorbar(
                g["speed_max_mps"],
                g[metric],
                yerr=g[metric + "_ci95"],
                marker="o",
                capsize=3,
                label=f"pause {pause:g} s",
            )
        ax.set_xlabel("maximum speed (m/s)")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[0].legend()
    fig.suptitle(title)
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--n", type=int, default=50, help="robots")
    p.add_argument("--side", type=float, default=1000.0, help="side of the area, m")
    p.add_argument("--range", type=float, default=150.0, help="communication range, m")
    p.add_argument("--duration", type=float, default=300.0, help="simulated seconds per run")
    p.add_argument("--speed-min", type=float, default=0.5)
    p.add_argument("--speeds", type=float, nargs="+", default=[1.0, 2.5, 5.0, 10.0, 20.0], help="speed_max values")
    p.add_argument("--pauses", type=float, nargs="+", default=[0.0, 30.0])
    p.add_argument("--reps", type=int, default=5, help="replications per point")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    p.add_argument("--out", default="experiments-out", help="output directory")
    args = p.parse_args(argv)
    if any(v < args.speed_min for v in args.speeds):
        p.error("every --speeds value must be at least --speed-min")

    jobs = [
        {
            "n_robots": args.n,
            "side_m": args.side,
            "range_m": args.range,
            "duration_s": args.duration,
            "speed_min_mps": args.speed_min,
            "speed_max_mps": v,
            "pause_s": pause,
            "seed": args.seed,
            "rep": rep,
        }
        for v in args.speeds
        for pause in args.pauses
        for rep in range(args.reps)
    ]
    with ProcessPoolExecutor(max_workers=args.workers) as pool:
        rows = list(tqdm(pool.map(one_run, jobs), total=len(jobs), unit="run", desc="cluster stability"))
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    df = pd.DataFrame(rows)
    df.to_csv(out / "cluster_stability.csv", index=False)
    summary = summarize(df)
    title = f"{args.n} robots, range {args.range:g} m, {args.side:g} m square, {args.reps} replications"
    plot(summary, out / "cluster_stability.png", title)
    print(summary.round(3).to_string(index=False))
    print(f"wrote {out / 'cluster_stability.csv'} and {out / 'cluster_stability.png'}")


if __name__ == "__main__":
    main()
