"""Log-distance propagation, the loss chain and its parameters."""

import math

import numpy as np
import pytest

import netsim.radio.propagation
from netsim.errors import ConfigError
from netsim.radio.propagation import (
    LogDistanceParams,
    LossChain,
    Pairs,
    effective_range_m,
    implied_range_m,
    log_distance,
    path_loss_db,
    reach_m,
    unit_disk,
)
from netsim.radio.shadowing import PairShadowing
from netsim.world.maps import OccupancyMap


def test_received_power_follows_the_log_distance_formula():
    """P_r = P_t - PL(d0) - 10 n log10(d / d0), with PL(d0) below d0."""
    p = LogDistanceParams(tx_power_dbm=15.0, reference_distance_m=2.0, reference_loss_db=45.0, path_loss_exponent=2.5)
    d = np.array([0.0, 1.0, 2.0, 20.0, 200.0])
    pairs = Pairs(np.zeros(5, int), np.arange(1, 6), np.zeros((5, 2)), np.column_stack([d, 0 * d]), d)
    got = log_distance(p).received_dbm(pairs)
    expected = [15 - 45, 15 - 45, 15 - 45, 15 - 45 - 25, 15 - 45 - 50]
    assert got == pytest.approx(expected, abs=1e-12)


def test_default_implied_range_is_100_m():
    assert implied_range_m(LogDistanceParams()) == pytest.approx(100.0, rel=1e-15)
    p = LogDistanceParams(sensitivity_dbm=-90.0, path_loss_exponent=2.0)
    assert implied_range_m(p) == pytest.approx(10 ** (70 / 20))


def test_receivable_iff_within_implied_range_without_shadowing(rng):
    """No shadowing, no walls: receivable exactly when d <= implied range."""
    p = LogDistanceParams(path_loss_exponent=3.7, sensitivity_dbm=-77.0)
    r = implied_range_m(p)
    pos = rng.uniform(0, 3 * r, (300, 2))
    a, b = np.triu_indices(300, 1)
    pairs = Pairs.between(a, b, pos)
    assert np.array_equal(log_distance(p).receivable(pairs), pairs.distance_m <= r)


def test_effective_range_is_the_threshold_of_receivability(rng):
    """With shadowing X and W walls a pair links exactly within effective_range_m(X, W)."""
    p = LogDistanceParams(shadowing_sigma_db=6.0, wall_loss_db=7.0)
    x = rng.normal(0, 6, 2000)
    walls = rng.integers(0, 4, 2000)
    d = rng.uniform(0, 300, 2000)
    rx = p.tx_power_dbm - path_loss_db(d, p) - x - p.wall_loss_db * walls
    r = effective_range_m(p, x, walls)
    ok = np.abs(d - r) > 1e-9 * r  # off the exact threshold
    assert np.array_equal((rx >= p.sensitivity_dbm)[ok], (d <= r)[ok])
    assert (r[(p.budget_db - x - 7 * walls) < 0] == 0).all()


def test_reach_bounds_every_link_under_shadowing(rng):
    """No pair beyond reach_m ever links, however lucky its shadowing."""
    p = LogDistanceParams(shadowing_sigma_db=8.0)
    reach = reach_m(p)
    assert reach == pytest.approx(100.0 * 10 ** (32 / 30))
    pos = np.array([[0.0, 0.0], [reach * 1.0001, 0.0], [reach * 0.9, 0.0]])
    sh = PairShadowing(8.0, 10.0, rng)
    # Force the luckiest value the clip allows on both pairs.
    sh.sample([0, 0], [1, 2], [0.0, 0.0])
    sh._x[:] = -100.0
    got = log_distance(p, sh).receivable(Pairs.between([0, 0], [1, 2], pos, np.zeros(3)))
    assert got.tolist() == [False, True]


def test_chain_drops_pairs_before_costly_terms():
    """Terms after the one that rules a pair out are not evaluated on it."""
    seen = []

    class Spy:
        lowest_db = 0.0

        def loss_db(self, pairs):
            seen.append(pairs.b.tolist())
            return np.zeros(len(pairs.b))

    p = LogDistanceParams()
    chain = LossChain(netsim.radio.propagation.LogDistanceLoss(p), Spy())
    d = np.array([50.0, 150.0, 99.0])
    pairs = Pairs(np.zeros(3, int), np.array([1, 2, 3]), np.zeros((3, 2)), np.zeros((3, 2)), d)
    mask = chain.receivable(pairs, p.radio)
    assert mask.tolist() == [True, False, True]
    assert seen == [[1, 3]]


def test_chain_keeps_pairs_that_shadowing_may_rescue(rng):
    """A term that can lower the loss (shadowing) keeps far pairs in the running."""
    p = LogDistanceParams(shadowing_sigma_db=6.0)
    sh = PairShadowing(6.0, 10.0, rng)
    d = np.array([150.0])
    pairs = Pairs(np.array([0]), np.array([1]), np.zeros((1, 2)), np.zeros((1, 2)), d, np.zeros(1))
    sh.sample([0], [1], [0.0])
    sh._x[:] = -20.0  # a 20 dB gain: 150 m is then within 100 * 10^(20/30) = 464 m
    assert log_distance(p, sh).receivable(pairs).tolist() == [True]


def test_unit_disk_chain_uses_the_senders_range():
    """Unequal ranges: the receiver must be within the sender's range."""
    prop = unit_disk(np.array([10.0, 30.0]))
    pos = np.array([[0.0, 0.0], [20.0, 0.0]])
    assert prop.receivable(Pairs.between([0, 1], [1, 0], pos)).tolist() == [False, True]


def test_unit_disk_on_a_map_needs_line_of_sight():
    occ = np.zeros((10, 10), dtype=bool)
    occ[:, 5] = True
    m = OccupancyMap(occ, ~occ, 1.0, (0.0, 0.0))
    pos = np.array([[1.0, 1.0], [9.0, 1.0], [4.0, 8.0]])
    got = unit_disk(20.0, m).receivable(Pairs.between([0, 0], [1, 2], pos))
    assert got.tolist() == [False, True]


def test_wall_loss_per_wall():
    occ = np.zeros((4, 30), dtype=bool)
    occ[:, [5, 6, 15, 25]] = True  # a thick wall (one), then two thin ones
    m = OccupancyMap(occ, ~occ, 1.0, (0.0, 0.0))
    p = LogDistanceParams(wall_loss_db=4.5)
    pos = np.array([[1.0, 2.0], [10.0, 2.0], [20.0, 2.0], [29.0, 2.0]])
    pairs = Pairs.between([0, 0, 0], [1, 2, 3], pos)
    drop = log_distance(p).received_dbm(pairs) - log_distance(p, occupancy=m).received_dbm(pairs)
    assert drop == pytest.approx([4.5, 9.0, 13.5])


@pytest.mark.parametrize(
    "field, value",
    [
        ("tx_power_dbm", math.nan),
        ("tx_power_dbm", 1000.0),
        ("tx_power_dbm", True),
        ("tx_power_dbm", "20"),
        ("reference_distance_m", 0.0),
        ("reference_distance_m", -1.0),
        ("reference_distance_m", math.inf),
        ("reference_loss_db", -3.0),
        ("path_loss_exponent", 0.0),
        ("path_loss_exponent", math.inf),
        ("sensitivity_dbm", 5.0),
        ("sensitivity_dbm", -math.inf),
        ("shadowing_sigma_db", -1.0),
        ("shadowing_sigma_db", 50.0),
        ("shadowing_decorrelation_m", 0.0),
        ("shadowing_decorrelation_m", math.inf),
        ("wall_loss_db", -1.0),
        ("wall_loss_db", math.nan),
    ],
)
def test_bad_parameter_names_its_key(field, value):
    with pytest.raises(ConfigError) as err:
        LogDistanceParams(**{field: value})
    assert err.value.key == f"channel.{field}"
    # A truth value as the file spells it (true), anything else as Python shows it.
    shown = "true" if value is True else repr(value)
    assert str(err.value).startswith(f"channel.{field} = {shown}: ")
    assert "\n" not in str(err.value)


def test_sensitivity_above_reference_power_is_refused():
    """If nothing links even at d0, the parameters are a mistake."""
    with pytest.raises(ConfigError, match="channel.sensitivity_dbm"):
        LogDistanceParams(tx_power_dbm=20.0, reference_loss_db=40.0, sensitivity_dbm=-20.0)


def test_a_pairs_loss_and_margin_are_summed_as_a_frames_decision_sums_them():
    """``loss_db`` is ``(PL(d) + X) + W`` in that order, the order of a frame's decision, and
    ``margin_db`` the power ``P_t`` less it, less the sensitivity: 17 dB at 10 m (PL 70 dB)
    with 3 dB of shadowing and two 5 dB walls."""
    p = LogDistanceParams(shadowing_sigma_db=4.0)
    assert float(p.loss_db(10.0, 3.0, 2)) == 83.0 and float(p.margin_db(10.0, 3.0, 2)) == 17.0
    rng = np.random.default_rng(5)
    d, x, w = rng.uniform(0.5, 300.0, 20000), rng.normal(0.0, 4.0, 20000), rng.integers(0, 4, 20000)
    loss = p.loss_db(d, x, w)
    assert loss.tobytes() == ((p.path_loss_db(d) + x) + 5.0 * w).tobytes()
    assert p.margin_db(d, x, w).tobytes() == ((p.tx_power_dbm - loss) - p.sensitivity_dbm).tobytes()


@pytest.mark.parametrize("compiled", ["0", "1"])
def test_a_frame_is_heard_exactly_when_its_margin_is_not_negative(monkeypatch, compiled):
    """The margin a plan keeps links by and the radio's decision are one law: heard iff the
    margin is at least 0, to the last bit. Written as the budget less the loss, the margin
    of the first case below is negative while the frame is heard."""
    from netsim.radio.chain import Radio

    monkeypatch.setenv("NETSIM_COMPILED", compiled)
    cases = [(-4.973827848471961, -67.04947567172289, np.array([62.07564782325093]))]
    rng = np.random.default_rng(1)
    for _ in range(50):
        tx, sens = rng.uniform(-10.0, 30.0), rng.uniform(-100.0, -60.0)
        cases.append((tx, sens, (tx - sens) + rng.integers(-4, 5, 2000) * np.spacing(tx - sens)))
    for tx, sens, loss in cases:
        radio = Radio(tx, sens)
        heard = radio.hears(loss)
        assert heard.any() and (~heard).any() or len(loss) == 1
        assert np.array_equal(heard, radio.margin_db(loss) >= 0.0)
    assert Radio(*cases[0][:2]).hears(cases[0][2]).all()
