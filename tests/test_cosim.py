"""Driving a run from outside (docs/cosim.md): sim.drive, positions, neighbours, send, inbox."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from netsim.cosim import Arrival, CommandError
from netsim.run import build, collect
from tests.fixtures import make_config


def driven(tmp_path, positions, protocol="none", side_m=1000.0, range_m=10.0, seed=3, world=None, **proto_keys):
    """A run of robots placed at ``positions`` that move only as driven."""
    csv = tmp_path / "start.csv"
    pd.DataFrame(np.asarray(positions, dtype=float), columns=["x_m", "y_m"]).to_csv(csv, index=False)
    protocol_section = {"model": protocol, **proto_keys}
    if protocol == "clustering":
        protocol_section.setdefault("message_rate_hz", 0.0)
    config = make_config(
        seed=seed,
        duration_s=100.0,
        world={"n_robots": len(positions), "side_m": side_m, "placement": str(csv), **(world or {})},
        mobility={"model": "external"},
        channel={"range_m": range_m},
        protocol=protocol_section,
        output={"position_interval_s": 0.0},
    )
    return build(config)


def link_downs(sim) -> list:
    downs: list = []
    sim.events.on("link_down", downs.append)
    return downs


def test_driven_robot_loses_link_when_distance_reaches_range(tmp_path):
    """A robot driven away from its neighbour loses the link at the instant the distance
    reaches the range (unit disk): t = t_drive + (r - d0) / v."""
    sim = driven(tmp_path, [[100.0, 100.0], [105.0, 100.0]], range_m=10.0)
    downs = link_downs(sim)
    sim.run(until_s=3.0)
    sim.drive([1], [[2.0, 0.0]])
    sim.run(until_s=20.0)
    assert len(downs) == 1
    assert (downs[0].a, downs[0].b) == (0, 1)
    assert downs[0].t_s == pytest.approx(3.0 + (10.0 - 5.0) / 2.0, abs=1e-9)


def test_both_driven_robots_lose_link_at_closed_form_instant(tmp_path):
    """Two robots driven at once on slanted courses part when ``|d0 + (v1 - v0) t| = r``."""
    p0, p1 = np.array([200.0, 200.0]), np.array([203.0, 204.0])
    v0, v1 = np.array([-0.3, 0.7]), np.array([1.1, -0.4])
    sim = driven(tmp_path, [p0, p1], range_m=10.0)
    downs = link_downs(sim)
    sim.run(until_s=1.5)
    sim.drive([0, 1], [v0, v1])
    sim.run(until_s=60.0)
    d, w = p1 - p0, v1 - v0
    a, b, c = w @ w, 2 * d @ w, d @ d - 10.0**2
    t = (-b + math.sqrt(b * b - 4 * a * c)) / (2 * a)
    assert [e.t_s for e in downs] == [pytest.approx(1.5 + t, abs=1e-9)]


def test_positions_are_the_driven_legs_at_now(tmp_path):
    """sim.positions() is (N, 2) at sim.now: start + velocity x time driven; undriven robots stay."""
    sim = driven(tmp_path, [[10.0, 10.0], [50.0, 50.0]])
    sim.run(until_s=2.0)
    sim.drive(np.array([0]), np.array([[1.5, -0.5]]))
    sim.run(until_s=6.0)
    assert sim.now == 6.0
    np.testing.assert_allclose(sim.positions(), [[16.0, 8.0], [50.0, 50.0]], atol=1e-12)


def test_drive_stops_a_robot_on_the_border(tmp_path):
    """A robot driven toward the border stops on it, at the instant it reaches it, and stays
    there (a leg at rest, cause "border")."""
    sim = driven(tmp_path, [[90.0, 50.0]], side_m=100.0)
    sim.run(until_s=1.0)
    sim.drive([0], [[2.0, 1.0]])
    sim.run(until_s=30.0)
    np.testing.assert_allclose(sim.positions(), [[100.0, 55.0]], atol=1e-9)
    legs = sim.state.legs()
    last = legs.iloc[-1]
    assert last["cause"] == "border" and last["t_s"] == pytest.approx(6.0, abs=1e-12)
    assert (last["vx_mps"], last["vy_mps"]) == (0.0, 0.0)


def test_drive_outward_from_the_border_does_not_move(tmp_path):
    """A robot on the border driven outward, even partly, stays where it is."""
    sim = driven(tmp_path, [[0.0, 40.0]], side_m=100.0)
    sim.run(until_s=1.0)
    sim.drive([0], [[-1.0, 1.0]])
    sim.run(until_s=5.0)
    np.testing.assert_allclose(sim.positions(), [[0.0, 40.0]])
    sim.drive([0], [[1.0, 1.0]])
    sim.run(until_s=7.0)
    np.testing.assert_allclose(sim.positions(), [[2.0, 42.0]], atol=1e-12)


def test_a_later_drive_cancels_the_stop_at_the_border(tmp_path):
    """A robot turned away before it reaches the border is not stopped where the old course met it."""
    sim = driven(tmp_path, [[90.0, 50.0]], side_m=100.0)
    sim.drive([0], [[2.0, 0.0]])
    sim.run(until_s=2.0)
    sim.drive([0], [[-2.0, 0.0]])
    sim.run(until_s=10.0)
    np.testing.assert_allclose(sim.positions(), [[90.0 + 4.0 - 16.0, 50.0]], atol=1e-9)
    assert "border" not in set(sim.state.legs()["cause"])


def test_drive_on_a_map_stops_short_of_the_wall(tmp_path):
    """On a map a driven robot stops in a free cell, just short of the first one that is not free."""
    sim = driven(tmp_path, [[5.0, 5.0]], side_m=40.0, world={"map": "office"})
    occupancy = sim.parts.occupancy
    start = sim.positions()
    assert occupancy.is_free(start).all()
    sim.drive([0], [[1.0, 0.3]])
    sim.run(until_s=100.0)  # the run's end: well after the robot meets a wall
    here = sim.positions()
    assert occupancy.is_free(here).all()
    assert sim.state.velocity_mps[0].tolist() == [0.0, 0.0]
    assert sim.state.legs().iloc[-1]["cause"] == "border"
    # One step further along the course is not free (a wall), unless it was the border.
    ahead = here + 0.05 * np.array([[1.0, 0.3]])
    assert not occupancy.is_free(ahead).all() or (here[0] >= 40.0 - 1e-9).any()


def test_neighbours_are_the_live_entries_of_the_table(tmp_path):
    """sim.neighbours(i) is what i's table holds live now, and follows the Acks: a robot
    driven away is dropped tau after its last Ack heard."""
    sim = driven(tmp_path, [[100.0, 100.0], [105.0, 100.0], [100.0, 106.0]], protocol="ack")
    sim.run(until_s=5.0)
    assert sim.neighbours(0).tolist() == [1, 2]
    table = sim.models["protocol"].table
    assert sim.neighbours(1).tolist() == sorted(table.live_ids(sim.now, 1).tolist())
    sim.drive([2], [[0.0, 50.0]])
    sim.run(until_s=10.0)
    assert sim.neighbours(0).tolist() == [1]


def test_sent_message_arrives_in_the_inbox(tmp_path):
    """sim.send relays a message as the protocol's own; it arrives in the destination's
    inbox with its time, source and payload, as the messages table records it."""
    line = [[100.0 + 8.0 * k, 100.0] for k in range(5)]
    sim = driven(tmp_path, line, protocol="clustering")
    sim.run(until_s=10.0)
    mid = sim.send(0, 4, {"hello": 1})
    assert sim.inbox(4) == []
    sim.run(until_s=12.0)
    (arrival,) = sim.inbox(4)
    messages = collect(sim)["messages"].set_index("msg_id")
    assert isinstance(arrival, Arrival)
    assert (arrival.src, arrival.payload, arrival.msg_id) == (0, {"hello": 1}, mid)
    assert arrival.t_s == messages.loc[mid, "t_delivered_s"] and messages.loc[mid, "delivered"]
    assert sim.inbox(0) == []


def _play(tmp_path, call=None, named=""):
    """The run of the bad-call test; ``call`` (which must raise a CommandError naming
    ``named``) made between the drives."""
    sim = driven(tmp_path, [[100.0 + 8.0 * k, 100.0] for k in range(4)], protocol="clustering")
    sim.run(until_s=4.0)
    sim.drive([1], [[0.5, 0.0]])
    if call is not None:
        with pytest.raises(CommandError, match=named.replace("(", r"\(").replace(")", r"\)").replace("[", r"\[")):
            call(sim)
    sim.drive([2], [[0.0, 0.7]])
    sim.send(0, 3, "after")
    sim.run(until_s=30.0)
    return sim


@pytest.fixture(scope="module")
def good_play(tmp_path_factory):
    """The bad-call test's run without the bad call (the same for every call): its tables
    and robot 3's inbox."""
    good = _play(tmp_path_factory.mktemp("good"))
    return collect(good), good.inbox(3)


@pytest.mark.parametrize(
    ("call", "named"),
    [
        (lambda s: s.drive([7], [[1.0, 0.0]]), "7"),
        (lambda s: s.drive([-1], [[1.0, 0.0]]), "-1"),
        (lambda s: s.drive([0], [[math.nan, 0.0]]), "nan"),
        (lambda s: s.drive([0], [[math.inf, 0.0]]), "inf"),
        (lambda s: s.drive([0], [[3e8, 1e300]]), "faster than light"),
        (lambda s: s.drive([0, 1], [[1.0, 0.0]]), "(1, 2)"),
        (lambda s: s.drive([0, 0], [[1.0, 0.0], [2.0, 0.0]]), "[0, 0]"),
        (lambda s: s.drive(["a"], [[1.0, 0.0]]), "'a'"),
        (lambda s: s.drive([0], [["1", "0"]]), "[['1', '0']]: must be numbers"),
        (lambda s: s.drive([0, 1], [[1.0, 0.0], [True, False]]), "[True, False]]: must be numbers"),
        (lambda s: s.send(0, 9, "x"), "9"),
        (lambda s: s.send(0, 0, "x"), "0"),
        (lambda s: s.send(1.5, 2, "x"), "1.5"),
        (lambda s: s.neighbours(12), "12"),
        (lambda s: s.inbox(-3), "-3"),
        (lambda s: s.run(until_s="20"), "'20'"),
        (lambda s: s.run(until_s=True), "True"),
    ],
)
def test_bad_call_names_the_value_and_changes_nothing(tmp_path, good_play, call, named):
    """A call with an unknown robot, a non-finite velocity or a wrong shape raises a
    CommandError naming the value; the run goes on exactly as if it had not been made."""
    tables, inbox = good_play
    bad = _play(tmp_path, call, named)
    got = collect(bad)
    for name, frame in tables.items():
        pd.testing.assert_frame_equal(frame, got[name], obj=name)
    assert inbox == bad.inbox(3)


def test_drive_needs_the_external_model(build_sim):
    """sim.drive under a mobility model that moves robots itself is refused, naming the model."""
    sim = build_sim(world={"n_robots": 3, "side_m": 100.0}, mobility={"model": "static"}, duration_s=5.0)
    with pytest.raises(CommandError, match="'static'"):
        sim.drive([0], [[1.0, 0.0]])


def test_same_seed_and_calls_give_the_same_outputs(tmp_path):
    """The same seed and the same calls give the same tables, positions, beliefs and inboxes, bit for bit."""

    def play():
        sim = driven(tmp_path, [[100.0 + 7.0 * (k % 4), 100.0 + 7.0 * (k // 4)] for k in range(12)], "clustering")
        rng = np.random.default_rng(5)
        seen = []
        for step in range(15):
            sim.drive(np.arange(12), rng.uniform(-1.0, 1.0, (12, 2)))
            if step % 4 == 0:
                sim.send(step % 12, (step + 5) % 12, step)
            sim.run(until_s=sim.now + 1.0)
            seen.append((sim.positions().tobytes(), [sim.neighbours(i).tobytes() for i in range(12)]))
        return sim, seen

    (a, seen_a), (b, seen_b) = play(), play()
    assert seen_a == seen_b
    fa, fb = collect(a), collect(b)
    for name in fa:
        pd.testing.assert_frame_equal(fa[name], fb[name], check_exact=True, obj=name)
    assert [a.inbox(i) for i in range(12)] == [b.inbox(i) for i in range(12)]


@pytest.mark.slow
def test_docs_examples_run_and_print_what_they_say(tmp_path, monkeypatch, capsys):
    """The Python examples of docs/cosim.md run, and print what their comments say."""
    import re
    from pathlib import Path

    text = (Path(__file__).resolve().parents[1] / "docs" / "cosim.md").read_text()
    monkeypatch.chdir(tmp_path)
    for block in re.findall(r"```python\n(.*?)```", text, re.S):
        exec(compile(block, "docs/cosim.md", "exec"), {})
    out = capsys.readouterr().out
    assert "[1 4 5 6 7 8 9]" in out
    assert "Arrival(t_s=5.002" in out and "payload={'task': 'survey'}" in out
    assert "LinkDown(t_s=10.106" in out


def test_set_legs_is_set_leg_for_each_robot():
    """RobotState.set_legs gives the state and legs that set_leg gives robot by robot."""
    from netsim.state import RobotState

    rng = np.random.default_rng(2)
    states = [RobotState(6, 100.0, 10.0) for _ in range(2)]
    for st in states:
        st.place(np.arange(12.0).reshape(6, 2) * 7.0)
    for t in (1.0, 2.5, 4.0):
        idx = rng.permutation(6)[:4]
        v = rng.uniform(-1, 1, (4, 2))
        v[0] = 0.0
        states[0].set_legs(idx, t, v, cause=["command", "border", "command", "command"])
        for i, vi, c in zip(idx, v, ["command", "border", "command", "command"]):
            states[1].set_leg(int(i), t, vi, cause=c)
    a, b = states
    for name in ("origin_m", "velocity_mps", "t0_s", "odometer_m"):
        assert getattr(a, name).tobytes() == getattr(b, name).tobytes(), name
    pd.testing.assert_frame_equal(a.legs(), b.legs(), check_exact=True)


def test_unknown_robot_ids_are_named_as_the_docs_say():
    """The first id that is no robot, and the ids there are (docs/cosim.md: ``robots: 12 is
    no robot; ids are 0 to 9``); the id one past the last is no robot either."""
    from netsim.cosim import robot_id, robot_ids

    with pytest.raises(CommandError) as err:
        robot_ids([3, 12, 15], 10)
    assert str(err.value) == "robots: 12 is no robot; ids are 0 to 9"
    with pytest.raises(CommandError, match=r"^robots: 10 is no robot; ids are 0 to 9$"):
        robot_ids([10], 10)
    with pytest.raises(CommandError, match=r"^robot = 10: no such robot; ids are 0 to 9$"):
        robot_id(10, 10)
    assert robot_id(9, 10) == 9 and robot_ids([9, 0], 10).tolist() == [9, 0]


@pytest.mark.parametrize("robots", [[True], [[0, 1]], [0.0]], ids=["truth-value", "2-d", "float"])
def test_robot_ids_that_are_not_a_list_of_integers_are_refused(robots):
    """A truth value is not a robot id (True is not robot 1), nor a table of ids, nor a float."""
    from netsim.cosim import robot_ids

    with pytest.raises(CommandError, match=r"must be integer robot ids in \[0, 4\)$"):
        robot_ids(robots, 4)


def test_no_robot_ids_is_no_robot_to_drive():
    """An empty sequence of ids is no robot (with its (0, 2) velocities), not a bad call."""
    from netsim.cosim import robot_ids, velocities

    ids = robot_ids([], 4)
    assert ids.dtype == np.int64 and ids.shape == (0,)
    assert velocities(np.empty((0, 2)), 0).shape == (0, 2)


@pytest.mark.parametrize(
    ("given", "k", "message"),
    [
        ([math.nan, 0.0], 1, "velocities_mps[0] = [nan, 0.0]: must be finite, m/s"),
        ([[1.0, 0.0], [0.0, -math.inf], [math.nan, 1.0]], 3, "velocities_mps[1] = [0.0, -inf]: must be finite, m/s"),
        ([[1.0, 0.0], [3e8, 0.0], [0.0, 4e8]], 3, "velocities_mps[1] = [300000000.0, 0.0]: faster than light"),
        ([1.0, 0.0], 2, "velocities_mps has shape (2,): one row (vx, vy) per robot is (2, 2)"),
        ([[1.0, 0.0, 0.0]], 1, "velocities_mps has shape (1, 3): one row (vx, vy) per robot is (1, 2)"),
    ],
    ids=["nan", "first-not-finite", "first-too-fast", "pair-for-two", "three-columns"],
)
def test_a_bad_velocity_is_named_by_its_first_row_and_what_is_wrong(given, k, message):
    """A velocity that is not finite is said to be so (not faster than light), at the first
    row that is; a pair stands for one robot only, and a row has two components."""
    from netsim.cosim import velocities

    with pytest.raises(CommandError) as err:
        velocities(given, k)
    assert str(err.value).startswith(message)


@pytest.mark.parametrize("dtype", [np.uint64, np.int32, np.uint8])
def test_robot_ids_of_any_integer_type_are_int64_ids(dtype):
    """Ids given as any numpy integer type (unsigned 64-bit ones too, which numpy's counting
    refuses) are the run's int64 ids."""
    from netsim.cosim import robot_ids

    ids = robot_ids(np.array([2, 0], dtype=dtype), 4)
    assert ids.dtype == np.int64 and ids.tolist() == [2, 0]


def test_what_a_protocol_does_not_keep_is_one_clear_error(tmp_path):
    """Under a protocol without neighbour tables, sim.neighbours names it; under one that
    relays no messages, sim.send names it, and sim.inbox is empty (of a robot there is:
    an unknown one is refused all the same)."""
    none = driven(tmp_path, [[100.0, 100.0], [105.0, 100.0]], protocol="none")
    with pytest.raises(CommandError, match=r"^protocol.model = 'none' keeps no neighbour tables$"):
        none.neighbours(0)
    ack = driven(tmp_path, [[100.0, 100.0], [105.0, 100.0]], protocol="ack")
    with pytest.raises(CommandError, match=r"^protocol.model = 'ack' relays no messages \(the clustering does\)$"):
        ack.send(0, 1, "x")
    assert ack.inbox(1) == []
    with pytest.raises(CommandError, match=r"^robot = 2: no such robot; ids are 0 to 1$"):
        ack.inbox(2)
