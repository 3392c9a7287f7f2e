"""Candidate pairs of a few robots come from every pair, not from scipy's KD-tree: the same
pairs, and a small run never imports scipy.spatial."""

import subprocess
import sys

import numpy as np
import pytest

from netsim.crossings import ALL_PAIRS_MAX, all_pairs_within, near_pairs


@pytest.mark.parametrize("torus", [False, True])
def test_every_pair_within_range_is_the_kd_tree_pairs(torus):
    """``all_pairs_within`` finds the KD-tree's pairs within the range, and none further than
    rounding allows, ordered ``(i, j)`` with ``i < j``; on the plane and on a torus, with
    positions on a lattice (distances exactly the range) and coincident ones."""
    from scipy.spatial import cKDTree

    rng = np.random.default_rng(2)
    side = 300.0
    layouts = [
        rng.uniform(0, side, (ALL_PAIRS_MAX, 2)),
        np.round(rng.uniform(0, side, (40, 2)) / 50) * 50 % side,
        np.zeros((5, 2)),
        rng.uniform(0, side, (2, 2)),
    ]
    for pos in layouts:
        for r in (0.0, 50.0, 120.0, 1000.0):
            box = side if torus else None
            got = all_pairs_within(pos, r, box)
            found = [tuple(p) for p in got.tolist()]
            assert found == sorted(found) and all(i < j for i, j in found)
            tree = cKDTree(pos, boxsize=box) if torus else cKDTree(pos)
            inner = {tuple(p) for p in tree.query_pairs(r, output_type="ndarray").tolist()}
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
