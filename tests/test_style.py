"""One style for every drawing of a run: the figures and the browser replay take every
colour, marker and size from :mod:`netsim.tools.style` and name none of their own, so
that neither can change a colour without the other."""

import re
from importlib import resources
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from netsim.tools import figures, style, viewer
from netsim.tools.cli import main

ASSETS = resources.files("netsim.tools.viewer").joinpath("assets")
HEX = re.compile(r"(?<![&\w])#([0-9a-fA-F]{8}|[0-9a-fA-F]{6}|[0-9a-fA-F]{3,4})\b")
FUNCTIONS = re.compile(r"\b(rgba?|hsla?|hwb|lab|lch|color)\(")
# A colour's name in quotes; not a table's column (``frame["b"]``: a link's end).
NAMES = re.compile(
    r"""(?<!\[)["'`](black|white|red|green|blue|grey|gray|orange|yellow|purple|pink|magenta|cyan|brown|k|r|g|b)["'`]"""
)


def _grey(hex_colour: str) -> bool:
    h = hex_colour if len(hex_colour) >= 6 else "".join(c * 2 for c in hex_colour)
    return h[0:2] == h[2:4] == h[4:6]


def test_the_replay_script_names_no_colour():
    """Every colour the page draws with comes from the style it is given (META.palette)."""
    js = ASSETS.joinpath("replay.js").read_text()
    assert HEX.findall(js) == [] and FUNCTIONS.findall(js) == [] and NAMES.findall(js) == []


def test_the_replay_page_style_sheet_has_only_greys():
    """The page's chrome (text, borders, backgrounds) is grey; no colour of a group, a
    role, a link or a message can hide there."""
    css = ASSETS.joinpath("replay.css").read_text()
    colours = HEX.findall(css)
    assert colours and all(_grey(c) for c in colours)
    assert all(m.group(0).startswith("rgba(255, 255, 255") for m in re.finditer(r"rgba?\([^)]*\)", css))
    assert HEX.findall(ASSETS.joinpath("page.html").read_text()) == []


def test_the_figures_name_no_colour():
    """``netsim figures`` passes matplotlib no colour literal (only "none")."""
    src = Path(figures.__file__).read_text()
    literals = re.findall(r"\b(?:c|colou?rs?|(?:edge|face)colou?rs?)\s*=\s*[\"']([^\"']*)[\"']", src)
    assert set(literals) <= {"none"}
    assert NAMES.findall(src) == []
    assert HEX.findall(src) == []


@pytest.mark.slow
def test_the_page_carries_the_style_itself(tmp_path):
    """The replay's page embeds :func:`style.as_json` as is: a colour changed in the style
    changes the figures and the page alike."""
    out = tmp_path / "run"
    args = ["run", "--out", str(out), "--quiet", "--set", "world.n_robots=6", "--set", "duration_s=5"]
    assert main(args) == 0
    meta = viewer.data.pack(out)["meta"]
    assert meta["palette"] == style.as_json()
    every = [style.NO_GROUP, style.LINK, style.OUTLINE, style.BORDER, style.WALL, style.MESSAGE]
    assert all(re.fullmatch(r"#[0-9a-fA-F]{6}", c) for c in [*style.GROUP_PALETTE, *every, *style.SERIES.values()])


def _frames(leader_xy: dict[float, dict[int, tuple[float, float]]], n: int):
    """Roles and positions of robots ``0..n-1``: at each time, the leaders given (at the
    positions given) and everyone else far away as a member."""
    roles, pos = [], []
    for t, leaders in leader_xy.items():
        for i in range(n):
            roles.append((t, i, "alpha" if i in leaders else "beta"))
            x, y = leaders.get(i, (1e6 + 10.0 * i, 1e6))
            pos.append((t, i, x, y))
    return (
        pd.DataFrame(roles, columns=["t_s", "robot", "role"]),
        pd.DataFrame(pos, columns=["t_s", "robot", "x_m", "y_m"]),
    )


def test_a_group_keeps_one_colour_and_neighbours_differ_at_every_instant():
    """Leaders 0 and 1 are close at t = 0, 1 and 2 at t = 1, 2 and 0 at t = 2 (100 m range,
    300 m makes neighbours): the three slots all differ; 3 was never near anyone: slot 0."""
    roles, pos = _frames(
        {
            0.0: {0: (0.0, 0.0), 1: (200.0, 0.0), 2: (5000.0, 0.0), 3: (9000.0, 9000.0)},
            1.0: {0: (5000.0, 0.0), 1: (200.0, 0.0), 2: (400.0, 0.0), 3: (9000.0, 9000.0)},
            2.0: {0: (0.0, 0.0), 1: (5000.0, 5000.0), 2: (250.0, 0.0)},
        },
        5,
    )
    slots = style.run_group_slots(roles, pos, "alpha", 100.0)
    assert set(slots) == {0, 1, 2, 3}
    assert len({slots[0], slots[1], slots[2]}) == 3 and slots[3] == 0


def test_leaders_far_apart_at_every_instant_share_the_first_colour():
    roles, pos = _frames({float(t): {0: (0.0, 0.0), 1: (1000.0 * (t + 1), 0.0)} for t in range(5)}, 3)
    assert style.run_group_slots(roles, pos, "alpha", 100.0) == {0: 0, 1: 0}


def test_distances_wrap_on_a_torus():
    roles, pos = _frames({0.0: {0: (10.0, 10.0), 1: (990.0, 990.0)}}, 2)
    assert style.run_group_slots(roles, pos, "alpha", 50.0) == {0: 0, 1: 0}
    assert style.run_group_slots(roles, pos, "alpha", 50.0, side_m=1000.0) == {0: 0, 1: 1}


def test_a_gateways_other_group_is_its_lowest_besides_its_own():
    groups = pd.DataFrame(
        {"robot": [4, 4, 4, 5], "group": [9, 2, 7, 3], "primary": [False, True, False, True]},
    )
    assert style.other_group(groups).to_dict() == {4: 7}


def test_run_colours_match_the_snapshot_rule_for_one_instant():
    """With a single sampled instant, the run's colouring is the one-instant colouring."""
    rng = np.random.default_rng(3)
    xy = rng.uniform(0, 3000, (40, 2))
    leaders = {int(i): tuple(xy[i]) for i in range(0, 40, 2)}
    roles, pos = _frames({0.0: leaders}, 40)
    slots = style.run_group_slots(roles, pos, "alpha", 100.0)
    once = style.group_colours(list(leaders), [leaders[i] for i in leaders], 100.0)
    assert {i: style.GROUP_PALETTE[s] for i, s in slots.items()} == once


def _colour_of(run_dir: Path) -> np.ndarray:
    import base64
    import gzip

    packed = viewer.data.pack(run_dir)
    raw = gzip.decompress(base64.b64decode(packed["blob"]))
    code, offset, length = packed["meta"]["arrays"]["colour_of"]
    assert code == "i16"
    return np.frombuffer(raw, dtype="<i2", count=length, offset=offset)


@pytest.mark.slow
def test_a_run_without_sampled_positions_is_coloured_at_every_ack_period(tmp_path):
    """Without positions.parquet the replay decides the colours on the legs at every Ack
    period: the same colours as the same run sampled every Ack period."""
    base = ["run", "--quiet", "--set", "world.n_robots=30", "--set", "duration_s=20", "--set", "world.side_m=500"]
    for name, interval in (("none", "0"), ("every", "1.0")):
        assert main([*base, "--out", str(tmp_path / name), "--set", f"output.position_interval_s={interval}"]) == 0
    assert not len(pd.read_parquet(tmp_path / "none" / "positions.parquet"))
    colours = _colour_of(tmp_path / "none")
    assert (colours >= 0).sum() > 3 and len(set(colours.tolist())) > 3
    assert colours.tolist() == _colour_of(tmp_path / "every").tolist()
