"""Candidate pairs come from one grid (netsim._kernels.near_pairs), plain or compiled: the
KD-tree's pairs, in the grid's order either way, and a small run never imports
scipy.spatial."""

import subprocess
import sys

import numpy as np
import pytest

from netsim.compiled import compiled_copy
from netsim.geometry import near_pairs
from tests.oracles.near_pairs import all_pairs_within, kd_tree_pairs


@pytest.mark.parametrize("kind", ["plain", "compiled"])
@pytest.mark.parametrize("torus", [False, True])
def test_near_pairs_are_every_pair_within_range(torus, kind):
    """The grid, plain and compiled, finds every pair within the range (each once, ``i <
    j``) and at most pairs further by a relative 1e-9 (a distance at the range rounds either
    way: callers filter exactly); on the plane and on a torus, with positions on a lattice
    (distances exactly the range), coincident ones, and a pair whose distance rounds to
    either side of the range. The oracles (every pair, the KD-tree) agree within the same
    bounds."""
    import netsim._kernels

    kernels = compiled_copy("netsim._kernels") if kind == "compiled" else netsim._kernels
    rng = np.random.default_rng(2)
    side = 300.0
    layouts = [
        rng.uniform(0, side, (64, 2)),
        np.round(rng.uniform(0, side, (40, 2)) / 50) * 50 % side,
        np.zeros((5, 2)),
        rng.uniform(0, side, (2, 2)),
        np.array([[200.0, 200.0], [100.01586481765521, 201.7812107788257]]),  # 100 m, rounding either way
    ]
    for pos in layouts:
        for r in (0.0, 50.0, 120.0, 1000.0):
            box = side if torus else None
            inner = {tuple(p) for p in kd_tree_pairs(pos, r * (1 - 1e-9), box).tolist()}
            outer = {tuple(p) for p in kd_tree_pairs(pos, r * (1 + 1e-9), box).tolist()}
            every = [tuple(p) for p in all_pairs_within(pos, r, box).tolist()]
            assert every == sorted(every) and inner <= set(every) <= outer
            found = [tuple(p) for p in kernels.near_pairs(pos, r, side if torus else 0.0).tolist()]
            assert len(found) == len(set(found)) and all(i < j for i, j in found)
            assert inner <= set(found) <= outer


def test_near_pairs_plain_and_compiled_are_the_same_list(monkeypatch):
    """``near_pairs`` gives the same pairs in the same order whether a run calls the grid
    compiled or as plain Python (NETSIM_COMPILED)."""
    pos = np.random.default_rng(4).uniform(0, 200, (30, 2))
    got = {}
    for compiled in ("0", "1"):
        monkeypatch.setenv("NETSIM_COMPILED", compiled)
        got[compiled] = near_pairs(pos, 60.0, None).tolist()
    assert got["0"] == got["1"] and len(got["0"]) > 20


def test_small_run_does_not_import_the_kd_tree(tmp_path):
    """``netsim run`` with 10 robots leaves scipy.spatial unloaded."""
    code = (
        "import sys\n"
        "from netsim.tools.cli import main\n"
        "try:\n"
        f"    main(['run', '--out', {str(tmp_path)!r}, '--no-progress', '--quiet',"
        " '--set', 'world.n_robots=10', '--set', 'duration_s=5', '--set', 'protocol.model=ack'])\n"
        "except SystemExit as exc:\n"
        "    assert not exc.code, exc.code\n"
        "print('scipy.spatial' in sys.modules)\n"
    )
    env = {k: v for k, v in __import__("os").environ.items() if k != "NETSIM_COMPILED"}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env)
    assert out.stdout.strip().splitlines()[-1] == "False"


@pytest.mark.parametrize("compiled", ["0", "1"])
@pytest.mark.parametrize("solved", ["after the run", "during the run"])
def test_robots_standing_at_their_range_are_linked_as_the_state_test_says(monkeypatch, compiled, solved):
    """Two robots standing still at their range, to the last bit either side: the links table
    has the pair exactly when its distance (``np.hypot``) is within the range (the one rule
    of in range, :func:`netsim._kernels.reaches`, where the squares would say otherwise),
    the candidate pairs found by the grid plain or compiled (it finds them with a slack),
    links solved after the run or during it."""
    from netsim.links.lifetimes import link_lifetimes
    from netsim.run import collect, simulation
    from netsim.state import RobotState
    from tests.fixtures import make_config

    monkeypatch.setenv("NETSIM_COMPILED", compiled)
    base = np.array([100.01586481765521, 201.7812107788257])
    linked = 0
    for k in range(-3, 4):
        # k ulps either side of the edge case found in review.
        other = np.array([np.nextafter(base[0], base[0] + np.sign(k)) if k else base[0], base[1]])
        for _ in range(abs(k) - 1):
            other[0] = np.nextafter(other[0], other[0] + np.sign(k))
        pos = np.array([[200.0, 200.0], other])
        if solved == "after the run":
            st = RobotState(2, 1000.0, 100.0)
            st.place(pos)
            links = link_lifetimes(st.legs(), st.range_m, 10.0, 1000.0)
        else:
            config = make_config(
                duration_s=10.0,
                world={"n_robots": 2, "side_m": 1000.0},
                mobility={"model": "static"},
                channel={"range_m": 100.0},
                protocol={"model": "none"},
                output={"position_interval_s": 0.0},
                events={"runtime_links": "on"},
            )
            sim = simulation(config)
            sim.state.place(pos)
            sim.run()
            links = collect(sim)["links"]
        d = pos[0] - pos[1]
        assert len(links) == int(np.hypot(*d) <= 100.0), (k, compiled)
        linked += len(links)
    assert 0 < linked < 7  # both sides of the edge were tried
