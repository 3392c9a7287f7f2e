"""BonnMotion and ROS 2 bags in and out, and ``netsim export``: every format round-trips
or matches its reference (the waypoints' linear interpolation, the written poses)."""

from __future__ import annotations

import gzip
import json
import math
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from netsim import load
from netsim.area import Bounds
from netsim.errors import NetsimInputError
from netsim.formats import bonnmotion, rosbag2, waypoints
from netsim.run import build, collect
from netsim.stamps import ns
from netsim.tools.cli import main
from netsim.tools.export import export


def _positions(legs: pd.DataFrame, t: float, n: int) -> np.ndarray:
    """Every robot's exact position at ``t`` from its legs."""
    out = np.empty((n, 2))
    for i in range(n):
        g = legs[(legs["robot"] == i) & (legs["t_s"] <= t)].iloc[-1]
        out[i] = g["x_m"] + g["vx_mps"] * (t - g["t_s"]), g["y_m"] + g["vy_mps"] * (t - g["t_s"])
    return out


def _run(settings: list[str]):
    config = load(None, ["duration_s=40", "world.n_robots=8", "protocol.model=clustering", *settings])
    sim = build(config)
    sim.run()
    return config, collect(sim)


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("run") / "run"
    sets = ["duration_s=40", "world.n_robots=8", "mobility.stationary_start=false", "mobility.pause_s=0"]
    assert main(["run", *(a for s in sets for a in ("--set", s)), "--out", str(out), "--quiet"]) == 0
    return out


def test_bonnmotion_file_is_followed_linearly_between_waypoints(tmp_path):
    """A node is at its first waypoint until its time, moves linearly to each next one,
    and stays at the last; the run's legs give exactly these positions."""
    path = tmp_path / "s.movements"
    path.write_text("0 10 10 10 20 10 20 20 30\n5 100 100 15 100 200\n")
    with pytest.warns(UserWarning, match="ends at 20 s, before duration_s = 40: the robots stand still"):
        config, frames = _run(
            ["mobility.model=trace", f"mobility.trace_file={path}", "world.n_robots=2", "protocol.model=none"]
        )
    legs = frames["legs"]
    expect = {
        0.0: [[10, 10], [100, 100]],
        5.0: [[15, 10], [100, 100]],
        10.0: [[20, 10], [100, 150]],
        15.0: [[20, 20], [100, 200]],
        20.0: [[20, 30], [100, 200]],
        39.0: [[20, 30], [100, 200]],
    }
    for t, xy in expect.items():
        assert np.allclose(_positions(legs, t, 2), xy, atol=1e-9), t


def test_bonnmotion_equal_times_are_a_jump(tmp_path):
    """Two waypoints at one instant: the node is at the second from then on."""
    path = tmp_path / "j.movements"
    path.write_text("0 0 0 4 0 0 4 50 50 40 50 50\n")
    _config, frames = _run(
        ["mobility.model=trace", f"mobility.trace_file={path}", "world.n_robots=1", "protocol.model=none"]
    )
    assert np.allclose(_positions(frames["legs"], 3.9, 1), [[0, 0]])
    assert np.allclose(_positions(frames["legs"], 4.0, 1), [[50, 50]])


@pytest.mark.slow
def test_bonnmotion_export_round_trips_the_positions(run_dir, tmp_path, capsys):
    """``netsim export --format bonnmotion`` then replaying the file gives the run's
    positions at every instant (checked on a fine grid) to 1e-6 m, gzip included; it says
    it wrote both files."""
    out = tmp_path / "r.movements.gz"
    assert main(["export", str(run_dir), "--format", "bonnmotion", "--out", str(out)]) == 0
    assert capsys.readouterr().out.strip() == f"wrote {out} and {tmp_path / 'r.params'}"
    assert (tmp_path / "r.params").read_text().count("nn=8") == 1
    assert gzip.open(out, "rt").read().count("\n") == 8
    legs = pd.read_parquet(run_dir / "legs.parquet")
    _config, frames = _run(["mobility.model=trace", f"mobility.trace_file={out}", "protocol.model=none"])
    for t in np.linspace(0.0, 39.99, 97):
        assert np.allclose(_positions(frames["legs"], t, 8), _positions(legs, t, 8), atol=1e-6), t


# Two robots that jump: robot 0 stands, jumps, moves, jumps at the end of a move, moves on;
# robot 1 moves, jumps, stands. Links (range 30 m) open and close at the jumps.
JUMPS = "0 10 10 5 10 10 5 50 50 10 50 50 12 70 50 12 20 80 20 20 90 24 20 90\n0 60 60 8 60 20 8 30 30 24 30 30\n"


@pytest.mark.parametrize("fmt, name", [("bonnmotion", "j.movements"), ("ns2", "j.ns2")])
def test_export_of_a_run_with_jumps_replays_its_positions_and_links(tmp_path, fmt, name):
    """A run whose robots jump (a trace's repeated instant, an ns-2 scheduled ``set``, a
    placement), exported and replayed, gives its positions back at every instant, just
    before and after each jump too, and its links at the same instants: the writers say
    where a leg ended before the jump, not only where the next one starts."""
    trace = tmp_path / "jumps.movements"
    trace.write_text(JUMPS)
    (tmp_path / "jumps.params").write_text("x=100\ny=100\nduration=24\nnn=2\n")
    sets = ["duration_s=24", "world.n_robots=2", "world.side_m=100", "channel.range_m=30", "protocol.model=none"]
    run = tmp_path / "run"
    argv = ["run", "--quiet", *(a for s in sets for a in ("--set", s)), "--set", "mobility.model=trace"]
    assert main([*argv, "--set", f"mobility.trace_file={trace}", "--out", str(run)]) == 0
    out = tmp_path / name
    assert main(["export", str(run), "--format", fmt, "--out", str(out)]) == 0
    _config, frames = _run([*sets, "mobility.model=trace", f"mobility.trace_file={out}"])
    legs = pd.read_parquet(run / "legs.parquet")
    for t in [*np.linspace(0.0, 23.99, 97), 4.999999, 5.0, 7.999999, 8.0, 11.999999, 12.0]:
        assert np.allclose(_positions(frames["legs"], t, 2), _positions(legs, t, 2), atol=1e-6), t
    links = pd.read_parquet(run / "links.parquet")
    assert len(links) == 2
    cols = ["a", "b", "t_up_s", "t_down_s"]
    assert np.allclose(frames["links"][cols].to_numpy(float), links[cols].to_numpy(float), atol=1e-6)


@pytest.mark.filterwarnings("always::UserWarning")
def test_a_torus_runs_bag_export_says_a_trace_replay_of_it_crosses_the_square(tmp_path, capsys):
    """A bag holds sampled poses: replayed as a trace, a robot goes straight from the sample
    before a border to the one after it, across the square. The export says so."""
    sets = ["world.torus=true", "world.n_robots=3", "duration_s=20", "world.side_m=200", "channel.range_m=60"]
    sets += ["protocol.model=none"]
    run = tmp_path / "run"
    assert main(["run", "--quiet", *(a for s in sets for a in ("--set", s)), "--out", str(run)]) == 0
    assert main(["export", str(run), "--format", "rosbag2", "--out", str(tmp_path / "bag")]) == 0
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and "replay a torus run from --format ns2 or bonnmotion" in err, err


def test_a_torus_runs_bag_replayed_on_the_torus_says_where_it_crosses_the_square(tmp_path):
    """Replayed on the torus, a bag of a torus run goes straight across the square between
    two poses about a border; the replay says so, naming the first such robot and time
    (the BonnMotion and ns-2 exports, whose jumps are two poses at one instant, say nothing:
    the test below)."""
    sets = ["world.torus=true", "world.n_robots=5", "duration_s=100", "world.side_m=200", "channel.range_m=60"]
    sets += ["protocol.model=none", "mobility.model=random_direction", "mobility.speed_min_mps=3"]
    sets += ["mobility.speed_max_mps=5", "mobility.turn_interval_s=40"]
    run = tmp_path / "run"
    assert main(["run", "--quiet", *(a for s in sets for a in ("--set", s)), "--out", str(run)]) == 0
    from netsim.tools.export import export

    with pytest.warns(UserWarning, match="replay a torus run from --format ns2"):
        export(run, "rosbag2", tmp_path / "bag")
    replay = [s for s in sets if not s.startswith("mobility.")] + ["mobility.model=trace"]
    with pytest.warns(
        UserWarning, match=r"a robot's next pose lies more than half the square away \(robot \d+ at t = "
    ):
        _run([*replay, f"mobility.trace_file={tmp_path / 'bag'}"])


@pytest.mark.parametrize("fmt, name", [("bonnmotion", "t.movements"), ("ns2", "t.ns2")])
def test_export_of_a_torus_run_stays_in_the_square_and_replays_on_the_torus(tmp_path, fmt, name):
    """A torus run's legs run on past the borders; the formats know no torus, so the export
    cuts each leg at the border and jumps the robot to the opposite one. Every written
    coordinate lies in the square, and the file replayed on the same torus gives the run's
    positions (folded) and links back."""
    from netsim.trajectory import sample_positions

    sets = ["world.torus=true", "world.n_robots=5", "duration_s=200", "world.side_m=200", "channel.range_m=60"]
    sets += ["protocol.model=none"]
    moves = ["mobility.model=random_direction", "mobility.speed_min_mps=3", "mobility.speed_max_mps=5"]
    moves += ["mobility.turn_interval_s=40"]
    run = tmp_path / "run"
    argv = ["run", "--quiet", *(a for s in sets + moves for a in ("--set", s))]
    assert main([*argv, "--out", str(run)]) == 0
    legs = pd.read_parquet(run / "legs.parquet")
    assert legs["x_m"].min() < 0 or legs["x_m"].max() > 200  # the run did cross a border
    out = tmp_path / name
    assert main(["export", str(run), "--format", fmt, "--out", str(out)]) == 0
    text = out.read_text()
    if fmt == "bonnmotion":
        coords = [v for line in text.splitlines() for k, v in enumerate(map(float, line.split())) if k % 3]
    else:
        coords = [float(v) for v in re.findall(r"set [XY]_ ([-+\d.e]+)", text)]
        coords += [float(v) for pair in re.findall(r"setdest ([-+\d.e]+) ([-+\d.e]+)", text) for v in pair]
    # In the square, but for the rounding of a leg's end at a border (the run's own tolerance).
    assert len(coords) > 20 and min(coords) >= -2e-7 and max(coords) <= 200.0 + 2e-7
    _config, frames = _run([*sets, "mobility.model=trace", f"mobility.trace_file={out}"])
    times = np.linspace(0.0, 199.99, 401)
    want = sample_positions(legs, 5, times, 200.0, True)[["x_m", "y_m"]].to_numpy()
    got = sample_positions(frames["legs"], 5, times, 200.0, True)[["x_m", "y_m"]].to_numpy()
    off = np.abs(want - got)
    assert np.minimum(off, 200.0 - off).max() < 1e-6
    links = pd.read_parquet(run / "links.parquet")
    cols = ["a", "b", "t_up_s", "t_down_s"]
    assert len(links) > 5 and np.allclose(frames["links"][cols].to_numpy(float), links[cols].to_numpy(float), atol=1e-6)


@pytest.mark.parametrize("torus", [False, True])
def test_ns2_export_heads_for_no_destination_on_the_border_as_ns2_refuses_it(tmp_path, torus):
    """ns-2's ``set_destination`` refuses a destination with x <= 0, x >= X (and so on y):
    robots that turn at a wall (random direction) or wrap (a torus) end legs on the border,
    and each such ``setdest`` is written just inside it, never on or past it (a leg's end
    recomputed from its motion fell 1.4e-14 m outside). The file still replays the run."""
    from netsim.trajectory import sample_positions

    sets = ["world.n_robots=3", "duration_s=60", "world.side_m=200", "channel.range_m=60", "protocol.model=none"]
    sets += ["world.torus=true"] if torus else []
    moves = ["mobility.model=random_direction", "mobility.speed_max_mps=10"]
    run, out = tmp_path / "run", tmp_path / "run.tcl"
    assert main(["run", "--quiet", *(a for s in sets + moves for a in ("--set", s)), "--out", str(run)]) == 0
    assert main(["export", str(run), "--format", "ns2", "--out", str(out)]) == 0
    dest = np.array(re.findall(r"setdest ([-+\d.e]+) ([-+\d.e]+)", out.read_text()), float)
    assert len(dest) > 5 and (dest > 0).all() and (dest < 200).all()
    legs = pd.read_parquet(run / "legs.parquet")
    p = legs[["x_m", "y_m"]].to_numpy()
    assert torus or ((p == 0) | (p == 200)).any()  # the run did turn on a border
    _config, frames = _run([*sets, "mobility.model=trace", f"mobility.trace_file={out}"])
    times = np.linspace(0.0, 59.99, 301)
    want = sample_positions(legs, 3, times, 200.0, torus)[["x_m", "y_m"]].to_numpy()
    got = sample_positions(frames["legs"], 3, times, 200.0, torus)[["x_m", "y_m"]].to_numpy()
    off = np.abs(want - got)
    assert np.minimum(off, 200.0 - off).max() < 1e-6


@pytest.mark.parametrize("velocity", [(-1.0, -1.0), (2.0, 2.0), (-1.0, 2.0), (3.0, -7.0), (0.0, -4.0)])
def test_torus_legs_folded_at_corners_and_borders_stay_in_the_square(velocity):
    """Legs cut at each border they reach, corners included (both axes at one instant, either
    way): every piece starts in the square, and the pieces put the robot where the torus
    does at every instant."""
    from netsim.trajectory import folded_legs, sample_positions

    legs = pd.DataFrame(
        {"t_s": [0.0, 0.0], "robot": [0, 1], "x_m": [50.0, 0.0], "y_m": [50.0, 200.0]}
        | {"vx_mps": [velocity[0]] * 2, "vy_mps": [velocity[1]] * 2, "cause": ["start"] * 2}
    )
    folded = folded_legs(legs, 2, 200.0, 180.0)
    assert folded[["x_m", "y_m"]].to_numpy().min() >= 0.0 and folded[["x_m", "y_m"]].to_numpy().max() <= 200.0
    times = np.linspace(0.0, 180.0, 721)
    want = sample_positions(legs, 2, times, 200.0, True)[["x_m", "y_m"]].to_numpy()
    got = sample_positions(folded, 2, times)[["x_m", "y_m"]].to_numpy()
    off = np.abs(want - got)
    assert np.minimum(off, 200.0 - off).max() < 1e-9
    assert got.min() >= -1e-9 and got.max() <= 200.0 + 1e-9


def test_bonnmotion_reads_3d_files_with_their_params(tmp_path):
    """``J=3D`` in the ``.params`` beside: four numbers a waypoint, z dropped."""
    (tmp_path / "d.params").write_text("model=RandomWaypoint3D\nx=100.0\ny=100.0\nnn=1\nJ=3D\n")
    (tmp_path / "d.movements").write_text("0 1 2 3 10 11 12 13\n")
    wp, params = bonnmotion.read(tmp_path / "d.movements")
    assert params["J"] == "3D"
    assert np.allclose(wp.positions_at(5.0), [[6, 7]])


def test_bonnmotion_reads_j_3d_in_either_case_as_bonnmotion_does(tmp_path):
    """BonnMotion takes ``J=3D`` and ``J=3d`` alike for a 3D scenario: four numbers a waypoint."""
    (tmp_path / "d.params").write_text("nn=1\nJ=3d\n")
    (tmp_path / "d.movements").write_text("0 1 2 3 10 11 12 13\n")
    wp, _params = bonnmotion.read(tmp_path / "d.movements")
    assert np.allclose(wp.positions_at(5.0), [[6, 7]])


def test_bonnmotion_params_node_count_must_match_the_node_lines(tmp_path):
    """``nn`` in the ``.params`` beside the file is checked against its node lines: one line
    naming both files."""
    (tmp_path / "n.params").write_text("x=100.0\ny=100.0\nnn=3\n")
    path = tmp_path / "n.movements"
    path.write_text("0 1 2\n0 3 4\n")
    with pytest.raises(NetsimInputError, match=r"n\.params: nn = 3 but .*n\.movements has 2 node lines$"):
        bonnmotion.read(path)


@pytest.mark.parametrize(
    "area, keys",
    [
        (100.0, {"x": "100.0", "y": "100.0"}),
        (Bounds(10.0, 20.0, 110.0, 220.0), {"x": "110.0", "y": "220.0"}),
        (Bounds(-10.0, 20.0, 90.0, 220.0), {"x": "100.0", "y": "200.0", "x_min": "-10.0", "y_min": "20.0"}),
    ],
)
def test_bonnmotion_params_give_the_areas_far_corner_or_its_size_and_near_corner(tmp_path, area, keys):
    """BonnMotion's area is ``[0, x] x [0, y]``: an area in the positive quadrant is written
    as its far corner, one reaching below 0 as its size with ``x_min`` and ``y_min``."""
    wp = waypoints.Waypoints.of([0], [0.0], [50.0], [60.0], "test")
    bonnmotion.write(tmp_path / "a.movements", wp, area, 10.0)
    params = bonnmotion.read_params(tmp_path / "a.params")
    assert {k: v for k, v in params.items() if k in ("x", "y", "x_min", "y_min")} == keys


def test_waypoints_of_robots_not_numbered_from_0_without_gaps_are_refused():
    """Every robot from 0 to the highest named needs a waypoint: one line naming the source
    and the robots without one."""
    with pytest.raises(NetsimInputError, match=r"^src: robot\(s\) \[1, 3\] have no position$"):
        waypoints.Waypoints.of([0, 2, 4], [0.0] * 3, [1.0] * 3, [1.0] * 3, "src")


def test_waypoints_positions_follow_each_leg_and_are_at_the_second_of_a_jump():
    """Between two waypoints a robot is on the straight line from one to the next at
    constant speed; at an instant with two waypoints (a jump) it is at the second."""
    wp = waypoints.Waypoints.of([0] * 5, [0, 10, 20, 20, 30], [0, 10, 10, 50, 50], [0, 0, 20, 20, 0], "test")
    assert wp.positions_at(15.0).tolist() == [[10.0, 10.0]]
    assert wp.positions_at(20.0).tolist() == [[50.0, 20.0]]
    assert wp.positions_at(25.0).tolist() == [[50.0, 10.0]]


@pytest.mark.parametrize(
    "text, says",
    [
        ("0 1 2 3 4\n", ":1: 5 numbers do not make whole waypoints"),
        ("0 1 2\n0 1 x\n", ":2: 'x' is not a number"),
        ("0 1_0 2\n", ":1: '1_0' is not a number"),
        ("5 1 2 3 4 5\n", ":1: waypoint 2: time 3 goes back"),
        ("0 1 2 inf 3 4\n", ":1: numbers must be finite"),
        ("-1 1 2 3 4 5\n", ":1: negative time -1"),
        ("\n", "no movement line"),
    ],
)
def test_malformed_bonnmotion_file_names_the_file_and_line(tmp_path, text, says):
    path = tmp_path / "bad.movements"
    path.write_text(text)
    with pytest.raises(NetsimInputError) as err:
        bonnmotion.read(path)
    assert str(path) in str(err.value) and says in str(err.value)


def test_bonnmotion_positions_outside_the_area_exit_2_one_line(tmp_path, capsys):
    path = tmp_path / "far.movements"
    path.write_text("0 10 10 5 2000 10\n")
    out = tmp_path / "out"
    code = main(
        [
            "run",
            "--set",
            "mobility.model=trace",
            "--set",
            f"mobility.trace_file={path}",
            "--set",
            "world.n_robots=1",
            "--out",
            str(out),
            "--no-progress",
        ]
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "world.side_m" in err[0] and "2000" in err[0]
    assert not out.exists()


@pytest.mark.slow
def test_rosbag2_export_holds_every_sampled_pose_and_reads_back(run_dir, tmp_path):
    """The bag has a PoseStamped per sampled position on /robot_<i>/pose (stamps = simulated
    time), links, roles and messages; replaying it gives the sampled positions exactly."""
    out = tmp_path / "bag"
    assert main(["export", str(run_dir), "--format", "rosbag2", "--out", str(out)]) == 0
    from rosbags.rosbag2 import Reader

    with Reader(out) as reader:
        topics = {c.topic: c.msgtype for c in reader.connections}
        counts = {c.topic: c.msgcount for c in reader.connections}
    pos = pd.read_parquet(run_dir / "positions.parquet")
    assert topics["/robot_0/pose"] == "geometry_msgs/msg/PoseStamped"
    assert topics["/links"] == "visualization_msgs/msg/MarkerArray"
    assert topics["/robot_0/role"] == "std_msgs/msg/String"
    assert counts["/robot_3/pose"] == int((pos["robot"] == 3).sum())
    wp = rosbag2.read(out)
    for t in sorted(pos["t_s"].unique()):
        at = pos[pos["t_s"] == t].sort_values("robot")[["x_m", "y_m"]].to_numpy()
        assert np.array_equal(wp.positions_at(t), at), t


def test_rosbag2_links_at_each_sample_are_the_links_up_then(run_dir, tmp_path):
    """The bag's ``/links`` at each sampling instant t holds one segment per link up at t:
    ``t_up_s <= t < t_down_s``, and at the last sample T the links still up at the end
    (``censored_end``, ``t_down_s = T``)."""
    out = tmp_path / "bag"
    assert main(["export", str(run_dir), "--format", "rosbag2", "--out", str(out)]) == 0
    from rosbags.rosbag2 import Reader

    store = rosbag2._typestore()
    segments = {}
    with Reader(out) as reader:
        conns = [c for c in reader.connections if c.topic == "/links"]
        for conn, stamp, raw in reader.messages(connections=conns):
            msg = store.deserialize_cdr(raw, conn.msgtype)
            segments[stamp / 1e9] = len(msg.markers[0].points) // 2
    links = pd.read_parquet(run_dir / "links.parquet")
    end = float(pd.read_parquet(run_dir / "positions.parquet")["t_s"].max())
    assert max(segments) == end
    for t, got in segments.items():
        up = (links.t_up_s <= t) & ((t < links.t_down_s) | (links.censored_end & (t <= links.t_down_s)))
        assert got == int(up.sum()), t
    assert segments[end] == int(links.censored_end.sum()) > 0


def _bag(
    path: Path,
    tracks: dict[str, list[tuple[float, float, float]]],
    msgtype: str,
    frames: dict[str, str] | None = None,
    static: list[tuple[str, str, float, float, float]] = (),
) -> None:
    """A bag of ``tracks`` (per topic, poses ``(t, x, y)``) of type ``msgtype``, each topic's
    headers in the frame ``frames[topic]`` (none by default), and the transforms
    ``(parent, child, x, y, yaw)`` on /tf_static."""
    from rosbags.rosbag2 import Writer

    store = rosbag2._typestore()
    with Writer(path, version=8) as w:
        if static:
            conn = w.add_connection("/tf_static", "tf2_msgs/msg/TFMessage", typestore=store)
            transforms = []
            for parent, child, x, y, yaw in static:
                header = rosbag2._make(store, "std_msgs/msg/Header", frame_id=parent)
                turn = rosbag2._make(store, "geometry_msgs/msg/Quaternion", z=math.sin(yaw / 2), w=math.cos(yaw / 2))
                shift = rosbag2._make(store, "geometry_msgs/msg/Vector3", x=x, y=y)
                transform = rosbag2._make(store, "geometry_msgs/msg/Transform", translation=shift, rotation=turn)
                transforms.append(
                    rosbag2._make(
                        store,
                        "geometry_msgs/msg/TransformStamped",
                        header=header,
                        child_frame_id=child,
                        transform=transform,
                    )
                )
            msg = rosbag2._make(store, "tf2_msgs/msg/TFMessage", transforms=transforms)
            w.write(conn, 0, store.serialize_cdr(msg, "tf2_msgs/msg/TFMessage"))
        for topic, poses in tracks.items():
            conn = w.add_connection(topic, msgtype, typestore=store)
            for t, x, y in poses:
                point = rosbag2._make(store, "geometry_msgs/msg/Point", x=x, y=y)
                pose = rosbag2._make(store, "geometry_msgs/msg/Pose", position=point)
                header = rosbag2._make(
                    store, "std_msgs/msg/Header", stamp=rosbag2._stamp(store, t), frame_id=(frames or {}).get(topic, "")
                )
                if msgtype == "nav_msgs/msg/Odometry":
                    cov = rosbag2._make(store, "geometry_msgs/msg/PoseWithCovariance", pose=pose)
                    msg = rosbag2._make(store, msgtype, header=header, pose=cov)
                else:
                    msg = rosbag2._make(store, msgtype, header=header, pose=pose)
                w.write(conn, int(t * 1e9), store.serialize_cdr(msg, msgtype))


def test_rosbag2_odometry_times_count_from_the_first_stamp_and_late_robots_wait(tmp_path):
    """Odometry on /robot_<i>/odom: times from the bag's first stamp; a robot whose log
    starts later waits at its first pose."""
    bag = tmp_path / "odom"
    _bag(
        bag,
        {"/robot_0/odom": [(100.0, 0, 0), (110.0, 10, 0)], "/robot_1/odom": [(105.0, 5, 5), (115.0, 5, 15)]},
        "nav_msgs/msg/Odometry",
    )
    wp = rosbag2.read(bag)
    assert np.allclose(wp.positions_at(0.0), [[0, 0], [5, 5]])
    assert np.allclose(wp.positions_at(5.0), [[5, 0], [5, 5]])
    assert np.allclose(wp.positions_at(10.0), [[10, 0], [5, 10]])


ODOM_FRAMES = {"/robot_0/odom": "robot_0/odom", "/robot_1/odom": "/robot_1/odom"}
ODOM_TRACKS = {"/robot_0/odom": [(0.0, 0, 0), (10.0, 1, 0)], "/robot_1/odom": [(0.0, 0, 0), (10.0, 1, 0)]}


def test_a_bags_robots_in_frames_nothing_joins_are_refused(tmp_path):
    """Each robot's odometry in its own frame, from its own origin, and no static transform
    between them: placed as one frame the robots would stand on top of each other, so the
    bag is refused in one line naming the frames."""
    bag = tmp_path / "own_frames"
    _bag(bag, ODOM_TRACKS, "nav_msgs/msg/Odometry", ODOM_FRAMES)
    with pytest.raises(NetsimInputError) as err:
        rosbag2.read(bag)
    assert str(err.value) == (
        f"{bag}: the robots' poses are in 2 frames ('robot_0/odom', 'robot_1/odom') that no transforms on "
        "/tf_static join under one: netsim places every robot in one frame; record the poses in one frame "
        "(such as map), or the static transforms from theirs to it"
    )


def test_a_bags_frames_joined_by_static_transforms_are_placed_in_their_common_frame(tmp_path):
    """/tf_static joins the robots' odometry frames under map (robot 1's through a chain of
    two, the slash of a frame's name aside): each pose is placed in map, ``R(yaw) p + t``."""
    bag = tmp_path / "joined"
    static = [
        ("map", "robot_0/odom", 5.0, 0.0, 0.0),
        ("map", "yard", 10.0, 0.0, math.pi / 2),
        ("/yard", "robot_1/odom", 0.0, 2.0, 0.0),
    ]
    _bag(bag, ODOM_TRACKS, "nav_msgs/msg/Odometry", ODOM_FRAMES, static)
    wp = rosbag2.read(bag)
    assert np.allclose(wp.positions_at(0.0), [[5, 0], [8, 0]])
    assert np.allclose(wp.positions_at(10.0), [[6, 0], [8, 1]])


def test_a_bags_storage_file_named_for_the_bag_says_what_to_give(tmp_path):
    """A bag's storage file given for the bag (its name says a bag: read as one) names the
    folder to give; one alone, without the folder's metadata.yaml, says how to make it
    (a bag is read from its folder)."""
    import shutil

    from netsim.mobility.trace_replay import TraceFormat, TraceParams, trace_format

    bag = tmp_path / "bag"
    _bag(bag, {"/robot_0/pose": [(0.0, 1, 1)]}, "geometry_msgs/msg/PoseStamped")
    (db3,) = bag.glob("*.db3")
    assert trace_format(TraceParams(trace_file=str(db3))) is TraceFormat.ROSBAG2
    assert trace_format(TraceParams(trace_file="field.mcap")) is TraceFormat.ROSBAG2
    with pytest.raises(NetsimInputError) as err:
        rosbag2.read(db3)
    assert str(err.value) == f"{db3}: the storage file of a bag; give the bag's folder, {bag}"
    alone = tmp_path / "alone.mcap"
    shutil.copy(db3, alone)
    with pytest.raises(NetsimInputError, match=r"a storage file alone, .* `ros2 bag reindex FOLDER` \(with `-s mcap`"):
        rosbag2.read(alone)


def test_robots_that_start_at_one_point_are_warned_of(tmp_path):
    """Frames are told apart by name: two robots' odometry each from its own origin, in
    frames both named odom, read as one frame; that they start at one point is said."""
    bag = tmp_path / "one_name"
    _bag(bag, ODOM_TRACKS, "nav_msgs/msg/Odometry", dict.fromkeys(ODOM_TRACKS, "odom"))
    with pytest.warns(UserWarning, match=r"one_name: 2 robots start at \(0, 0\): odometry from each robot's own"):
        rosbag2.read(bag)


def test_static_transforms_that_go_round_a_cycle_are_refused(tmp_path):
    """Transforms whose chain comes back to a frame have no top to place the robots in: one
    line naming the cycle."""
    bag = tmp_path / "cycle"
    static = [("yard", "robot_0/odom", 1.0, 0.0, 0.0), ("robot_0/odom", "yard", 1.0, 0.0, 0.0)]
    _bag(bag, ODOM_TRACKS, "nav_msgs/msg/Odometry", ODOM_FRAMES, static)
    with pytest.raises(NetsimInputError) as err:
        rosbag2.read(bag)
    assert (
        str(err.value)
        == f"{bag}: the transforms on /tf_static go round a cycle ('robot_0/odom' -> 'yard' -> 'robot_0/odom')"
    )


def test_a_robot_whose_poses_change_frame_is_refused(tmp_path):
    """A robot's poses in two frames: one line naming them (each pose would be placed as if
    in one)."""
    from rosbags.rosbag2 import Writer

    store = rosbag2._typestore()
    two = tmp_path / "two"
    with Writer(two, version=8) as w:
        conn = w.add_connection("/robot_0/pose", "geometry_msgs/msg/PoseStamped", typestore=store)
        for t, frame in ((0.0, "map"), (1.0, "odom")):
            header = rosbag2._make(store, "std_msgs/msg/Header", stamp=rosbag2._stamp(store, t), frame_id=frame)
            msg = rosbag2._make(store, "geometry_msgs/msg/PoseStamped", header=header)
            w.write(conn, int(t * 1e9), store.serialize_cdr(msg, "geometry_msgs/msg/PoseStamped"))
    with pytest.raises(NetsimInputError, match=r"robot 0's poses are in several frames \('map', 'odom'\)$"):
        rosbag2.read(two)


def test_rosbag2_topics_key_chooses_each_robots_topic(tmp_path):
    bag = tmp_path / "named"
    _bag(bag, {"/alpha/pose": [(0.0, 1, 1)], "/beta/pose": [(0.0, 2, 2)]}, "geometry_msgs/msg/PoseStamped")
    assert np.allclose(rosbag2.read(bag, ["/beta/pose", "/alpha/pose"]).initial_m(), [[2, 2], [1, 1]])
    with pytest.raises(NetsimInputError, match="no pose topic /robot_<i>"):
        rosbag2.read(bag)


def test_a_bags_pose_topic_without_a_message_is_named(tmp_path):
    """A robot's pose topic that holds no message leaves it without a position: one line
    naming the topic and the robot, not a count of nodes that disagrees with the team."""
    bag = tmp_path / "quiet"
    _bag(bag, {"/robot_0/pose": [(0.0, 1, 1)], "/robot_1/pose": []}, "geometry_msgs/msg/PoseStamped")
    with pytest.raises(NetsimInputError, match=r"topic '/robot_1/pose' of robot 1 holds no pose message$"):
        rosbag2.read(bag)


def _mixed_bag(path: Path, pose_topics: list[str], string_topics: list[str]) -> None:
    """A bag with one PoseStamped on each of ``pose_topics`` and one String on each of
    ``string_topics``."""
    from rosbags.rosbag2 import Writer

    store = rosbag2._typestore()
    with Writer(path, version=8) as w:
        for k, topic in enumerate(pose_topics):
            conn = w.add_connection(topic, "geometry_msgs/msg/PoseStamped", typestore=store)
            point = rosbag2._make(store, "geometry_msgs/msg/Point", x=1.0 + k, y=1.0)
            pose = rosbag2._make(store, "geometry_msgs/msg/Pose", position=point)
            header = rosbag2._make(store, "std_msgs/msg/Header", stamp=rosbag2._stamp(store, 0.0))
            msg = rosbag2._make(store, "geometry_msgs/msg/PoseStamped", header=header, pose=pose)
            w.write(conn, 0, store.serialize_cdr(msg, "geometry_msgs/msg/PoseStamped"))
        for topic in string_topics:
            conn = w.add_connection(topic, "std_msgs/msg/String", typestore=store)
            msg = rosbag2._make(store, "std_msgs/msg/String", data="hi")
            w.write(conn, 0, store.serialize_cdr(msg, "std_msgs/msg/String"))


def test_a_bags_topic_of_another_type_is_named_with_its_type(tmp_path):
    """A robot whose only topic holds no pose is not read, and a warning says so with the
    topic's type; a topic of mobility.topics that holds no pose names its type; an unknown
    one lists at most ten of the bag's pose topics, /robot_2 before /robot_10."""
    bag = tmp_path / "mixed"
    _mixed_bag(bag, [f"/robot_{i}/pose" for i in (0, 1, 2, 10, 3, 4, 5, 6, 7, 8, 9, 11)], ["/robot_12/pose"])
    with pytest.warns(
        UserWarning,
        match=r"robot\(s\) \[12\] have topics but none holding a pose \(/robot_12/pose: std_msgs/msg/String",
    ):
        assert len(rosbag2.read(bag).initial_m()) == 12
    with pytest.raises(NetsimInputError, match="topic '/robot_12/pose' of mobility.topics holds std_msgs/msg/String"):
        rosbag2.read(bag, ["/robot_0/pose", "/robot_12/pose"])
    with pytest.raises(NetsimInputError) as err:
        rosbag2.read(bag, ["/nowhere"])
    assert "(pose topics in the bag: /robot_0/pose, /robot_1/pose, /robot_2/pose, /robot_3/pose" in str(err.value)
    assert str(err.value).endswith("/robot_9/pose and 2 more)")


def test_a_bags_stamps_that_go_back_or_repeat_are_read_in_order_with_a_warning(tmp_path):
    """Poses whose header stamps, in the bag's order, go back are read in stamp order, and
    ones that repeat a stamp put the robot where the last of them does: each said in a
    warning (both were silent)."""
    from rosbags.rosbag2 import Writer

    store = rosbag2._typestore()
    bag = tmp_path / "stamps"
    with Writer(bag, version=8) as w:
        conn = w.add_connection("/robot_0/pose", "geometry_msgs/msg/PoseStamped", typestore=store)
        # (log time, header stamp, x): the third pose is stamped before the second, the last repeats.
        for k, (stamp, x) in enumerate([(0.0, 0.0), (2.0, 2.0), (1.0, 1.0), (3.0, 3.0), (3.0, 4.0)]):
            point = rosbag2._make(store, "geometry_msgs/msg/Point", x=x, y=0.0)
            pose = rosbag2._make(store, "geometry_msgs/msg/Pose", position=point)
            header = rosbag2._make(store, "std_msgs/msg/Header", stamp=rosbag2._stamp(store, stamp))
            msg = rosbag2._make(store, "geometry_msgs/msg/PoseStamped", header=header, pose=pose)
            w.write(conn, k * 1_000_000_000, store.serialize_cdr(msg, "geometry_msgs/msg/PoseStamped"))
    with pytest.warns(UserWarning) as caught:
        wp = rosbag2.read(bag)
    said = [str(c.message) for c in caught]
    assert any("1 pose(s) have a header stamp earlier than the pose before them" in m for m in said), said
    assert any("1 pose(s) repeat the header stamp of the pose before them" in m for m in said), said
    assert wp.t_s.tolist() == [0.0, 1.0, 2.0, 3.0, 3.0] and wp.x_m.tolist() == [0.0, 1.0, 2.0, 3.0, 4.0]


def _stamped_bag(path: Path, rows: list[tuple[str, float, float, float, float]]) -> None:
    """A bag of PoseStamped rows ``(topic, log time, header stamp, x, y)``, in that order."""
    from rosbags.rosbag2 import Writer

    store = rosbag2._typestore()
    msgtype = "geometry_msgs/msg/PoseStamped"
    with Writer(path, version=8) as w:
        conns = {}
        for topic, log_s, stamp_s, x, y in rows:
            if topic not in conns:
                conns[topic] = w.add_connection(topic, msgtype, typestore=store)
            point = rosbag2._make(store, "geometry_msgs/msg/Point", x=x, y=y)
            pose = rosbag2._make(store, "geometry_msgs/msg/Pose", position=point)
            header = rosbag2._make(store, "std_msgs/msg/Header", stamp=rosbag2._stamp(store, stamp_s))
            msg = rosbag2._make(store, msgtype, header=header, pose=pose)
            w.write(conns[topic], ns(log_s), store.serialize_cdr(msg, msgtype))


def test_a_bags_stamps_are_read_to_the_nanosecond(tmp_path):
    """A header stamp is its seconds and its nanoseconds: poses 0.25 s apart are 0.25 s apart."""
    bag = tmp_path / "fine"
    _stamped_bag(bag, [("/robot_0/pose", 0.0, 7.0, 0.0, 0.0), ("/robot_0/pose", 1.0, 7.25, 1.0, 0.0)])
    assert rosbag2.read(bag).t_s.tolist() == [0.0, 0.25]


def test_a_bags_times_count_from_its_earliest_stamp(tmp_path):
    """Times count from the earliest header stamp of all the robots' poses, not from the
    stamp of the pose logged first."""
    bag = tmp_path / "late"
    _stamped_bag(bag, [("/robot_0/pose", 0.0, 10.0, 0.0, 0.0), ("/robot_1/pose", 1.0, 4.0, 5.0, 5.0)])
    wp = rosbag2.read(bag)
    assert wp.robot.tolist() == [0, 1] and wp.t_s.tolist() == [6.0, 0.0]


@pytest.mark.parametrize(
    "topics, says",
    [
        (["/robot_0/pose", "/robot_2/pose"], r"no pose topic for robot\(s\) \[1\] \(robots are numbered from 0\)$"),
        (
            ["/robot_0/odom", "/robot_0/pose", "/robot_1/pose"],
            r"robot 0 has several pose topics \['/robot_0/odom', '/robot_0/pose'\]; name one per robot",
        ),
    ],
)
def test_a_bags_default_topics_are_one_pose_topic_per_robot_from_0(tmp_path, topics, says):
    """Without mobility.topics, robots 0 to the highest numbered each need exactly one pose
    topic: a gap, or a robot with two, is one line naming the robot."""
    bag = tmp_path / "topics"
    _stamped_bag(bag, [(topic, 0.0, 0.0, 1.0, 1.0) for topic in topics])
    with pytest.raises(NetsimInputError, match=says):
        rosbag2.read(bag)


def test_a_bags_pose_that_is_not_finite_is_refused(tmp_path):
    """A pose whose position is no finite number (a NaN of a lost fix) is one line."""
    bag = tmp_path / "nan"
    _stamped_bag(bag, [("/robot_0/pose", 0.0, 0.0, 1.0, 1.0), ("/robot_0/pose", 1.0, 1.0, float("nan"), 1.0)])
    with pytest.raises(NetsimInputError, match="a pose has a non-finite position$"):
        rosbag2.read(bag)


def _exported_bag(run_dir: Path, out: Path, wanted) -> list[tuple[str, int, object]]:
    """``(topic, stamp in ns, message)`` of the messages on the topics ``wanted(topic)`` of
    the run's bag export, in the bag's order."""
    from rosbags.rosbag2 import Reader

    assert main(["export", str(run_dir), "--format", "rosbag2", "--out", str(out)]) == 0
    store = rosbag2._typestore()
    with Reader(out) as reader:
        conns = [c for c in reader.connections if wanted(c.topic)]
        return [(c.topic, stamp, store.deserialize_cdr(raw, c.msgtype)) for c, stamp, raw in reader.messages(conns)]


def test_a_bags_poses_and_links_are_in_frame_map_with_the_identity_orientation(run_dir, tmp_path):
    """Every exported pose and links marker is in frame ``map`` with the unit quaternion of
    no rotation (RViz and Foxglove refuse a zero quaternion)."""
    msgs = _exported_bag(run_dir, tmp_path / "bag", lambda topic: topic.endswith("/pose") or topic == "/links")
    assert {topic for topic, _, _ in msgs} >= {"/robot_0/pose", "/links"}
    for topic, _stamp, msg in msgs:
        posed = msg.markers[0] if topic == "/links" else msg
        q = posed.pose.orientation
        assert posed.header.frame_id == "map" and (q.x, q.y, q.z, q.w) == (0.0, 0.0, 0.0, 1.0), topic


def test_rosbag2_links_are_a_line_list_joining_the_positions_of_each_linked_pair(run_dir, tmp_path):
    """``/links`` at a sampling instant is one LINE_LIST marker (type 5): each two points
    are the sampled positions of the two robots of a link up then."""
    pos = pd.read_parquet(run_dir / "positions.parquet")
    links = pd.read_parquet(run_dir / "links.parquet")
    seen = 0
    for _topic, stamp, msg in _exported_bag(run_dir, tmp_path / "bag", lambda topic: topic == "/links"):
        (marker,) = msg.markers
        assert marker.type == 5
        at = pos[pos["t_s"].map(ns) == stamp].set_index("robot")
        t = float(at["t_s"].iloc[0])
        up = (links.t_up_s <= t) & ((t < links.t_down_s) | (links.censored_end & (t <= links.t_down_s)))
        want = sorted(
            sorted(tuple(at.loc[r, ["x_m", "y_m"]]) for r in pair) for pair in links[up][["a", "b"]].to_numpy()
        )
        points = [(p.x, p.y) for p in marker.points]
        assert sorted(sorted(points[k : k + 2]) for k in range(0, len(points), 2)) == want, t
        seen += len(want)
    assert seen > 0


def test_rosbag2_roles_and_messages_are_the_runs_rows_at_their_times(run_dir, tmp_path):
    """Each role change is JSON text on ``/robot_<i>/role`` at its time (role, leader,
    cause); each message is JSON text on ``/messages`` when it is sent and, if delivered,
    when it is delivered (with its hops and latency)."""
    roles = pd.read_parquet(run_dir / "roles.parquet")
    messages = pd.read_parquet(run_dir / "messages.parquet")
    want = [
        (ns(t), f"/robot_{r}/role", {"role": role, "leader": int(leader), "cause": cause})
        for t, r, role, leader, cause in roles[["t_s", "robot", "role", "leader", "cause"]].itertuples(index=False)
    ]
    for m in messages.itertuples(index=False):
        ids = {"msg_id": int(m.msg_id), "src": int(m.src), "dst": int(m.dst)}
        want.append((ns(m.t_sent_s), "/messages", {"event": "sent", **ids}))
        if m.delivered:
            done = {"hops": int(m.hops), "latency_s": float(m.latency_s)}
            want.append((ns(m.t_delivered_s), "/messages", {"event": "delivered", **ids, **done}))
    assert messages["delivered"].any() and not messages["delivered"].all()
    wanted = lambda topic: topic.endswith("/role") or topic == "/messages"  # noqa: E731
    got = [(stamp, topic, json.loads(msg.data)) for topic, stamp, msg in _exported_bag(run_dir, tmp_path / "b", wanted)]
    key = lambda row: (row[0], row[1], json.dumps(row[2], sort_keys=True))  # noqa: E731
    assert sorted(got, key=key) == sorted(want, key=key)


def test_bag_without_pose_topics_exits_2_one_line(tmp_path, capsys):
    bag = tmp_path / "empty"
    _bag(bag, {"/chatter": []}, "geometry_msgs/msg/PoseStamped")
    bag2 = tmp_path / "notabag"
    bag2.mkdir()
    for b in (bag, bag2):
        code = main(
            [
                "run",
                "--set",
                "mobility.model=trace",
                "--set",
                f"mobility.trace_file={b}",
                "--set",
                "world.n_robots=1",
                "--out",
                str(tmp_path / "o"),
                "--no-progress",
            ]
        )
        err = capsys.readouterr().err.strip().splitlines()
        assert code == 2 and len(err) == 1 and str(b) in err[0], err
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize(
    "args, says",
    [
        (["--format", "gpx"], "--format gpx"),
        (["--format", "bonnmotion", "--out", "x.txt"], "NAME.movements"),
        (["--format", "ns2", "--out", "y.movements"], "an ns-2 file named so would be read back as bonnmotion"),
        (["--format", "ns2", "--out", "t.db3"], "an ns-2 file named so would be read back as rosbag2"),
        (["--format", "ns2", "--out", "y.movements.gz"], "an ns-2 file named so would be read back as bonnmotion"),
        (["--format", "ns2", "--out", "y.tcl.gz"], "an ns-2 file is written as plain text; give a name without .gz"),
        (["--format", "rosbag2", "--out", "z.mcap"], "a bag is a folder (its storage file inside it)"),
        (["--format", "rosbag2", "--out", "z.db3"], "give the folder's name, without .db3"),
    ],
)
def test_export_bad_arguments_exit_2_one_line(run_dir, tmp_path, capsys, args, says):
    argv = ["export", str(run_dir), *args]
    if "--out" not in args:
        argv += ["--out", str(tmp_path / "o.movements")]
    else:
        argv[argv.index("--out") + 1] = str(tmp_path / argv[argv.index("--out") + 1])
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and says in err[0]
    assert list(tmp_path.iterdir()) == []


def test_export_refuses_an_existing_output_and_a_non_run(run_dir, tmp_path, capsys):
    taken = tmp_path / "taken.movements"
    taken.write_text("keep")
    assert main(["export", str(run_dir), "--format", "bonnmotion", "--out", str(taken)]) == 2
    assert taken.read_text() == "keep"
    assert main(["export", str(tmp_path), "--format", "ns2", "--out", str(tmp_path / "x.tcl")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and "exists already" in err[0] and "not a run directory" in err[1]


@pytest.mark.parametrize("fmt", ["ns2", "bonnmotion"])
@pytest.mark.parametrize("name", ["nd/", "nd/."])
def test_export_to_a_name_that_names_a_directory_is_refused(run_dir, tmp_path, capsys, fmt, name):
    """``--out nd/`` (or ``nd/.``) asks for a directory, where ns-2 and BonnMotion write a
    file: one line, exit 2, nothing written (it wrote a file named ``nd``)."""
    assert main(["export", str(run_dir), "--format", fmt, "--out", str(tmp_path) + "/" + name]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "names a directory" in err[0]
    assert list(tmp_path.iterdir()) == []


def test_a_bag_named_as_a_directory_is_written_there(run_dir, tmp_path):
    """A bag is a directory: ``--out bag/`` writes it as ``bag``."""
    assert main(["export", str(run_dir), "--format", "rosbag2", "--out", f"{tmp_path}/bag/"]) == 0
    assert (tmp_path / "bag").is_dir() and any((tmp_path / "bag").iterdir())


def test_a_bag_export_leaves_nothing_beside_the_bag(run_dir, tmp_path):
    """The bag is written in a temporary folder and moved into place: only the bag is left."""
    assert main(["export", str(run_dir), "--format", "rosbag2", "--out", str(tmp_path / "bag")]) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bag"]


def test_a_bag_export_of_a_run_without_sampled_positions_is_one_line(tmp_path, capsys):
    """A bag holds the sampled poses: a run that sampled none (``output.position_interval_s
    = 0``) is refused in one line, exit 2, nothing written."""
    sets = ["duration_s=5", "world.n_robots=2", "output.position_interval_s=0", "protocol.model=none"]
    assert main(["run", "--quiet", *(a for s in sets for a in ("--set", s)), "--out", str(tmp_path / "run")]) == 0
    assert main(["export", str(tmp_path / "run"), "--format", "rosbag2", "--out", str(tmp_path / "bag")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "positions.parquet is empty" in err[0], err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]


def test_export_refuses_a_folder_without_a_manifest(run_dir, tmp_path, capsys):
    """A run directory is one ``netsim run`` finished writing (its ``manifest.json``): a copy
    without it is refused in one line, before anything is written."""
    import shutil

    run = tmp_path / "run"
    shutil.copytree(run_dir, run)
    (run / "manifest.json").unlink()
    assert main(["export", str(run), "--format", "ns2", "--out", str(tmp_path / "x.tcl")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "not a run directory (no manifest.json)" in err[0], err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]


@pytest.mark.parametrize("fmt, name", [("ns2", "x.tcl"), ("bonnmotion", "x.movements.gz")])
def test_an_export_that_fails_while_writing_leaves_nothing(run_dir, tmp_path, monkeypatch, fmt, name):
    """The file is written under a temporary name and moved into place: a writer that fails
    half-way (a full disk) leaves no file behind, temporary or not."""
    from netsim.formats import ns2

    def half_way(path, *args, **kwargs):
        Path(path).write_text("$node_(0) set X_ 1")
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(ns2 if fmt == "ns2" else bonnmotion, "write", half_way)
    with pytest.raises(OSError):
        export(run_dir, fmt, tmp_path / name)
    assert list(tmp_path.iterdir()) == []


def test_bonnmotion_export_refuses_an_existing_params_file(run_dir, tmp_path, capsys):
    """The .params written beside NAME.movements is an output too: one that exists is one
    line, exit 2, and neither file is written."""
    params = tmp_path / "p.params"
    params.write_text("mine")
    assert main(["export", str(run_dir), "--format", "bonnmotion", "--out", str(tmp_path / "p.movements")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "p.params" in err[0] and "exists already" in err[0]
    assert params.read_text() == "mine" and sorted(tmp_path.iterdir()) == [params]


def test_waypoints_from_legs_reproduce_the_legs(run_dir):
    legs = pd.read_parquet(run_dir / "legs.parquet")
    wp = waypoints.from_legs(legs, 8, 40.0)
    for t in (0.0, 3.3, 17.25, 40.0):
        assert np.allclose(wp.positions_at(t), _positions(legs, t, 8), atol=1e-9)


@pytest.mark.parametrize(
    "name, read_as, others",
    [
        ("scenario.db3", "a bag", "'ns2' or 'bonnmotion'"),
        ("scenario.movements", "BonnMotion", "'ns2' or 'rosbag2'"),
        ("scenario.txt", "ns-2", "'bonnmotion' or 'rosbag2'"),
    ],
)
def test_every_guessed_format_is_said_with_the_others_to_set(tmp_path, capsys, name, read_as, others):
    """Whatever format a file's name made netsim read it as, a file that is not that format
    says so, and names the other formats mobility.trace_format takes."""
    path = tmp_path / name
    path.write_text('$node_(0) set X_ 1.0\n$node_(0) set Y_ 1.0\n$ns_ at 1.0 "$node_(0) setdest 2.0 1.0 1.0"\n')
    if name.endswith(".txt"):
        path.write_text("0 10 10 5 20 10\n")  # BonnMotion's, read as ns-2
    argv = ["run", "--set", "mobility.model=trace", "--set", f"mobility.trace_file={path}"]
    assert main([*argv, "--set", "world.n_robots=1", "--out", str(tmp_path / "out"), "--no-progress"]) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert line.endswith(
        f" (read as {read_as}, the format guessed from the name: set mobility.trace_format = {others} for another)"
    ), line
    assert not (tmp_path / "out").exists()


def test_a_format_set_is_named_in_the_error_of_a_file_not_in_it(tmp_path, capsys):
    """An ns-2 file read as BonnMotion because mobility.trace_format says so: the error says
    which format it was read as, and that the key asked it (it named a line and a word)."""
    path = tmp_path / "scen.tcl"
    path.write_text("$node_(0) set X_ 1.0\n$node_(0) set Y_ 1.0\n")
    argv = ["run", "--set", "mobility.model=trace", "--set", f"mobility.trace_file={path}"]
    argv += ["--set", "mobility.trace_format=bonnmotion", "--set", "world.n_robots=1"]
    assert main([*argv, "--out", str(tmp_path / "out"), "--no-progress"]) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert line.endswith(" (read as BonnMotion, as mobility.trace_format = 'bonnmotion' asks)"), line
    assert not (tmp_path / "out").exists()


def test_a_guessed_format_is_named_in_the_error(tmp_path, capsys):
    """A BonnMotion file not named .movements is read as ns-2 by guess: its error says the
    format was guessed and names mobility.trace_format."""
    path = tmp_path / "scenario.txt"
    path.write_text("0 10 10 5 20 10\n")
    code = main(
        ["run", "--set", "mobility.model=trace", "--set", f"mobility.trace_file={path}"]
        + ["--set", "world.n_robots=1", "--out", str(tmp_path / "out"), "--no-progress"]
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1
    assert "no ns-2 movement line" in err[0] and "guessed" in err[0] and "mobility.trace_format" in err[0]
    assert (
        main(
            ["run", "--quiet", "--set", "mobility.model=trace", "--set", f"mobility.trace_file={path}"]
            + ["--set", "mobility.trace_format=bonnmotion", "--set", "world.n_robots=1", "--set", "duration_s=5"]
            + ["--out", str(tmp_path / "out2")]
        )
        == 0
    )


@pytest.mark.slow
@pytest.mark.filterwarnings("always::UserWarning")
def test_a_trace_shorter_than_the_run_is_warned_about(run_dir, tmp_path, capsys):
    """A BonnMotion export of a 40 s run replayed for 60 s: one warning line naming the
    trace's end (its .params' duration) and duration_s; none for the run's own length."""
    out = tmp_path / "r.movements.gz"
    assert main(["export", str(run_dir), "--format", "bonnmotion", "--out", str(out)]) == 0
    capsys.readouterr()
    replay = [
        "run",
        "--quiet",
        "--set",
        "mobility.model=trace",
        "--set",
        f"mobility.trace_file={out}",
        "--set",
        "world.n_robots=8",
    ]
    assert main([*replay, "--set", "duration_s=60", "--out", str(tmp_path / "a")]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("netsim: warning: ")
    assert "ends at 40 s (duration=40.0 in r.params), before duration_s = 60" in err[0]
    assert main([*replay, "--set", "duration_s=40", "--out", str(tmp_path / "b")]) == 0
    assert capsys.readouterr().err == ""


@pytest.mark.filterwarnings("always::UserWarning")
@pytest.mark.parametrize(
    "bounds", ["[-100.0, -100.0, 100.0, 100.0]", "[0.0, -100.0, 200.0, 100.0]", "[-100.0, 0.0, 100.0, 200.0]"]
)
def test_ns2_export_of_an_area_below_zero_warns_that_ns2_refuses_it(tmp_path, capsys, bounds):
    """ns-2's topography starts at 0: a run whose area reaches below it on either axis is
    exported (netsim and ns-3 read it back) with one warning that says so and names
    BonnMotion's corner."""
    sets = ["world.n_robots=3", "duration_s=20", f"world.bounds_m={bounds}", "protocol.model=none"]
    run, out = tmp_path / "run", tmp_path / "run.tcl"
    assert main(["run", "--quiet", *(a for s in sets for a in ("--set", s)), "--out", str(run)]) == 0
    capsys.readouterr()
    assert main(["export", str(run), "--format", "ns2", "--out", str(out)]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "reaches below 0, where ns-2's topography starts" in err[0], err
    assert out.is_file()


@pytest.mark.parametrize("fmt", ["ns2", "bonnmotion"])
@pytest.mark.parametrize(
    "damage, says",
    [
        (lambda legs: legs[legs["robot"] != 7], "robot 7 has no leg"),
        (lambda legs: legs.iloc[:0], "robot 0 has no leg"),
        (lambda legs: legs.assign(t_s=legs["t_s"].where(legs.index != 3, np.nan)), "not a finite number"),
        (lambda legs: legs.assign(t_s=legs["t_s"] - 5.0), "a time before 0"),
    ],
)
def test_export_of_damaged_legs_is_one_line_and_writes_nothing(run_dir, tmp_path, capsys, fmt, damage, says):
    """A legs table without a robot's leg (config.toml's n_robots raised since), or with a
    time or position that is no number, or a time before 0: one line, exit 2, nothing
    written; a robot without a leg was a traceback, a NaN time a file no reader takes."""
    import shutil

    run = tmp_path / "run"
    shutil.copytree(run_dir, run)
    damage(pd.read_parquet(run / "legs.parquet")).to_parquet(run / "legs.parquet")
    out = tmp_path / ("x.tcl" if fmt == "ns2" else "x.movements")
    assert main(["export", str(run), "--format", fmt, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and says in err[0], err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]


def test_a_bonnmotion_params_file_that_is_not_text_is_one_line(tmp_path, capsys):
    """A .params beside the movements that is not UTF-8: one line naming it, exit 2 (a
    UnicodeDecodeError traceback)."""
    movements = tmp_path / "s.movements"
    movements.write_text("0 10 10 5 20 20\n0 30 30\n")
    (tmp_path / "s.params").write_bytes(b"model=R\xe9\xff\nnn=2\n")
    code, err = _run_trace(tmp_path, capsys, movements, 2)
    assert code == 2 and len(err) == 1 and "s.params: cannot be read" in err[0], err
    assert not (tmp_path / "o").exists()


def _run_trace(tmp_path, capsys, trace, n_robots):
    """``netsim run`` of ``n_robots`` on the trace file ``trace`` into ``tmp_path / "o"``: its
    exit status and the lines it printed on stderr."""
    code = main(
        ["run", "--out", str(tmp_path / "o"), "--no-progress", "--set", f"world.n_robots={n_robots}"]
        + ["--set", "duration_s=5", "--set", "mobility.model=trace", "--set", f"mobility.trace_file={trace}"]
    )
    return code, capsys.readouterr().err.strip().splitlines()


def test_a_refused_trace_is_its_one_error_line_without_the_readers_warnings(tmp_path, capsys):
    """An ns-2 file with a line the reader skips (a warning) and too few nodes for the team:
    the refusal alone, one line, exit 2; the skipped line's warnings came first."""
    trace = tmp_path / "s.tcl"
    trace.write_text('$node_(1) set X_ 1\n$node_(1) set Y_ 1\n$ns_ at -1 "$node_(1) setdest 5 5 1"\n')
    code, err = _run_trace(tmp_path, capsys, trace, 5)
    assert code == 2 and len(err) == 1 and err[0].endswith(f"must equal the 2 nodes of {trace}: set it to 2"), err
    assert not (tmp_path / "o").exists()


@pytest.mark.filterwarnings("always::UserWarning")
@pytest.mark.parametrize("fmt", ["ns2", "bonnmotion"])
def test_a_session_ended_early_is_exported_to_where_it_ended(tmp_path, capsys, fmt):
    """A bridge session stopped by Ctrl-C keeps its planned duration_s in config.toml and
    ends its tables (and summary.json's duration_s) where it stopped: the export ends there
    too, not carrying every robot's last leg on to the plan's end."""
    run = tmp_path / "session"
    # A flow planned after where the session ended: the export says nothing of it.
    flow = "traffic.flows=[{src=0, dst=1, start_s=20, stop_s=25, rate_bps=800, packet_bytes=100}]"
    sets = ["duration_s=6", "world.n_robots=4", "mobility.stationary_start=false", "mobility.pause_s=0", flow]
    assert main(["run", *(a for s in sets for a in ("--set", s)), "--out", str(run), "--quiet"]) == 0
    assert "traffic.flows[0] starts at 20 s" in capsys.readouterr().err
    config = run / "config.toml"
    config.write_text(config.read_text().replace("duration_s = 6.0", "duration_s = 30.0", 1))
    out = tmp_path / ("s.tcl" if fmt == "ns2" else "s.movements")
    assert main(["export", str(run), "--format", fmt, "--out", str(out)]) == 0
    assert capsys.readouterr().err == ""
    legs = pd.read_parquet(run / "legs.parquet")
    replayed = tmp_path / "replayed"
    sets = ["mobility.model=trace", f"mobility.trace_file={out}", "world.n_robots=4", "duration_s=30"]
    sets.append("protocol.model=none")
    assert main(["run", *(a for s in sets for a in ("--set", s)), "--out", str(replayed), "--quiet"]) == 0
    again = pd.read_parquet(replayed / "legs.parquet")
    # The robots stand still from where the session ended: at 29 s where they were at 6 s.
    assert np.allclose(_positions(again, 29.0, 4), _positions(legs, 6.0, 4), atol=1e-6)
    if fmt == "bonnmotion":
        assert "duration=6.0" in (tmp_path / "s.params").read_text()
    # A damaged summary leaves the plan's end, as before the summary was read: no refusal.
    (run / "summary.json").write_text("not JSON")
    assert main(["export", str(run), "--format", fmt, "--out", str(tmp_path / ("t" + out.name[1:]))]) == 0


def test_a_run_of_a_relative_trace_repeats_from_its_config_anywhere(tmp_path, monkeypatch):
    """A trace named relative to the working directory is kept absolute in the run's
    config.toml: that file, run from another directory, replays the same trace."""
    here, elsewhere = tmp_path / "here", tmp_path / "elsewhere"
    here.mkdir()
    elsewhere.mkdir()
    (here / "s.movements").write_text("0 10 10 10 20 10\n0 30 30 10 40 30\n")
    monkeypatch.chdir(here)
    sets = ["mobility.model=trace", "mobility.trace_file=s.movements", "world.n_robots=2", "duration_s=10"]
    assert main(["run", *(a for s in sets for a in ("--set", s)), "--out", "first", "--quiet"]) == 0
    monkeypatch.chdir(elsewhere)
    assert main(["run", str(here / "first" / "config.toml"), "--out", "again", "--quiet"]) == 0
    first, again = (pd.read_parquet(d / "legs.parquet") for d in (here / "first", elsewhere / "again"))
    pd.testing.assert_frame_equal(first, again)


def test_rosbag2_packets_are_the_runs_rows_at_their_times(tmp_path):
    """Each packet of packets.parquet is JSON text on ``/packets`` when it is sent and, if
    delivered, when it is delivered (with its hops and latency): a routing protocol's run,
    which has no messages table, has its traffic in the bag too."""
    run = tmp_path / "aodv"
    flow = "traffic.flows=[{src=0, dst=5, start_s=2, stop_s=18, rate_bps=8000, packet_bytes=1000}]"
    sets = ["duration_s=20", "world.n_robots=8", "protocol.model=aodv", "protocol.message_rate_hz=1", flow]
    assert main(["run", *(a for s in sets for a in ("--set", s)), "--out", str(run), "--quiet"]) == 0
    packets = pd.read_parquet(run / "packets.parquet")
    want = []
    for m in packets.itertuples(index=False):
        ids = {"flow": int(m.flow), "packet": int(m.packet), "src": int(m.src), "dst": int(m.dst)}
        want.append((ns(m.t_sent_s), "/packets", {"event": "sent", **ids}))
        if m.delivered:
            done = {"hops": int(m.hops), "latency_s": float(m.latency_s)}
            want.append((ns(m.t_delivered_s), "/packets", {"event": "delivered", **ids, **done}))
    assert packets["delivered"].any() and set(packets["flow"]) == {-1, 0}
    got = [
        (stamp, topic, json.loads(msg.data))
        for topic, stamp, msg in _exported_bag(run, tmp_path / "b", lambda topic: topic in ("/packets", "/messages"))
    ]
    key = lambda row: (row[0], row[1], json.dumps(row[2], sort_keys=True))  # noqa: E731
    assert sorted(got, key=key) == sorted(want, key=key)
