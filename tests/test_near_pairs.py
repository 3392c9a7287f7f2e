"""Candidate pairs of a few robots come from every pair, not from scipy's KD-tree: the same
pairs, and a small run never imports scipy.spatial."""

import subprocess
import sys

import numpy as np
import pytest

from netsim.geometry import ALL_PAIRS_MAX, all_pairs_within, near_pairs


@pytest.mark.parametrize("torus", [False, True])
def test_every_pair_within_range_is_the_kd_tree_pairs(torus):
    """``all_pairs_within`` finds the KD-tree's pairs within the range, but for rounding at
    the range itself (each rounds a distance its own way: callers ask with slack), ordered
    ``(i, j)`` with ``i < j``; on the plane and on a torus, with positions on a lattice
    (distances exactly the range), coincident ones, and a pair whose distance rounds to
    either side of the range."""
    from scipy.spatial import cKDTree

    rng = np.random.default_rng(2)
    side = 300.0
    layouts = [
        rng.uniform(0, side, (ALL_PAIRS_MAX, 2)),
        np.round(rng.uniform(0, side, (40, 2)) / 50) * 50 % side,
        np.zeros((5, 2)),
        rng.uniform(0, side, (2, 2)),
        np.array([[200.0, 200.0], [100.01586481765521, 201.7812107788257]]),  # 100 m, rounding either way
    ]
    for pos in layouts:
        for r in (0.0, 50.0, 120.0, 1000.0):
            box = side if torus else None
            got = all_pairs_within(pos, r, box)
            found = [tuple(p) for p in got.tolist()]
            assert found == sorted(found) and all(i < j for i, j in found)
            tree = cKDTree(pos, boxsize=box) if torus else cKDTree(pos)
            inner = {tuple(p) for p in tree.query_pairs(r * (1 - 1e-9), output_type="ndarray").tolist()}
            outer = {tuple(p) for p in tree.query_pairs(r * (1 + 1e-9), output_type="ndarray").tolist()}
            assert inner <= set(found) <= outer


def test_near_pairs_of_a_few_robots_without_compiled_loops(monkeypatch):
    """With the numpy code, ``near_pairs`` of up to ALL_PAIRS_MAX positions is every pair
    within range."""
    monkeypatch.setenv("NETSIM_COMPILED", "0")
    pos = np.random.default_rng(4).uniform(0, 200, (30, 2))
    assert near_pairs(pos, 60.0, None).tolist() == all_pairs_within(pos, 60.0, None).tolist()


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


@pytest.mark.parametrize("finder", ["every pair", "kd-tree", "grid"])
@pytest.mark.parametrize("solved", ["after the run", "during the run"])
def test_robots_standing_at_their_range_are_linked_as_the_state_test_says(monkeypatch, finder, solved):
    """Two robots standing still at their range, to the last bit either side: the links table
    has the pair exactly when its squared distance is within the range's square (the state
    test), whichever way the candidate pairs were found (their finders each round a distance
    at the range their own way), links solved after the run or during it."""
    from netsim import geometry
    from netsim.links.lifetimes import link_lifetimes
    from netsim.run import collect, simulation
    from netsim.state import RobotState
    from tests.fixtures import make_config

    monkeypatch.setenv("NETSIM_COMPILED", "1" if finder == "grid" else "0")
    if finder == "kd-tree":
        monkeypatch.setattr(geometry, "ALL_PAIRS_MAX", 0)
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
        assert len(links) == int(d @ d <= 100.0 * 100.0), (k, finder)
        linked += len(links)
    assert 0 < linked < 7  # both sides of the edge were tried
