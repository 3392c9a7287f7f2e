"""Bad maps and bad radio values through the CLI: one line naming the key and the value,
exit status 2, nothing written."""

from __future__ import annotations

import pytest

from netsim.tools.cli import main
from netsim.tools.radio_checks import wall_test_map
from netsim.world.maps import save_map
from tests.fixtures import check_refused


def good_map(tmp_path, origin=(0.0, 0.0)):
    m = wall_test_map()
    return save_map(tmp_path / "walls.yaml", m.occupied, m.free, m.resolution_m, origin)


def bad_maps(tmp_path):
    good = good_map(tmp_path)
    yaml = good.read_text()
    out = {}

    def write(name, text):
        p = tmp_path / name
        p.write_text(text)
        out[name] = p

    write("malformed.yaml", "image: [walls.pgm\nresolution: : 0.25\n")
    write("not_a_mapping.yaml", "- just\n- a list\n")
    write("missing_keys.yaml", "image: walls.pgm\nresolution: 0.25\n")
    write("no_image.yaml", yaml.replace("image: walls.pgm", "image: nowhere.pgm"))
    (tmp_path / "garbage.pgm").write_bytes(b"P5 this is not an image")
    write("bad_image.yaml", yaml.replace("image: walls.pgm", "image: garbage.pgm"))
    write("nan_resolution.yaml", yaml.replace("resolution: 0.25", "resolution: .nan"))
    write("bad_thresholds.yaml", yaml.replace("free_thresh: 0.196", "free_thresh: 0.9"))
    return out


@pytest.mark.parametrize(
    "name, words",
    [
        ("malformed.yaml", "not valid YAML"),
        ("not_a_mapping.yaml", "YAML mapping"),
        ("missing_keys.yaml", "lacks origin"),
        ("no_image.yaml", "no such file"),
        ("bad_image.yaml", "not a readable PGM or PNG"),
        ("nan_resolution.yaml", "resolution"),
        ("bad_thresholds.yaml", "free_thresh"),
    ],
)
def test_bad_map_file_is_one_line_exit_2_nothing_written(tmp_path, capsys, name, words):
    path = bad_maps(tmp_path)[name]
    check_refused(
        tmp_path, capsys, [f"world.map={path}", "world.side_m=40", "mobility.model=static"], "world.map", words
    )


def test_missing_map_file(tmp_path, capsys):
    check_refused(
        tmp_path, capsys, [f"world.map={tmp_path / 'nope.yaml'}", "mobility.model=static"], "world.map", "no such file"
    )


def test_map_smaller_than_the_area(tmp_path, capsys):
    path = good_map(tmp_path)
    check_refused(
        tmp_path, capsys, [f"world.map={path}", "world.side_m=100", "mobility.model=static"], "world.map", "smaller"
    )


def test_origin_putting_the_area_outside_the_map(tmp_path, capsys):
    path = good_map(tmp_path, origin=(5.0, -3.0))
    check_refused(
        tmp_path,
        capsys,
        [f"world.map={path}", "world.side_m=30", "mobility.model=static"],
        "world.map",
        "does not contain the area",
    )


@pytest.mark.parametrize(
    "override, key, words",
    [
        ("channel.tx_power_dbm=nan", "channel.tx_power_dbm", "NaN"),
        ("channel.sensitivity_dbm=-inf", "channel.sensitivity_dbm", "finite"),
        ("channel.reference_loss_db=inf", "channel.reference_loss_db", "finite"),
        ("channel.path_loss_exponent=-2", "channel.path_loss_exponent", "(0, 10]"),
        ("channel.shadowing_sigma_db=50", "channel.shadowing_sigma_db", "[0, 20]"),
        ("channel.shadowing_decorrelation_m=0", "channel.shadowing_decorrelation_m", "> 0"),
        ("channel.wall_loss_db=-3", "channel.wall_loss_db", "[0, 100]"),
        ("channel.tx_power_dbm=200", "channel.tx_power_dbm", "[-60, 60]"),
        ("channel.sensitivity_dbm=-10", "channel.sensitivity_dbm", "no pair links even at the reference distance"),
        ("channel.tx_power_dbm=loud", "channel.tx_power_dbm", "number"),
    ],
)
def test_bad_db_value_is_one_line_exit_2_nothing_written(tmp_path, capsys, override, key, words):
    check_refused(tmp_path, capsys, ["channel.propagation=log_distance", override], key, words)


def test_unknown_propagation_model(tmp_path, capsys):
    check_refused(tmp_path, capsys, ["channel.propagation=rayleigh"], "channel.propagation", "'log_distance'")


def test_model_that_cannot_respect_a_map(tmp_path, capsys):
    trace = tmp_path / "x.tcl"
    trace.write_text("$node_(0) set X_ 1.0\n$node_(0) set Y_ 1.0\n")
    check_refused(
        tmp_path,
        capsys,
        [
            "world.map=office",
            "world.side_m=200",
            "world.n_robots=1",
            "mobility.model=trace",
            f"mobility.trace_file={trace}",
        ],
        "world.map",
        "cannot keep robots off the map's walls",
    )


def test_grid_placement_into_a_wall_is_refused_before_anything_is_written(tmp_path, capsys):
    check_refused(
        tmp_path,
        capsys,
        ["world.map=office", "world.side_m=200", "world.n_robots=25", "world.placement=grid", "mobility.model=static"],
        "world.placement",
        "not in a free cell",
    )


def test_csv_placement_into_a_wall_is_refused_before_anything_is_written(tmp_path, capsys):
    """A CSV placement on a map must put every robot in a free cell, as a grid must."""
    csv = tmp_path / "at.csv"
    csv.write_text("x_m,y_m\n100.0,100.0\n0.1,0.1\n")
    sets = ["world.map=office", "world.side_m=200", "world.n_robots=2", f"world.placement={csv}"]
    check_refused(tmp_path, capsys, [*sets, "mobility.model=static"], "world.placement", "puts robot 1 at (0.1, 0.1)")


def test_a_torus_with_shadowing_must_exceed_twice_the_reach(tmp_path, capsys):
    """On a torus the reach's disks around a robot's images must be disjoint, as the range's
    are: at 6 dB the default radio reaches 631 m, so a 1,000 m torus is refused, naming the
    reach, and a 1,300 m one runs."""
    radio = ["channel.propagation=log_distance", "channel.shadowing_sigma_db=6", "world.torus=true"]
    check_refused(tmp_path, capsys, radio + ["world.side_m=1000"], "world.side_m", "twice the radio's reach (631")
    ok = tmp_path / "ok"
    argv = ["run", "--quiet", "--no-progress", "--out", str(ok)]
    for o in radio + ["world.side_m=1300", "world.n_robots=5", "duration_s=2"]:
        argv += ["--set", o]
    assert main(argv) == 0
