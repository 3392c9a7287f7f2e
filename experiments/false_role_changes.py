"""False role changes against loss and ``tau / ack_period`` (docs/validation.md item 9).

Pairs of static robots, far from each other, each pair a leader and its member, so that
every leader loss is false: the member times out only when ``k`` consecutive Acks of its
leader are lost (``k`` = Ack instants in the ``tau`` window, its end included). A sweep of
``channel.loss_probability`` x ``protocol.tau_s`` (Ack period 1 s, no jitter) measures the
leader's Acks until the first false timeout, against the theory
``(1 - p^k) / ((1 - p) p^k)`` (infinite at ``p = 0``, its limit: no Ack is lost, no wait
ends), and the false role changes per robot per minute. A member
still waiting when the run ends counts its Acks so far
(:func:`netsim.tools.analysis.mean_acks_until_leader_loss`): the completed waits alone
leave the long ones out and fall short of the theory.

Writes ``false_role_changes.csv`` (its columns: docs/experiments.md) and
``false_role_changes.png``.

    python experiments/false_role_changes.py
    python experiments/false_role_changes.py --losses 0.2 0.4 0.6 --taus 1.5 2.5 3.5 --pairs 300
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pandas as pd
from netsim.protocols.roles import LABELS

from netsim.errors import NetsimInputError
from netsim.tools import analysis
from netsim.tools import sweep as sweepmod
from netsim.tools.args import Parser
from netsim.tools.figures import pyplot
from netsim.tools.output import claim_dir


def _sweep(args, placement: str):
    """The sweep of tau and loss over pairs placed by ``placement`` (a file, or a name to
    check the points with before the file is written)."""
    return sweepmod.parse(
        {
            "name": "false_role_changes",
            "replications": args.reps,
            "tables": ["roles"],
            "base": {
                "seed": args.seed,
                "duration_s": args.duration,
                "world": {
                    "n_robots": 2 * args.pairs,
                    "side_m": 100.0 * args.pairs,
                    "placement": placement,
                },
                "mobility": {"model": "static"},
                "channel": {"range_m": 10.0},
                "protocol": {
                    "model": "clustering",
                    "ack_period_s": 1.0,
                    "ack_jitter_s": 0.0,
                    "election_policy": "none",
                    "message_rate_hz": 0.0,
                },
                "output": {"position_interval_s": 0.0},
            },
            "grid": {"channel.loss_probability": args.losses, "protocol.tau_s": args.taus},
        }
    )


def waits_by_pair(roles: pd.DataFrame, tau_s: float, end_s: float) -> pd.DataFrame:
    """The waits of :func:`netsim.tools.analysis.acks_waited`, one per robot that became a
    member (both robots of a pair can, one after the other), each with its ``run_id`` and
    ``pair``: robots ``2i`` and ``2i + 1`` are pair ``i`` (the placement's order)."""
    waits = [
        analysis.acks_waited(rr, tau_s, 1.0, LABELS, end_s).assign(run_id=run_id, pair=pair)
        for (run_id, pair), rr in roles.groupby(["run_id", roles["robot"] // 2])
    ]
    return pd.concat(waits, ignore_index=True)


def main(argv=None) -> None:
    p = Parser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--pairs", type=int, default=200)
    p.add_argument("--losses", type=float, nargs="+", default=[0.2, 0.3, 0.4, 0.5, 0.6])
    p.add_argument("--taus", type=float, nargs="+", default=[1.5, 2.5, 3.5], help="tau in Ack periods (1 s)")
    p.add_argument("--duration", type=float, default=300.0)
    sweepmod.add_runner_arguments(p, "false_role_changes", reps=1)
    args = p.parse_args(argv)
    if args.pairs < 1:
        raise NetsimInputError(f"--pairs {args.pairs}: at least 1")
    for loss in args.losses:
        if not 0 <= loss < 1:
            raise NetsimInputError(f"--losses {loss:g}: each a probability in [0, 1)")
    # Every point and the workers checked, the scheduler reached and the folders judged before
    # the placement file is written: bad input leaves no output behind.
    sweepmod.check_workers(args.workers)
    checked = _sweep(args, "uniform")
    checked.runs()
    scheduler = sweepmod.connect(args.scheduler) if args.scheduler else None
    with claim_dir(args.out, "--out") as out:
        sweepmod.refuse_another_sweeps_dir(out / "sweep", checked.name)
        measure(args, out, scheduler)


def measure(args, out: Path, scheduler) -> None:
    """The sweep run into ``out`` (its placement file written first), its table and figure."""
    pos = np.zeros((2 * args.pairs, 2))
    pos[0::2, 0] = pos[1::2, 0] = np.arange(args.pairs) * 100.0
    pos[1::2, 1] = 5.0
    placement = out / "pairs.csv"
    pd.DataFrame(pos, columns=["x_m", "y_m"]).to_csv(placement, index=False)
    sweep = _sweep(args, str(placement.resolve()))
    print(sweepmod.run_sweep(sweep, out / "sweep", workers=args.workers, scheduler=scheduler).text())
    runs = sweepmod.load(out / "sweep")
    roles = sweepmod.load_table(out / "sweep", "roles")
    rows = []
    for (loss, tau), g in runs.groupby(["channel.loss_probability", "protocol.tau_s"]):
        r = roles[roles.run_id.isin(g.run_id)]
        waited = waits_by_pair(r, tau, args.duration)
        pairs = waited[["run_id", "pair"]].drop_duplicates()
        mean, low, high = analysis.mean_acks_until_leader_loss(waited)
        k = analysis.spurious_timeout_window(tau, 1.0)
        false_changes = (r.cause == LABELS.leader_lost).sum() / (len(g) * 2 * args.pairs * args.duration / 60)
        rows.append(
            {
                "loss_probability": loss,
                "tau_over_period": tau,
                "k": k,
                "pairs_measured": len(pairs),
                "waits_measured": len(waited),
                "pairs_still_waiting": len(waited.loc[~waited["lost"], ["run_id", "pair"]].drop_duplicates()),
                "acks_until_false_loss": mean,
                "ci95_low": low,
                "ci95_high": high,
                "theory": analysis.expected_acks_until_spurious_timeout(loss, k),
                "false_leader_losses_per_robot_per_min": false_changes,
            }
        )
    df = pd.DataFrame(rows)
    df.to_csv(out / "false_role_changes.csv", index=False)
    plt = pyplot()
    fig, (left, right) = plt.subplots(1, 2, figsize=(10, 4), constrained_layout=True)
    ps = np.linspace(min(args.losses), max(args.losses), 100)
    for tau, g in df.groupby("tau_over_period"):
        k = int(g.k.iloc[0])
        line = left.errorbar(
            g.loss_probability,
            g.acks_until_false_loss,
            yerr=[g.acks_until_false_loss - g.ci95_low, g.ci95_high - g.acks_until_false_loss],
            fmt="o",
            capsize=3,
            label=f"tau = {tau:g} t (k = {k})",
        )
        left.plot(ps, analysis.expected_acks_until_spurious_timeout(ps, k), "--", color=line[0].get_color())
        right.plot(g.loss_probability, g.false_leader_losses_per_robot_per_min, "o-", label=f"tau = {tau:g} t")
    left.set(
        xlabel="loss probability p",
        ylabel="leader Acks until a false leader loss",
        yscale="log",
        title="measured (95 % CI) and theory (dashed)",
    )
    left.legend()
    right.set(
        xlabel="loss probability p",
        ylabel="false leader losses per robot per minute",
        title=f"{args.pairs} static leader-member pairs",
    )
    right.legend()
    fig.savefig(out / "false_role_changes.png", dpi=120)
    print(df.round(3).to_string(index=False))
    print(f"wrote {out / 'false_role_changes.csv'} and {out / 'false_role_changes.png'}")


if __name__ == "__main__":
    sweepmod.run_script(main, resumable=True)
