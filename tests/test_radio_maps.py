"""Reading ROS map_server maps: pixel semantics, geometry, and every bad input refused in one line."""

import numpy as np
import pytest
from PIL import Image

from netsim.area import Bounds
from netsim.errors import ConfigError
from netsim.world.maps import EXAMPLES, load_map, occupancy_from_pixels, save_map

YAML = """image: {image}
resolution: {resolution}
origin: {origin}
negate: {negate}
occupied_thresh: 0.65
free_thresh: 0.196
"""


def _write(tmp_path, pixels, mode=None, suffix=".pgm", resolution=0.5, origin="[-1.0, -2.0, 0.0]", negate=0, extra=""):
    img = tmp_path / f"map{suffix}"
    Image.fromarray(np.asarray(pixels, dtype=np.uint8), mode).save(img)
    y = tmp_path / "map.yaml"
    y.write_text(YAML.format(image=img.name, resolution=resolution, origin=origin, negate=negate) + extra)
    return y


def test_trinary_semantics_as_map_server():
    """p = (255 - v) / 255: occupied if p > occupied_thresh, free if p < free_thresh, else unknown."""
    v = np.array([[0, 89, 90, 205, 254, 255, 205]], dtype=np.uint8)
    occ, free = occupancy_from_pixels(v, False, 0.65, 0.196)
    # p: 1, 0.651, 0.647, 0.196, 0.004, 0, 0.196
    assert occ.tolist() == [[True, True, False, False, False, False, False]]
    assert free.tolist() == [[False, False, False, False, True, True, False]]


def test_negate_swaps_black_and_white():
    v = np.array([[0, 255]], dtype=np.uint8)
    occ, free = occupancy_from_pixels(v, True, 0.65, 0.196)
    assert occ.tolist() == [[False, True]] and free.tolist() == [[True, False]]


def test_colour_channels_are_averaged_and_alpha_too_in_trinary_mode():
    rgb = np.array([[[0, 0, 255]]], dtype=np.uint8)  # mean 85: p = 0.667 > 0.65
    assert occupancy_from_pixels(rgb, False, 0.65, 0.196)[0].tolist() == [[True]]
    rgba = np.array([[[255, 255, 255, 0]]], dtype=np.uint8)  # trinary: mean 191.25 -> p = 0.25
    occ, free = occupancy_from_pixels(rgba, False, 0.65, 0.196, "trinary", has_alpha=True)
    assert not occ[0, 0] and not free[0, 0]
    opaque = np.array([[[255, 255, 255, 255]]], dtype=np.uint8)
    occ, free = occupancy_from_pixels(opaque, False, 0.65, 0.196, "scale", has_alpha=True)
    assert free[0, 0]  # scale: alpha left out of the mean


def test_pixels_of_other_channel_counts_are_refused():
    """Gray or RGB, with or without alpha: four channels without an alpha were read as a
    shade of 0, every cell a wall."""
    with pytest.raises(ValueError, match="1 \\(gray\\) or 3 \\(RGB\\) colour channels"):
        occupancy_from_pixels(np.zeros((1, 1, 4), np.uint8), False, 0.65, 0.196)


def test_a_gray_pixel_with_alpha_is_read_as_its_rgba_twin():
    """Nav2 averages red, green, blue (a gray value is all three) and, in trinary mode, the
    alpha: an opaque black gray+alpha pixel has p = 0.75, a wall, as its RGBA twin; a mean
    over the two channels gave 0.5, unknown, and every wall of such a map vanished."""
    gray = np.array([[0, 100, 254, 205]], dtype=np.uint8)
    la = np.stack([gray, np.full_like(gray, 255)], axis=2)
    rgba = np.concatenate([np.repeat(gray[:, :, None], 3, axis=2), la[:, :, 1:]], axis=2)
    for mode in ("trinary", "scale"):
        got = occupancy_from_pixels(la, False, 0.65, 0.196, mode, has_alpha=True)
        want = occupancy_from_pixels(rgba, False, 0.65, 0.196, mode, has_alpha=True)
        assert [g.tolist() for g in got] == [w.tolist() for w in want], mode
    assert occupancy_from_pixels(la, False, 0.65, 0.196, "trinary", has_alpha=True)[0].tolist() == [
        [True, False, False, False]
    ]


def test_a_pixel_not_fully_opaque_is_unknown_in_scale_mode():
    """ROS 2's map_server in scale mode: a pixel that is not fully opaque is unknown,
    whatever its colour (map_saver writes unknown cells so); a transparent black pixel was
    read as a wall, a transparent white one as free."""
    rgba = np.array([[[0, 0, 0, 0], [255, 255, 255, 0], [255, 255, 255, 254], [0, 0, 0, 255]]], dtype=np.uint8)
    occ, free = occupancy_from_pixels(rgba, False, 0.65, 0.196, "scale", has_alpha=True)
    assert occ.tolist() == [[False, False, False, True]]
    assert free.tolist() == [[False, False, False, False]]


def test_loaded_map_geometry(tmp_path):
    """Image row 0 is the top; origin is the lower-left corner; half-open cells."""
    px = np.full((4, 6), 254, dtype=np.uint8)
    px[0, 5] = 0  # top-right pixel
    px[3, 0] = 0  # bottom-left pixel
    px[1, 2] = 205  # unknown
    m = load_map(_write(tmp_path, px))
    assert m.shape == (4, 6)
    assert m.extent_m == (-1.0, 2.0, -2.0, 0.0)
    assert m.occupied[0, 0] and m.occupied[3, 5]
    assert not m.free[2, 2] and not m.occupied[2, 2]
    # The bottom-left pixel covers x in [-1, -0.5), y in [-2, -1.5).
    assert m.is_free([[-0.75, -1.75], [-0.5, -1.75], [1.9, -0.1], [5.0, 5.0]]).tolist() == [False, True, False, False]
    assert m.cells([[2.0, 0.0]]) == ([5], [3])  # the far corner belongs to the last cell


def test_numbers_as_map_saver_writes_them_are_numbers(tmp_path):
    """yaml-cpp writes -1000 at map_saver's precision as -1e+03, which YAML 1.1 reads as
    text; map_server reads it as a number, and so does netsim (it was refused)."""
    px = np.full((4, 6), 254, dtype=np.uint8)
    m = load_map(_write(tmp_path, px, resolution="5e-01", origin="[-1e+03, 2E3, 0]"))
    assert m.origin_m == (-1000.0, 2000.0) and m.resolution_m == 0.5
    assert load_map(_write(tmp_path, px, origin="[1.5e3, .5e1, 0]")).origin_m == (1500.0, 5.0)
    with pytest.raises(ConfigError, match=r"'origin: \['1e', 0, 0\]' must be \[x, y, yaw\]"):
        load_map(_write(tmp_path, px, origin="[1e, 0, 0]"))


def test_png_and_rgb_images(tmp_path):
    px = np.zeros((3, 3, 3), dtype=np.uint8) + 254
    px[1, 1] = 0
    m = load_map(_write(tmp_path, px, "RGB", ".png"))
    assert m.occupied.sum() == 1 and m.occupied[1, 1]


def test_round_trip_with_save_map(tmp_path):
    rng = np.random.default_rng(1)
    occ = rng.random((7, 9)) < 0.3
    free = ~occ & (rng.random((7, 9)) < 0.8)
    y = save_map(tmp_path / "m.yaml", occ, free, 0.1, (3.0, 4.0))
    m = load_map(y)
    assert np.array_equal(m.occupied, occ) and np.array_equal(m.free, free)
    assert m.origin_m == (3.0, 4.0) and m.resolution_m == 0.1
    # A georeferenced origin and a fine resolution come back exactly (six digits put the
    # origin 0.32 m off).
    m = load_map(save_map(tmp_path / "geo.yaml", occ, free, 0.0123456789, (512345.678, -1234.5678), 0.7, 0.2))
    assert m.origin_m == (512345.678, -1234.5678) and m.resolution_m == 0.0123456789


@pytest.mark.parametrize("name", EXAMPLES)
def test_example_maps_load_by_name(name):
    m = load_map(name)
    assert m.extent_m == (0.0, 200.0, 0.0, 200.0)
    m.check_area(200.0)


def _one_line_error(call, *fragments):
    with pytest.raises(ConfigError) as err:
        call()
    msg = str(err.value)
    assert err.value.key == "world.map"
    assert msg.startswith("world.map = ")
    assert "\n" not in msg
    for f in fragments:
        assert f in msg, msg
    return msg


def test_missing_file():
    _one_line_error(lambda: load_map("/no/such/map.yaml"), "/no/such/map.yaml", "no such file")


def test_malformed_yaml(tmp_path):
    y = tmp_path / "bad.yaml"
    y.write_text("image: [unclosed\n")
    _one_line_error(lambda: load_map(y), "not valid YAML")
    y.write_text("- just\n- a list\n")
    _one_line_error(lambda: load_map(y), "YAML mapping")


def test_missing_keys(tmp_path):
    y = tmp_path / "m.yaml"
    y.write_text("image: m.pgm\nresolution: 0.1\n")
    _one_line_error(lambda: load_map(y), "origin", "negate", "occupied_thresh", "free_thresh")


@pytest.mark.parametrize(
    "kwargs, fragment",
    [
        ({"resolution": 0}, "resolution"),
        ({"resolution": "'fine'"}, "resolution"),
        ({"resolution": ".nan"}, "resolution"),
        ({"origin": "[0, 0]"}, "origin"),
        ({"origin": "[0, 0, 0.5]"}, "yaw"),
        ({"origin": "[0, .inf, 0]"}, "origin"),
        ({"negate": 2}, "negate"),
    ],
)
def test_bad_values(tmp_path, kwargs, fragment):
    y = _write(tmp_path, np.full((4, 4), 254), **kwargs)
    _one_line_error(lambda: load_map(y), fragment)


@pytest.mark.parametrize(
    "occ, free, fragment",
    [("0.2", "0.6", "bad thresholds"), ("1.5", "0.1", "occupied_thresh"), ("0.65", "-0.1", "free_thresh")],
)
def test_bad_thresholds(tmp_path, occ, free, fragment):
    y = _write(tmp_path, np.full((4, 4), 254))
    y.write_text(y.read_text().replace("occupied_thresh: 0.65", f"occupied_thresh: {occ}").replace("0.196", free))
    _one_line_error(lambda: load_map(y), fragment)


def test_raw_mode_refused(tmp_path):
    y = _write(tmp_path, np.full((4, 4), 254), extra="mode: raw\n")
    _one_line_error(lambda: load_map(y), "raw")


def test_missing_or_unreadable_image(tmp_path):
    y = _write(tmp_path, np.full((4, 4), 254))
    (tmp_path / "map.pgm").unlink()
    _one_line_error(lambda: load_map(y), "map.pgm", "no such file")
    (tmp_path / "map.pgm").write_bytes(b"P5\n garbage")
    _one_line_error(lambda: load_map(y), "not a readable")


def test_sixteen_bit_image_refused(tmp_path):
    img = tmp_path / "map.png"
    Image.fromarray(np.full((4, 4), 60000, dtype=np.uint16)).save(img)
    y = tmp_path / "map.yaml"
    y.write_text(YAML.format(image="map.png", resolution=1.0, origin="[0, 0, 0]", negate=0))
    _one_line_error(lambda: load_map(y), "8 bits")


def test_map_smaller_than_the_area(tmp_path):
    m = load_map(_write(tmp_path, np.full((40, 30), 254), resolution=1.0, origin="[0, 0, 0]"))
    m.check_area(30.0)
    _one_line_error(lambda: m.check_area(35.0), "30 m x 40 m", "smaller than the area")


def test_origin_putting_the_area_outside_the_map(tmp_path):
    m = load_map(_write(tmp_path, np.full((50, 50), 254), resolution=1.0, origin="[5, -10, 0]"))
    _one_line_error(lambda: m.check_area(40.0), "origin [5, -10]", "does not contain the area")


def test_area_without_free_cell(tmp_path):
    m = load_map(_write(tmp_path, np.full((10, 10), 0), resolution=1.0, origin="[0, 0, 0]"))
    _one_line_error(lambda: m.check_area(10.0), "no free cell")


def test_thresholds_are_strict():
    """At exactly a threshold a cell is unknown: occupied needs p > occupied_thresh, free p < free_thresh."""
    v = np.array([[205, 155]], dtype=np.uint8)
    occ, free = occupancy_from_pixels(v, False, (255 - 155) / 255, (255 - 205) / 255)
    assert occ.tolist() == [[False, False]] and free.tolist() == [[False, False]]


def test_a_map_whose_image_was_edited_is_read_again(tmp_path):
    """The cache of maps was keyed on the YAML file alone: an image edited (a wall drawn)
    in the same process was not seen, and the run's map_sha256 named the stale map."""
    from netsim.world.maps import cached_map

    y = _write(tmp_path, np.full((6, 8), 254))
    assert not cached_map(y).occupied.any()
    walled = np.full((6, 8), 254)
    walled[:, 4] = 0
    Image.fromarray(walled.astype(np.uint8)).save(tmp_path / "map.pgm")
    assert cached_map(y).occupied[:, 4].all()


def test_map_saver_negate_swaps_free_and_occupied(tmp_path):
    """With ``negate: 1`` the YAML's map reads ``p = v / 255``: a black pixel is free, a
    white one a wall, a mid gray (p = 0.39) unknown."""
    px = np.array([[0, 255, 100]], dtype=np.uint8)
    m = load_map(_write(tmp_path, px, origin="[0, 0, 0]", negate=1))
    assert m.occupied.tolist() == [[False, True, False]] and m.free.tolist() == [[True, False, False]]


def test_equal_thresholds_are_no_bad_thresholds(tmp_path):
    """Only ``free_thresh`` above ``occupied_thresh`` is refused: equal thresholds leave no
    unknown shade but the threshold itself."""
    y = _write(tmp_path, np.array([[0, 128, 254]]), origin="[0, 0, 0]")
    y.write_text(y.read_text().replace("0.196", "0.65"))
    m = load_map(y)
    assert m.occupied.tolist() == [[True, False, False]] and m.free.tolist() == [[False, True, True]]


def test_a_map_without_mode_is_read_in_trinary_mode(tmp_path):
    """``mode`` is optional and ``trinary`` by default: the alpha of a half-transparent white
    pixel is averaged in (p = 0.13, free), where ``scale`` would make it unknown."""
    rgba = np.array([[[255, 255, 255, 128], [0, 0, 0, 255]]], dtype=np.uint8)
    m = load_map(_write(tmp_path, rgba, "RGBA", ".png", origin="[0, 0, 0]"))
    assert m.free.tolist() == [[True, False]] and m.occupied.tolist() == [[False, True]]


def _save_image(path, mode):
    """A 1 x 3 PNG in PIL ``mode`` (gray with alpha, or a palette) of an opaque black, an
    opaque white and a transparent white."""
    if mode == "LA":
        Image.fromarray(np.array([[[0, 255], [254, 255], [255, 0]]], dtype=np.uint8), "LA").save(path)
    else:
        img = Image.fromarray(np.array([[0, 1, 2]], dtype=np.uint8), "P")
        img.putpalette([0, 0, 0, 255, 255, 255, 255, 255, 255])
        img.save(path, transparency=2)


@pytest.mark.parametrize("mode", ["LA", "P"])
def test_the_alpha_of_a_gray_or_palette_image_is_averaged_in_under_trinary(tmp_path, mode):
    """A gray image's alpha, or a palette's transparent colour, is averaged in under trinary
    as an RGBA image's is: an opaque black is a wall (p = 0.75), an opaque white free, a
    transparent white unknown (p = 0.25)."""
    _save_image(tmp_path / "map.png", mode)
    y = tmp_path / "map.yaml"
    y.write_text(YAML.format(image="map.png", resolution=1.0, origin="[0, 0, 0]", negate=0))
    m = load_map(y)
    assert m.occupied.tolist() == [[True, False, False]] and m.free.tolist() == [[False, True, False]]


def test_an_area_is_judged_by_the_free_cells_inside_it(tmp_path):
    """A map must have a free cell in the area: the columns are told by x and the rows by y,
    so a wide area whose only free cells are at its far end is accepted, and one that holds
    none is refused."""
    px = np.zeros((10, 40), dtype=np.uint8)
    px[:, 35] = 254
    m = load_map(_write(tmp_path, px, resolution=1.0, origin="[0, 0, 0]"))
    m.check_area(Bounds(20.0, 0.0, 40.0, 10.0), bounds_given=True)
    _one_line_error(lambda: m.check_area(Bounds(0.0, 0.0, 20.0, 10.0), bounds_given=True), "no free cell")


def test_an_area_the_map_covers_but_for_rounding_is_inside_it(tmp_path):
    """18 pixels of 0.15 m reach 2.6999999999999997 m: the map covers the area [0, 2.7]^2 as
    the user wrote it, which is not refused."""
    m = load_map(_write(tmp_path, np.full((18, 18), 254), resolution=0.15, origin="[0, 0, 0]"))
    assert m.extent_m[1] < 2.7
    m.check_area(Bounds(0.0, 0.0, 2.7, 2.7), bounds_given=True)
    m.check_area(2.7)


def test_a_maps_fingerprint_names_its_cells_their_size_and_where_they_lie(tmp_path):
    """The map's sha256 (recorded by a run) is the same for the same map and differs when
    its origin or its resolution does, not only its cells."""
    px = np.full((4, 6), 254)
    base = load_map(_write(tmp_path, px))
    assert load_map(_write(tmp_path, px)).sha256 == base.sha256
    assert load_map(_write(tmp_path, px, origin="[-1.0, -1.0, 0.0]")).sha256 != base.sha256
    assert load_map(_write(tmp_path, px, resolution=0.25)).sha256 != base.sha256
