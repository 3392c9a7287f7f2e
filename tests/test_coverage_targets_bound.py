"""experiments/coverage_targets.py ``--bound`` (docs/model.md 5.2, "Under 4 dB shadowing"):
rule 1 replaced by an oracle that reads the true network, to bound what rule 1 could give.
One test per rule of the oracle; and the script's refusal of a bad ``--set``."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from tests.fixtures import script

ROOT = Path(__file__).resolve().parents[1]


def targets():
    return script("experiments/coverage_targets.py")


def exit_status(monkeypatch, argv: list[str]) -> int:
    """The exit status of ``coverage_targets.py ARGV`` as its ``__main__`` runs it: ``main``
    within :func:`netsim.tools.sweep.run_script`, which says bad input in one line."""
    from netsim.tools.sweep import run_script

    monkeypatch.setattr(sys, "argv", ["coverage_targets.py"])
    module = targets()
    with pytest.raises(SystemExit) as exit_:
        run_script(lambda: sys.exit(module.main(argv)))
    return exit_.value.code


# Robot 0 at the origin, 1 at 80 m, 2 between them (about 43 m from each): the link 0-1 is the
# longest; in the global plan's order (weight) the short link 0-2 is the weakest, as if in a
# deep fade.
POS = np.array([[0.0, 0.0], [80.0, 0.0], [40.0, 15.0]])
LINKS = SimpleNamespace(i=np.array([0, 0, 1]), j=np.array([1, 2, 2]), weight=np.array([2.0, 3.0, 1.0]))


def controller():
    return SimpleNamespace(rules=SimpleNamespace(candidates=lambda pos, t_s: LINKS))


def heard(known: np.ndarray):
    return SimpleNamespace(known=known)


def test_bound_oracle_lets_go_of_a_link_joined_through_links_before_it_over_the_robots_remembered():
    """By length over the robots it remembers: robot 0 lets go of 1 (80 m) when it remembers 2,
    the detour 0-2-1 being of shorter links up; not when it does not remember 2 (the detour is
    out of its graph), though the whole team's graph has it; it never lets go of a robot it
    does not remember."""
    t = targets()
    everyone = ~np.eye(3, dtype=bool)
    out = t.oracle_let_go(controller(), "length", "remembered")(POS, None, heard(everyone), 10.0)
    assert out[0, 1] and not out[0, 2] and not out[1, 2]
    only_1 = everyone.copy()
    only_1[0, 2] = False
    assert not t.oracle_let_go(controller(), "length", "remembered")(POS, None, heard(only_1), 10.0)[0, 1]
    team = t.oracle_let_go(controller(), "length", "team")(POS, None, heard(only_1), 10.0)
    assert team[0, 1] and not team[0, 2]
    assert not t.oracle_let_go(controller(), "margin", "team")(POS, None, heard(only_1), 10.0)[0, 2]


def test_bound_oracle_over_two_hops_reaches_the_robots_remembered_by_those_it_remembers():
    """Over two hops robot 0's graph holds the robots it remembers and those they remember: it
    lets go of 1 through 2, which it does not remember but 1 does; not when no robot it
    remembers remembers 2 (then 2 is out of its graph, as over the robots it remembers)."""
    t = targets()
    memories = ~np.eye(3, dtype=bool)
    memories[0, 2] = False
    out = t.oracle_let_go(controller(), "length", "two hops")(POS, None, heard(memories), 10.0)
    assert out[0, 1] and not out[0, 2]
    assert not t.oracle_let_go(controller(), "length", "remembered")(POS, None, heard(memories), 10.0)[0, 1]
    memories[1, 2] = False
    assert not t.oracle_let_go(controller(), "length", "two hops")(POS, None, heard(memories), 10.0)[0, 1]


def test_bound_oracle_by_margin_lets_go_of_a_short_link_in_a_deep_fade():
    """In the global plan's order (the margin left, as its weights) robot 0 lets go of its short
    link to 2, the weakest, through 0-1-2, and keeps the long 0-1, which no detour of
    stronger links replaces."""
    t = targets()
    everyone = ~np.eye(3, dtype=bool)
    out = t.oracle_let_go(controller(), "margin", "remembered")(POS, None, heard(everyone), 10.0)
    assert out[0, 2] and not out[0, 1]
    assert out[2, 0] and not out[1, 0] and not out[1, 2]


def test_bound_oracle_by_records_orders_as_rule_1_does():
    """In rule 1's own order (bands of the length at zero shadowing under the records, then the
    ends' ids): with every record at 0 dB robot 0 lets go of 1 (80 m) through 2, as by length;
    a deep fade recorded on 0-2 (+12 dB: 43 m is 107 m at zero shadowing) puts that link last,
    and 0 lets go of 2 through 1 instead; a link without a record comes after every other; links
    of one band come in the order of their ends' ids."""
    from netsim.mobility.keep import FADE_SIGMAS
    from netsim.mobility.local import FadeRule

    t = targets()
    everyone = ~np.eye(3, dtype=bool)
    rule = FadeRule(True, 4.0, 10.0, 60.0, 1.0, 3.0, FADE_SIGMAS)  # nominal reach 100 m
    ctl = controller()
    ctl.fade, ctl.cfg = SimpleNamespace(rule=rule), SimpleNamespace(band_m=7.5)

    def oracle(records_db):
        return t.oracle_let_go(ctl, "records", "two hops")(
            POS, None, SimpleNamespace(known=everyone, records_db=records_db), 10.0
        )

    flat = np.zeros((3, 3))
    out = oracle(flat)
    assert out[0, 1] and not out[0, 2] and not out[1, 2]
    fade = flat.copy()
    fade[0, 2] = 12.0
    out = oracle(fade)
    assert out[0, 2] and out[2, 0] and not out[0, 1] and not out[1, 2]
    unread = flat.copy()
    unread[1, 2] = np.nan
    out = oracle(unread)
    assert out[1, 2] and out[2, 1] and not out[0, 1] and not out[0, 2]
    # Three links of one band (40 m apart each) are ordered by their ends' ids: 1-2 comes last.
    triangle = np.array([[0.0, 0.0], [40.0, 0.0], [20.0, 34.64]])
    out = t.oracle_let_go(ctl, "records", "two hops")(
        triangle, None, SimpleNamespace(known=everyone, records_db=flat), 10.0
    )
    assert out[1, 2] and out[2, 1] and not out[0, 1] and not out[0, 2]


@pytest.mark.slow
def test_bound_runs_every_plan_and_oracle_on_each_seed_and_prints_their_ratios(tmp_path):
    """``--bound`` runs, on each seed, the global plan, the local plan and the local plan with
    each oracle of rule 1, writes every run as it ends, and prints each over the global plan."""
    run = subprocess.run(
        [sys.executable, str(ROOT / "experiments" / "coverage_targets.py"), "--bound", "--n", "8", "--seeds", "1"]
        + ["--duration", "40", "--workers", "1", "--csv", str(tmp_path / "b.csv")],
        capture_output=True,
        text=True,
        cwd=tmp_path,
    )
    assert run.returncode == 0, run.stderr[-2000:]
    runs = pd.read_csv(tmp_path / "b.csv")
    assert sorted(runs["plan"]) == sorted(["global", "local", *targets().ORACLES])
    assert "margin, team" in run.stdout and "least" in run.stdout


def test_bound_runs_only_the_oracles_asked_and_counts_the_seeds_at_80_percent(tmp_path, monkeypatch, capsys):
    """``--oracles`` picks rule 1's oracles by their slugs (the global and local plans run
    always), and the table ends with the seeds at 0.8 or more of the global plan."""
    module = targets()
    ran = []

    def fake(job, duration_s):
        kind, n, seed = job
        ran.append(kind)
        of_bound = {"global": 0.5, "local": 0.35, "margin, team": 0.45}[kind] * (1.0 if seed == 1 else 0.8)
        return {"N": n, "seed": seed, "plan": kind, "of bound": of_bound, "grew": 0}

    monkeypatch.setattr(module, "run_jobs", lambda one, jobs, args: pd.DataFrame([fake(j, 0.0) for j in jobs]))
    assert module.main(["--bound", "--seeds", "2", "--n", "8", "--oracles", "margin-team"]) == 0
    assert sorted(set(ran)) == ["global", "local", "margin, team"]
    out = capsys.readouterr().out.strip().splitlines()
    # N, local, margin-team: the local plan at 0.7 of the global plan on both seeds, the oracle at 0.9.
    assert out[-3] == "seeds at 0.8 or more of the global plan:" and out[-1].split() == ["8", "0", "2"]


def test_oracles_outside_bound_is_one_line_exit_2(capsys, monkeypatch):
    code = exit_status(monkeypatch, ["--shadowing", "--oracles", "margin-team"])
    err = capsys.readouterr().err
    assert code == 2 and err.strip().splitlines() == ["coverage_targets.py: error: --oracles applies to --bound only"]


# Unknown, out of range, without a value, and keys that name a run in the table (dotted or as a table).
BAD_SETTINGS = ["coverage.nonsense=1", "coverage.detour_sigmas=-1", "coverage.detour_sigmas"]
BAD_SETTINGS += ["coverage.plan=local", "seed=3", 'coverage={plan="global"}', "world={n_robots=5}"]


@pytest.mark.parametrize("setting", BAD_SETTINGS)
def test_shadowing_with_a_bad_setting_is_one_line_exit_2_and_writes_nothing(tmp_path, capsys, monkeypatch, setting):
    """``--shadowing --set``: a setting the configuration refuses stops the script before any
    run, with one line on stderr and exit 2, and no CSV."""
    csv = tmp_path / "s.csv"
    code = exit_status(monkeypatch, ["--shadowing", "--seeds", "1", "--n", "8", "--set", setting, "--csv", str(csv)])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1 and "coverage_targets.py: error:" in err
    assert not csv.exists()


@pytest.mark.parametrize(
    "args, said",
    [
        (["--n", "20", "0"], "--n 0: at least 1"),
        (["--shadowing", "--seeds", "0"], "--seeds 0: at least 1"),
        (["--workers", "0"], "--workers 0: at least 1"),
        (["--duration", "-1"], "--duration -1: must be finite and after control starts (10 s)"),
        (["--why", "--duration", "nan"], "--duration nan: must be finite and after control starts (10 s)"),
        (["--why", "--duration", "inf"], "--duration inf: must be finite and after control starts (10 s)"),
        (["--why", "--duration", "5"], "--duration 5: must be finite and after control starts (10 s)"),
        (["--why", "--seed", "-1"], "--seed -1: must be >= 0"),
    ],
)
def test_bad_sizes_seeds_workers_or_duration_are_one_line_exit_2(tmp_path, capsys, monkeypatch, args, said):
    """Refused before any run (a run of 0 robots or a pool of 0 workers would end in a
    traceback): one line naming the option, exit 2, no CSV."""
    csv = tmp_path / "s.csv"
    code = exit_status(monkeypatch, [*args, "--csv", str(csv)])
    err = capsys.readouterr().err
    assert code == 2 and err.strip().splitlines() == [f"coverage_targets.py: error: {said}"]
    assert not csv.exists()


@pytest.mark.parametrize("mode", [[], ["--bound"], ["--why"], ["--shadowing", "--bound"]])
def test_set_outside_shadowing_is_one_line_exit_2(tmp_path, capsys, monkeypatch, mode):
    """``--set`` acts on ``--shadowing`` runs alone: elsewhere it would be ignored, so it is
    refused (one line, exit 2, no CSV)."""
    csv = tmp_path / "s.csv"
    code = exit_status(monkeypatch, [*mode, "--set", "coverage.detour_sigmas=2", "--csv", str(csv)])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1 and "--shadowing runs only" in err
    assert not csv.exists()


def test_shadowing_table_counts_ratios_whole_networks_and_settled_runs():
    """One row per N from both plans' runs: the local plan's share of the global plan's
    coverage on the same seed (least, mean, seeds at 80 % or more), the seeds whose network
    gained nothing, and the runs whose control ended before the run (NaN: cut while still
    spreading); the row passes only when every seed reaches 80 %."""
    runs = pd.DataFrame(
        {
            "plan": ["global", "local"] * 3,
            "N": [20] * 6,
            "seed": [1, 1, 2, 2, 3, 3],
            "of bound": [0.5, 0.45, 0.6, 0.42, 0.4, 0.36],
            "grew": [0, 0, 0, 1, 0, 0],
            "settled s": [400.0, 300.0, np.nan, 500.0, 350.0, np.nan],
        }
    )
    row = targets().shadowing_table(runs).iloc[0]
    assert row["local/global least"] == pytest.approx(0.7) and row["seeds >= 80 %"] == 2
    assert (row["global whole"], row["local whole"]) == (3, 2)
    assert (row["global settled"], row["local settled"]) == (2, 2)
    assert not row["pass"]
