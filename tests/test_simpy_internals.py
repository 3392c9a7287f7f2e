"""SimPy's internals are read and set in netsim/simpy_internals.py alone, which refuses a
SimPy of a major version it was not tested with."""

import ast
from pathlib import Path

import pytest

from netsim import simpy_internals
from netsim.simpy_internals import SimPyVersionError, check_version

ROOT = Path(__file__).resolve().parents[1]
PRIVATE = {"_queue", "_eid", "_now", "_ok", "_value"}


@pytest.mark.parametrize("version", ["4.0.0", "4.1.2", "4.1"])
def test_the_tested_major_version_is_accepted(version):
    """A SimPy of the tested major version loads."""
    check_version(version)


@pytest.mark.parametrize("version", ["5.0.0", "3.0.13", "10.1"])
def test_another_major_version_is_refused_in_one_line(version):
    """Any other major version stops with one line naming the version installed, the one
    tested and how to install it."""
    with pytest.raises(SimPyVersionError) as caught:
        check_version(version)
    message = str(caught.value)
    assert "\n" not in message
    assert f"SimPy {version} is installed" in message
    assert f"SimPy {simpy_internals.TESTED_MAJOR}" in message and "pip install" in message


@pytest.mark.slow
def test_no_other_module_touches_simpys_internals():
    """Outside netsim/simpy_internals.py no module of netsim, protocols, mobility or hooks
    reads or sets SimPy's private attributes (``_queue``, ``_eid``, ``_now``, ``_ok``,
    ``_value``) on anything but ``self``."""
    found = []
    for package in ("netsim", "protocols", "mobility", "hooks"):
        for path in sorted((ROOT / package).rglob("*.py")):
            if path.name == "simpy_internals.py":
                continue
            for node in ast.walk(ast.parse(path.read_text())):
                if isinstance(node, ast.Attribute) and node.attr in PRIVATE:
                    owner = node.value
                    if not (isinstance(owner, ast.Name) and owner.id == "self"):
                        found.append(f"{path.relative_to(ROOT)}:{node.lineno} .{node.attr}")
    assert found == []
