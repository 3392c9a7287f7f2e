"""Connected coverage on the office map from a connected start, against the free-area bound:
item 2 of the map targets, measured and printed in one table.

Every run is the office scenario of ``netsim validate``'s coverage items
(:func:`netsim.tools.validate.coverage_settings`: 200 m x 200 m office, static robots that
only the coverage controller moves, range 30 m) with a start that is connected on the run's
own links: ``world.placement = "connected"`` in a square of side ``--start-side`` (60 m)
about the area's centre, inside the free region of that point. Rows: each radio (line of
sight; log-distance with 5 dB a wall, an implied range of 30 m) x each plan
(``coverage.plan = "global"`` and ``"local"``) at N = ``--n`` (40), over ``--seeds`` seeds.

Columns, over the seeds of a row: ``comp0`` the most components the real network
(``links.parquet``) had at t = 0 (1: every start connected); ``start`` and ``final`` the
mean covered fraction of the free-area bound ``min(1, U(N) / A_free)`` (``covered_of_bound_all``,
docs/model.md 5.3) at control start and at the end, ``final min`` its least; ``split`` in
how many seeds the real network ever had more components after control started than at
its start (checked at every link event); ``moved_m`` the mean distance a robot travelled;
``unsettled`` in how many seeds the stopping rule had not ended control when the run did.
A row passes when every seed ends at 0.5 of the bound or more and none split; the
command exits 1 when a row fails (as ``netsim validate`` does), 0 when every row passes.

``--csv FILE`` writes every run's row: ``radio``, ``plan``, ``N``, ``seed``, ``comp0``,
``start``, ``final``, ``split`` (True or False), ``moved_m`` and ``settled_s`` (when the
stopping rule ended control; empty when it never did). ``--figure FILE`` (``.png``,
``.svg`` or ``.pdf``) also draws, for the lowest seed of each row, the map (walls dark)
with where the robots ended (red) and the disk of ``coverage.radius_m`` each covers
(blue; darker where disks overlap, as where several robots stand on one spot), each panel
titled with its radio, plan, seed and covered fraction of the bound at the end.

    python experiments/coverage_on_map.py --workers 2
    python experiments/coverage_on_map.py --seeds 2 --radios "office, line of sight"
    python experiments/coverage_on_map.py --figure office.png
"""

from __future__ import annotations

import argparse
import sys
from contextlib import nullcontext
from pathlib import Path

import numpy as np
import pandas as pd

from netsim.errors import NetsimInputError
from netsim.tools.args import Parser
from netsim.tools.cli import FIGURE_SUFFIXES, check_out_files
from netsim.tools.interrupt import kept_if_interrupted
from netsim.tools.output import write_atomically
from netsim.tools.sweep import pooled, run_script
from netsim.tools.validate import COVERAGE_DURATION_S, COVERAGE_RADIOS, coverage_outcome, coverage_settings, cut_short

MAP_RADIOS = [r for r in COVERAGE_RADIOS if r.startswith("office")]
TARGET = 0.5


def settings(
    radio: str, plan: str, n: int, seed: int, duration_s: float, start_side_m: float, extra: tuple[str, ...] = ()
) -> list[str]:
    """The validate office scenario, started connected in the square about the centre
    (``extra``: more ``key=value`` settings)."""
    keys = coverage_settings(radio, plan, n, 0.0, seed, duration_s)
    return [*keys, "world.placement=connected", f"world.centre_side_m={start_side_m:g}", *extra]


def one(
    radio: str, plan: str, n: int, seed: int, duration_s: float, start_side_m: float, extra: tuple[str, ...] = ()
) -> dict:
    from netsim.config import load
    from netsim.run import execute

    config = load(None, settings(radio, plan, n, seed, duration_s, start_side_m, extra))
    result = execute(config)
    frames, summary = result.frames, result.summary
    o = coverage_outcome(frames, summary, n, config.coverage.start_s, duration_s)
    from netsim.metrics import components_in_links_table

    return {
        "radio": radio,
        "plan": plan,
        "N": n,
        "seed": seed,
        "comp0": int(components_in_links_table(frames["links"], n, [0.0])[0]),
        "start": float(summary["covered_of_bound_all_start"]),
        "final": o["of_bound"],
        "split": o["components_max"] > o["components_at_start"],
        "moved_m": float(summary["distance_mean_m"]),
        "settled_s": float(summary["control_settled_s"]),
        "final_xy": result.sim.positions().tolist(),
        "radius_m": float(config.coverage.radius_m or min(config.ranges_m())),
        "map": config.world.map,
    }


def told(run: dict) -> str:
    """One finished run, as the progress bar tells it."""
    return f"{run['plan']} plan, {run['radio']}, seed {run['seed']}: {run['final']:.3f} of the bound"


def table(runs: pd.DataFrame) -> pd.DataFrame:
    g = runs.groupby(["radio", "plan", "N"], sort=False)
    out = g.agg(
        seeds=("seed", "size"),
        comp0=("comp0", "max"),
        start=("start", "mean"),
        final=("final", "mean"),
        final_min=("final", "min"),
        split=("split", "sum"),
        moved_m=("moved_m", "mean"),
        unsettled=("settled_s", lambda s: int(s.isna().sum())),
    ).reset_index()
    out["pass"] = (out["final_min"] >= TARGET) & (out["split"] == 0)
    return out.rename(columns={"final_min": "final min"})


def figure(runs: pd.DataFrame, path: str) -> None:
    """For the lowest seed of each radio and plan, the map its run read (``map``) with where
    the robots ended and the disk each covers, titled with the covered fraction of the
    free-area bound."""
    from matplotlib.patches import Circle

    from netsim.tools.figures import draw_map, pyplot
    from netsim.world.maps import cached_map

    plt = pyplot()
    first = runs.sort_values("seed", kind="stable").groupby(["radio", "plan"], sort=False).head(1)
    fig, axes = plt.subplots(1, len(first), figsize=(4.2 * len(first), 4.6), squeeze=False)
    for ax, row in zip(axes[0], first.itertuples()):
        occupancy = cached_map(row.map)
        draw_map(ax, occupancy)
        xy = np.asarray(row.final_xy)
        for p in xy:
            ax.add_patch(Circle(p, row.radius_m, alpha=0.05, lw=0, color="tab:blue"))
        ax.plot(xy[:, 0], xy[:, 1], ".", color="tab:red", ms=4)
        x0, x1, y0, y1 = occupancy.extent_m
        ax.set(xlim=(x0, x1), ylim=(y0, y1), aspect="equal", xlabel="x (m)", ylabel="y (m)")
        ax.set_title(f"{row.radio}, {row.plan}, seed {row.seed}: {row.final:.3f}", fontsize=9)
    fig.tight_layout()
    write_atomically(Path(path), lambda tmp: fig.savefig(tmp, dpi=110, format=Path(path).suffix[1:].lower()))
    plt.close(fig)


def main(argv=None) -> int:
    p = Parser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--n", type=int, default=40, help="robots (default 40)")
    p.add_argument("--seeds", type=int, default=5, help="seeds per row, 1 .. SEEDS (default 5)")
    p.add_argument("--radios", nargs="+", default=MAP_RADIOS, help=f"of {MAP_RADIOS}")
    p.add_argument("--plans", nargs="+", default=["global", "local"], help="of global, local")
    p.add_argument("--start-side", type=float, default=60.0, help="side of the start square, m (default 60)")
    p.add_argument(
        "--duration", type=float, default=COVERAGE_DURATION_S, help="simulated seconds per run (default 600)"
    )
    p.add_argument("--workers", type=int, default=2, help="runs at a time, one process each (default 2)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--csv", help="also write every run's row here")
    p.add_argument("--figure", help=f"also draw where the robots ended ({', '.join(FIGURE_SUFFIXES)})")
    args = p.parse_args(argv)
    for option, given, known in (("--radios", args.radios, MAP_RADIOS), ("--plans", args.plans, ["global", "local"])):
        unknown = [x for x in given if x not in known]
        if unknown:
            raise NetsimInputError(f"{option} {unknown[0]!r}: not one of {known}")
    for option, value in (("--n", args.n), ("--seeds", args.seeds), ("--workers", args.workers)):
        if value < 1:
            raise NetsimInputError(f"{option} {value}: at least 1")
    for option, value in (("--start-side", args.start_side), ("--duration", args.duration)):
        if not value > 0:
            raise NetsimInputError(f"{option} {value:g}: must be positive")
    # Before any run: a file that cannot be written would lose them all.
    check_out_files({"--csv": args.csv, "--figure": args.figure}, figures=("--figure",))
    seeds = range(1, args.seeds + 1)
    jobs = [
        (radio, plan, args.n, seed, args.duration, args.start_side)
        for radio in args.radios
        for plan in args.plans
        for seed in seeds
    ]
    name = Path(__file__).name
    done = pooled(one, jobs, args.workers, name, not args.no_progress, star=True, describe=told)
    runs = pd.DataFrame(list(done))
    out = table(runs)
    with pd.option_context("display.width", 200, "display.float_format", "{:.3f}".format):
        print(out.to_string(index=False))
    failed = int((~out["pass"]).sum())
    rule = f"every seed at {TARGET:g} of the free-area bound or more, none split"
    print(f"{len(out) - failed} of {len(out)} rows pass ({rule})")
    if cut_short(args.duration):
        print(cut_short(args.duration))
    # The files last, each whole or not at all: an interrupt says which are in place.
    if args.csv:
        rows = runs.drop(columns=["final_xy", "radius_m", "map"])
        write_atomically(Path(args.csv), lambda tmp: rows.to_csv(tmp, index=False))
    if args.figure:
        line = f"{Path(__file__).name}: interrupted; every run's row is written in {args.csv}, the figure is not"
        with kept_if_interrupted(line) if args.csv else nullcontext():
            figure(runs, args.figure)
    return 1 if failed else 0


if __name__ == "__main__":
    run_script(lambda: sys.exit(main()))
