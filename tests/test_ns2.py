"""ns-2 movement files: generate, parse (setdest, BonnMotion), replay exactly."""

import warnings

import numpy as np
import pandas as pd
import pytest

from netsim.errors import NetsimInputError
from netsim.formats import ns2
from netsim.run import build, execute
from netsim.tools.cli import main
from netsim.trajectory import sample_positions
from tests.fixtures import make_config

SETDEST_SAMPLE = """\
#
# nodes: 2, pause: 2.00, max speed: 5.00, max x: 100.00, max y: 100.00
#
$node_(0) set X_ 10.000000000000
$node_(0) set Y_ 20.000000000000
$node_(0) set Z_ 0.000000000000
$node_(1) set X_ 50.000000000000
$node_(1) set Y_ 50.000000000000
$node_(1) set Z_ 0.000000000000
$god_ set-dist 0 1 1
$ns_ at 2.000000000000 "$node_(0) setdest 40.000000000000 60.000000000000 5.000000000000"
$ns_ at 3.500000000000 "$god_ set-dist 0 1 2"
$ns_ at 4.000000000000 "$node_(1) setdest 50.000000000000 90.000000000000 2.000000000000"
$ns_ at 5.0 "$node_(0) setdest 10.0 20.0 1.0"
"""


def test_parse_setdest_file(tmp_path):
    f = tmp_path / "s.tcl"
    f.write_text(SETDEST_SAMPLE)
    scen = ns2.read(f)
    assert scen.n_robots == 2
    assert scen.initial_m.tolist() == [[10.0, 20.0], [50.0, 50.0]]
    # Node 0's first stop (at 12 s) is cancelled by its second setdest at 5 s.
    ev = scen.events
    assert list(zip(ev.t_s, ev.robot)) == [(2.0, 0), (4.0, 1), (5.0, 0), (20.0, 0), (24.0, 1)]
    assert ev.kind.tolist() == ["velocity", "velocity", "velocity", "stop", "stop"]


def test_replay_follows_ns2_semantics(tmp_path):
    """setdest leaves from where the node is, stops on arrival, a new setdest replaces the
    old one mid-way."""
    f = tmp_path / "s.tcl"
    f.write_text(SETDEST_SAMPLE)
    cfg = make_config(
        duration_s=60.0,
        world={"n_robots": 2, "side_m": 100.0},
        mobility={"model": "trace", "trace_file": str(f)},
        protocol={"model": "none"},
    )
    sim = build(cfg)
    sim.run()
    st = sim.state
    pos = lambda t: sample_positions(st.legs(), 2, [t])[["x_m", "y_m"]].to_numpy()
    # Node 0: at t = 5 it has covered 15 m of the 50 m toward (40, 60) (direction (0.6, 0.8)).
    p5 = np.array([10 + 0.6 * 15, 20 + 0.8 * 15])
    assert pos(5.0)[0] == pytest.approx(p5)
    back = np.linalg.norm(p5 - [10, 20])  # then back to (10, 20) at 1 m/s, arriving at 5 + 15
    assert pos(5.0 + back / 2)[0] == pytest.approx((p5 + [10, 20]) / 2)
    assert pos(40.0)[0] == pytest.approx([10, 20])
    # Node 1: leaves at 4, arrives at (50, 90) at 24 and stays.
    assert pos(14.0)[1] == pytest.approx([50, 70])
    assert pos(24.0)[1] == pytest.approx([50, 90])
    assert pos(50.0)[1] == pytest.approx([50, 90])


def test_generated_scenario_replays_to_the_same_positions(tmp_path):
    """`netsim scenario generate` then model = "trace" reproduces the generator's motion."""
    f = tmp_path / "scen.tcl"
    assert (
        main(
            [
                "scenario",
                "generate",
                "--n",
                "20",
                "--side",
                "500",
                "--speed-min",
                "0.5",
                "--speed-max",
                "5",
                "--pause",
                "2",
                "--duration",
                "300",
                "--seed",
                "3",
                "-o",
                str(f),
            ]
        )
        == 0
    )
    text = f.read_text()
    assert "$node_(19) set X_" in text and "setdest" in text
    gen = make_config(
        seed=3,
        duration_s=300.0,
        world={"n_robots": 20, "side_m": 500.0},
        mobility={"speed_min_mps": 0.5, "speed_max_mps": 5.0, "pause_s": 2.0},
        protocol={"model": "none"},
    )
    original = build(gen)
    original.run()
    replay = build(
        make_config(
            duration_s=300.0,
            world={"n_robots": 20, "side_m": 500.0},
            mobility={"model": "trace", "trace_file": str(f)},
            protocol={"model": "none"},
        )
    )
    replay.run()
    times = np.linspace(0, 299.9, 700)
    a = sample_positions(original.state.legs(), 20, times)[["x_m", "y_m"]].to_numpy()
    b = sample_positions(replay.state.legs(), 20, times)[["x_m", "y_m"]].to_numpy()
    assert np.abs(a - b).max() < 1e-6


def test_bonnmotion_style_file_is_read(tmp_path):
    f = tmp_path / "bm.ns_movements"
    f.write_text('$node_(0) set X_ 1.5\n$node_(0) set Y_ 2.5\n$ns_ at 0.0 "$node_(0) setdest 11.5 2.5 1.0"\n')
    scen = ns2.read(f)
    assert scen.events.iloc[0].tolist()[:3] == [0.0, 0, "velocity"]


@pytest.mark.parametrize(
    "text, words",
    [
        ("$node_(0) set X_ inf\n", ":1: X_ inf must be finite"),
        ('$node_(0) set X_ 1\n$ns_ at 1 "$node_(0) setdest 1 nan 1"\n', ":2: Y nan must be finite"),
        ("$node_(0) set X_ abc\n", "no ns-2 movement line"),
        ("hello\n", "no ns-2 movement line"),
        ("", "no ns-2 movement line"),
        ("# only a comment\n", "no ns-2 movement line"),
    ],
)
def test_malformed_files_name_the_line(tmp_path, text, words):
    f = tmp_path / "bad.tcl"
    f.write_text(text)
    with pytest.raises(NetsimInputError, match=words):
        ns2.read(f)


def test_nodes_without_an_initial_position_start_at_the_origin_as_in_ns3(tmp_path):
    """As ns-3's Ns2MobilityHelper: a coordinate never set is 0, with one warning naming
    the nodes; a node that appears only in commands counts."""
    f = tmp_path / "partial.tcl"
    f.write_text(
        "$node_(0) set X_ 5.0\n$node_(0) set Y_ 6.0\n$node_(1) set X_ 7.0\n"
        '$ns_ at 1.0 "$node_(3) setdest 10.0 0.0 2.0"\n'
    )
    with pytest.warns(UserWarning, match=r"node\(s\) \[1, 2, 3\] .* start at 0") as caught:
        scen = ns2.read(f)
    assert len(caught) == 1
    assert scen.n_robots == 4
    assert scen.initial_m.tolist() == [[5.0, 6.0], [7.0, 0.0], [0.0, 0.0], [0.0, 0.0]]
    cfg = make_config(
        duration_s=10.0,
        world={"n_robots": 4, "side_m": 100.0},
        mobility={"model": "trace", "trace_file": str(f)},
        protocol={"model": "none"},
    )
    with pytest.warns(UserWarning):
        sim = build(cfg)
    sim.run()
    pos = sample_positions(sim.state.legs(), 4, [0.0, 3.0, 9.0])[["x_m", "y_m"]].to_numpy().reshape(3, 4, 2)
    assert pos[0, 3].tolist() == [0.0, 0.0] and pos[1, 3].tolist() == [4.0, 0.0] and pos[2, 3].tolist() == [10.0, 0.0]


@pytest.mark.filterwarnings("always::UserWarning")
def test_cli_warns_in_one_line_for_nodes_without_a_position(tmp_path, capsys):
    f = tmp_path / "partial.tcl"
    f.write_text('$node_(0) set X_ 5.0\n$node_(0) set Y_ 6.0\n$ns_ at 1.0 "$node_(1) setdest 10.0 0.0 2.0"\n')
    code = main(
        ["run", "--quiet", "--out", str(tmp_path / "o"), "--set", "mobility.model=trace"]
        + ["--set", f"mobility.trace_file={f}", "--set", "world.n_robots=2", "--set", "duration_s=5"]
    )
    err = capsys.readouterr().err.splitlines()
    assert code == 0
    assert len(err) == 1 and err[0].startswith("netsim: warning: ") and "node(s) [1]" in err[0]


def test_trace_node_count_must_match(tmp_path, capsys):
    f = tmp_path / "s.tcl"
    f.write_text(SETDEST_SAMPLE)
    code = main(
        [
            "run",
            "--quiet",
            "--out",
            str(tmp_path / "o"),
            "--set",
            "mobility.model=trace",
            "--set",
            f"mobility.trace_file={f}",
            "--set",
            "world.n_robots=3",
        ]
    )
    assert code == 2 and "world.n_robots = 3" in capsys.readouterr().err


def test_a_file_of_starting_positions_only_gives_robots_that_stand_still(tmp_path):
    """As ns-3's Ns2MobilityHelper: a file with `$node_(i) set X_ / Y_` lines and no
    `$ns_ at` line places the robots, which then stand still for the whole run."""
    f = tmp_path / "start.tcl"
    f.write_text("$node_(0) set X_ 10.0\n$node_(0) set Y_ 20.0\n$node_(1) set X_ 30.5\n$node_(1) set Y_ 40.0\n")
    scen = ns2.read(f)
    assert scen.events.empty
    cfg = make_config(
        duration_s=20.0,
        world={"n_robots": 2, "side_m": 100.0},
        mobility={"model": "trace", "trace_file": str(f)},
        protocol={"model": "none"},
    )
    sim = build(cfg)
    sim.run()
    pos = sample_positions(sim.state.legs(), 2, [0.0, 7.5, 19.9])[["x_m", "y_m"]].to_numpy().reshape(3, 2, 2)
    assert (pos == [[10.0, 20.0], [30.5, 40.0]]).all()


# -- ns-2's meaning of a file, and ns-3's as an option -------------------------------------------
JUMPS = """\
$node_(0) set X_ 100.0
$node_(0) set Y_ 450.0
$node_(1) set X_ 150.0
$node_(1) set Y_ 450.0
$node_(2) set X_ 125.0
$node_(2) set Y_ 50.0
$node_(3) set X_ 140.0
$node_(3) set Y_ 440.0
$ns_ at 21.25 "$node_(2) set Y_ 450.0"
$ns_ at 40.5 "$node_(3) set X_ 900.0"
"""


def _links_of(tmp_path, text, **mobility):
    f = tmp_path / "jumps.tcl"
    f.write_text(text)
    cfg = make_config(
        duration_s=60.0,
        world={"n_robots": 4, "side_m": 1000.0},
        channel={"range_m": 100.0},
        mobility={"model": "trace", "trace_file": str(f), **mobility},
        protocol={"model": "none"},
    )
    links = execute(cfg).frames["links"]
    return {(int(a), int(b)): (float(u), float(d)) for a, b, u, d in links[["a", "b", "t_up_s", "t_down_s"]].to_numpy()}


def test_a_scheduled_set_moves_the_robot_at_its_time_and_its_links_change_then(tmp_path):
    """ns-2's meaning (the default): `$ns_ at T "$node_(i) set Y_ y"` leaves the robot where
    its initial lines put it until T, then it jumps: its links open and close at T exactly."""
    got = _links_of(tmp_path, JUMPS)
    assert got == {
        (0, 1): (0.0, 60.0),
        (0, 2): (21.25, 60.0),
        (1, 2): (21.25, 60.0),
        (0, 3): (0.0, 40.5),
        (1, 3): (0.0, 40.5),
        (2, 3): (21.25, 40.5),
    }


def test_ns3_semantics_place_a_scheduled_set_from_the_start(tmp_path):
    """mobility.ns2_semantics = "ns3" reads the file as ns-3's Ns2MobilityHelper does: a
    scheduled set moves the robot when the file is read (from t = 0), and again at T."""
    got = _links_of(tmp_path, JUMPS, ns2_semantics="ns3")
    assert got == {(0, 1): (0.0, 60.0), (0, 2): (0.0, 60.0), (1, 2): (0.0, 60.0)}


def test_a_bad_ns2_semantics_is_one_line_exit_2(tmp_path, capsys):
    f = tmp_path / "s.tcl"
    f.write_text(SETDEST_SAMPLE)
    code = main(
        ["run", "--quiet", "--out", str(tmp_path / "o"), "--set", "mobility.model=trace"]
        + ["--set", f"mobility.trace_file={f}", "--set", "world.n_robots=2", "--set", "mobility.ns2_semantics=ns4"]
    )
    err = capsys.readouterr().err.splitlines()
    assert code == 2 and len(err) == 1
    assert err[0].startswith("netsim: error: mobility.ns2_semantics = 'ns4'") and "'ns2', 'ns3'" in err[0]
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize(
    ("name", "key", "value", "said"),
    [
        ("s.tcl", "topics", ["/robot_0/odom", "/robot_1/odom"], "mobility.topics: applies to ROS 2 bags only"),
        ("s.tcl", "ns2_semantics", "ns3", None),  # read: no warning
        ("s.movements", "ns2_semantics", "ns3", "mobility.ns2_semantics: applies to ns-2 files only"),
    ],
)
def test_a_key_of_another_traces_format_is_warned_of(tmp_path, recwarn, name, key, value, said):
    """A trace format's own key set for a trace of another format (a bag's pose topics for an
    ns-2 file, ns-3's reading for a BonnMotion file) does nothing: one warning naming the key,
    the format the file is read as and that it is ignored; the format's own key, none."""
    f = tmp_path / name
    f.write_text(SETDEST_SAMPLE if name.endswith(".tcl") else "0 10 10 5 20 10\n0 30 10\n")
    make_config(world={"n_robots": 2}, mobility={"model": "trace", "trace_file": str(f), key: value})
    warned = [str(w.message) for w in recwarn]
    read_as = "ns-2" if name.endswith(".tcl") else "BonnMotion"
    assert warned == ([] if said is None else [f"{said}, and {f} is read as {read_as}; ignored"])


OUT_OF_ORDER = """\
$node_(0) set X_ 100.0
$node_(0) set Y_ 100.0
$ns_ at 10.0 "$node_(0) setdest 900.0 200.0 4.0"
$ns_ at 5.0 "$node_(0) setdest 500.0 900.0 0.0"
"""


def test_lines_out_of_time_order_are_named_in_a_warning_and_applied_in_time_order(tmp_path):
    """A node's line earlier than one before it is named in one warning; ns-2 applies the
    lines in time order, so the robot stops at its setdest's destination and stays in the area."""
    f = tmp_path / "late.tcl"
    f.write_text(OUT_OF_ORDER)
    with pytest.warns(UserWarning, match=r"line\(s\) 4 \(node\(s\) \[0\]\) are earlier .* time order") as caught:
        scen = ns2.read(f)
    assert len(caught) == 1
    cfg = make_config(
        duration_s=300.0,
        world={"n_robots": 1, "side_m": 1000.0},
        mobility={"model": "trace", "trace_file": str(f)},
        protocol={"model": "none"},
    )
    with pytest.warns(UserWarning):
        sim = build(cfg)
    sim.run()
    pos = sample_positions(sim.state.legs(), 1, [7.0, 299.0])[["x_m", "y_m"]].to_numpy()
    assert pos.tolist() == [[100.0, 100.0], pytest.approx([900.0, 200.0])]
    assert scen.events.kind.tolist() == ["velocity", "velocity", "stop"]


@pytest.mark.filterwarnings("always::UserWarning")
def test_a_robot_that_leaves_the_area_is_one_line_naming_it_the_time_and_the_line(tmp_path, capsys):
    """Read as ns-3 reads it, the out-of-order file never stops the robot: the replayed
    motion leaves the area, which is refused before the run (robot, time, file line)."""
    f = tmp_path / "late.tcl"
    f.write_text(OUT_OF_ORDER)
    code = main(
        ["run", "--quiet", "--out", str(tmp_path / "o"), "--set", "mobility.model=trace", "--set", "world.n_robots=1"]
        + ["--set", f"mobility.trace_file={f}", "--set", "mobility.ns2_semantics=ns3"]
    )
    err = [line for line in capsys.readouterr().err.splitlines() if "warning" not in line]
    assert code == 2 and len(err) == 1
    assert err[0].startswith("netsim: error: mobility.trace_file: robot 0 leaves the area")
    # It leaves (100, 100) at 10 s toward (900, 200) at 4 m/s: x = 1000 at 10 + 900 / (4 cos a).
    t_out = 10.0 + 900.0 / (4.0 * 800.0 / np.hypot(800.0, 100.0))
    assert f"at t = {t_out:.9g} s" in err[0] and f"{f}:3" in err[0]
    assert not (tmp_path / "o").exists()


def test_skipped_lines_are_counted_in_one_warning(tmp_path):
    """Movement lines that are not understood (a truncated last line, a negative speed) are
    skipped, and one warning counts them and names the first lines."""
    f = tmp_path / "cut.tcl"
    f.write_text(
        "$node_(0) set X_ 1.0\n$node_(0) set Y_ 2.0\n$god_ set-dist 0 1 2\n"
        '$ns_ at 1.0 "$node_(0) setdest 5.0 5.0 -2.0"\n$ns_ at 2.0 "$node_(0) setdest 5.0 5.0 1.0"\n'
        '$ns_ at 9.0 "$node_(0) setdest 5'
    )
    with pytest.warns(UserWarning, match=r"2 movement line\(s\) not understood .* line\(s\) 4, 6$") as caught:
        ns2.read(f)
    assert len(caught) == 1


@pytest.mark.parametrize(
    "last", ['$ns_ at 9.0 "', '$ns_ at 9.0 "$node_(1', '$ns_ at 9.0 "$node_(0) setd', "$ns_ at 9.", "$node_(0) se"]
)
def test_a_file_cut_anywhere_in_its_last_line_warns_of_it(tmp_path, last):
    """A file cut short (as ``head -c`` cuts it) ends inside a line, without a newline, or
    leaves a quote open: that line is counted in the warning wherever the cut falls, not
    skipped without a word as other Tcl is (a whole line of other Tcl still is)."""
    f = tmp_path / "cut.tcl"
    body = '$node_(0) set X_ 1.0\n$node_(0) set Y_ 2.0\n$ns_ at 0.5 "$god_ set-dist 0 1 2"\n'
    f.write_text(body + '$ns_ at 2.0 "$node_(0) setdest 5.0 5.0 1.0"\n' + last)
    with pytest.warns(UserWarning, match=r"1 movement line\(s\) not understood \(a line cut short.* line\(s\) 5$"):
        ns2.read(f)
    f.write_text(body + '$ns_ at 2.0 "$node_(0) setdest 5.0 5.0 1.0"\n' + '$ns_ at 9.0 "$god_ set-dist 0 1 3"\n')
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        ns2.read(f)


@pytest.mark.parametrize(
    "tcl",
    ['set t "Run #1"', 'puts "a 5\\" screen"', "set s {say hi}", "$ns_ run", "}", "# the end"],
)
def test_other_tcl_is_skipped_without_a_word_even_as_the_last_line_without_newline(tmp_path, tcl):
    """Tcl that is no movement line (quotes in a string, an escaped quote, the script's
    last command) warns of nothing, also as the file's last line without its newline."""
    f = tmp_path / "ok.tcl"
    body = '$node_(0) set X_ 1.0\n$node_(0) set Y_ 2.0\n$ns_ at 2.0 "$node_(0) setdest 5.0 5.0 1.0"\n'
    for text in (f"{body}{tcl}\n", f"{body}{tcl}"):
        f.write_text(text)
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            ns2.read(f)


def test_a_movement_line_read_as_the_last_without_newline_warns_it_may_be_cut(tmp_path):
    """A last movement line that reads (its number may be cut: 12 of 12.5) but ends the
    file without a newline is used, and a warning says it may be cut."""
    f = tmp_path / "cut.tcl"
    f.write_text("$node_(0) set X_ 1.0\n$node_(0) set Y_ 12")
    with pytest.warns(UserWarning, match=r"line 2, the last, ends the file without a newline"):
        scenario = ns2.read(f)
    assert scenario.initial_m[0].tolist() == [1.0, 12.0]


SETDEST_FAR = '$node_(0) set X_ 10\n$node_(0) set Y_ 10\n$ns_ at 1 "$node_(0) setdest {x} 10 {v}"\n'


def test_a_setdest_toward_a_point_beyond_the_area_is_judged_by_the_motion_up_to_the_end(tmp_path, capsys):
    """Heading for x = 1000 at 1 m/s, the robot is at x = 29 when the 20 s run ends: the run
    goes ahead. At 50 m/s toward x = 400 it leaves at 6.8 s: one line naming the robot, the
    time and the line (both were refused by the destination, without either)."""
    base = ["run", "--quiet", "--set", "mobility.model=trace", "--set", "world.n_robots=1"]
    base += ["--set", "duration_s=20", "--set", "world.side_m=300"]
    slow, fast = tmp_path / "far.tcl", tmp_path / "leave.tcl"
    slow.write_text(SETDEST_FAR.format(x=1000, v=1))
    fast.write_text(SETDEST_FAR.format(x=400, v=50))
    assert main([*base, "--set", f"mobility.trace_file={slow}", "--out", str(tmp_path / "a")]) == 0
    legs = pd.read_parquet(tmp_path / "a" / "legs.parquet")
    assert legs.x_m.max() <= 300
    capsys.readouterr()
    assert main([*base, "--set", f"mobility.trace_file={fast}", "--out", str(tmp_path / "b")]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and "robot 0 leaves the area" in err[0] and "at t = 6.8 s" in err[0] and f"{fast}:3" in err[0]
    assert not (tmp_path / "b").exists()


def test_a_nodes_lines_at_one_instant_are_not_out_of_time_order(tmp_path):
    """Lines of one node at equal times (a jump's ``set X_`` and ``set Y_`` and its
    ``setdest``, as netsim export writes them) are in time order: no warning."""
    f = tmp_path / "same.tcl"
    f.write_text(
        "$node_(0) set X_ 1.0\n$node_(0) set Y_ 2.0\n"
        '$ns_ at 3.0 "$node_(0) set X_ 5.0"\n$ns_ at 3.0 "$node_(0) set Y_ 6.0"\n'
        '$ns_ at 3.0 "$node_(0) setdest 9.0 6.0 1.0"\n'
    )
    for semantics in ns2.SEMANTICS:
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            ns2.read(f, semantics=semantics)


@pytest.mark.parametrize("semantics", ns2.SEMANTICS)
def test_a_scheduled_set_of_z_never_moves_the_robot_in_the_plane(tmp_path, semantics):
    """``Z_`` is ignored: ``$ns_ at T "$node_(i) set Z_ z"`` changes neither x nor y, in
    either reading (ns-3 still puts the node where it is at T)."""
    f = tmp_path / "z.tcl"
    f.write_text('$node_(0) set X_ 10.0\n$node_(0) set Y_ 20.0\n$ns_ at 5.0 "$node_(0) set Z_ 7.0"\n')
    scen = ns2.read(f, semantics=semantics)
    assert scen.initial_m.tolist() == [[10.0, 20.0]]
    placed = scen.events[scen.events.kind == "position"]
    assert (placed[["x_m", "y_m"]].to_numpy() == [10.0, 20.0]).all()


@pytest.mark.parametrize("node", ["1.5", "-1"])
def test_a_node_number_with_a_dot_or_a_minus_names_no_node_as_in_ns3(tmp_path, node):
    """ns-3's helper takes ``(i)`` for a node only when ``i`` has no ``.`` and no leading
    ``-``: such a line is skipped (and counted), not read as node 1."""
    f = tmp_path / "ids.tcl"
    f.write_text(f"$node_(0) set X_ 1.0\n$node_(0) set Y_ 2.0\n$node_({node}) set X_ 9.0\n")
    with pytest.warns(UserWarning, match=r"1 movement line\(s\) not understood .* line\(s\) 3$"):
        scen = ns2.read(f)
    assert scen.n_robots == 1 and scen.initial_m.tolist() == [[1.0, 2.0]]


def test_a_scheduled_set_to_a_word_is_skipped_by_ns2_and_read_as_0_by_ns3(tmp_path):
    """ns-3's helper does not check a scheduled ``set``'s value, so a word counts as 0 (the
    node starts at x = 0 and is put there at T); ns-2's reading skips the line."""
    f = tmp_path / "word.tcl"
    f.write_text('$node_(0) set X_ 10.0\n$node_(0) set Y_ 20.0\n$ns_ at 5.0 "$node_(0) set X_ abc"\n')
    as_ns3 = ns2.read(f, semantics="ns3")
    assert as_ns3.initial_m.tolist() == [[0.0, 20.0]]
    assert as_ns3.events[["t_s", "kind", "x_m", "y_m"]].values.tolist() == [[5.0, "position", 0.0, 20.0]]
    with pytest.warns(UserWarning, match=r"1 movement line\(s\) not understood .* line\(s\) 3$"):
        as_ns2 = ns2.read(f, semantics="ns2")
    assert as_ns2.initial_m.tolist() == [[10.0, 20.0]] and as_ns2.events.empty
