"""A live command whose optional extra (``ros``: Cyclone DDS, the Foxglove SDK) is not
installed is refused in one line that names the extra: exit status 2, nothing written."""

from __future__ import annotations

import importlib.util

import pytest

from netsim.tools.cli import main

REAL_FIND_SPEC = importlib.util.find_spec


def without(monkeypatch, *modules: str) -> None:
    """The machine as if ``modules`` were not installed."""
    monkeypatch.setattr(
        importlib.util, "find_spec", lambda name, *a, **k: None if name in modules else REAL_FIND_SPEC(name, *a, **k)
    )


@pytest.mark.parametrize(
    ("argv", "missing", "named"),
    [
        (["bridge", "--set", "mobility.model=external"], ("cyclonedds",), "cyclonedds"),
        (["bridge", "--set", "mobility.model=external", "--live", "0"], ("foxglove",), "foxglove"),
        (["run", "--live", "0"], ("foxglove",), "foxglove"),
    ],
)
def test_a_live_command_without_its_extra_is_one_line_exit_2_nothing_written(
    tmp_path, capsys, monkeypatch, argv, missing, named
):
    without(monkeypatch, *missing)
    out = tmp_path / "out"
    assert main([*argv, "--quiet", "--set", "duration_s=1", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("netsim: error: netsim ") and "\n" not in err, err
    assert named in err and "netsim-robots[ros]" in err
    assert not out.exists()
