"""The radio's physics in one place: one path-loss law, one radio's power and sensitivity."""

import dataclasses

import numpy as np

import netsim.radio._kernels as plain_kernels
from netsim import config as cfgmod
from netsim.compiled import compiled_copy
from netsim.radio.chain import LogDistanceLoss, Pairs, Radio
from netsim.radio.mac import PowerModel
from netsim.radio.propagation import LogDistanceParams, RadioParams, log_distance, path_loss_db
from tests import two_ray_plugin


def _distances():
    rng = np.random.default_rng(3)
    return np.r_[0.0, 0.5, rng.uniform(0.0, 400.0, 2000)]


def test_every_loss_is_the_one_path_loss_law():
    """The chain's path-loss term, the law asked of the parameters and the shared medium's
    mean power all compute PL(d) by the one kernel: equal bit for bit to it, plain and
    compiled, and the medium's power is the radio's P_t less that loss."""
    p = LogDistanceParams(tx_power_dbm=17.0, reference_distance_m=1.5, reference_loss_db=41.3, path_loss_exponent=2.7)
    d = _distances()
    n10 = 10.0 * p.path_loss_exponent
    law = np.array([plain_kernels.path_loss_db(x, p.reference_distance_m, p.reference_loss_db, n10) for x in d])
    compiled = np.empty(len(d))
    compiled_copy("netsim.radio._kernels").path_losses_db(d, p.reference_distance_m, p.reference_loss_db, n10, compiled)
    pairs = Pairs(np.zeros(len(d), np.int64), np.arange(len(d)), None, None, d)
    assert np.array_equal(compiled, law)
    assert np.array_equal(path_loss_db(d, p), law)
    assert np.array_equal(p.path_loss_db(d), law)
    assert np.array_equal(LogDistanceLoss(p).loss_db(pairs), law)
    assert np.array_equal(log_distance(p).received_dbm(pairs), p.tx_power_dbm - law)
    power = PowerModel(p, noise_floor_dbm=-95.0, capture_threshold_db=10.0)
    assert np.array_equal(power.received_mw(d), 10.0 ** ((p.tx_power_dbm - law) / 10.0))


def test_transmit_power_and_sensitivity_are_the_radios():
    """channel.tx_power_dbm and channel.sensitivity_dbm are declared once, by the radio's
    keys, which every model with power extends (log-distance, a user's two-ray ground)
    without declaring them again; the keys reach the radio a run's chain is heard with."""
    radio_fields = {f.name: f for f in dataclasses.fields(RadioParams)}
    assert set(radio_fields) == {"tx_power_dbm", "sensitivity_dbm"}
    for params in (LogDistanceParams, two_ray_plugin.TwoRayParams):
        fields = {f.name: f for f in dataclasses.fields(params)}
        for name, field in radio_fields.items():
            assert fields[name] is field, f"{params.__name__} declares {name} again"
    config = cfgmod.load(
        None, ["channel.propagation=log_distance", "channel.tx_power_dbm=23", "channel.sensitivity_dbm=-71.5"]
    )
    assert config.channel.radio.radio == Radio(23.0, -71.5)
    assert log_distance(config.channel.radio).radio == Radio(23.0, -71.5)


def test_ten_db_is_a_factor_of_ten_and_in_db_undoes_linear():
    """The shared medium's units: ``linear`` turns dBm into mW (dB into a factor) and
    ``in_db`` turns a factor back, on numbers and on arrays alike."""
    from netsim.radio.chain import in_db, linear

    assert linear(10.0) == 10.0 and abs(linear(-30.0) - 1e-3) < 1e-15
    db = np.array([-95.0, -3.0, 0.0, 20.0])
    np.testing.assert_allclose(in_db(linear(db)), db, rtol=0, atol=1e-12)
