"""The local plan's expansion on a map (docs/model.md 5.1, rule 6 on a map;
netsim.mobility.explored): the cells each robot knows its team has covered, passed on with
the Acks, and the push toward the nearest free cell outside them."""

from __future__ import annotations

import math

import numpy as np
import pytest
from netsim.mobility.explored import Explored
from netsim.mobility.geodesic import FreeGrid, expansion_to_unexplored

from netsim.area import Bounds
from tests.test_coverage_geodesic import SIDE_M, room_with_a_door


def grid() -> FreeGrid:
    return FreeGrid(room_with_a_door(), Bounds.square(SIDE_M))


def cells_of(g: FreeGrid, packed: np.ndarray) -> np.ndarray:
    return np.unpackbits(packed, count=g.w * g.h).astype(bool)


def test_each_point_covers_alone_what_the_coverage_rule_says():
    """A robot's own cells (:meth:`FreeGrid.covered_each`) are the cells the covered
    fraction's rule gives for that robot alone (:meth:`FreeGrid.covered`), near the grid's
    edges, across the wall and off the grid too."""
    g = grid()
    rng = np.random.default_rng(2)
    pts = np.r_[rng.uniform(-1.0, SIDE_M + 1.0, (40, 2)), [[0.0, 0.0], [SIDE_M, SIDE_M], [10.1, 3.0]]]
    for radius in (0.3, 2.0, 7.5):
        each = g.covered_each(pts, radius)
        for k in range(len(pts)):
            np.testing.assert_array_equal(each[k], g.covered(pts[k : k + 1], radius), err_msg=f"{k} {radius}")


def test_expansion_on_a_map_a_robot_learns_the_cells_its_neighbours_covered_from_their_acks():
    """Rule 6 on a map: at each step a robot's explored cells are its own of the last step,
    those it covers now, and those each robot it heard announced at its latest step before
    the Ack it heard; an Ack sent before that robot's first step carries none, one sent
    between its last two steps the earlier step's."""
    g = grid()
    ex = Explored(g, 3)
    pos = np.array([[2.0, 2.0], [2.0, 18.0], [18.0, 18.0]])
    known = ~np.eye(3, dtype=bool)
    sent = np.full((3, 3), 0.5)  # every Ack before the first step
    own = [cells_of(g, np.packbits(g.covered(pos[k : k + 1], 3.0))) for k in range(3)]
    first = ex.step(pos, 3.0, known, sent, now_s=1.0)
    for k in range(3):
        np.testing.assert_array_equal(cells_of(g, first[k]), own[k])
    moved = pos + [[0.0, 2.0], [0.0, 0.0], [0.0, 0.0]]
    sent = np.full((3, 3), 1.2)  # after the first step: each carries its sender's first cells
    sent[2, 0] = 0.9  # robot 2's latest Ack of robot 0 left before robot 0's first step
    second = ex.step(moved, 3.0, known, sent, now_s=2.0)
    now0 = g.covered(moved[:1], 3.0)
    np.testing.assert_array_equal(cells_of(g, second[0]), own[0] | now0 | own[1] | own[2])
    np.testing.assert_array_equal(cells_of(g, second[2]), own[2] | own[1])
    # Between the first and second steps: robot 2 now hears robot 0's first step's cells.
    sent[2, 0] = 1.5
    third = ex.step(moved, 3.0, known, sent, now_s=3.0)
    assert cells_of(g, third[2])[own[0]].all() and not cells_of(g, third[2])[now0 & ~own[0]].any()


def test_expansion_on_a_map_pushes_toward_the_free_space_a_robot_knows_unexplored():
    """Rule 6 on a map: a robot that knows the first room explored is pushed at the cap
    through the door to the second; one that knows both rooms explored is not pushed; two
    robots that know the same cells get the same push as one search gives them."""
    from netsim.mobility.forces import EXPANSION_CAP

    g = grid()
    x_m = g.origin_m[0] + (np.arange(g.w * g.h) % g.w + 0.5) * g.cell_m
    first_room = x_m < 10.0
    everything = np.ones(g.w * g.h, bool)
    packed = np.packbits(np.array([first_room, first_room, everything]), axis=1)
    pos = np.array([[5.0, 15.0], [5.0, 5.0], [5.0, 15.0]])
    push, d = expansion_to_unexplored(g, pos, packed, 30.0, 1.0)
    np.testing.assert_allclose(np.hypot(*push[:2].T), EXPANSION_CAP * 30.0)
    to_door = np.array([10.0, 3.0]) - pos[0]
    assert push[0] @ to_door > 0.9 * np.hypot(*push[0]) * np.hypot(*to_door)  # the grid's moves: within 13.3 degrees
    assert push[1, 0] > 2 * abs(push[1, 1])
    assert (push[2] == 0).all() and math.isinf(d[2]) and np.isfinite(d[:2]).all()
    alone, _ = expansion_to_unexplored(g, pos[1:2], packed[1:2], 30.0, 1.0)
    np.testing.assert_array_equal(alone[0], push[1])


@pytest.mark.slow
def test_a_local_run_on_a_map_spreads_out_of_the_start_room_by_what_it_heard():
    """A local-plan run on the office map from a connected start: the robots' explored
    cells grow beyond what they cover at control start (they heard the others' and moved),
    the stopping rule reads their distance to the space they know unexplored, and the
    real network never splits."""
    import netsim.mobility.coverage as coverage

    from netsim import config
    from netsim.metrics import components_at_link_events
    from netsim.run import execute
    from netsim.tools.validate import coverage_settings

    seen: dict[str, list] = {"known": [], "progress": []}
    step_ = coverage.Explored.step

    def spy_step(self, pos, radius_m, known, sent_s, now_s):
        out = step_(self, pos, radius_m, known, sent_s, now_s)
        seen["known"].append(np.unpackbits(out, axis=1).sum(axis=1).mean())
        return out

    progress_ = coverage.CoverageController._expansion_progress

    def spy_progress(self, to_m):
        seen["progress"].append(float(np.nanmean(np.where(np.isfinite(to_m), to_m, np.nan))))
        return progress_(self, to_m)

    coverage.Explored.step = spy_step
    coverage.CoverageController._expansion_progress = spy_progress
    try:
        keys = coverage_settings("office, line of sight", "local", 20, 0.0, 1, 120.0)
        r = execute(config.load(None, [*keys, "world.placement=connected", "world.centre_side_m=60"]))
    finally:
        coverage.Explored.step = step_
        coverage.CoverageController._expansion_progress = progress_
    assert seen["known"][-1] > 2 * seen["known"][0]
    # Every step's distance is read but the first's, when each robot knows only its own cells.
    assert len(seen["progress"]) == len(seen["known"]) - 1 > 50
    links = r.frames["links"]
    _, counts = components_at_link_events(
        *(links[c].to_numpy() for c in ("a", "b", "t_up_s", "t_down_s", "censored_end")), 20
    )
    assert counts.max() == 1
