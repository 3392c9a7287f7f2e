"""Link-lifetime analysis: Kaplan-Meier with censoring, against a hand-computed example."""

import numpy as np
import pandas as pd
import pytest

from netsim.tools.analysis import kaplan_meier, lifetime_summary, link_durations, median, restricted_mean


def test_kaplan_meier_hand_computed_example():
    """Durations 1, 2, 2+, 3, 4+, 5 (+: censored).
    S(1) = 5/6; S(2) = 5/6 * 4/5 = 2/3 (the link censored at 2 is still at risk at 2);
    S(3) = 2/3 * 2/3 = 4/9; S(5) = 0. Median 3. Area under S up to 5:
    1 + 5/6 + 2/3 + 2 * 4/9 = 3.3889."""
    d, e = [1, 2, 2, 3, 4, 5], [1, 1, 0, 1, 0, 1]
    km = kaplan_meier(d, e)
    assert km["t_s"].tolist() == [1, 2, 3, 5]
    assert km["at_risk"].tolist() == [6, 5, 3, 1]
    assert km["survival"].tolist() == pytest.approx([5 / 6, 2 / 3, 4 / 9, 0.0])
    assert median(km)[0] == 3
    mean, lo, hi = restricted_mean(km, d, e)
    assert mean == pytest.approx(1 + 5 / 6 + 2 / 3 + 2 * 4 / 9)
    assert lo < mean < hi
    # Greenwood at t = 1: S^2 * 1 / (6 * 5); the log-log band contains S.
    assert (km["ci_low"] <= km["survival"]).all() and (km["survival"] <= km["ci_high"]).all()


def test_without_censoring_the_restricted_mean_is_the_mean():
    d = np.random.default_rng(1).exponential(10.0, 500)
    km = kaplan_meier(d, np.ones(500, bool))
    assert restricted_mean(km, d, np.ones(500, bool))[0] == pytest.approx(d.mean())
    assert median(km)[0] == pytest.approx(np.sort(d)[249], abs=1e-12)


def test_censoring_corrected_mean_beats_dropping_censored_links():
    """Exponential lifetimes (mean 10) cut at 12: KM recovers the survival curve where the
    naive mean of the ended links is far too low."""
    rng = np.random.default_rng(2)
    true = rng.exponential(10.0, 20_000)
    d, e = np.minimum(true, 12.0), true <= 12.0
    km = kaplan_meier(d, e)
    s_at_5 = km.loc[km.t_s <= 5, "survival"].iloc[-1]
    assert s_at_5 == pytest.approx(np.exp(-0.5), abs=0.01)
    assert d[e].mean() < 5.0  # the naive answer
    assert restricted_mean(km, d, e)[0] == pytest.approx(10 * (1 - np.exp(-1.2)), rel=0.02)


def test_link_durations_skip_links_up_at_the_start():
    links = pd.DataFrame(
        {
            "a": [0, 0, 1],
            "b": [1, 2, 2],
            "t_up_s": [0.0, 3.0, 5.0],
            "t_down_s": [4.0, 8.0, 10.0],
            "censored": [True, False, True],
            "censored_start": [True, False, False],
            "censored_end": [False, False, True],
        }
    )
    ld = link_durations(links)
    assert ld["duration_s"].tolist() == [5.0, 5.0] and ld["observed"].tolist() == [True, False]
    s = lifetime_summary(links)
    assert s["links"] == 2 and s["censored"] == 1


def test_kaplan_meier_counts_at_risk_and_ends_at_every_time():
    """At each ended lifetime t, ``at_risk`` counts the lifetimes at least t long (ended
    or not) and ``events`` the ended ones equal to t: ties and censoring at t included."""
    rng = np.random.default_rng(5)
    d = rng.integers(1, 30, 400).astype(float)
    e = rng.random(400) < 0.6
    km = kaplan_meier(d, e)
    for t, n, ev in km[["t_s", "at_risk", "events"]].to_numpy().tolist():
        assert n == (d >= t).sum() and ev == ((d == t) & e).sum()


@pytest.fixture(scope="module")
def default_run():
    from netsim.run import execute
    from tests.fixtures import make_config

    config = make_config(seed=1, duration_s=150.0, world={"n_robots": 30, "side_m": 600.0}, channel={"range_m": 100.0})
    return execute(config)


def test_summary_leads_with_the_kaplan_meier_mean_link_duration(default_run):
    """The summary's first link duration is the Kaplan-Meier restricted mean of
    ``lifetime_summary`` with its confidence interval (links up at the end counted), before
    ``mean_link_duration_s``, the mean of the complete links alone (kept, and lower)."""
    summary, links = default_run.summary, default_run.frames["links"]
    km = lifetime_summary(links)
    assert summary["link_duration_km_mean_s"] == km["mean_s"]
    assert summary["link_duration_km_ci_low_s"] == km["mean_ci_low_s"]
    assert summary["link_duration_km_ci_high_s"] == km["mean_ci_high_s"]
    keys = list(summary)
    assert keys.index("link_duration_km_mean_s") < keys.index("mean_link_duration_s")
    done = links[~links["censored"]]
    assert summary["mean_link_duration_s"] == (done["t_down_s"] - done["t_up_s"]).mean()
    assert links["censored_end"].any() and summary["mean_link_duration_s"] < summary["link_duration_km_mean_s"]


def test_printed_summary_names_the_complete_links_mean_for_what_it_is(default_run):
    """The printed summary shows ``mean_link_duration_s`` as the mean of complete links
    only, and the Kaplan-Meier mean as such; summary.json keeps the bare keys."""
    from netsim.tools.cli import summary_table

    lines = summary_table(default_run.summary).splitlines()
    assert any(ln.split()[:4] == ["mean_link_duration_s", "(complete", "links", "only)"] for ln in lines)
    assert any(ln.split()[:2] == ["link_duration_km_mean_s", "(Kaplan-Meier)"] for ln in lines)


def test_acks_waited_counts_a_member_still_waiting_at_the_end_as_censored():
    """Robot 1 joins at 10 s and times out at 20.5 s (tau 2.5 s, period 1 s, k = 2): 8 + 2
    Acks; robot 3 joins at 12 s and is still waiting at the run's end, 40 s: 28 Acks so
    far, right-censored; robot 0 never became a member."""
    from netsim.protocols.roles import LABELS

    from netsim.tools.analysis import acks_until_leader_loss, acks_waited

    roles = pd.DataFrame(
        {
            "t_s": [0.0, 10.0, 20.5, 12.0],
            "robot": [0, 1, 1, 3],
            "role": [LABELS.leader, LABELS.member, LABELS.undecided, LABELS.member],
            "cause": ["", "", LABELS.leader_lost, ""],
        }
    )
    waited = acks_waited(roles, 2.5, 1.0, LABELS, 40.0)
    assert waited["acks"].tolist() == [10.0, 28.0] and waited["lost"].tolist() == [True, False]
    assert acks_until_leader_loss(roles, 2.5, 1.0, LABELS).tolist() == [10.0]


def test_mean_wait_counts_the_waits_cut_by_the_end():
    """Memoryless waits of mean 100 Acks cut at 150: the mean of the completed waits falls
    short (about 56), the waits so far counted give the mean back within its interval."""
    from netsim.tools.analysis import mean_acks_until_leader_loss

    rng = np.random.default_rng(3)
    wait = rng.geometric(1 / 100.0, 2000).astype(float)
    waited = pd.DataFrame({"acks": np.minimum(wait, 150.0), "lost": wait <= 150.0})
    mean, low, high = mean_acks_until_leader_loss(waited)
    assert low < 100.0 < high and high - low < 15.0
    assert waited.loc[waited["lost"], "acks"].mean() < 60.0
