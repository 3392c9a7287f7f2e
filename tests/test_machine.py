"""What this machine has (netsim.machine): its memory, and the GiB the refusals print."""

import os

import pytest

from netsim import machine


def test_the_machines_memory_is_its_pages_times_their_size(monkeypatch):
    """The physical memory is the number of physical pages times the page size."""
    said = {"SC_PAGE_SIZE": 4096, "SC_PHYS_PAGES": 1000}
    monkeypatch.setattr(os, "sysconf", lambda name: said[name])
    assert machine.machine_memory_bytes() == 4_096_000


@pytest.mark.parametrize("error", [ValueError, OSError])
def test_a_system_that_does_not_say_its_memory_has_none(monkeypatch, error):
    """A name the system does not know (ValueError) or cannot answer (OSError): None, not 0."""

    def sysconf(name):
        raise error(name)

    monkeypatch.setattr(os, "sysconf", sysconf)
    assert machine.machine_memory_bytes() is None


def test_a_system_without_sysconf_has_no_memory_to_tell(monkeypatch):
    monkeypatch.delattr(os, "sysconf")
    assert machine.machine_memory_bytes() is None


@pytest.mark.parametrize(
    ("nbytes", "printed"),
    [
        (1.5 * 2**30, "1.5"),
        (12_345.5 * 2**30, "12,345.5"),
        (999_999.5 * 2**30, "999,999.5"),
        # From a million GiB on: two significant digits.
        (1e6 * 2**30, "1e+06"),
        (3.14159e7 * 2**30, "3.1e+07"),
    ],
)
def test_gib_prints_one_decimal_with_thousands_then_two_significant_digits(nbytes, printed):
    assert machine.gib(nbytes) == printed
