"""The replay page (``netsim view``), opened from disk in a real browser (the system's
headless Chromium, through playwright) with every network request blocked: what it draws
at the cursor must be what the run's Parquet files say."""

import io
import os
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from netsim.tools import style, viewer
from netsim.tools.cli import main

CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]


def _run(out: Path, *sets: str) -> Path:
    args = ["run", "--out", str(out), "--quiet", "--view"]
    for s in sets:
        args += ["--set", s]
    assert main(args) == 0
    return out


@pytest.fixture(scope="module")
def browser():
    if not Path(CHROMIUM).is_file():
        if os.environ.get("CI"):
            pytest.fail(f"{CHROMIUM} is missing: .ci/run installs Debian's chromium package")
        pytest.skip(f"no {CHROMIUM} (apt-get install chromium)")
    sync_api = pytest.importorskip("playwright.sync_api")
    with sync_api.sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        yield b
        b.close()


class Page:
    """A replay page with its console errors and every request it attempted."""

    def __init__(self, browser, html: Path):
        self.url = html.resolve().as_uri()
        self.page = browser.new_page(viewport={"width": 1100, "height": 800})
        self.page.set_default_timeout(15000)
        self.errors: list[str] = []
        self.requests: list[str] = []
        self.page.on("console", lambda m: self.errors.append(m.text) if m.type == "error" else None)
        self.page.on("pageerror", lambda e: self.errors.append(str(e)))
        self.page.route("**/*", self._route)
        self.page.goto(self.url)
        self.wait_for("window.netsimView && (window.netsimView.ready || window.netsimView.error)")
        assert self.js("netsimView.error") is None

    def _route(self, route):
        self.requests.append(route.request.url)
        if route.request.url == self.url:
            route.continue_()
        else:
            route.abort()

    def js(self, expr: str):
        return self.page.evaluate(expr)

    def wait_for(self, condition: str):
        """Until ``condition`` holds, checked every animation frame (the page's policy
        forbids the string evaluation of playwright's own waiting)."""
        check = f"const check = () => ({condition}) ? done() : requestAnimationFrame(check)"
        self.page.evaluate(f"new Promise(done => {{ {check}; check(); }})")

    def close(self):
        assert self.errors == []
        assert self.requests == [self.url], "the page must load nothing but itself"
        self.page.close()


@pytest.fixture
def open_page(browser):
    pages = []

    def _open(html: Path) -> Page:
        pages.append(Page(browser, html))
        return pages[-1]

    yield _open
    for p in pages:
        p.close()


# -- the truth, from the Parquet files ---------------------------------------------------
def positions_at(run: Path, n: int, t: float, side: float | None = None) -> np.ndarray:
    legs = pd.read_parquet(run / "legs.parquet").sort_values(["robot", "t_s"], kind="stable")
    cur = legs[legs["t_s"] <= t].groupby("robot").tail(1).set_index("robot").sort_index()
    assert list(cur.index) == list(range(n))
    xy = cur[["x_m", "y_m"]].to_numpy() + cur[["vx_mps", "vy_mps"]].to_numpy() * (t - cur[["t_s"]].to_numpy())
    return np.mod(xy, side) if side else xy


def roles_at(run: Path, n: int, t: float) -> list[str]:
    roles = pd.read_parquet(run / "roles.parquet").sort_values("t_s", kind="stable")
    last = roles[roles["t_s"] <= t].groupby("robot").tail(1)
    out = ["gamma"] * n
    for r in last.itertuples():
        out[r.robot] = r.role
    return out


def links_at(run: Path, t: float) -> set[tuple[int, int]]:
    links = pd.read_parquet(run / "links.parquet")
    up = links[(links["t_up_s"] <= t) & ((t < links["t_down_s"]) | links["censored_end"])]
    return set(zip(up["a"].tolist(), up["b"].tolist()))


def gateways_at(run: Path, t: float) -> set[int]:
    groups = pd.read_parquet(run / "groups.parquet")
    sample = groups[groups["t_s"] == groups.loc[groups["t_s"] <= t, "t_s"].max()]
    counts = sample.groupby("robot").size()
    return set(counts[counts > 1].index.tolist())


def assert_matches(page: Page, run: Path, n: int, t: float, side: float | None = None):
    """What the page draws at ``t`` is what the files say."""
    assert page.js(f"netsimView.seek({t!r})") == t
    drawn = np.array(page.js("netsimView.positions()"))
    np.testing.assert_allclose(drawn, positions_at(run, n, t, side), rtol=0, atol=1e-9)
    assert page.js("netsimView.roles()") == roles_at(run, n, t)
    truth = links_at(run, t)
    assert page.js("netsimView.linksDrawn") == len(truth)
    assert {tuple(p) for p in page.js("netsimView.links()")} == truth


@pytest.fixture(scope="module")
def moving_run(tmp_path_factory):
    """40 robots, random waypoint, clustering, a message a second, 15 % of receptions lost."""
    out = tmp_path_factory.mktemp("replay") / "moving"
    return _run(
        out,
        "seed=3",
        "duration_s=60",
        "world.n_robots=40",
        "world.side_m=600",
        "channel.range_m=130",
        "protocol.message_rate_hz=1.0",
        "channel.loss_probability=0.15",
    )


# -- tests ---------------------------------------------------------------------------------
@pytest.mark.slow
def test_drawn_positions_roles_and_links_equal_the_files(moving_run, open_page):
    """After seeking, forward and back, the page's robots sit at the exact positions of
    their legs, with the roles of roles.parquet, and it draws the links up at that instant."""
    page = open_page(moving_run / "view.html")
    for t in (0.0, 4.25, 17.3, 42.0001, 59.9, 11.5):  # the last one seeks backwards
        assert_matches(page, moving_run, 40, t)


@pytest.mark.slow
def test_gateways_are_drawn_from_the_groups_sample(moving_run, open_page):
    """A member in two groups at the last groups sample is drawn as a gateway."""
    page = open_page(moving_run / "view.html")
    found = 0
    for t in (20.5, 40.5):
        page.js(f"netsimView.seek({t})")
        shapes, roles = page.js("netsimView.shapes()"), roles_at(moving_run, 40, t)
        expected = {i for i in gateways_at(moving_run, t) if roles[i] == "beta"}
        assert {i for i, s in enumerate(shapes) if s == "gateway"} == expected
        found += len(expected)
    assert found > 0


@pytest.mark.slow
def test_play_advances_time(moving_run, open_page):
    page = open_page(moving_run / "view.html")
    page.js("netsimView.seek(10)")
    page.js("netsimView.play()")
    page.wait_for("netsimView.t > 10.5")
    page.js("netsimView.pause()")
    t = page.js("netsimView.t")
    assert page.js("netsimView.playing") is False
    # What was drawn while playing is the run at that instant too.
    np.testing.assert_allclose(np.array(page.js("netsimView.positions()")), positions_at(moving_run, 40, t), atol=1e-9)


@pytest.mark.slow
def test_relayed_messages_are_drawn_as_they_hop(moving_run, open_page):
    """Within the message trail, one segment per robot's first reception of a message
    (hops.parquet, less the repeats and the source hearing its own message again)."""
    page = open_page(moving_run / "view.html")
    assert page.page.locator("#hops-label").inner_text() == "relayed messages"
    hops = pd.read_parquet(moving_run / "hops.parquet")
    src = pd.read_parquet(moving_run / "messages.parquet").set_index("msg_id")["src"]
    first = hops.sort_values("t_received_s").groupby(["msg_id", "receiver"]).head(1)
    first = first[first["receiver"].to_numpy() != src.loc[first["msg_id"]].to_numpy()]
    assert len(first) < len(hops)
    page.page.select_option("#trail", "2")
    for t in (float(hops["t_sent_s"].iloc[len(hops) // 2]) + 0.5, 30.0, 55.0):
        page.js(f"netsimView.seek({t})")
        expected = int(((first["t_sent_s"] <= t) & (first["t_sent_s"] > t - 2)).sum())
        assert page.js("netsimView.hopsDrawn") == expected
    assert expected > 0


@pytest.mark.slow
def test_screenshot_is_not_blank(moving_run, open_page):
    from PIL import Image

    page = open_page(moving_run / "view.html")
    page.js("netsimView.seek(30)")
    png = page.page.locator("#field").screenshot()
    img = np.asarray(Image.open(io.BytesIO(png)).convert("RGB")).reshape(-1, 3)
    colours = {tuple(c) for c in np.unique(img, axis=0).tolist()}
    group = {tuple(int(h[k : k + 2], 16) for k in (1, 3, 5)) for h in style.GROUP_PALETTE}
    assert (img != 255).any(axis=1).mean() > 0.005  # something is drawn
    assert colours & group  # in the groups' colours


@pytest.mark.slow
def test_hover_shows_id_role_leader_and_neighbours(moving_run, open_page):
    page = open_page(moving_run / "view.html")
    t = 30.0
    page.js(f"netsimView.seek({t})")
    roles = roles_at(moving_run, 40, t)
    i = roles.index("beta")
    x, y = page.js(f"netsimView.screenOf({i})")
    box = page.page.locator("#field").bounding_box()
    page.page.mouse.move(box["x"] + x, box["y"] + y)
    page.wait_for("netsimView.tooltip() !== ''")
    tip = page.js("netsimView.tooltip()")
    true_nbrs = sorted(b if a == i else a for a, b in links_at(moving_run, t) if i in (a, b))
    leader = page.js("netsimView.leaders()")[i]
    assert tip.startswith(f"robot {i}: ")
    assert f"leader {leader}" in tip
    assert f"true neighbours now: {len(true_nbrs)} [{', '.join(map(str, true_nbrs))}]" in tip
    assert "believed at t = 30 s:" in tip


def _ids_text(ids) -> str:
    return f"{len(ids)} [{', '.join(map(str, ids))}]" if len(ids) else "0"


@pytest.mark.slow
def test_hover_shows_believed_and_true_neighbours_by_id(moving_run, open_page):
    """At the last beliefs sample, every robot's believed and in-range neighbours by id
    are the table's; hovering a robot with a stale and a missing neighbour lists them."""
    nb = pd.read_parquet(moving_run / "neighbour_beliefs.parquet")
    page = open_page(moving_run / "view.html")
    for t in (12.0, 30.5, 47.25):
        page.js(f"netsimView.seek({t})")
        sample = nb[nb["t_s"] == nb.loc[nb["t_s"] <= t, "t_s"].max()]
        got = page.js("Array.from({length: netsimView.n}, (_, i) => netsimView.neighbourBeliefs(i))")
        for i, g in enumerate(got):
            mine = sample[sample["robot"] == i]
            assert g["t"] == sample["t_s"].iloc[0]
            assert g["believed"] == mine.loc[mine["believed"], "neighbour"].tolist()
            assert g["inRange"] == mine.loc[mine["in_range"], "neighbour"].tolist()
            assert g["stale"] == mine.loc[mine["believed"] & ~mine["in_range"], "neighbour"].tolist()
            assert g["missing"] == mine.loc[~mine["believed"] & mine["in_range"], "neighbour"].tolist()
    # A robot whose beliefs differ from the truth both ways, at a sample.
    differ = nb.assign(stale=nb["believed"] & ~nb["in_range"], missing=nb["in_range"] & ~nb["believed"])
    per = differ.groupby(["t_s", "robot"])[["stale", "missing"]].sum()
    t, i = per[(per["stale"] > 0) & (per["missing"] > 0)].index[0]
    mine = nb[(nb["t_s"] == t) & (nb["robot"] == i)]
    page.page.uncheck("#show-hops")
    page.js(f"netsimView.seek({t})")
    x, y = page.js(f"netsimView.screenOf({i})")
    box = page.page.locator("#field").bounding_box()
    page.page.mouse.move(box["x"] + x, box["y"] + y)
    page.wait_for(f"netsimView.hovered === {i}")
    tip = page.js("netsimView.tooltip()")
    believed = mine.loc[mine["believed"], "neighbour"].tolist()
    in_range = mine.loc[mine["in_range"], "neighbour"].tolist()
    assert f"believed at t = {t:g} s: {_ids_text(believed)}" in tip
    assert f"in range then: {_ids_text(in_range)}" in tip
    assert f"(stale): {_ids_text(sorted(set(believed) - set(in_range)))}" in tip
    assert f"(missing): {_ids_text(sorted(set(in_range) - set(believed)))}" in tip


@pytest.mark.slow
def test_strip_chart_shows_leaders_components_and_the_ack_delivery_ratio(moving_run, open_page):
    """At the cursor, the chart's values are the number of leaders drawn, the Ack delivery
    ratio of the interval of ack_delivery.parquet the cursor is in, and the components of
    the links up (at its samples)."""
    d = pd.read_parquet(moving_run / "ack_delivery.parquet")
    assert (d["delivery_ratio"].iloc[2:] < 1).all()  # the loss shows
    page = open_page(moving_run / "view.html")
    names = [s["name"] for s in page.js("JSON.parse(document.getElementById('netsim-meta').text).series")]
    assert {"leaders", "components", "ack_delivery"} <= set(names)
    for t in (0.5, 17.3, 30.0, 59.9):
        page.js(f"netsimView.seek({t})")
        values = page.js("netsimView.series()")
        assert values["ack_delivery"] == d.loc[d["t_s"] <= t, "delivery_ratio"].iloc[-1]
        assert values["leaders"] == page.js("netsimView.roles()").count("alpha")
    page.js("netsimView.seek(30)")  # a sample of the components series (600 of 60 s)
    assert page.js("netsimView.series()")["components"] == page.js("netsimView.components")
    legend = page.page.locator("#chart-legend").inner_text()
    assert f"Ack delivery ratio: {d.loc[d['t_s'] <= 30, 'delivery_ratio'].iloc[-1]:.3f}" in legend


@pytest.mark.slow
def test_figures_and_replay_colour_every_robot_alike(moving_run, open_page):
    """At a positions sample, each robot's fill and edge in the replay are what
    ``netsim figures`` gives it (one colour per group for the whole run, from the same
    style), and the pixels drawn at the leaders are those colours."""
    from PIL import Image

    from netsim.tools import figures

    run = figures.read_run(moving_run)
    colours = figures.run_colours(run)
    page = open_page(moving_run / "view.html")
    page.page.uncheck("#show-links")
    page.page.uncheck("#show-hops")
    for t in (15.0, 40.0):
        snap = figures.snapshot(run, t)
        assert snap.t_s == t
        page.js(f"netsimView.seek({t})")
        group = np.where(snap.role == "alpha", np.arange(40), snap.leader)
        expect_fill = [
            style.ROLE_STYLE["gamma"]["colour"] if r == "gamma" else colours.get(int(g), style.NO_GROUP)
            for r, g in zip(snap.role, group)
        ]
        gateway = (snap.role == "beta") & (snap.other_group >= 0)
        expect_edge = [
            style.ROLE_STYLE["alpha"]["edge"] if r == "alpha" else colours.get(int(o), style.NO_GROUP) if gw else ""
            for r, o, gw in zip(snap.role, snap.other_group, gateway)
        ]
        assert [c.upper() for c in page.js("netsimView.colours()")] == [c.upper() for c in expect_fill]
        assert [c.upper() for c in page.js("netsimView.edges()")] == [c.upper() for c in expect_edge]
        assert gateway.any() and len(set(colours.values())) > 3
        img = np.asarray(Image.open(io.BytesIO(page.page.locator("#field").screenshot())).convert("RGB"))
        for i in np.flatnonzero(snap.role == "alpha"):
            x, y = page.js(f"netsimView.screenOf({int(i)})")
            want = tuple(int(expect_fill[i][k : k + 2], 16) for k in (1, 3, 5))
            assert tuple(img[int(y), int(x)]) == want


@pytest.mark.slow
def test_coverage_run(tmp_path, open_page):
    """A coverage run: leaders move under the control loop, the chart has the covered
    fraction, and the coverage disks are drawn on demand."""
    run = _run(
        tmp_path / "cov",
        "world.n_robots=30",
        'world.placement="centre"',
        "world.centre_side_m=250",
        'mobility.model="static"',
        "channel.range_m=100",
        "coverage.enabled=true",
        "duration_s=40",
    )
    page = open_page(run / "view.html")
    series = page.js("JSON.parse(document.getElementById('netsim-meta').text).series")
    assert "covered_leaders" in [s["name"] for s in series]
    for t in (5.0, 25.5, 40.0):
        assert_matches(page, run, 30, t)
    legs = pd.read_parquet(run / "legs.parquet")
    assert (legs["t_s"] > 10).any()  # robots did move under control

    def ink(disks: str) -> int:
        page.page.select_option("#disks", disks)
        page.js("netsimView.seek(25.5)")
        img = np.asarray(__import__("PIL.Image").Image.open(io.BytesIO(page.page.locator("#field").screenshot())))
        return int((img[..., :3] != 255).any(axis=-1).sum())

    assert ink("leaders") > 2 * ink("off")


@pytest.mark.slow
def test_one_robot_run(tmp_path, open_page):
    """One robot (and no message traffic: there is nobody to send to)."""
    run = _run(tmp_path / "one", "world.n_robots=1", "protocol.message_rate_hz=0", "duration_s=20")
    page = open_page(run / "view.html")
    for t in (0.0, 3.3, 20.0):
        assert_matches(page, run, 1, t)
    assert page.js("netsimView.roles()") == ["alpha"]


def test_the_header_names_the_square_the_robots_move_in(tmp_path, open_page):
    """A square area from the origin other than world.side_m's: the header gives its side
    (it gave side_m's, 1000 m, beside a 500 m field)."""
    run = _run(tmp_path / "sq", "world.n_robots=3", "duration_s=5", "world.bounds_m=[0, 0, 500, 500]")
    page = open_page(run / "view.html")
    text = page.js("document.body.innerText")
    assert "500 m square" in text and "1000 m square" not in text


@pytest.mark.slow
def test_torus_positions_wrap(tmp_path, open_page):
    """On a torus the drawn positions wrap into the square (this run has no protocol:
    no roles, no messages)."""
    run = _run(
        tmp_path / "torus",
        "world.n_robots=15",
        "world.side_m=400",
        "world.torus=true",
        'mobility.model="random_direction"',
        "mobility.speed_min_mps=8",
        "mobility.speed_max_mps=10",
        "channel.range_m=80",
        "duration_s=60",
        'protocol.model="none"',
    )
    page = open_page(run / "view.html")
    for t in (33.3, 59.0):
        assert_matches(page, run, 15, t, side=400.0)
        drawn = np.array(page.js("netsimView.positions()"))
        assert ((drawn >= 0) & (drawn < 400)).all()
    _links_across_the_seam_end_at_the_border(page, 400.0)
    # The page folds and takes nearest images as the engine does, ties and the edge
    # included: a half side rounds to even, a tiny negative coordinate folds to 0.
    from netsim import _kernels

    side = 400.0
    offsets = [k * side / 2 for k in range(-5, 6)] + [-1e-300, -1e-14, 399.9999999999, 123.4, -777.7, 1e6 + 0.3]
    laws = [
        page.js(f"[netsimView.torusLaws.nearestImage({d!r}, {side}), netsimView.torusLaws.wrap({d!r}, {side})]")
        for d in offsets
    ]
    engine = [[_kernels.nearest_image(d, 0.0, side)[0], float(_kernels.fold(d, side))] for d in offsets]
    assert laws == engine


def _links_across_the_seam_end_at_the_border(page, side_m):
    """At an instant with a link across the seam, nothing is drawn outside the area but the
    markers of robots near the border: the link's halves stop at the border (they ran on to
    the other robot's image, up to a range past it)."""
    from PIL import Image

    def past_the_border_m(a, b):
        """How far past the border the halves of a link across the seam reach (0: none)."""
        crossed = np.abs(pos[a] - pos[b]) > side_m / 2
        to_border = np.minimum(pos[[a, b]], side_m - pos[[a, b]])  # each end, each axis
        return float(to_border[:, crossed].min()) if crossed.any() else 0.0

    for t in np.linspace(0.0, 60.0, 241):
        page.js(f"netsimView.seek({float(t)!r})")
        pos = np.array(page.js("netsimView.positions()"))
        if max((past_the_border_m(a, b) for a, b in page.js("netsimView.links()")), default=0.0) > 30.0:
            break
    else:
        pytest.fail("no link across the seam reaching 30 m past the border in the run")
    box = page.page.locator("#field").bounding_box()
    img = np.asarray(Image.open(io.BytesIO(page.page.locator("#field").screenshot())).convert("RGB"))
    scale = img.shape[1] / box["width"]  # device pixels per CSS pixel
    (x0, y0), (x1, y1) = page.js("netsimView.toScreen(0, 0)"), page.js(f"netsimView.toScreen({side_m}, {side_m})")
    margin = 12  # CSS pixels: a robot's marker at the border reaches past it
    cols = np.arange(img.shape[1]) / scale
    rows = np.arange(img.shape[0]) / scale
    outside = (
        (cols[None, :] < min(x0, x1) - margin)
        | (cols[None, :] > max(x0, x1) + margin)
        | (rows[:, None] < min(y0, y1) - margin)
        | (rows[:, None] > max(y0, y1) + margin)
    )
    background = img[0, 0]
    assert (img[outside] == background).all(), f"drawn outside the area at t = {t}"


@pytest.mark.slow
def test_older_run_without_legs_uses_the_sampled_positions(moving_run, tmp_path, open_page):
    old = tmp_path / "old"
    shutil.copytree(moving_run, old)
    (old / "legs.parquet").unlink()
    (old / "view.html").unlink()
    assert main(["view", str(old)]) == 0
    page = open_page(old / "view.html")
    pos = pd.read_parquet(old / "positions.parquet")
    page.js("netsimView.seek(12)")
    sample = pos[pos["t_s"] == 12.0].sort_values("robot")[["x_m", "y_m"]].to_numpy()
    # Exact at a sample (they travelled as 32-bit floats: micrometres off in a small
    # area, 0.1 m in a georeferenced one).
    np.testing.assert_allclose(np.array(page.js("netsimView.positions()")), sample, rtol=0, atol=1e-9)


@pytest.mark.slow
def test_walls_of_a_map_are_drawn(moving_run, tmp_path, open_page):
    """The map slot: an occupancy grid's occupied cells are drawn in the wall colour."""
    occupied = np.zeros((60, 60), dtype=bool)
    occupied[:, 30] = True  # a wall down the middle: x in [300, 310) m
    html = viewer.write(moving_run, tmp_path / "map.html", viewer.MapGrid(occupied, 10.0, (0.0, 0.0)))
    page = open_page(html)
    page.page.uncheck("#show-links")
    page.page.uncheck("#show-hops")
    page.js("netsimView.seek(0)")
    from PIL import Image

    img = np.asarray(Image.open(io.BytesIO(page.page.locator("#field").screenshot())).convert("RGB"))
    wall = tuple(int(style.WALL[k : k + 2], 16) for k in (1, 3, 5))
    robots = np.array(page.js("netsimView.positions()"))

    def colours_at(x_m: float) -> list[tuple]:
        # Points along a vertical line, away from every robot (robots are drawn on top).
        ys = [y for y in np.arange(20.0, 600.0, 20.0) if np.hypot(*(robots - [x_m, y]).T).min() > 25]
        assert len(ys) > 5
        out = []
        for y in ys:
            sx, sy = page.js(f"netsimView.toScreen({x_m}, {y})")
            out.append(tuple(img[round(sy), round(sx)].tolist()))
        return out

    assert all(c == wall for c in colours_at(305.0))
    assert not any(c == wall for c in colours_at(200.0))


@pytest.mark.slow
def test_walls_of_a_run_with_a_map_are_drawn(tmp_path, open_page):
    """A run on the office map: the page draws its walls from the run's own world.map, in
    the wall colour where the map is occupied and not where it is free."""
    from netsim.world.maps import cached_map

    run = _run(
        tmp_path / "office",
        "world.n_robots=4",
        "world.side_m=30",
        'world.map="office"',
        "mobility.stationary_start=false",
        "channel.range_m=10",
        "duration_s=20",
    )
    page = open_page(run / "view.html")
    assert page.js("JSON.parse(document.getElementById('netsim-meta').text).map") is not None
    page.page.uncheck("#show-links")
    page.page.uncheck("#show-hops")
    page.js("netsimView.seek(0)")
    from PIL import Image

    img = np.asarray(Image.open(io.BytesIO(page.page.locator("#field").screenshot())).convert("RGB"))
    wall = tuple(int(style.WALL[k : k + 2], 16) for k in (1, 3, 5))
    robots = np.array(page.js("netsimView.positions()"))
    m = cached_map("office")
    # Centres of cells inside a straight run of 3 wall cells, and of 3 x 3 blocks of free
    # cells, inside the area, away from robots (a 30 m area: a cell is several pixels wide).
    occ = m.occupied
    block = occ[1:-1, 1:-1] & ((occ[1:-1, :-2] & occ[1:-1, 2:]) | (occ[:-2, 1:-1] & occ[2:, 1:-1]))
    free = m.free
    fblock = free[:-2, :-2] & free[1:-1, 1:-1] & free[2:, 2:] & free[:-2, 2:] & free[2:, :-2]
    fblock &= free[1:-1, :-2] & free[1:-1, 2:] & free[:-2, 1:-1] & free[2:, 1:-1]

    def points(mask):
        j, i = np.nonzero(mask)
        xy = np.column_stack([(i + 1.5) * m.resolution_m, (j + 1.5) * m.resolution_m])
        keep = (xy > 1).all(axis=1) & (xy < 29).all(axis=1)
        # Away from the page's scale grid lines (drawn over the walls).
        keep &= (np.abs(xy - 5.0 * np.round(xy / 5.0)) > 0.3).all(axis=1)
        xy = xy[keep]
        xy = xy[np.hypot(*(xy[:, None, :] - robots[None]).transpose(2, 0, 1)).min(axis=1) > 2]
        return xy[np.random.default_rng(1).choice(len(xy), 40, replace=False)]

    def colour(x, y):
        sx, sy = page.js(f"netsimView.toScreen({x}, {y})")
        return tuple(img[round(sy), round(sx)].tolist())

    got = [colour(x, y) for x, y in points(block)]
    assert all(c == wall for c in got)
    assert not any(colour(x, y) == wall for x, y in points(fblock))


# -- the command, without a browser ------------------------------------------------------
@pytest.mark.slow
def test_view_writes_one_self_contained_file(moving_run, tmp_path, capsys):
    """`netsim view RUN --out FILE`: one file, no external script, style or image, and the
    same run gives the same bytes."""
    out = tmp_path / "sub" / "replay.html"
    assert main(["view", str(moving_run), "--out", str(out)]) == 0
    assert "wrote" in capsys.readouterr().out
    text = out.read_text()
    assert out.read_bytes() == (moving_run / "view.html").read_bytes()
    low = text.lower()
    for needle in ("<script src", "<link", "http://", "https://", "@import", "url("):
        assert needle not in low, needle
    assert list(tmp_path.rglob("*")) == [tmp_path / "sub", out]  # no temporary left behind


@pytest.mark.parametrize(
    "setup, message",
    [
        (lambda d: None, "no such run directory"),
        (lambda d: d.mkdir(), "not a run directory (no config.toml)"),
    ],
)
def test_view_of_a_bad_directory_is_a_one_line_error(tmp_path, capsys, setup, message):
    run = tmp_path / "run"
    setup(run)
    assert main(["view", str(run), "--out", str(tmp_path / "v.html")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("netsim: error: ") and message in err and err.count("\n") == 1
    assert not (tmp_path / "v.html").exists()


@pytest.mark.slow
def test_view_needs_legs_or_positions(moving_run, tmp_path, capsys):
    run = tmp_path / "bare"
    run.mkdir()
    shutil.copy(moving_run / "config.toml", run)
    assert main(["view", str(run)]) == 2
    assert "no legs.parquet and no sampled positions.parquet" in capsys.readouterr().err
    assert list(run.iterdir()) == [run / "config.toml"]


@pytest.mark.slow
def test_the_form_shows_the_command_for_another_scenario(moving_run, open_page):
    """The paper's workflow from the page: N, speeds, duration, range and seed give the
    `netsim run` command, starting from the run's own configuration."""
    page = open_page(moving_run / "view.html")
    page.page.click("#workflow summary")
    command = page.page.inner_text("#command")
    assert command.startswith("netsim run moving/config.toml")
    assert "--set world.n_robots=40" in command and "--set channel.range_m=130" in command
    page.page.fill("#form input[name=n_robots]", "120")
    page.page.fill("#form input[name=speed_max_mps]", "2.5")
    command = page.page.inner_text("#command")
    assert "--set world.n_robots=120" in command and "--set mobility.speed_max_mps=2.5" in command
    assert "--seed 3" in command and command.rstrip().endswith("--view")


def test_the_form_keeps_a_runs_ranges_one_a_robot(tmp_path, open_page):
    """A run of per-robot ranges: the form leaves the range empty (the command keeps the
    run's list) until a range for all is typed. (It filled in the least range, and the
    command, run as shown, gave every robot 100 m.)"""
    run = _run(tmp_path / "ranges", "world.n_robots=3", "channel.range_m=[100.0, 150.0, 120.0]", "duration_s=5")
    page = open_page(run / "view.html")
    page.page.click("#workflow summary")
    assert "channel.range_m" not in page.page.inner_text("#command")
    page.page.fill("#form input[name=range_m]", "90")
    assert "--set channel.range_m=90" in page.page.inner_text("#command")


@pytest.mark.slow
def test_a_run_without_roles_is_drawn_as_in_the_figures(tmp_path, open_page):
    """The Ack beacon alone: no roles, so plain grey dots in both drawings; the chart
    still has the Ack delivery ratio."""
    from netsim.tools import figures

    run = _run(tmp_path / "ack", "protocol.model=ack", "world.n_robots=12", "duration_s=20")
    snap = figures.snapshot(figures.read_run(run), 10.0)
    assert set(snap.role) == {"none"}
    page = open_page(run / "view.html")
    page.js("netsimView.seek(10)")
    assert page.js("netsimView.shapes()") == ["none"] * 12
    assert page.js("netsimView.colours()") == [style.ROLE_STYLE["none"]["colour"]] * 12
    assert page.js("netsimView.edges()") == [""] * 12
    assert "robot (no roles)" in page.page.locator("#legend").inner_text()
    d = pd.read_parquet(run / "ack_delivery.parquet")
    assert page.js("netsimView.series()")["ack_delivery"] == d.loc[d["t_s"] <= 10, "delivery_ratio"].iloc[-1]


def test_the_delivered_series_counts_a_message_once_it_has_arrived():
    """The strip chart's delivered fraction at t: of the messages sent by t, those arrived
    by t (the side panel's count). Messages sent at 1, 2 and 3 s; the first arrives at
    1.5 s, the second never, the third at 3.4 s. (The chart counted a message from its
    sending on, if it arrived at all: 1 at 1 s, while the panel said none had arrived.)"""
    from netsim.tools.viewer.data import Blob, series
    from tests.fixtures import make_config

    messages = pd.DataFrame(
        {"t_sent_s": [1.0, 2.0, 3.0], "delivered": [True, False, True], "t_delivered_s": [1.5, np.nan, 3.4]}
    )
    links = pd.DataFrame({"a": [], "b": [], "t_up_s": [], "t_down_s": [], "censored_end": []})
    blob = Blob()
    series(make_config(duration_s=5.0, world={"n_robots": 2}), links, pd.DataFrame(), None, messages, None, blob)
    arrays = {}
    data = b"".join(blob.parts)
    for name, (_code, offset, size) in blob.index.items():
        if name.startswith("s_delivered"):
            arrays[name] = np.frombuffer(data, "<f8", size, offset)
    assert arrays["s_delivered_t"].tolist() == [1.0, 1.5, 2.0, 3.0, 3.4]
    assert arrays["s_delivered_v"].tolist() == [0.0, 1.0, 0.5, 1 / 3, 2 / 3]


def test_a_run_named_like_markup_still_loads(moving_run, tmp_path, open_page):
    """The run directory's name goes into the page's data (its title): a name holding
    ``<!--<script>`` must stay text. (Only ``</`` was escaped: the parser took the rest of
    the page as the script, and it stayed on "loading..." with no error.)"""
    odd = tmp_path / "r<!--<script>"
    shutil.copytree(moving_run, odd)
    (odd / "view.html").unlink()
    assert main(["view", str(odd)]) == 0
    text = (odd / "view.html").read_text()
    meta = text[text.index('id="netsim-meta">') + len('id="netsim-meta">') :]
    assert "<" not in meta[: meta.index("</script>")]  # no markup in the data: nothing to parse
    page = open_page(odd / "view.html")
    assert page.js("netsimView.ready") and page.js("netsimView.n") == 40
    assert "r<!--<script>" in page.js("JSON.parse(document.getElementById('netsim-meta').textContent).title")


@pytest.fixture(scope="module")
def routed_run(tmp_path_factory):
    """AODV carrying a flow of three-frame packets and random pairs' messages."""
    out = tmp_path_factory.mktemp("replay") / "aodv"
    return _run(
        out,
        "seed=5",
        "duration_s=40",
        "world.n_robots=30",
        "world.side_m=500",
        "channel.range_m=130",
        "protocol.model=aodv",
        "protocol.message_rate_hz=1.0",
        "traffic.flows=[{src=0, dst=7, start_s=5, stop_s=35, rate_bps=16000, packet_bytes=4000}]",
    )


def test_a_routing_runs_replay_draws_its_packets_as_they_hop(routed_run):
    """A routing protocol writes no messages table: the replay's messages are its packets
    (packets.parquet, in order of sending) and each hop of hops.parquet is drawn under the
    packet it carries a frame of, each robot's first reception of the packet once."""
    from netsim.tools.viewer.data import pack

    packets = pd.read_parquet(routed_run / "packets.parquet").sort_values("t_sent_s", kind="stable")
    hops = pd.read_parquet(routed_run / "hops.parquet")
    meta, arrays = _packed(pack(routed_run))
    assert meta["has"]["messages"] and meta["has"]["hops"] and meta["message_noun"] == "packet"
    assert arrays["msg_src"].tolist() == packets["src"].tolist()
    assert arrays["msg_dst"].tolist() == packets["dst"].tolist()
    assert arrays["msg_delivered"].astype(bool).tolist() == packets["delivered"].tolist()
    # Each packet's first reception by each robot, by the packet's place in sending order.
    place = {key: k for k, key in enumerate(zip(packets["flow"], packets["packet"]))}
    first = hops.sort_values("t_received_s", kind="stable").drop_duplicates(["flow", "packet", "receiver"])
    drawn = sorted(zip(arrays["hop_msg"].tolist(), arrays["hop_receiver"].tolist()))
    expected = sorted((place[(f, p)], r) for f, p, r in zip(first["flow"], first["packet"], first["receiver"]))
    assert drawn == expected and len(drawn) < len(hops)
    assert {(m, r) for m, r in drawn if r == packets["dst"].iloc[m]} == {
        (m, d) for m, d in enumerate(packets["dst"]) if packets["delivered"].iloc[m]
    }


def _packed(packed: dict) -> tuple[dict, dict[str, np.ndarray]]:
    """The page's metadata and its arrays, decoded as the page decodes them."""
    import base64
    import gzip

    from netsim.tools.viewer.data import Blob

    dtypes = {code: dtype for dtype, code in Blob.CODES.items()}
    meta = packed["meta"]
    data = gzip.decompress(base64.b64decode(packed["blob"]))
    arrays = {}
    for name, (code, offset, size) in meta["arrays"].items():
        arrays[name] = np.frombuffer(data, dtypes[code], size, offset)
    return meta, arrays


@pytest.mark.slow
def test_a_routing_runs_packets_are_counted_and_drawn_on_the_page(routed_run, open_page):
    """The page counts packets, not messages, names them in its legend, and draws the
    hops of those sent within the trail."""
    page = open_page(routed_run / "view.html")
    packets = pd.read_parquet(routed_run / "packets.parquet")
    page.js("netsimView.seek(20)")
    text = page.page.locator("#now").inner_text()
    sent = int((packets["t_sent_s"] <= 20).sum())
    arrived = int((packets["delivered"] & (packets["t_delivered_s"] <= 20)).sum())
    assert f"packets sent {sent}, arrived {arrived}" in text and arrived > 0
    assert "routed packet" in page.page.locator("#legend").inner_text()
    assert page.page.locator("#hops-label").inner_text() == "routed packets"
    assert page.page.locator("#trail-label").inner_text() == "packet trail"
    assert page.js("netsimView.hopsDrawn") > 0


def test_a_routing_run_without_hops_still_shows_its_packets_and_one_without_packets_none(routed_run, tmp_path):
    """A routing run written before routing runs wrote hops.parquet still has its packets
    as the replay's messages, without hops; without packets.parquet either, it has
    neither, and its page speaks of messages, not of packets it does not have."""
    from netsim.tools.viewer.data import pack

    old = tmp_path / "old"
    shutil.copytree(routed_run, old)
    (old / "hops.parquet").unlink()
    meta, arrays = _packed(pack(old))
    assert meta["has"]["messages"] and not meta["has"]["hops"] and meta["message_noun"] == "packet"
    assert len(arrays["msg_src"]) == len(pd.read_parquet(old / "packets.parquet"))
    (old / "packets.parquet").unlink()
    meta, _ = _packed(pack(old))
    assert not meta["has"]["messages"] and meta["message_noun"] == "message"
