"""Benchmark: the replay page (``netsim view``) at scale: file size, time to write it, and
frame rate while playing, in the system's headless Chromium.

Workload: random waypoint (0.5-5 m/s, pause 2 s), range 100 m, the square's side chosen
for a mean degree of about 10, the clustering protocol, a message every 5 s. The page plays
at 1x for a few seconds of wall time with links and messages shown; the browser's own
``requestAnimationFrame`` timestamps give the frame intervals, and the page times its own
drawing (``netsimView.stats()``). Headless Chromium without a GPU draws the canvas in
software, so this is a floor for what a laptop's browser does.

    python benchmarks/replay.py                      # N = 1,000, 120 s
    python benchmarks/replay.py --n 200 --duration 600 --no-browser   # file size only
"""

from __future__ import annotations

import math
import os
import re
import statistics
import sys
import tempfile
import time
from pathlib import Path

from netsim.tools.args import Parser

CHROMIUM = "/usr/bin/chromium"
ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]


def simulate(n: int, duration: float, out: Path) -> float:
    from netsim.tools.cli import main

    side = 100.0 * math.sqrt(n * math.pi / 10.0)
    start = time.perf_counter()
    sets = [f"world.n_robots={n}", f"world.side_m={side:.1f}", "channel.range_m=100", f"duration_s={duration}"]
    argv = ["run", "--out", str(out), "--quiet", "--no-progress"]
    for s in sets:
        argv += ["--set", s]
    assert main(argv) == 0
    return time.perf_counter() - start


def _descendants_cpu_s() -> float:
    """CPU time (user + system) of every process descending from this one: the
    playwright driver and the browser's processes."""
    parent: dict[int, int] = {}
    cpu: dict[int, float] = {}
    tick = os.sysconf("SC_CLK_TCK")
    for d in Path("/proc").iterdir():
        if not d.name.isdigit():
            continue
        try:
            fields = (d / "stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        parent[int(d.name)] = int(fields[1])
        cpu[int(d.name)] = (int(fields[11]) + int(fields[12])) / tick
    me, total = os.getpid(), 0.0
    for pid in cpu:
        p = pid
        while p in parent and p != me:
            p = parent[p]
        if p == me and pid != me:
            total += cpu[pid]
    return total


def play(html: Path, seconds: float, width: int, height: int, hide=()) -> dict:
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=ARGS)
        page = browser.new_page(viewport={"width": width, "height": height})
        url = html.resolve().as_uri()
        page.route("**/*", lambda r: r.continue_() if r.request.url == url else r.abort())
        start = time.perf_counter()
        page.goto(url)
        page.evaluate(
            "new Promise(done => { const c = () => window.netsimView && netsimView.ready ? done()"
            " : requestAnimationFrame(c); c(); })"
        )
        load_s = time.perf_counter() - start
        for what in hide:
            page.uncheck(f"#show-{what}")
        page.evaluate("netsimView.seek(5); netsimView.setSpeed(1)")
        frames0, cpu0 = page.evaluate("netsimView.frames"), _descendants_cpu_s()
        page.evaluate("netsimView.play()")
        page.wait_for_timeout(seconds * 1000)
        stats = page.evaluate("netsimView.stats()")
        frames, cpu = page.evaluate("netsimView.frames") - frames0, _descendants_cpu_s() - cpu0
        links, n = page.evaluate("[netsimView.linksDrawn, netsimView.n]")
        browser.close()
    intervals = stats["intervals"][5:]
    draw = stats["drawMs"][5:]
    cpu_ms = 1000 * cpu / max(frames, 1)
    return {"load_s": load_s, "intervals": intervals, "draw": draw, "links": links, "n": n, "cpu_ms": cpu_ms}


def main() -> int:
    p = Parser(description=__doc__.splitlines()[0])
    p.add_argument("--n", type=int, default=1000, help="robots")
    p.add_argument("--duration", type=float, default=120.0, help="simulated seconds")
    p.add_argument("--seconds", type=float, default=6.0, help="wall seconds of playing")
    p.add_argument("--size", default="1280x800", help="viewport, WIDTHxHEIGHT")
    p.add_argument("--no-browser", action="store_true", help="file size and writing time only")
    p.add_argument("--run", help="replay this run directory instead of simulating one")
    p.add_argument("--hide", nargs="*", default=[], choices=["links", "hops"], help="layers to switch off")
    args = p.parse_args()
    if not re.fullmatch(r"[1-9][0-9]*x[1-9][0-9]*", args.size):
        p.error(f"--size {args.size!r}: WIDTHxHEIGHT in pixels, such as 1280x800")
    if not args.no_browser and not Path(CHROMIUM).is_file():
        p.error(f"no {CHROMIUM} to play the replay in (apt-get install chromium), or --no-browser")

    from netsim.tools import viewer

    with tempfile.TemporaryDirectory() as tmp:
        if args.run:
            run = Path(args.run)
            print(f"run: {run}")
        else:
            run = Path(tmp) / "run"
            sim_s = simulate(args.n, args.duration, run)
            print(f"N = {args.n}, {args.duration:g} s simulated in {sim_s:.1f} s")
        start = time.perf_counter()
        html = viewer.write(run, Path(tmp) / "view.html")
        write_s = time.perf_counter() - start
        size = html.stat().st_size
        print(f"view.html: {size / 2**20:.2f} MiB, written in {write_s:.1f} s")
        if args.no_browser:
            return 0
        w, h = (int(v) for v in args.size.split("x"))
        r = play(html, args.seconds, w, h, args.hide)
    iv, dr = sorted(r["intervals"]), sorted(r["draw"])
    if not iv:
        print("no frames recorded", file=sys.stderr)
        return 1
    q = lambda xs, f: xs[min(len(xs) - 1, int(f * len(xs)))]
    print(f"page ready in {r['load_s']:.2f} s; {r['links']} links drawn at the end")
    print(
        f"frames: {len(iv)} in {sum(iv) / 1000:.1f} s -> {1000 * len(iv) / sum(iv):.1f} fps "
        f"(interval median {statistics.median(iv):.1f} ms, 95th percentile {q(iv, 0.95):.1f} ms)"
    )
    print(f"page's drawing per frame: median {statistics.median(dr):.1f} ms, 95th percentile {q(dr, 0.95):.1f} ms")
    print(f"browser CPU per frame, all processes (raster and compositing included): {r['cpu_ms']:.1f} ms")
    print(f"load average during the run: {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    return 0


if __name__ == "__main__":
    sys.exit(main())
