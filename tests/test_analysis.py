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


def _links(run_id: int, durations: list[float], censored_end: list[bool]) -> pd.DataFrame:
    """Links of one run, all up after its start, each lasting its duration."""
    n = len(durations)
    t_up = np.arange(n, dtype=float)
    return pd.DataFrame(
        {
            "run_id": run_id,
            "a": 0,
            "b": np.arange(1, n + 1),
            "t_up_s": t_up,
            "t_down_s": t_up + np.asarray(durations, float),
            "censored": censored_end,
            "censored_start": False,
            "censored_end": censored_end,
        }
    )


def test_compare_lifetimes_summarises_each_combination_of_the_keys_in_order():
    """One row per combination of the keys, sorted by them, each the lifetime summary of
    the links of that combination's runs alone (replications pooled); a combination whose
    runs saw no link has its row, without figures."""
    from netsim.tools.analysis import compare_lifetimes

    runs = pd.DataFrame({"run_id": [0, 1, 2, 3, 4], "speed": [2, 1, 2, 1, 2], "pause": [0, 0, 5, 5, 0]})
    links = pd.concat(
        [
            _links(0, [3.0, 5.0, 9.0], [False, False, True]),
            _links(1, [10.0, 12.0], [False, False]),
            _links(2, [1.0, 2.0, 4.0, 8.0], [False, True, False, False]),
            _links(4, [6.0, 7.0], [False, True]),
        ],
        ignore_index=True,
    )
    table = compare_lifetimes(runs, links, ["speed", "pause"])
    assert table[["speed", "pause"]].values.tolist() == [[1, 0], [1, 5], [2, 0], [2, 5]]
    expected = [
        lifetime_summary(links[links["run_id"] == 1]),
        None,
        lifetime_summary(links[links["run_id"].isin([0, 4])]),
        lifetime_summary(links[links["run_id"] == 2]),
    ]
    for row, want in zip(table.to_dict("records"), expected):
        if want is None:
            assert row["links"] == 0 and np.isnan(row["mean_s"]) and np.isnan(row["median_s"])
        else:
            assert {k: row[k] for k in want} == pytest.approx(want, nan_ok=True)


def test_compare_lifetimes_of_a_sweep_that_kept_no_link_has_a_row_per_combination():
    """A sweep none of whose runs kept a link (its links table read back empty, without
    columns): every combination has its row, without figures."""
    from netsim.tools.analysis import compare_lifetimes

    runs = pd.DataFrame({"run_id": [0, 1], "speed": [2, 1]})
    table = compare_lifetimes(runs, pd.DataFrame(), ["speed"])
    assert table["speed"].tolist() == [1, 2] and table["links"].tolist() == [0, 0]
    assert table["mean_s"].isna().all()


def test_acks_waited_counts_from_the_first_joining_to_the_first_loss_after_it():
    """Robot 1 joins at 10 s, loses its leader at 20.5 s, joins again at 30 s and loses it
    at 45.5 s (tau 2.5 s, period 1 s, k = 2): its wait is the first, 8 + 2 Acks."""
    from netsim.protocols.roles import LABELS

    from netsim.tools.analysis import acks_waited

    roles = pd.DataFrame(
        {
            "t_s": [10.0, 20.5, 30.0, 45.5],
            "robot": [1, 1, 1, 1],
            "role": [LABELS.member, LABELS.undecided, LABELS.member, LABELS.undecided],
            "cause": ["", LABELS.leader_lost, "", LABELS.leader_lost],
        }
    )
    waited = acks_waited(roles, 2.5, 1.0, LABELS, 100.0)
    assert waited["acks"].tolist() == [10.0] and waited["lost"].tolist() == [True]


def test_acks_waited_counts_whole_periods_despite_rounding():
    """Times a whole number of periods apart that floating point puts just below it still
    count that many Acks: a timeout 0.7 s after joining (tau 0.3 s, period 0.1 s: k = 3)
    is 4 + 3 Acks, a wait 0.3 s long at the end 3."""
    from netsim.protocols.roles import LABELS

    from netsim.tools.analysis import acks_waited

    roles = pd.DataFrame(
        {
            "t_s": [0.0, 0.7, 0.0],
            "robot": [1, 1, 2],
            "role": [LABELS.member, LABELS.undecided, LABELS.member],
            "cause": ["", LABELS.leader_lost, ""],
        }
    )
    assert (0.7 - 0.0 - 0.3) / 0.1 < 4 and (0.3 - 0.0) / 0.1 < 3  # the rounding in question
    waited = acks_waited(roles, 0.3, 0.1, LABELS, 0.3)
    assert waited["acks"].tolist() == [7.0, 3.0] and waited["lost"].tolist() == [True, False]


def test_mean_wait_is_every_ack_waited_over_the_losses_with_an_exponential_interval():
    """Waits of 10 and 20 Acks that ended and one of 30 still running: 60 Acks over 2
    losses, a mean of 30, within 30 exp(-+z / sqrt(2)), z the two-sided 95 % normal quantile."""
    from statistics import NormalDist

    from netsim.tools.analysis import mean_acks_until_leader_loss

    waited = pd.DataFrame({"acks": [10.0, 20.0, 30.0], "lost": [True, True, False]})
    z = NormalDist().inv_cdf(0.975)
    mean, low, high = mean_acks_until_leader_loss(waited)
    assert (mean, low, high) == pytest.approx((30.0, 30.0 * np.exp(-z / np.sqrt(2)), 30.0 * np.exp(z / np.sqrt(2))))


def test_mean_wait_without_a_loss_is_not_a_number():
    from netsim.tools.analysis import mean_acks_until_leader_loss

    waited = pd.DataFrame({"acks": [12.0, 30.0], "lost": [False, False]})
    assert all(np.isnan(v) for v in mean_acks_until_leader_loss(waited))


def test_torus_link_duration_mean_is_pi_squared_r_over_8_v():
    """docs/validation.md item 6: pi^2 R / (8 v), here R = 100 m, v = 2 m/s."""
    from netsim.tools.analysis import torus_link_duration_mean

    assert torus_link_duration_mean(100.0, 2.0) == pytest.approx(np.pi**2 * 100.0 / 16.0)
    assert torus_link_duration_mean(100.0, 2.0) == pytest.approx(61.685, abs=1e-3)


def test_only_a_rule3_timeout_ends_a_wait_for_a_leader_loss():
    """A member made undecided by another rule (its leader resigned) did not lose its leader
    by timeout: no wait ended for it."""
    from netsim.protocols.roles import LABELS

    from netsim.tools.analysis import acks_waited

    roles = pd.DataFrame(
        {
            "t_s": [10.0, 15.0],
            "robot": [1, 1],
            "role": [LABELS.member, LABELS.undecided],
            "cause": ["rule2_join", "rule5_leader_resigned"],
        }
    )
    assert acks_waited(roles, 2.5, 1.0, LABELS).empty


# The durations of test_kaplan_meier_hand_computed_example: 1, 2, 2+, 3, 4+, 5.
_D, _E = [1, 2, 2, 3, 4, 5], [1, 1, 0, 1, 0, 1]
# Two-sided standard normal quantiles, written out (not computed as the module does).
_Z = {0.95: 1.959963984540054, 0.8: 1.2815515655446004}


def test_kaplan_meier_refuses_durations_and_observed_of_unequal_lengths():
    with pytest.raises(ValueError, match="durations and observed must have the same length"):
        kaplan_meier([1.0, 2.0, 3.0], [True, False])


@pytest.mark.parametrize("level", [0.95, 0.8])
def test_the_kaplan_meier_band_is_greenwoods_on_the_log_log_scale_at_the_level_asked(level):
    """Greenwood's sums by hand (d / (n (n - d)) at each end: 1/30, + 1/20, + 1/6), the band
    ``S ** exp(+-z se)`` with ``se = sqrt(greenwood) / |log S|`` and ``z`` the level's
    two-sided normal quantile."""
    km = kaplan_meier(_D, _E, level)
    z = _Z[level]
    for row, (s, g) in enumerate([(5 / 6, 1 / 30), (2 / 3, 1 / 30 + 1 / 20), (4 / 9, 1 / 30 + 1 / 20 + 1 / 6)]):
        se = np.sqrt(g) / abs(np.log(s))
        assert km["ci_low"][row] == pytest.approx(s ** np.exp(z * se), rel=1e-12)
        assert km["ci_high"][row] == pytest.approx(s ** np.exp(-z * se), rel=1e-12)


def test_where_the_survival_reaches_zero_its_band_is_zero():
    """The last lifetime at risk ends at 5: the survival is 0 there, and so is its band,
    both edges (the upper end of the median's interval is then that time)."""
    km = kaplan_meier(_D, _E)
    last = km.iloc[-1]
    assert (last["survival"], last["ci_low"], last["ci_high"]) == (0.0, 0.0, 0.0)
    assert median(km)[2] == 5.0


@pytest.mark.parametrize("level", [0.95, 0.8])
def test_the_restricted_means_interval_is_klein_and_moeschbergers(level):
    """Variance: the sum over ends t_i of A_i ** 2 d_i / (n_i (n_i - d_i)), A_i the area under
    the curve from t_i to the horizon (5 s: 43/18, 14/9, 8/9; the end at 5, n = d,
    adds nothing); the interval is the mean plus and minus z times its root."""
    km = kaplan_meier(_D, _E, level)
    mean, lo, hi = restricted_mean(km, _D, _E, level=level)
    areas = [5 / 6 + 2 / 3 + 8 / 9, 2 / 3 + 8 / 9, 8 / 9]
    var = areas[0] ** 2 / 30 + areas[1] ** 2 / 20 + areas[2] ** 2 / 6
    half = _Z[level] * np.sqrt(var)
    assert mean - lo == pytest.approx(half, rel=1e-12) and hi - mean == pytest.approx(half, rel=1e-12)


def test_the_median_is_the_first_time_the_survival_falls_to_one_half_or_below():
    """Four lifetimes 1, 2, 3, 4, all ended: the survival is exactly 1/2 at 2, the median."""
    assert median(kaplan_meier([1, 2, 3, 4], [1, 1, 1, 1]))[0] == 2.0


def test_the_medians_interval_is_where_the_bands_edges_cross_one_half():
    """The lower end of the median's interval is where the band's lower edge falls to one
    half (first), the upper end where its upper edge does."""
    d = np.random.default_rng(4).exponential(10.0, 300)
    km = kaplan_meier(d, np.ones(300, bool))
    med, lo, hi = median(km)
    assert lo < med < hi
    assert lo == km.loc[km["ci_low"] <= 0.5, "t_s"].iloc[0]
    assert hi == km.loc[km["ci_high"] <= 0.5, "t_s"].iloc[0]


def test_a_summary_of_links_none_of_which_ended_has_counts_and_no_figure():
    """Links born during the run and all still up at its end: counted, all censored, and
    no mean or median (the longest would otherwise pass for the mean)."""
    links = pd.DataFrame(
        {
            "t_up_s": [1.0, 2.0, 0.0],
            "t_down_s": [10.0, 10.0, 10.0],
            "censored_start": [False, False, True],
            "censored_end": [True, True, True],
        }
    )
    s = lifetime_summary(links)
    assert s["links"] == 2 and s["censored"] == 2
    figures = ["mean_s", "mean_ci_low_s", "mean_ci_high_s", "median_s", "median_ci_low_s", "median_ci_high_s"]
    assert all(np.isnan(s[f]) for f in figures)


def test_the_lifetime_summary_is_the_links_kaplan_meier_figures_at_the_level_asked():
    """``lifetime_summary(links, level)``: the links born during the run, those still up at
    the end counted as censored, and the restricted mean and median of their Kaplan-Meier
    curve with intervals at ``level``, each figure in its place."""
    rng = np.random.default_rng(6)
    up = rng.uniform(0.0, 50.0, 200)
    down = up + rng.exponential(20.0, 200)
    end = down > 80.0
    links = pd.DataFrame(
        {
            "t_up_s": np.r_[0.0, up],
            "t_down_s": np.r_[30.0, np.minimum(down, 80.0)],
            "censored_start": np.r_[True, np.zeros(200, bool)],
            "censored_end": np.r_[False, end],
        }
    )
    d, e = np.minimum(down, 80.0) - up, ~end
    km = kaplan_meier(d, e, 0.8)
    mean, lo, hi = restricted_mean(km, d, e, level=0.8)
    med, med_lo, med_hi = median(km)
    assert 0 < end.sum() < 100  # censored and ended links count apart
    assert lifetime_summary(links, 0.8) == {
        "links": 200,
        "censored": int(end.sum()),
        "mean_s": mean,
        "mean_ci_low_s": lo,
        "mean_ci_high_s": hi,
        "median_s": med,
        "median_ci_low_s": med_lo,
        "median_ci_high_s": med_hi,
    }
    assert lo < mean < hi and med_lo < med < med_hi
    wider = lifetime_summary(links)
    assert wider["mean_ci_low_s"] < lo and wider["median_ci_high_s"] >= med_hi
