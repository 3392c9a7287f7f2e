"""What a local plan of *turns* would reach on the office map, rule by rule: a measurement
of a prototype, not a plan a run can choose (docs/experiments.md, "What a plan of turns
would reach").

The prototype replaces the local plan's step (``coverage.plan = "local"``,
docs/model.md 5.1) in the worker processes of this script only. At each control step
every robot draws a rank from the step's time and its number, which every robot can
compute; a robot moves only if it outranks every robot of its *turn group* (``kept``: the
robots it keeps or that keep it; ``remembered``: those it remembers or that remember it),
so of two robots that remember each other one holds while the other moves. The mover
needs no region (rule 5 by region): it tests each kept link against where the holder
stands, along its own step. Each variant then takes each rule from an oracle or from the
plan:

- ``rule1``: ``tree``, the minimum spanning tree of the true clear links (oracle); or
  ``plan``, the plan's rule 1 (:func:`netsim.mobility.local.let_go`, with its walls'
  test) on what the robots heard, or ``plan-true`` on their true positions;
- ``test``: ``sight``, true line of sight to the holder's true position at 25 points
  along the step (oracle); or ``walls``, the plan's walls' test of the step and the disk
  where the holder can be (:func:`netsim.mobility.local.step_clear_of_walls`, exact);
- the wish: through free space toward the free cells no robot covers, from every robot's
  true position (oracle: :func:`netsim.mobility.geodesic.expansion_to_uncovered`), in
  every variant but the last two: ``known``, through free space toward the free cells
  that neither the robot nor a robot it remembers covers, where it knows them to be (one
  search a robot and step: these runs are slow); ``plan-wish``, the plan's own wish
  (rule 6's expansion in straight lines, the pushes, the pulls).

The coverage stopping rule's gain test is off (``coverage.stop_gain = 0``): with turns a
robot moves at one step in several, and the test ended runs that were still spreading.

Prints one row per variant: the mean covered fraction of the free-area bound at the end
(``covered_of_bound_all``), its least over the seeds, and the seeds whose real network
(``links.parquet``) ever split after control started, as
``experiments/coverage_on_map.py`` counts them.

    python experiments/turns_on_map.py --workers 2
    python experiments/turns_on_map.py --variants oracle plan --seeds 5
"""

from __future__ import annotations

import argparse
import sys
from concurrent.futures import ProcessPoolExecutor
from typing import NamedTuple

import numpy as np
import pandas as pd
from coverage_on_map import MAP_RADIOS, one

from netsim.errors import NetsimInputError
from netsim.tools.args import Parser
from netsim.tools.sweep import run_script


class Variant(NamedTuple):
    turns: str  # "kept" or "remembered"
    rule1: str  # "tree", "plan" or "plan-true"
    test: str  # "sight" or "walls"
    wish: str = "free"  # "free" (oracle), "known" or "plan"


VARIANTS = {
    "oracle-kept": Variant("kept", "tree", "sight"),
    "oracle": Variant("remembered", "tree", "sight"),
    "rule1-true": Variant("remembered", "plan-true", "sight"),
    "rule1": Variant("remembered", "plan", "sight"),
    "plan": Variant("remembered", "plan", "walls"),
    "known": Variant("remembered", "plan", "walls", "known"),
    "plan-wish": Variant("remembered", "plan", "walls", "plan"),
}
# A team of turns moves a robot in several at each step: the plan's stopping rule, which ends
# control once the covered fraction stops rising by coverage.stop_gain over its window,
# would end runs that are still spreading, so it is off (control runs to the end).
STOPPING = ("coverage.stop_gain=0",)
# Points along the mover's step at which the oracle looks.
SIGHT_POINTS = 25


def install(variant: Variant) -> None:
    """Replace the local plan's wish and step in this process by the prototype's."""
    from netsim.mobility import coverage

    if variant.wish != "plan":
        propose = coverage.CoverageController._propose_local
        coverage.CoverageController._propose_local = _wish_through_free_space(propose, variant.wish)
    coverage.CoverageController._plan_local = lambda self, step: _turns(self, step, variant)


def _wish_through_free_space(propose, knowing: str):
    from netsim.mobility.geodesic import expansion_to_uncovered

    def wish(self, step) -> None:
        propose(self, step)  # the robots' memories and lists, as the plan takes them
        pos = step.positions_m
        if knowing == "known":
            wished = _known_expansion(self, pos)
        else:
            wished, _ = expansion_to_uncovered(self.grid, pos, self.radius_m, self.range_m, self.cfg.gain)
        wished = self._slide(pos, wished)
        speed = np.hypot(*wished.T)
        wished[speed < self.cfg.stop_speed_mps] = 0.0
        step.velocity_mps[:] = wished
        self._max_wish = float(speed.max(initial=0.0))

    return wish


def _known_expansion(self, pos: np.ndarray) -> np.ndarray:
    """Each robot's expansion down the distance through free space to the nearest free cell
    that neither it nor a robot it remembers (where it knows it to be) covers: the global
    plan's push on a map (:func:`netsim.mobility.geodesic.expansion_to_uncovered`), one
    search per robot from what it knows."""
    from netsim.mobility.geodesic import expansion_to_uncovered

    known = self.memory.known(self.env.now, self.cfg.release_s)
    out = np.zeros((len(pos), 2))
    for i in range(len(pos)):
        points = np.concatenate([pos[i : i + 1], self.knows.xy[i, known[i]]])
        out[i] = expansion_to_uncovered(self.grid, points, self.radius_m, self.range_m, self.cfg.gain)[0][0]
    return out


def _in_sight(occupancy, pos: np.ndarray) -> np.ndarray:
    from netsim.world.los import line_of_sight

    n = len(pos)
    a, b = np.triu_indices(n, 1)
    ok = line_of_sight(occupancy, pos[a], pos[b])
    out = np.zeros((n, n), dtype=bool)
    out[a[ok], b[ok]] = True
    return out | out.T


def _kept(self, step, variant: Variant) -> tuple[np.ndarray, np.ndarray]:
    """Rule 1 of ``variant``: who keeps whom, and who is silent."""
    import copy

    from netsim.mobility import local
    from scipy.sparse.csgraph import minimum_spanning_tree

    memory, knows, heard, c = self.memory, self.knows, self.heard, self.cfg
    limits, pos, t0 = self.local_limits, step.positions_m, step.t_s
    quiet = local.silent(memory, self.env.now, self.loop.lead_s, self.silence)
    window = 0.0 if self.silence is None else self.silence.window_s
    if variant.rule1 == "tree":
        d = np.hypot(*(pos[:, None, :] - pos[None, :, :]).transpose(2, 0, 1))
        up = _in_sight(self.occupancy, pos) & (d < limits.range_m - limits.margin_m)
        tree = minimum_spanning_tree(np.triu(np.where(up, d + 1e-9, 0.0))).toarray() > 0
        return tree | tree.T, quiet
    if variant.rule1 == "plan-true":
        knows = copy.copy(knows)
        knows.xy = np.broadcast_to(pos[None, :, :], knows.xy.shape).copy()
        knows.sent_s = np.where(np.isfinite(knows.sent_s), t0, -np.inf)
        knows.leg_speed_mps = np.zeros_like(knows.leg_speed_mps)
        knows.leg_from_s = np.full_like(knows.leg_from_s, -np.inf)
        window = 0.0
    speed = limits.speed_max_mps
    gone = local.let_go(pos, knows, heard, t0, speed, c.band_m, limits.range_m, self.local_walls, None, window, quiet)
    return heard.known & ~quiet & ~gone, quiet


def ranks(t_s: float, n: int) -> np.ndarray:
    """Each robot's rank at the step at ``t_s``: a permutation every robot can compute."""
    return np.random.default_rng(int(round(t_s * 1000))).permutation(n)


def turn_takers(group: np.ndarray, rank: np.ndarray) -> np.ndarray:
    """The robots that move at a step: those that outrank every robot of their turn group
    (``group``, ``(n, n)``, symmetric), so that of two robots in each other's group at most
    one moves."""
    return ~(group & (rank[None, :] > rank[:, None])).any(axis=1)


def _turns(self, step, variant: Variant):
    from netsim.mobility import local
    from netsim.mobility.geodesic import short_of_walls, within_reach

    memory, knows, heard = self.memory, self.knows, self.heard
    limits, pos, t0 = self.local_limits, step.positions_m, step.t_s
    n = len(pos)
    kept, quiet = _kept(self, step, variant)
    self.kept, self.silent, self.halves = kept, quiet, None
    announced, earlier = (self.announced_mps, self.announced_s), (self.earlier_mps, self.earlier_s)
    wish = step.velocity_mps + local.latest_pulls(pos, knows, kept, announced, earlier, t0, limits, memory.sent_s)
    self.earlier_mps, self.earlier_s = self.announced_mps, self.announced_s
    self.announced_mps = within_reach(self.occupancy, pos, wish, limits.period_s, limits.reach_m)
    self.announced_s = self.env.now
    group = (kept | kept.T) if variant.turns == "kept" else (heard.known | heard.known.T)
    moves = turn_takers(group, ranks(t0, n))
    plan = local.plan_local(pos, wish * moves[:, None], knows, kept, t0, limits)
    move = short_of_walls(self.occupancy, pos, plan.velocity_mps * limits.period_s, 1.0)
    planned = move.copy()
    robot, other = np.nonzero(kept & (np.hypot(*move.T) > 0)[:, None])
    best = np.ones(n)
    best[robot] = 0.0  # a mover with kept links takes the largest fraction they all pass
    for s in sorted(x for x in local.WALL_TRIES if x > 0):
        if len(robot) == 0:
            break
        ok = np.ones(len(robot), dtype=bool)
        if variant.test == "sight":
            from netsim.world.los import line_of_sight

            for f in np.linspace(0.0, 1.0, SIGHT_POINTS):
                ok &= line_of_sight(self.occupancy, pos[robot] + f * s * move[robot], pos[other])
        else:
            q = knows.xy[robot, other]
            e0 = local.travel_at_cap_m(knows.sent_s[robot, other], t0, limits.speed_max_mps)
            ok &= local.step_clear_of_walls(self.local_walls, pos[robot], s * move[robot], q, e0)
        failed = np.zeros(n, dtype=bool)
        failed[robot[~ok]] = True
        passed = np.zeros(n, dtype=bool)
        passed[robot] = True
        best = np.where(passed & ~failed, s, best)
    move = move * best[:, None]
    changed = np.hypot(*(move - planned).T) > 1e-9 * limits.range_m
    held = plan.held | ((plan.velocity_mps != 0).any(axis=1) & changed)
    return plan._replace(velocity_mps=move / limits.period_s, held=held)


def run(name: str, radio: str, n: int, seed: int, duration_s: float, start_side_m: float) -> dict:
    install(VARIANTS[name])
    row = one(radio, "local", n, seed, duration_s, start_side_m, STOPPING)
    return {"variant": name, **{k: row[k] for k in ("radio", "N", "seed", "final", "split", "moved_m")}}


def main(argv=None) -> int:
    p = Parser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--variants", nargs="+", default=list(VARIANTS), help=f"of {list(VARIANTS)} (default all)")
    p.add_argument("--n", type=int, default=40, help="robots (default 40)")
    p.add_argument("--seeds", type=int, default=3, help="seeds per row, 1 .. SEEDS (default 3)")
    p.add_argument("--radio", default=MAP_RADIOS[0], help=f"of {MAP_RADIOS} (default {MAP_RADIOS[0]!r})")
    p.add_argument("--start-side", type=float, default=60.0, help="side of the start square, m (default 60)")
    p.add_argument("--duration", type=float, default=600.0, help="simulated seconds per run (default 600)")
    p.add_argument("--workers", type=int, default=2, help="runs at a time, one process each (default 2)")
    args = p.parse_args(argv)
    unknown = [v for v in args.variants if v not in VARIANTS]
    if unknown:
        raise NetsimInputError(f"--variants {unknown[0]!r}: not one of {list(VARIANTS)}")
    if args.radio not in MAP_RADIOS:
        raise NetsimInputError(f"--radio {args.radio!r}: not one of {MAP_RADIOS}")
    for option, value in (("--n", args.n), ("--seeds", args.seeds), ("--workers", args.workers)):
        if value < 1:
            raise NetsimInputError(f"{option} {value}: at least 1")
    for option, x in (("--start-side", args.start_side), ("--duration", args.duration)):
        if not x > 0:
            raise NetsimInputError(f"{option} {x:g}: must be positive")
    jobs = [
        (v, args.radio, args.n, seed, args.duration, args.start_side)
        for v in args.variants
        for seed in range(1, args.seeds + 1)
    ]
    # One process per run: a variant replaces the plan's methods in the process it runs in.
    with ProcessPoolExecutor(args.workers, max_tasks_per_child=1) as pool:
        runs = pd.DataFrame(list(pool.map(run, *zip(*jobs))))
    out = (
        runs.groupby("variant", sort=False)
        .agg(
            seeds=("seed", "size"),
            final=("final", "mean"),
            final_min=("final", "min"),
            split=("split", "sum"),
            moved_m=("moved_m", "mean"),
        )
        .reset_index()
        .rename(columns={"final_min": "final min"})
    )
    with pd.option_context("display.width", 200, "display.float_format", "{:.3f}".format):
        print(out.to_string(index=False))
    return 0


if __name__ == "__main__":
    run_script(lambda: sys.exit(main()))
