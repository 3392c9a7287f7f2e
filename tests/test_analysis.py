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
