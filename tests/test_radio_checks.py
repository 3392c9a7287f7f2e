"""The radio's closed-form checks (netsim validate) pass, and fail on a broken model."""

import pytest

from netsim.radio.propagation import LogDistanceParams
from netsim.tools import radio_checks as checks


def test_log_distance_without_shadowing_is_a_unit_disk():
    (c,) = checks.check_unit_disk_equivalence(LogDistanceParams(path_loss_exponent=2.7), n=400, seed=3)
    assert c.passed and c.measured == 0


@pytest.mark.slow
def test_link_fraction_follows_phi_in_every_bin():
    """Static uniform deployment, sigma = 6 dB: every bin within 4 SE of Phi (clipped at 4 sigma)."""
    results = checks.check_link_probability(LogDistanceParams(shadowing_sigma_db=6.0), n_robots=1500, seed=5)
    assert len(results) >= 10
    assert all(c.passed for c in results), [c for c in results if not c.passed]


@pytest.mark.slow
def test_link_fraction_check_catches_a_wrong_sigma(monkeypatch):
    """The check can fail: shadowing drawn with 8 dB against a 6 dB theory is caught."""
    from netsim.radio import shadowing

    real = shadowing.PairShadowing

    def wrong(sigma_db, *args, **kwargs):
        return real(sigma_db * 4 / 3, *args, **kwargs)

    monkeypatch.setattr(checks, "PairShadowing", wrong)
    results = checks.check_link_probability(LogDistanceParams(shadowing_sigma_db=6.0), n_robots=1500, seed=5)
    assert not all(c.passed for c in results)


def test_link_probability_closed_form():
    p = LogDistanceParams(shadowing_sigma_db=5.0)
    # At the implied range the margin is 0: probability 1/2. 4 sigma beyond: clipped to 0.
    assert checks.link_probability(100.0, p) == pytest.approx(0.5)
    r_clip = 100.0 * 10 ** (20 / 30)
    assert checks.link_probability(r_clip * 1.001, p) == 0.0
    assert checks.link_probability(r_clip * 0.999, p) == pytest.approx(3.2e-5, rel=0.05)


def test_shadowing_correlation_checks_pass():
    assert all(c.passed for c in checks.check_shadowing_correlation(seed=2))


def test_wall_checks_pass_and_catch_a_leaky_wall(monkeypatch):
    assert all(c.passed for c in checks.check_walls(LogDistanceParams(wall_loss_db=7.5)))
    # A radio whose walls leak: the models built without the map they are given.
    disk, log = checks.unit_disk, checks.log_distance
    monkeypatch.setattr(checks, "unit_disk", lambda r, occupancy=None: disk(r))
    monkeypatch.setattr(checks, "log_distance", lambda p, shadowing=None, occupancy=None: log(p, shadowing))
    assert not any(c.passed for c in checks.check_walls() if c.item in ("W1", "W3"))
