"""The replay of a run in a browser (``netsim view``): one self-contained HTML file.

The page (``assets/``: markup, style and script, all inlined) draws the robots on a
canvas at their exact positions at the cursor, with roles, groups, links, relayed
messages, coverage disks and a strip chart, from the arrays :func:`data.pack` makes of
the run directory. It loads nothing from anywhere: it opens from disk, can be mailed,
and the same run gives the same file byte for byte.
"""

from __future__ import annotations

import html
import json
import re
from importlib import resources
from pathlib import Path

from netsim.tools.output import write_atomically
from netsim.tools.viewer.data import MapGrid, pack

__all__ = ["MapGrid", "page", "write"]


def _asset(name: str) -> str:
    return resources.files("netsim.tools.viewer").joinpath("assets", name).read_text(encoding="utf-8")


def _script_safe(text: str) -> str:
    # Inside <script>, "</" could end the element early.
    return text.replace("</", "<\\/")


def _json_in_script(value: object) -> str:
    """``value`` as JSON that no text in it (a run directory's name in the title) can turn
    into markup inside ``<script>``: every ``<`` written as ``\\u003c``, which JSON reads
    back as ``<``. Escaping ``</`` is not enough: ``<!--<script`` sends the parser into the
    script's escaped states, where the page's own ``</script>`` no longer ends it."""
    return json.dumps(value, separators=(",", ":"), allow_nan=False).replace("<", "\\u003c")


def page(run_dir: str | Path, map_grid: MapGrid | None = None) -> str:
    """The replay page of the run in ``run_dir``, as one string of HTML."""
    data = pack(run_dir, map_grid)
    meta = data["meta"]
    parts = {
        "__TITLE__": html.escape(f"netsim replay: {meta['title']}"),
        "/*__STYLE__*/": _asset("replay.css"),
        "__META__": _json_in_script(meta),
        "__BLOB__": data["blob"],
        "/*__SCRIPT__*/": _script_safe(_asset("replay.js")),
    }
    # One pass, so that no inserted text is itself searched for placeholders.
    pattern = re.compile("|".join(re.escape(k) for k in parts))
    return pattern.sub(lambda m: parts[m.group(0)], _asset("page.html"))


def write(run_dir: str | Path, out: str | Path | None = None, map_grid: MapGrid | None = None) -> Path:
    """Write the replay of ``run_dir`` to ``out`` (default ``run_dir/view.html``)."""
    target = Path(out) if out is not None else Path(run_dir) / "view.html"
    text = page(run_dir, map_grid)
    write_atomically(target, lambda p: p.write_text(text, encoding="utf-8"))
    return target
