"""`netsim validate`: the table, the exit status, and some of its checks."""

import pytest

from netsim.tools import validate
from netsim.tools.analysis import expected_acks_until_spurious_timeout, spurious_timeout_window
from netsim.tools.cli import main


def test_exit_status_follows_the_checks(monkeypatch, capsys):
    monkeypatch.setattr(validate, "CHECKS", [lambda: [validate.Check("0", "good", 1.0, 1.05, 0.1)]])
    assert main(["validate", "--no-progress"]) == 0
    assert "1 of 1 checks passed" in capsys.readouterr().out
    monkeypatch.setattr(validate, "CHECKS", [lambda: [validate.Check("0", "bad", 1.0, 1.5, 0.1)]])
    assert main(["validate", "--no-progress"]) == 1
    out = capsys.readouterr().out
    assert "NO" in out and "0 of 1 checks passed" in out


@pytest.mark.parametrize("check", [validate.check_unit_disk, validate.check_exact_links, validate.check_delivery_ratio])
def test_quick_checks_pass(check):
    for result in check():
        assert result.passed, result


def test_reference_density_in_validate_matches_published_values():
    assert validate.rwp_density(0.5, 0.5) == pytest.approx(2.2013, abs=1e-4)
    assert validate.rwp_density(0.1, 0.1) == pytest.approx(0.4762, abs=1e-4)


def test_spurious_timeout_window_and_expectation():
    assert [spurious_timeout_window(t, 1.0) for t in (1.5, 2.5, 3.0, 3.5)] == [1, 2, 2, 3]
    assert expected_acks_until_spurious_timeout(0.3, 3) == pytest.approx(51.48, abs=0.01)


@pytest.mark.parametrize("check", [validate.check_radio_correlation, validate.check_radio_walls])
def test_radio_quick_checks_pass(check):
    results = check()
    assert len(results) >= 3
    for result in results:
        assert result.passed, result


@pytest.mark.slow
@pytest.mark.parametrize("check", [validate.check_radio_unit_disk, validate.check_radio_link_probability])
def test_radio_run_checks_pass(check):
    results = check()
    assert results
    for result in results:
        assert result.passed, result


def test_radio_checks_are_in_validate():
    names = {c.__name__ for c in validate.CHECKS}
    assert {"check_radio_unit_disk", "check_radio_link_probability", "check_radio_correlation"} <= names
    assert "check_radio_walls" in names


def test_medium_checks_are_in_validate():
    names = {c.__name__ for c in validate.CHECKS}
    assert {"check_medium", "check_medium_none"} <= names


@pytest.mark.slow
@pytest.mark.parametrize("check", [validate.check_medium, validate.check_medium_none])
def test_medium_checks_pass(check):
    results = check()
    assert results
    for result in results:
        assert result.passed, result
