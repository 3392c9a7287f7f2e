"""Connected coverage on the radio the robots really have: the targets of docs/model.md
section 5, measured and printed in one table.

Every run starts dense (``world.placement = "centre"``, a central square of side
``40 sqrt(N)`` m, about 20 neighbours per robot), forms groups, then spreads by virtual
forces until the stopping rule ends control or the run ends. Rows:

- unit disk (range 100 m), N = 20, 60, 100, 200, each plan (``coverage.plan = "global"``
  and ``"local"``), with no loss and with 30 % loss (``channel.loss_probability = 0.3``):
  the covered fraction of the bound ``min(1, U(N) / A)`` at the end, against the floor
  (global 0.75, local 0.60);
- log-distance with 4 dB shadowing (nominal reach 100 m, N = 60), and the office map
  (N = 40 from the centre, range 30 m) with line of sight and with 5 dB per wall under
  log-distance, each plan: the fraction of the bound printed beside.

For every run: ``split`` is whether the real network (``links.parquet``, the links the
channel made) ever had more components after control started than when it started,
checked at every link event; ``table`` whether the coverage table's ``components``
equals that network's at every sample. A row passes when it did not split, its table is
true, and (unit disk) its fraction reaches the floor.

    python experiments/coverage_targets.py --workers 2            # every row (some 20 min on 2 cores)
    python experiments/coverage_targets.py --quick                # N = 20 and 60 only
"""

from __future__ import annotations

import argparse
import math
import sys
from concurrent.futures import ProcessPoolExecutor

import numpy as np
import pandas as pd
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components

FLOOR = {"global": 0.75, "local": 0.60}
SIDE_M = {20: 1000.0, 40: 200.0, 60: 1500.0, 100: 2000.0, 200: 2500.0}


def _components_at(links: pd.DataFrame, n: int, times: np.ndarray) -> np.ndarray:
    """Components of the network whose links are those up at each of ``times``."""
    a, b = links["a"].to_numpy(np.int64), links["b"].to_numpy(np.int64)
    up_s = links["t_up_s"].to_numpy(float)
    down_s = np.where(links["censored_end"].to_numpy(bool), np.inf, links["t_down_s"].to_numpy(float))
    out = np.empty(len(times), dtype=np.int64)
    for k, t in enumerate(times.tolist()):
        up = (up_s <= t) & (t < down_s)
        out[k] = connected_components(csr_matrix((np.ones(int(up.sum())), (a[up], b[up])), shape=(n, n)))[0]
    return out


def scenarios(quick: bool) -> list[tuple[str, str, int, float, list[str]]]:
    """``(radio, plan, N, loss, settings)`` for every row."""
    rows = []
    for n in (20, 60) if quick else (20, 60, 100, 200):
        for plan in ("global", "local"):
            for loss in (0.0, 0.3):
                rows.append(("unit disk", plan, n, loss, ["channel.range_m=100"]))
    shadow = ["channel.propagation=log_distance", "channel.shadowing_sigma_db=4"]
    office = ["world.map=office", "channel.range_m=30", "world.centre_side_m=40"]
    walls = [*office, "channel.propagation=log_distance", "channel.wall_loss_db=5", "channel.sensitivity_dbm=-64.3"]
    for plan in ("global", "local"):
        rows.append(("shadowing 4 dB", plan, 60, 0.0, shadow))
        rows.append(("office, line of sight", plan, 40, 0.0, office))
        rows.append(("office, 5 dB a wall", plan, 40, 0.0, walls))
    return rows


def one(row: tuple[str, str, int, float, list[str]], seed: int, duration_s: float) -> dict:
    from netsim import load
    from netsim.run import execute

    radio, plan, n, loss, extra = row
    settings = [
        f"seed={seed}",
        f"world.n_robots={n}",
        f"world.side_m={SIDE_M[n] if 'office' not in radio else 200.0}",
        "world.placement=centre",
        f"world.centre_side_m={40 * math.sqrt(n):.1f}",
        "mobility.model=static",
        "coverage.enabled=true",
        f"coverage.plan={plan}",
        "protocol.message_rate_hz=0",
        f"channel.loss_probability={loss}",
        f"duration_s={duration_s}",
        *extra,
    ]
    result = execute(load(None, settings))
    frames, summary = result.frames, result.summary
    links, cov = frames["links"], frames["coverage"]
    start_s = result.sim.config.coverage.start_s
    times = np.unique(np.r_[start_s, links["t_up_s"], links["t_down_s"]])
    times = times[(times >= start_s) & (times <= duration_s)]
    comps = _components_at(links, n, times)
    at_samples = _components_at(links, n, cov["t_s"].to_numpy(float))
    fraction = float(summary["covered_of_bound_all_final"])
    split = bool(comps.max() > comps[0]) if len(comps) else False
    table_true = bool((cov["components"].to_numpy() == at_samples).all())
    floor = FLOOR[plan] if radio == "unit disk" else math.nan
    return {
        "radio": radio,
        "plan": plan,
        "N": n,
        "loss": loss,
        "of bound": fraction,
        "floor": floor,
        "comp at start": int(comps[0]) if len(comps) else 0,
        "comp max": int(comps.max()) if len(comps) else 0,
        "split": split,
        "table true": table_true,
        "pass": (not split) and table_true and (math.isnan(floor) or fraction >= floor),
    }


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--quick", action="store_true", help="unit disk at N = 20 and 60 only, and the radio rows")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--duration", type=float, default=600.0, help="simulated seconds per run")
    p.add_argument("--csv", help="also write the table here")
    args = p.parse_args(argv)
    rows = scenarios(args.quick)
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
