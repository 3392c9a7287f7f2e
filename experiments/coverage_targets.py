"""Connected coverage on the radio the robots really have: the targets of docs/model.md
section 5, measured and printed in one table.

Every run starts dense (``world.placement = "centre"``, a central square of side
``40 sqrt(N)`` m, about 20 neighbours per robot; 40 m on the office map), forms groups,
then spreads by virtual forces until the stopping rule ends control or the run ends
(:func:`netsim.tools.validate.coverage_settings`, the scenario of ``netsim validate``'s
items 30 and 31). Rows:

- unit disk (range 100 m), N = 20, 60, 100, 200, each plan (``coverage.plan = "global"``
  and ``"local"``), with no loss and with 30 % loss (``channel.loss_probability = 0.3``):
  the covered fraction of the bound ``min(1, U(N) / A)`` at the end, against the floor
  (global 0.75, local 0.60);
- the office map (N = 40, range 30 m) with line of sight and with 5 dB per wall under
  log-distance, each plan: the fraction of the bound printed beside (4 dB shadowing:
  ``--shadowing``, below).

For every run: ``grew`` is how far the real network (``links.parquet``, the links the
channel made) ever went above its number of components at control start, checked at
every link event; ``table true`` whether the coverage table's ``components`` equals that
network's at every sample. A row passes when nothing grew, its table is true, and (unit
disk) its fraction reaches the floor.

    python experiments/coverage_targets.py --workers 2            # every row
    python experiments/coverage_targets.py --quick                # N = 20 and 60 only

``--shadowing`` prints instead the targets under 4 dB shadowing (log-distance, nominal
reach 100 m) at N = 20, 60, 100 over ``--seeds`` seeds (default 20), both plans on each
seed: per N, how many seeds the local plan covers at least 80 % of what the global plan
covers on the same seed (the least ratio beside), and in how many seeds each plan's real
network (``links.parquet``) gained no component after control started. A row passes when
the local plan reaches 80 % on every seed and each plan's network gained nothing in at
least 19 of 20 seeds (95 % of the seeds run).

    python experiments/coverage_targets.py --shadowing --workers 2
    python experiments/coverage_targets.py --shadowing --seeds 3 --n 20 60   # a quick look
"""

from __future__ import annotations

import argparse
import math
import sys
from concurrent.futures import ProcessPoolExecutor

import pandas as pd

from netsim.tools.validate import COVERAGE_FLOOR, COVERAGE_RADIOS, coverage_run


def scenarios(sizes: list[int], radios: bool) -> list[tuple[str, str, int, float]]:
    """``(radio, plan, N, loss)`` for every row."""
    rows = [("unit disk", plan, n, loss) for n in sizes for plan in ("global", "local") for loss in (0.0, 0.3)]
    for radio in COVERAGE_RADIOS:
        if radios and radio not in ("unit disk", "shadowing 4 dB"):
            rows += [(radio, plan, 40 if radio.startswith("office") else 60, 0.0) for plan in ("global", "local")]
    return rows


def one(row: tuple[str, str, int, float], seed: int, duration_s: float) -> dict:
    radio, plan, n, loss = row
    o = coverage_run(radio, plan, n, loss, seed, duration_s)
    floor = COVERAGE_FLOOR[plan] if radio == "unit disk" else math.nan
    grew = max(o["components_max"] - o["components_at_start"], 0)
    return {
        "radio": radio,
        "plan": plan,
        "N": n,
        "loss": loss,
        "of bound": o["of_bound"],
        "floor": floor,
        "comp at start": o["components_at_start"],
        "grew": grew,
        "table true": o["table_true"],
        "pass": grew == 0 and o["table_true"] and (math.isnan(floor) or o["of_bound"] >= floor),
    }


SHADOWING = "shadowing 4 dB"
SHADOWING_SIZES = [20, 60, 100]
SHARE = 0.8  # the local plan covers at least this share of what the global plan covers
WHOLE = 0.95  # of the seeds, in which a plan's real network gains no component


def shadowing_one(job: tuple[str, int, int], duration_s: float) -> dict:
    plan, n, seed = job
    o = coverage_run(SHADOWING, plan, n, 0.0, seed, duration_s)
    return {
        "plan": plan,
        "N": n,
        "seed": seed,
        "of bound": o["of_bound"],
        "grew": max(o["components_max"] - o["components_at_start"], 0),
    }


def shadowing_table(runs: pd.DataFrame) -> pd.DataFrame:
    """One row per N from the runs of both plans (:func:`shadowing_one`)."""
    rows = []
    for n, g in runs.groupby("N"):
        both = g.pivot(index="seed", columns="plan", values="of bound")
        grew = g.pivot(index="seed", columns="plan", values="grew")
        ratio = both["local"] / both["global"]
        seeds = len(both)
        whole_g, whole_l = int((grew["global"] == 0).sum()), int((grew["local"] == 0).sum())
        need = math.ceil(WHOLE * seeds)
        rows.append(
            {
                "N": int(n),
                "seeds": seeds,
                "global of bound": float(both["global"].mean()),
                "local of bound": float(both["local"].mean()),
                "local/global least": float(ratio.min()),
                "local/global mean": float(ratio.mean()),
                "seeds >= 80 %": int((ratio >= SHARE).sum()),
                "global whole": whole_g,
                "local whole": whole_l,
                "pass": bool((ratio >= SHARE).all() and whole_g >= need and whole_l >= need),
            }
        )
    return pd.DataFrame(rows)


def main_shadowing(args) -> int:
    sizes = args.n or SHADOWING_SIZES
    # Seed by seed, both plans side by side: a run cut short still has whole seeds.
    jobs = [(plan, n, seed) for seed in range(1, args.seeds + 1) for n in sizes for plan in ("global", "local")]
    done = []
    with ProcessPoolExecutor(args.workers) as pool:
        for run in pool.map(shadowing_one, jobs, [args.duration] * len(jobs)):
            done.append(run)
            print(run, flush=True)
            if args.csv:
                pd.DataFrame(done).to_csv(args.csv, index=False)
    runs = pd.DataFrame(done)
    table = shadowing_table(runs)
    with pd.option_context("display.width", 200, "display.max_rows", 200, "display.float_format", "{:.3f}".format):
        print(table.to_string(index=False))
    failed = int((~table["pass"]).sum())
    print(f"{len(table) - failed} of {len(table)} rows pass")
    return 1 if failed else 0


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--quick", action="store_true", help="unit disk at N = 20 and 60 only, and the radio rows")
    p.add_argument("--n", type=int, nargs="+", help="team sizes (default: 20 60 100 200; --shadowing: 20 60 100)")
    p.add_argument("--no-radios", action="store_true", help="the unit disk rows only")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--duration", type=float, default=600.0, help="simulated seconds per run")
    p.add_argument("--csv", help="also write the table here (with --shadowing: every run, as it ends)")
    p.add_argument("--shadowing", action="store_true", help="the targets under 4 dB shadowing (module notes)")
    p.add_argument("--seeds", type=int, default=20, help="--shadowing: seeds 1 to this")
    args = p.parse_args(argv)
    if args.shadowing:
        return main_shadowing(args)
    sizes = args.n or ([20, 60] if args.quick else [20, 60, 100, 200])
    rows = scenarios(sizes, not args.no_radios)
    with ProcessPoolExecutor(args.workers) as pool:
        results = list(pool.map(one, rows, [args.seed] * len(rows), [args.duration] * len(rows)))
    table = pd.DataFrame(results)
    with pd.option_context("display.width", 200, "display.max_rows", 200, "display.float_format", "{:.3f}".format):
        print(table.to_string(index=False))
    if args.csv:
        table.to_csv(args.csv, index=False)
    failed = int((~table["pass"]).sum())
    print(f"{len(table) - failed} of {len(table)} rows pass")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
