"""Make docs/images/live-view.png: a screenshot of `netsim run --live` in a Foxglove-protocol app.

It starts `netsim run --live PORT` on a scenario, opens the app in the system's headless
Chromium (through playwright) connected to `ws://127.0.0.1:PORT` with a layout of a 3D panel
(`/netsim/scene`) beside a Raw Messages panel (`/netsim/roles`), waits, takes the screenshot
and stops the run (Ctrl-C: a live `netsim run` writes nothing then).

The app is not part of netsim: give the URL of a served web build of the Foxglove app or of
Lichtblick (its open-source fork, same WebSocket protocol; the picture in docs/ros2.md is
Lichtblick 1.28.1), e.g. Lichtblick's `yarn web:build:prod` output served with
`python -m http.server 8080 -d web/.webpack`:

    pip install -e ".[ros,test]"      # foxglove-sdk, playwright; Pillow comes with matplotlib
    python docs/images/make_live_view.py --app-url http://127.0.0.1:8080/

The app reads the connection and the layout from its URL (`ds=foxglove-websocket`,
`ds.url=...`, `layoutUrl=...`); the layout is served by this script on a free port.
Not run by the test suite.
"""

from __future__ import annotations

import argparse
import http.server
import json
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
import urllib.parse
from pathlib import Path

HERE = Path(__file__).resolve().parent
# The 3D panel needs WebGL: without a GPU, Chromium renders it in software (SwiftShader).
CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader"]

# The scenario shown: a team of a few dozen robots under the clustering protocol, so that
# roles (colours) and links change while the picture is taken.
SCENARIO = [
    "duration_s=3600",
    "world.n_robots=40",
    "world.side_m=500",
    "channel.range_m=90",
    "mobility.speed_min_mps=2",
    "mobility.speed_max_mps=8",
]


def layout(side_m: float) -> dict:
    """A 3D panel looking straight down on the area, and the role changes as raw messages."""
    half = side_m / 2
    three_d = {
        "cameraState": {
            "perspective": False,
            "distance": side_m * 1.1,
            "phi": 0.0001,
            "thetaOffset": 0,
            "target": [0, 0, 0],
            "targetOffset": [half, half, 0],
            "targetOrientation": [0, 0, 0, 1],
            "fovy": 45,
            "near": 0.5,
            "far": 50000,
        },
        "followMode": "follow-none",
        "followTf": "world",
        "scene": {"enableStats": False, "backgroundColor": "#ffffff"},
        "transforms": {},
        "topics": {"/netsim/scene": {"visible": True}},
        "layers": {
            "grid": {
                "layerId": "foxglove.Grid",
                "visible": True,
                "frameId": "world",
                "size": side_m,
                "divisions": 10,
                "lineWidth": 1,
                "color": "#c0c0c0",
                "position": [half, half, 0],
                "rotation": [0, 0, 0],
                "order": 1,
            }
        },
        "publish": {"type": "point"},
        "imageMode": {},
    }
    raw = {"topicPath": "/netsim/roles", "diffEnabled": False, "expansion": "all", "showFullMessageForDiff": False}
    return {
        "configById": {"3D!netsim": three_d, "RawMessages!netsim": raw},
        "globalVariables": {},
        "userNodes": {},
        "playbackConfig": {"speed": 1},
        "layout": {"first": "3D!netsim", "second": "RawMessages!netsim", "direction": "row", "splitPercentage": 68},
    }


def serve(path: Path) -> tuple[http.server.ThreadingHTTPServer, int]:
    """Serve one file, readable from the app's origin (CORS)."""
    body = path.read_bytes()

    class Handler(http.server.BaseHTTPRequestHandler):
        def do_GET(self) -> None:
            self.send_response(200)
            self.send_header("Content-Type", "application/json")
            self.send_header("Access-Control-Allow-Origin", "*")
            self.send_header("Content-Length", str(len(body)))
            self.end_headers()
            self.wfile.write(body)

        def log_message(self, *args: object) -> None:
            pass

    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Handler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    return server, server.server_address[1]


def start_live(port: int, out: Path) -> subprocess.Popen:
    netsim = shutil.which("netsim", path=str(Path(sys.executable).parent)) or "netsim"
    cmd = [netsim, "run", "--live", str(port), "--out", str(out), "--quiet"]
    for s in SCENARIO:
        cmd += ["--set", s]
    proc = subprocess.Popen(cmd, stderr=subprocess.PIPE, text=True)
    assert proc.stderr is not None
    seen = []
    for line in proc.stderr:  # the server's address comes once it listens
        seen.append(line)
        if line.startswith("live view:"):
            print(line.strip(), file=sys.stderr)
            threading.Thread(target=shutil.copyfileobj, args=(proc.stderr, sys.stderr), daemon=True).start()
            return proc
    proc.wait()
    sys.exit("netsim run --live did not start:\n" + "".join(seen))


def shoot(app_url: str, ws_url: str, layout_url: str, png: Path, wait_s: float, size: tuple[int, int]) -> None:
    from playwright.sync_api import sync_playwright

    query = urllib.parse.urlencode({"ds": "foxglove-websocket", "ds.url": ws_url, "layoutUrl": layout_url})
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path="/usr/bin/chromium", args=CHROMIUM_ARGS)
        page = browser.new_page(viewport={"width": size[0], "height": size[1]})
        page.on("console", lambda m: print(f"app: {m.text}", file=sys.stderr) if m.type == "error" else None)
        page.goto(f"{app_url}?{query}")
        # Lichtblick opens with its left sidebar: close it to give the panels the room.
        close = page.locator("[data-testid=sidebar-close-left]")
        try:
            close.click(timeout=20_000)
        except Exception:
            print("no left sidebar to close", file=sys.stderr)
        time.sleep(wait_s)
        page.screenshot(path=str(png))
        browser.close()


def shrink(png: Path, max_bytes: int) -> None:
    """Quantize to a palette (the app's flat colours survive it) to keep the file small."""
    from PIL import Image

    img = Image.open(png).convert("RGB")
    img.quantize(colors=256, method=Image.Quantize.MEDIANCUT).save(png, optimize=True)
    while png.stat().st_size > max_bytes:
        img = img.resize((img.width * 9 // 10, img.height * 9 // 10), Image.Resampling.LANCZOS)
        img.quantize(colors=256, method=Image.Quantize.MEDIANCUT).save(png, optimize=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--app-url", required=True, help="URL of the served app (Foxglove or Lichtblick web build)")
    ap.add_argument("--port", type=int, default=8765, help="port of the live view (default 8765)")
    ap.add_argument("--wait", type=float, default=40.0, help="wall seconds between opening the app and the shot")
    ap.add_argument("--out", type=Path, default=HERE / "live-view.png")
    ap.add_argument("--size", default="1400x800", help="browser window, WIDTHxHEIGHT pixels")
    ap.add_argument("--max-kb", type=int, default=300, help="largest file size, KB")
    args = ap.parse_args()
    size = tuple(int(v) for v in args.size.split("x"))
    side_m = float(next(s for s in SCENARIO if s.startswith("world.side_m=")).split("=")[1])
    with tempfile.TemporaryDirectory() as tmp:
        layout_file = Path(tmp) / "netsim-live.json"
        layout_file.write_text(json.dumps(layout(side_m)))
        server, http_port = serve(layout_file)
        proc = start_live(args.port, Path(tmp) / "run")
        try:
            shoot(
                args.app_url,
                f"ws://127.0.0.1:{args.port}",
                f"http://127.0.0.1:{http_port}/netsim-live.json",
                args.out,
                args.wait,
                (size[0], size[1]),
            )
        finally:
            proc.send_signal(signal.SIGINT)
            proc.wait(timeout=30)
            server.shutdown()
    shrink(args.out, args.max_kb * 1000)
    print(f"wrote {args.out} ({args.out.stat().st_size // 1000} KB)", file=sys.stderr)


if __name__ == "__main__":
    main()
