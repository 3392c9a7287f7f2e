"""Pair shadowing: reciprocal, still while still, Gudmundson-correlated in pair travel."""

import math

import numpy as np
import pytest

from netsim.errors import ConfigError
from netsim.radio.shadowing import PairShadowing, pair_keys, split_keys
from netsim.tools.radio_checks import correlation_table


def _sh(sigma=6.0, dcorr=10.0, seed=1, step=0.0):
    return PairShadowing(sigma, dcorr, np.random.default_rng(seed), step_m=step)


def test_reciprocity():
    """X_ij = X_ji: the second direction sees the value the first one drew."""
    sh = _sh()
    x_ab = sh.sample([3, 7, 2], [5, 1, 9], [0.0, 0.0, 0.0])
    x_ba = sh.sample([5, 1, 9], [3, 7, 2], [0.0, 0.0, 0.0])
    assert np.array_equal(x_ab, x_ba)
    # Both directions in one batch share one draw too.
    sh2 = _sh(seed=2)
    both = sh2.sample([3, 5], [5, 3], [1.0, 1.0])
    assert both[0] == both[1]


def test_constant_while_the_pair_stands_still():
    """Looked at again at the same travel, a pair's shadowing has not changed."""
    sh = _sh()
    first = sh.sample(np.arange(50), np.arange(50) + 50, np.full(50, 12.5))
    for _ in range(3):
        again = sh.sample(np.arange(50), np.arange(50) + 50, np.full(50, 12.5))
        assert np.array_equal(first, again)


def test_changes_when_the_pair_travels():
    sh = _sh()
    first = sh.sample(np.arange(50), np.arange(50) + 50, np.zeros(50))
    later = sh.sample(np.arange(50), np.arange(50) + 50, np.full(50, 5.0))
    assert (first != later).all()


def test_no_shadowing_draws_nothing():
    """sigma = 0: zeros, and the generator is not touched."""
    rng = np.random.default_rng(9)
    sh = PairShadowing(0.0, 10.0, rng)
    assert sh.sample([0, 1], [2, 3], [0.0, 4.0]).tolist() == [0.0, 0.0]
    assert sh.draws == 0 and len(sh) == 0
    assert rng.random() == np.random.default_rng(9).random()


def test_stationary_law_is_normal_sigma(rng):
    """A pair seen for the first time draws N(0, sigma^2): mean and sd within 4 SE."""
    sh = PairShadowing(5.0, 10.0, rng)
    n = 20000
    x = sh.sample(np.arange(n), np.arange(n) + n, np.zeros(n))
    assert abs(x.mean()) < 4 * 5.0 / math.sqrt(n)
    assert abs(x.std() - 5.0) < 4 * 5.0 / math.sqrt(2 * n)


def test_clipped_at_four_sigma_but_state_is_not():
    sh = _sh(sigma=2.0)
    sh.sample([0], [1], [0.0])
    sh._x[:] = 30.0
    assert sh.sample([0], [1], [0.0]).tolist() == [8.0]
    assert sh.state([0], [1])[0].tolist() == [30.0]


def test_correlation_is_exponential_in_travel_whatever_the_schedule():
    """corr(X(0), X(delta)) = exp(-delta / d_corr), with irregular looks in between."""
    table = correlation_table(n_pairs=8000, seed=11)
    assert ((table.correlation >= table.lo) & (table.correlation <= table.hi)).all()


def test_stepped_process_correlation_at_multiples_of_the_step():
    """Piecewise constant in travel: at multiples of the step, still exp(-delta / d_corr)."""
    table = correlation_table(separations_m=(2.0, 6.0, 14.0), n_pairs=8000, seed=12, step_m=2.0)
    assert ((table.correlation >= table.lo) & (table.correlation <= table.hi)).all()


def test_stepped_process_is_constant_between_steps():
    sh = _sh(step=2.0)
    a = sh.sample([0], [1], [0.1])
    assert sh.sample([0], [1], [1.99]).tolist() == a.tolist()
    assert sh.sample([0], [1], [2.0]).tolist() != a.tolist()


def test_same_seed_same_values():
    a = _sh(seed=4).sample(np.arange(10), np.arange(10) + 10, np.arange(10.0))
    b = _sh(seed=4).sample(np.arange(10), np.arange(10) + 10, np.arange(10.0))
    assert np.array_equal(a, b)


def test_pair_keys_round_trip():
    a, b = np.array([5, 0, 2**31 - 1]), np.array([3, 9, 7])
    lo, hi = split_keys(pair_keys(a, b))
    assert lo.tolist() == [3, 0, 7] and hi.tolist() == [5, 9, 2**31 - 1]


@pytest.mark.parametrize(
    "args, key",
    [
        ((-1.0, 10.0), "channel.shadowing_sigma_db"),
        ((math.nan, 10.0), "channel.shadowing_sigma_db"),
        ((4.0, 0.0), "channel.shadowing_decorrelation_m"),
        ((4.0, math.inf), "channel.shadowing_decorrelation_m"),
    ],
)
def test_bad_parameters(args, key):
    with pytest.raises(ConfigError) as err:
        PairShadowing(*args, np.random.default_rng(0))
    assert err.value.key == key


@pytest.mark.parametrize("step_m", [-1.0, math.nan, math.inf])
def test_a_step_that_is_no_finite_number_at_least_zero_is_refused(step_m):
    with pytest.raises(ConfigError) as err:
        PairShadowing(4.0, 10.0, np.random.default_rng(0), step_m=step_m)
    assert err.value.key == "channel.shadowing_step_m"


class _Fives:
    """A generator whose standard normals are all 5: every draw lies beyond the clip."""

    def standard_normal(self, size):
        return np.full(size, 5.0)


@pytest.mark.parametrize("n_robots", [None, 4])
def test_a_pairs_first_draw_is_stored_unclipped(n_robots):
    """A pair seen for the first time is used clipped to 4 sigma, but its state keeps the
    draw itself (5 sigma here), as every later update does, so that the process's dynamics
    stay exact; with the pairs' slots made in advance (a small team) or not."""
    sh = PairShadowing(2.0, 10.0, _Fives(), n_robots=n_robots)
    assert sh.sample([0, 2], [1, 3], [0.0, 0.0]).tolist() == [8.0, 8.0]
    assert sh.state([0, 2], [1, 3])[0].tolist() == [10.0, 10.0]


@pytest.mark.parametrize("compiled", ["0", "1"])
def test_updates_equal_the_oracle(compiled, monkeypatch):
    """Same seed, same batches (new pairs, both directions, repeated looks): the update's
    loop, plain and compiled, gives the oracle's values (to the last bits of exp) and leaves
    the same records."""
    from tests.oracles import radio as oracle

    monkeypatch.setenv("NETSIM_COMPILED", compiled)

    def run(sample):
        rng = np.random.default_rng(21)
        sh = PairShadowing(6.0, 10.0, np.random.default_rng(22))
        travel = np.zeros(60)
        out = []
        for _ in range(40):
            a = rng.integers(0, 60, 25)
            b = rng.integers(0, 60, 25)
            ok = a != b
            a, b = a[ok], b[ok]
            a, b = np.r_[a, b[:3]], np.r_[b, a[:3]]  # some pairs in both directions
            travel += rng.random(60) * rng.integers(0, 2, 60)
            out.append(sample(sh, a, b, travel[a] + travel[b]))
        return np.concatenate(out), sh

    got, sh1 = run(lambda sh, a, b, s: sh.sample(a, b, s))
    want, sh2 = run(oracle.shadow_sample)
    assert np.allclose(got, want, rtol=0, atol=1e-9)
    assert np.array_equal(sh1._keys, sh2._keys) and np.allclose(sh1._x, sh2._x, atol=1e-9)


@pytest.mark.parametrize("compiled", ["1", "0"])
def test_pairs_listed_in_advance_give_the_same_values(compiled, monkeypatch):
    """With every pair's slot made at once (n_robots given) the values are exactly those of
    the table that grows as pairs are seen, draw for draw (the loop compiled and plain)."""
    from netsim.radio import shadowing as sh

    monkeypatch.setenv("NETSIM_COMPILED", compiled)
    rng = np.random.default_rng(3)
    looks = [(rng.integers(0, 40, 25), rng.integers(0, 40, 25)) for _ in range(30)]
    out = []
    for n_robots in (None, 40):
        s = sh.PairShadowing(5.0, 10.0, np.random.default_rng(9), n_robots=n_robots)
        vals = []
        for k, (a, b) in enumerate(looks):
            keep = a != b
            a, b = a[keep], b[keep]
            _, first = np.unique(sh.pair_keys(a, b), return_index=True)
            vals.append(s.sample(a[first], b[first], np.full(len(first), 2.0 * k)))
        out.append((np.concatenate(vals), len(s)))
    assert out[1][0].tolist() == out[0][0].tolist()
    assert out[1][1] == out[0][1]


def test_a_jump_counts_as_travel_for_the_shadowing():
    """A robot put elsewhere (a trace's set X_) stands among other obstacles: its jump
    counts in the pair's travel, the shadowing's clock, as the straight line it jumped (the
    pair's value decorrelates: exp(-94 / 10) here), while the summary's speed, a path
    length, leaves it out."""
    from netsim.config import from_dict
    from netsim.run import build, collect, summarize

    cfg = from_dict(
        {
            "seed": 1,
            "duration_s": 10.0,
            "world": {"n_robots": 2, "side_m": 1000.0},
            "mobility": {"model": "static"},
            "channel": {"propagation": "log_distance", "shadowing_sigma_db": 6.0},
            "protocol": {"model": "none"},
        }
    )
    sim = build(cfg)
    sim.state.place(np.array([[100.0, 500.0], [150.0, 500.0]]))
    sim.state.set_leg(1, 1.0, (0.0, 0.0), start_m=(100.0, 420.0))  # from (150, 500): 94.3 m
    travel = sim.state.pair_travelled_m(2.0, np.array([0]), np.array([1]))
    assert travel.tolist() == [pytest.approx(np.hypot(50.0, 80.0), rel=1e-12)]
    sim.state.set_leg(1, 2.0, (1.0, 0.0))
    sim.run()
    summary = summarize(sim, collect(sim), 0.0)
    assert summary["mean_speed_mps"] == pytest.approx(8.0 / (2 * 10.0), rel=1e-12)  # 8 m driven, no jump
