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
covers on the same seed (the least ratio beside), in how many seeds each plan's real
network (``links.parquet``) gained no component after control started, and in how many
each plan's control ended before the run did (``settled``: the team stopped spreading;
otherwise ``--duration`` cut it while it still spread). A row passes when
the local plan reaches 80 % on every seed and each plan's network gained nothing in at
least 19 of 20 seeds (95 % of the seeds run).

    python experiments/coverage_targets.py --shadowing --workers 2
    python experiments/coverage_targets.py --shadowing --seeds 3 --n 20 60   # a quick look

``--set KEY=VALUE`` (repeatable) puts a setting over the scenario's in both plans' runs of
``--shadowing``; a bad one, or ``--set`` with any other mode, is an error before any run
(exit 2).

    python experiments/coverage_targets.py --shadowing --set coverage.detour_sigmas=2

``--figure FILE`` (``.png``, ``.svg``, ``.pdf``; with ``--shadowing``) also draws the runs:
per N each seed's covered fraction of the bound for both plans, and the local plan's over
the global plan's on the same seed against the 0.8 target, a seed whose real network grew
marked.

    python experiments/coverage_targets.py --shadowing --figure shadowing.png

``--why`` runs the local plan under 4 dB shadowing on one seed (``--seed``, each ``--n``)
and prints where it loses to the global plan: per control step, how many robots moved,
held by rule 3 (a kept link they cannot answer for, alone or by halves) or wished
nothing, how many links robots let go of as silent (no Ack heard for longer than the
largest gap between two, on a channel that loses no frame), and of the links
that held a robot, how many were weak (margin below ``coverage.fade_margin_db``), already
down at the step (the true network), or up with a detour of truly shorter up links
(one rule 1 could in principle certify), or only with a detour of stronger links (the
global plan's order, by margin), or none; and, whatever their length, how many had a
detour of stronger links. ``--csv FILE`` writes that table too, a row per N.

    python experiments/coverage_targets.py --why --n 20 60 --duration 150

``--bound`` asks how much of the gap rule 1 (which links a robot lets go of) could close at
best: on seeds 1 to ``--seeds`` (each ``--n``, default 20) it runs the global plan, the
local plan, and the local plan with rule 1 replaced by an oracle that reads the true
network: a robot lets go of a link when the links up at the step join its ends through
links that come before it, by length, by the global plan's order (the margin left after
the plausible change of the shadowing) or by rule 1's own order (bands of the length at zero
shadowing under the epoch's records, every record read), over the robots it remembers, over
those and the robots they remember (two hops), or over the whole team (then with every
other rule of the local plan, its own limits and leashes, unchanged).
Not a plan (no robot knows the true network): a bound. Prints each run's covered fraction
of the bound over the global plan's on the same seed, and how far any run's real network
grew.

    python experiments/coverage_targets.py --bound --seeds 5 --n 20
    python experiments/coverage_targets.py --bound --oracles margin-team records-two-hops

The table's last rows per N: the mean and the least over the seeds; below it, in how many
seeds each run covers at least 0.8 of the global plan.
"""

from __future__ import annotations

import argparse
import math
import sys
from contextlib import ExitStack, closing, nullcontext
from functools import partial
from pathlib import Path

import pandas as pd

from netsim.config import Config
from netsim.errors import NetsimInputError
from netsim.tools.args import Parser
from netsim.tools.cli import FIGURE_SUFFIXES, check_out_files
from netsim.tools.interrupt import kept_if_interrupted
from netsim.tools.output import write_atomically
from netsim.tools.sweep import pooled, run_script
from netsim.tools.validate import (
    COVERAGE_DURATION_S,
    COVERAGE_FLOOR,
    COVERAGE_RADIOS,
    coverage_run,
    coverage_settings,
    cut_short,
)

NAME = Path(__file__).name


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


def shadowing_one(job: tuple[str, int, int, tuple[str, ...]], duration_s: float) -> dict:
    plan, n, seed, extra = job
    o = coverage_run(SHADOWING, plan, n, 0.0, seed, duration_s, extra)
    return {
        "plan": plan,
        "N": n,
        "seed": seed,
        "of bound": o["of_bound"],
        "grew": max(o["components_max"] - o["components_at_start"], 0),
        "settled s": o["settled_s"],
    }


def shadowing_table(runs: pd.DataFrame) -> pd.DataFrame:
    """One row per N from the runs of both plans (:func:`shadowing_one`)."""
    rows = []
    for n, g in runs.groupby("N"):
        both = g.pivot(index="seed", columns="plan", values="of bound")
        grew = g.pivot(index="seed", columns="plan", values="grew")
        settled = g.pivot(index="seed", columns="plan", values="settled s").notna()
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
                "global settled": int(settled["global"].sum()),
                "local settled": int(settled["local"].sum()),
                "pass": bool((ratio >= SHARE).all() and whole_g >= need and whole_l >= need),
            }
        )
    return pd.DataFrame(rows)


def write_csv(table: pd.DataFrame, path: str) -> None:
    """``table`` written whole to ``path`` or not at all, whenever an interrupt comes."""
    write_atomically(Path(path), lambda tmp: table.to_csv(tmp, index=False))


def told(run: dict) -> str:
    """One finished run, as the progress bar tells it."""
    return f"{run['plan']}, N = {run['N']}, seed {run['seed']}: {run['of bound']:.3f} of the bound"


def run_jobs(one, jobs: list, args) -> pd.DataFrame:
    """``one(job, duration)`` of every job over ``args.workers`` processes, the CSV written
    again as each run finishes (a run cut short keeps what it has), with a progress bar."""
    done = []
    runs = pooled(partial(one, duration_s=args.duration), jobs, args.workers, NAME, not args.no_progress, describe=told)
    # Closed on the way out: a Ctrl-C outside its loop (the CSV being written) would leave
    # its workers and bar to the interpreter's exit, after the line that reports it.
    with closing(runs), ExitStack() as kept:
        for run in runs:
            done.append(run)
            if args.csv:
                write_csv(pd.DataFrame(done), args.csv)
                if len(done) == 1:
                    kept.enter_context(kept_if_interrupted(f"{NAME}: interrupted; the runs finished are in {args.csv}"))
    return pd.DataFrame(done)


def shadowing_figure(runs: pd.DataFrame, path: str) -> None:
    """The ``--shadowing`` runs drawn (module notes): per N, each seed's covered fraction of
    the bound by plan (left), and the local plan's over the global plan's (right), against
    :data:`SHARE`; seeds where either plan's real network grew in red."""
    import numpy as np

    from netsim.tools.figures import pyplot

    plt = pyplot()
    fig, (cover, ratio) = plt.subplots(1, 2, figsize=(10, 4.2))
    sizes = sorted(runs["N"].unique())
    at_target = [""] * len(sizes)
    told_grew = False
    for k, n in enumerate(sizes):
        g = runs[runs["N"] == n]
        both = g.pivot(index="seed", columns="plan", values="of bound")
        grew = g.pivot(index="seed", columns="plan", values="grew").fillna(0).gt(0).any(axis=1)
        spread = np.linspace(-0.15, 0.15, len(both)) if len(both) > 1 else np.zeros(1)
        for dx, plan, colour in ((-0.2, "global", "tab:blue"), (0.2, "local", "tab:orange")):
            if plan in both:
                label = plan if k == 0 else None
                cover.plot(k + dx + 0.5 * spread, both[plan], ".", color=colour, label=label)
        if {"global", "local"} <= set(both):
            share = both["local"] / both["global"]
            ratio.plot(k + spread, share.where(~grew), ".", color="tab:orange")
            # The legend tells the marker once, at the first N that has one.
            split = "a network grew" if grew.any() and not told_grew else None
            told_grew = told_grew or grew.any()
            ratio.plot(k + spread, share.where(grew), "x", color="tab:red", label=split)
            ratio.plot([k - 0.3, k + 0.3], [share.mean()] * 2, "-", color="black", lw=1)
            at_target[k] = f"\n{int((share >= SHARE).sum())} of {len(share)} at {SHARE:g}"
    ratio.axhline(SHARE, ls="--", color="grey", lw=1, label=f"target {SHARE:g}")
    for ax, below in ((cover, [""] * len(sizes)), (ratio, at_target)):
        ax.set_xticks(range(len(sizes)), [f"N = {n}{told}" for n, told in zip(sizes, below)])
        ax.grid(axis="y", alpha=0.3)
    cover.set(ylabel="covered fraction of the bound", title="each seed, by plan")
    ratio.set(ylabel="local / global, same seed", title="local over global (bar: the mean)")
    cover.legend(fontsize=8)
    ratio.legend(fontsize=8)
    fig.tight_layout()
    write_atomically(Path(path), lambda tmp: fig.savefig(tmp, dpi=110, format=Path(path).suffix[1:].lower()))
    plt.close(fig)


def main_shadowing(args) -> int:
    sizes = args.n or SHADOWING_SIZES
    extra = tuple(args.set or ())
    # Seed by seed, both plans side by side: a run cut short still has whole seeds.
    jobs = [(plan, n, seed, extra) for seed in range(1, args.seeds + 1) for n in sizes for plan in ("global", "local")]
    runs = run_jobs(shadowing_one, jobs, args)
    table = shadowing_table(runs)
    with pd.option_context("display.width", 200, "display.max_rows", 200, "display.float_format", "{:.3f}".format):
        print(table.to_string(index=False))
    failed = int((~table["pass"]).sum())
    print(f"{len(table) - failed} of {len(table)} rows pass")
    if cut_short(args.duration):
        print(cut_short(args.duration))
    if args.figure:
        line = f"{NAME}: interrupted; the runs are in {args.csv}, the figure is not"
        with kept_if_interrupted(line) if args.csv else nullcontext():
            shadowing_figure(runs, args.figure)
    return 1 if failed else 0


def why(n: int, seed: int, duration_s: float) -> dict:
    """Where the local plan loses (module notes, ``--why``): counts over the run's control
    steps, from the plan's own state at each step and the true network."""
    import numpy as np
    from netsim.mobility import coverage
    from netsim.mobility.local import leash_radius
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import breadth_first_order, minimum_spanning_tree

    from netsim.geometry import distances_m, in_motion

    counts = dict.fromkeys(
        ["robot-steps", "moved", "held, rule 3", "held, no travel", "no wish", "let go as silent", "holding links",
         "weak", "down", "shorter detour", "stronger detour only", "no detour", "stronger detour"], 0)  # fmt: skip

    def bottleneck(size, i, j, weight):
        # The largest weight on the best path between every two robots (through the forest).
        tree = minimum_spanning_tree(coo_matrix((weight, (i, j)), shape=(size, size)).tocsr())
        tree = (tree + tree.T).tocsr()
        out = np.full((size, size), np.inf)
        for a in range(size):
            order, pred = breadth_first_order(tree, a, directed=False, return_predecessors=True)
            worst = np.full(size, np.inf)
            worst[a] = -np.inf
            for v in order[1:]:
                worst[v] = max(worst[pred[v]], tree[pred[v], v])
            out[a] = worst
        return out

    plan_local = coverage.CoverageController._plan_local

    def watched(self, step):
        plan = plan_local(self, step)
        knows, fade, limits, pos = self.knows, self.fade, self.local_limits, step.positions_m
        t0, speed = step.t_s, limits.speed_max_mps
        _, travel = fade.limits(knows, t0, t0 + limits.period_s, speed)
        kept = self.kept
        links = self.rules.candidates(pos, t0)
        length = distances_m(pos[links.i], pos[links.j])
        size = len(pos)
        shorter = bottleneck(size, links.i, links.j, length + 1e-9)
        stronger = bottleneck(size, links.i, links.j, links.weight)
        own_len = np.full((size, size), np.inf)
        own_len[links.i, links.j] = own_len[links.j, links.i] = length
        own_w = np.full((size, size), np.inf)
        own_w[links.i, links.j] = own_w[links.j, links.i] = links.weight
        dist = distances_m(np.repeat(pos, size, axis=0), knows.xy.reshape(-1, 2)).reshape(size, size)
        holding = kept & (dist > leash_radius(knows, t0, limits))
        if self.halves is not None:
            holding &= ~self.halves.usable
            # the travel the plan used: a half's, where the robot answered by halves
            travel = np.where(self.halves.usable, self.halves.travel_m, travel)
        moved = in_motion(plan.velocity_mps)
        wish = in_motion(step.velocity_mps)
        no_travel = fade.reach(travel, kept) <= 0
        counts["robot-steps"] += size
        counts["moved"] += int(moved.sum())
        counts["held, rule 3"] += int((~moved & wish & holding.any(axis=1)).sum())
        counts["held, no travel"] += int((~moved & wish & ~holding.any(axis=1) & no_travel).sum())
        counts["no wish"] += int((~moved & ~wish).sum())
        counts["let go as silent"] += int((self.silent & self.heard.known).sum())
        a, b = np.nonzero(holding & (~moved & wish)[:, None])
        up = np.isfinite(own_len[a, b])
        counts["holding links"] += len(a)
        counts["weak"] += int((knows.margin_db[a, b] < self.cfg.fade_margin_db).sum())
        counts["down"] += int((~up).sum())
        by_length = up & (shorter[a, b] < own_len[a, b] - 1e-6)
        by_margin = up & (stronger[a, b] < own_w[a, b] - 1e-9)
        counts["shorter detour"] += int(by_length.sum())
        counts["stronger detour only"] += int((by_margin & ~by_length).sum())
        counts["stronger detour"] += int(by_margin.sum())
        counts["no detour"] += int((up & ~by_length & ~by_margin).sum())
        return plan

    coverage.CoverageController._plan_local = watched
    try:
        o = coverage_run(SHADOWING, "local", n, 0.0, seed, duration_s)
    finally:
        coverage.CoverageController._plan_local = plan_local
    return {"N": n, "seed": seed, "of bound": o["of_bound"], **counts}


# Rule 1's oracles of --bound: (name, the order, over whom).
ORACLES = {
    "length, remembered": ("length", "remembered"),
    "margin, remembered": ("margin", "remembered"),
    "length, two hops": ("length", "two hops"),
    "margin, two hops": ("margin", "two hops"),
    "margin, team": ("margin", "team"),
    "records, two hops": ("records", "two hops"),
}


def oracle_let_go(controller, order: str, over: str):
    """Rule 1 replaced by an oracle (module notes, ``--bound``): robot ``i`` lets go of ``j``
    when the links up at the step (the true network, :meth:`LinkRules.candidates`) join
    them through links that come before ``(i, j)`` in ``order`` (``"length"``: the true
    lengths; ``"margin"``: the global plan's weights, the margin left after the plausible
    change of the shadowing; ``"records"``: rule 1's order, bands of the length at zero
    shadowing under the records of the step's epoch and then the ends' ids, every record
    read as if every list had arrived), over the robots ``i`` remembers (``over = "remembered"``),
    over those and the robots they remember (``"two hops"``: what ``i`` would know if each
    list also carried its sender's neighbours' lists) or over the whole team (``"team"``);
    only robots ``i`` remembers are let go of. Not a plan: it reads the true positions,
    shadowing and memories."""
    import numpy as np
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import breadth_first_order, minimum_spanning_tree

    from netsim.compiled import load
    from netsim.geometry import distances_m

    def rule_1_order(pos, links, records_db):
        # Rule 1's own kernel gives the bands, so the oracle orders exactly as rule 1 would
        # with every record read; the ends' ids then break ties as rule 1 breaks them.
        n = len(pos)
        kernels = load("netsim.mobility._local_kernels", n)
        fade, band_m = controller.fade.rule, controller.cfg.band_m
        nominal_m = kernels.range_at_loss_m(0.0, 0.0, fade.budget_db, fade.reference_distance_m, fade.exponent)
        lo, hi = np.minimum(links.i, links.j), np.maximum(links.i, links.j)
        length = distances_m(pos[links.i], pos[links.j])
        band = [kernels.link_band(d, records_db[a, b], band_m, fade, nominal_m) for d, a, b in zip(length, lo, hi)]
        return np.array(band, dtype=float) + (lo * n + hi + 1) / (n * n + 1)

    def let_go(pos, knows, heard, t0_s, *args, **kwargs):
        n = len(pos)
        links = controller.rules.candidates(pos, t0_s)
        if order == "length":
            key = distances_m(pos[links.i], pos[links.j])
        elif order == "records":
            key = rule_1_order(pos, links, heard.records_db)
        else:
            key = links.weight
        weight = np.full((n, n), np.inf)
        weight[links.i, links.j] = weight[links.j, links.i] = key
        out = np.zeros((n, n), dtype=bool)
        for i in range(n):
            if over == "remembered":
                others = np.flatnonzero(heard.known[i])
            elif over == "two hops":
                near = heard.known[i] | heard.known[heard.known[i]].any(axis=0)
                near[i] = False
                others = np.flatnonzero(near)
            else:
                others = np.flatnonzero(np.arange(n) != i)
            nodes = np.r_[i, others]
            sub = weight[np.ix_(nodes, nodes)]
            a, b = np.nonzero(np.triu(np.isfinite(sub), 1))
            if len(a) == 0:
                continue
            m = len(nodes)
            # Bottleneck of the best path from i: through the minimum spanning forest (a tiny
            # shift keeps zero weights in the graph).
            tree = minimum_spanning_tree(coo_matrix((sub[a, b] + 1e-12, (a, b)), shape=(m, m)).tocsr())
            tree = (tree + tree.T).tocsr()
            reached, pred = breadth_first_order(tree, 0, directed=False, return_predecessors=True)
            worst = np.full(m, np.inf)
            worst[0] = -np.inf
            for v in reached[1:]:
                worst[v] = max(worst[pred[v]], tree[pred[v], v])
            out[i, others] = heard.known[i, others] & (worst[1:] < sub[0, 1:] - 1e-9)
        return out

    return let_go


def bound_one(job: tuple[str, int, int], duration_s: float) -> dict:
    """One run of ``--bound``: the global plan, the local plan, or the local plan with an oracle."""
    kind, n, seed = job
    if kind in ("global", "local"):
        o = coverage_run(SHADOWING, kind, n, 0.0, seed, duration_s)
    else:
        from netsim.mobility import coverage

        plan_local, let_go = coverage.CoverageController._plan_local, coverage.let_go

        def watched(self, step):
            coverage.let_go = oracle_let_go(self, *ORACLES[kind])
            return plan_local(self, step)

        coverage.CoverageController._plan_local = watched
        try:
            o = coverage_run(SHADOWING, "local", n, 0.0, seed, duration_s)
        finally:
            coverage.CoverageController._plan_local, coverage.let_go = plan_local, let_go
    grew = max(o["components_max"] - o["components_at_start"], 0)
    return {"N": n, "seed": seed, "plan": kind, "of bound": o["of_bound"], "grew": grew}


def oracle_slug(name: str) -> str:
    """An oracle's name as ``--oracles`` takes it: ``"margin, team"`` is ``margin-team``."""
    return name.replace(", ", "-").replace(" ", "-")


def main_bound(args) -> int:
    sizes = args.n or [20]
    chosen = set(args.oracles or map(oracle_slug, ORACLES))
    kinds = ["global", "local", *(k for k in ORACLES if oracle_slug(k) in chosen)]
    jobs = [(kind, n, seed) for n in sizes for seed in range(1, args.seeds + 1) for kind in kinds]
    runs = run_jobs(bound_one, jobs, args)
    rows = []
    for (n, seed), g in runs.groupby(["N", "seed"]):
        got = g.set_index("plan")
        row = {"N": int(n), "seed": int(seed), "global": float(got.loc["global", "of bound"])}
        for kind in kinds[1:]:
            row[kind] = float(got.loc[kind, "of bound"] / got.loc["global", "of bound"])
        row["grew (most)"] = int(g["grew"].max())
        rows.append(row)
    table = pd.DataFrame(rows)
    means = table.groupby("N").mean(numeric_only=True).reset_index().assign(seed="mean")
    least = table.groupby("N").min(numeric_only=True).reset_index().assign(seed="least")
    reached = (table[kinds[1:]] >= 0.8).groupby(table["N"]).sum().reset_index()
    table = pd.concat([table, means, least], ignore_index=True)
    with pd.option_context("display.width", 200, "display.max_rows", 200, "display.float_format", "{:.3f}".format):
        print(table.to_string(index=False))
        print("\nseeds at 0.8 or more of the global plan:")
        print(reached.to_string(index=False))
    return 0


# The keys that name a run in the table: the script's to set.
RUNS_OWN = ("seed", "duration_s", "world.n_robots", "coverage.plan")


def check_options(args: argparse.Namespace) -> None:
    """Refuse (NetsimInputError) sizes, workers or seeds below 1, a duration that is not
    finite or ends before control starts, a negative seed, and a bad ``--set``
    (:func:`check_settings`), before any run."""
    for option, values in (("--n", args.n or []), ("--workers", [args.workers]), ("--seeds", [args.seeds])):
        for value in values:
            if value < 1:
                raise NetsimInputError(f"{option} {value}: at least 1")
    start_s = Config().coverage.start_s
    if not (math.isfinite(args.duration) and args.duration > start_s):
        raise NetsimInputError(f"--duration {args.duration:g}: must be finite and after control starts ({start_s:g} s)")
    if args.seed < 0:
        raise NetsimInputError(f"--seed {args.seed}: must be >= 0")
    if args.set:
        check_settings(args)
    if args.oracles and not args.bound:
        raise NetsimInputError("--oracles applies to --bound only")
    if args.figure is not None and (not args.shadowing or args.bound or args.why):
        raise NetsimInputError("--figure applies to --shadowing runs only")
    # Before any run: a file that cannot be written would lose them all.
    check_out_files({"--csv": args.csv, "--figure": args.figure}, figures=("--figure",))


def check_settings(args: argparse.Namespace) -> None:
    """Refuse ``--set`` (NetsimInputError) outside ``--shadowing``, on a key that names a run
    however it is written (``coverage.plan=...`` or ``coverage={plan=...}``), or where the
    configuration refuses it for either plan at any size the table runs."""
    from netsim.config import load, read_tree

    if not args.shadowing or args.bound or args.why:
        raise NetsimInputError("--set applies to --shadowing runs only")
    tree = read_tree(None, args.set)

    def given(key: str) -> bool:
        node = tree
        for part in key.split("."):
            if not isinstance(node, dict) or part not in node:
                return False
            node = node[part]
        return True

    taken = [key for key in RUNS_OWN if given(key)]
    if taken:
        raise NetsimInputError(f"--set cannot set {', '.join(taken)} (the runs' own)")
    for plan in ("global", "local"):
        for n in args.n or SHADOWING_SIZES:
            load(None, coverage_settings(SHADOWING, plan, n, 0.0, 1, args.duration, args.set))


def main(argv=None) -> int:
    p = Parser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--quick", action="store_true", help="unit disk at N = 20 and 60 only, and the radio rows")
    p.add_argument(
        "--n",
        type=int,
        nargs="+",
        help="team sizes (default: 20 60 100 200; --shadowing: 20 60 100; --bound: 20; --why: 20 60)",
    )
    p.add_argument("--no-radios", action="store_true", help="the unit disk rows only")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--figure", help=f"with --shadowing: also draw the runs ({', '.join(FIGURE_SUFFIXES)})")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--duration", type=float, default=COVERAGE_DURATION_S, help="simulated seconds per run")
    p.add_argument(
        "--csv",
        help="also write the table here (with --shadowing, --bound: every run, as it ends; --why: a row per N)",
    )
    p.add_argument("--shadowing", action="store_true", help="the targets under 4 dB shadowing (module notes)")
    p.add_argument(
        "--seeds", type=int, default=20, help="--shadowing, --bound: seeds 1 to this (--bound runs eight plans a seed)"
    )
    p.add_argument("--why", action="store_true", help="where the local plan loses under shadowing (module notes)")
    p.add_argument("--bound", action="store_true", help="what rule 1 could give at best under shadowing (module notes)")
    p.add_argument(
        "--oracles",
        nargs="+",
        choices=[oracle_slug(k) for k in ORACLES],
        help="--bound only: these of rule 1's oracles (default: all)",
    )
    p.add_argument(
        "--set",
        action="append",
        metavar="KEY=VALUE",
        help="--shadowing only: a setting over the scenario's, for both plans' runs (repeatable)",
    )
    args = p.parse_args(argv)
    check_options(args)
    if args.bound:
        return main_bound(args)
    if args.why:
        table = pd.DataFrame([why(n, args.seed, args.duration) for n in args.n or [20, 60]])
        with pd.option_context("display.width", 200, "display.float_format", "{:.3f}".format):
            print(table.T.to_string(header=False))
        if args.csv:
            write_csv(table, args.csv)
        return 0
    if args.shadowing:
        return main_shadowing(args)
    sizes = args.n or ([20, 60] if args.quick else [20, 60, 100, 200])
    rows = scenarios(sizes, not args.no_radios)
    jobs = [(row, args.seed, args.duration) for row in rows]
    table = pd.DataFrame(list(pooled(one, jobs, args.workers, NAME, not args.no_progress, star=True)))
    with pd.option_context("display.width", 200, "display.max_rows", 200, "display.float_format", "{:.3f}".format):
        print(table.to_string(index=False))
    failed = int((~table["pass"]).sum())
    print(f"{len(table) - failed} of {len(table)} rows pass")
    if cut_short(args.duration):
        print(cut_short(args.duration))
    if args.csv:
        write_csv(table, args.csv)
    return 1 if failed else 0


if __name__ == "__main__":
    run_script(lambda: sys.exit(main()))
