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


@pytest.mark.slow
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


# A pair whose distance (hypot) is a hair beyond 100 m while its square is within 100 m's
# square: where two codes of "in range" would part.
_EDGE = np.array([[200.0, 200.0], [100.01586481765521, 201.7812107788257]])


@pytest.mark.parametrize("compiled", ["0", "1"])
def test_in_range_is_one_rule_on_every_path(monkeypatch, compiled):
    """Whether a robot is in range is decided by one rule (``hypot <= r``) by every code
    that asks, plain and compiled: the range query of a transmission, the link solvers'
    state, the pairs in range (both ways), who reaches whom, on a pair the squares would
    put in range."""
    from netsim.compiled import load
    from netsim.radio.spatial import RangeIndex
    from netsim.state import RobotState
    from netsim.topology import geometric_pairs, reach_keys

    monkeypatch.setenv("NETSIM_COMPILED", compiled)
    d = _EDGE[0] - _EDGE[1]
    assert d @ d <= 100.0 * 100.0 and np.hypot(*d) > 100.0
    st = RobotState(2, 1000.0, 100.0)
    st.place(_EDGE)
    ids, _ = RangeIndex(st).within(0.0, 0)
    assert ids.tolist() == []
    kernels = load("netsim._kernels", 2)
    assert not kernels.in_range(_EDGE, np.array([0]), np.array([1]), np.array([100.0]), 0.0)[0]
    assert len(geometric_pairs(_EDGE, 100.0)[0]) == len(geometric_pairs(_EDGE, 100.0, directed=True)[0]) == 0
    assert reach_keys(_EDGE, 100.0).tolist() == []
    # A hair nearer, every path has the pair.
    near = _EDGE.copy()
    near[1, 0] = np.nextafter(near[1, 0], 200.0)
    st.place(near)
    assert RangeIndex(st).within(0.0, 0)[0].tolist() == [1]
    assert len(geometric_pairs(near, 100.0)[0]) == 1


@pytest.mark.parametrize("kind", ["plain", "compiled"])
def test_the_torus_wrap_is_the_nearest_image(kind):
    """The torus's one wrap (:func:`netsim._kernels.nearest_images`), plain and compiled,
    is the oracle's ``d - box round(d / box)`` bit for bit, halves of the side included."""
    from netsim import _kernels
    from netsim.compiled import compiled_copy
    from tests.oracles.near_pairs import wrap

    rng = np.random.default_rng(8)
    box = 37.3
    d = np.concatenate([rng.uniform(-3 * box, 3 * box, (2000, 2)), rng.integers(-6, 7, (200, 2)) * box / 2])
    kernels = compiled_copy("netsim._kernels") if kind == "compiled" else _kernels
    assert kernels.nearest_images(d, box).tobytes() == wrap(d, box).tobytes()


@pytest.mark.parametrize("compiled", ["0", "1"])
def test_true_neighbours_are_the_other_leaders_within_twice_the_range(monkeypatch, compiled):
    """With global knowledge a leader's neighbours are the other leaders within ``2 r_c``,
    in the order of the leaders, the same positions as a KD-tree's (the oracle)."""
    from netsim.mobility.coverage import true_neighbours

    from tests.oracles.near_pairs import ball_neighbours

    monkeypatch.setenv("NETSIM_COMPILED", compiled)
    rng = np.random.default_rng(21)
    pos = rng.uniform(0, 800, (60, 2))
    leaders = np.sort(rng.choice(60, 25, replace=False))
    got = true_neighbours(pos, leaders, 100.0)
    want = ball_neighbours(pos[leaders], 200.0)
    assert len(got) == len(want) == 25
    assert all(g.shape == w.shape and g.tobytes() == w.tobytes() for g, w in zip(got, want))
    assert sum(len(g) for g in got) > 20
