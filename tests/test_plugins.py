"""Models are found by name: built-in entry points, or a user's ``module:function``."""

import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

from netsim import plugins
from netsim.errors import ConfigError


def test_builtin_models_are_registered():
    assert {"random_waypoint", "random_direction", "static", "trace"} <= set(plugins.available(plugins.MOBILITY))
    assert "ack" in plugins.available(plugins.PROTOCOLS)


def test_unknown_model_lists_the_choices():
    with pytest.raises(ConfigError, match="random_waypoint"):
        plugins.resolve(plugins.MOBILITY, "teleport", "mobility.model")


def test_missing_user_module_is_a_clear_error():
    with pytest.raises(ConfigError, match="cannot be loaded"):
        plugins.resolve(plugins.MOBILITY, "no_such_module_xyz:install", "mobility.model")


@pytest.mark.slow
def test_user_mobility_model_from_the_current_directory(tmp_path):
    """The README's example: a module in the working directory, named on the command line."""
    (tmp_path / "mymodels_readme.py").write_text(
        "import math\n"
        "def circle(sim):\n"
        "    n, side = sim.state.n, sim.config.world.side_m\n"
        "    angles = [2 * math.pi * i / n for i in range(n)]\n"
        "    sim.state.place([[side / 2 + 100 * math.cos(a), side / 2 + 100 * math.sin(a)] for a in angles])\n"
    )
    # The installed console script, whose import path (unlike python -m) lacks the cwd.
    script = Path(sys.executable).parent / "netsim"
    if not script.exists():
        pytest.skip("the netsim console script is not installed next to this Python")
    out = tmp_path / "out"
    run = subprocess.run(
        [
            str(script),
            "run",
            "--quiet",
            "--out",
            str(out),
            "--set",
            "mobility.model=mymodels_readme:circle",
            "--set",
            "duration_s=5",
            "--set",
            "world.n_robots=12",
        ],
        cwd=tmp_path,
        capture_output=True,
        text=True,
    )
    assert run.returncode == 0, run.stderr
    pos = pd.read_parquet(out / "positions.parquet")
    r = ((pos.x_m - 500) ** 2 + (pos.y_m - 500) ** 2) ** 0.5
    assert r.to_numpy() == pytest.approx(100.0)


def test_each_group_lists_exactly_its_installed_entry_points():
    """The plugins of a group are its entry points as installed, in their order (read in
    one pass for all the groups)."""
    from importlib.metadata import entry_points

    for group in (plugins.MOBILITY, plugins.PROTOCOLS, plugins.CONTROLLERS, plugins.HOOKS, "netsim.none"):
        assert plugins._entry_points(group) == tuple(entry_points(group=group)), group
    assert plugins.available(plugins.PROTOCOLS) == ["ack", "clustering", "none"]
