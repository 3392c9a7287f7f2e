"""The output directory of a run, written so that nothing is ever half-written.

Every file is first written into a private temporary directory inside the output
directory and then moved into place with an atomic rename; if anything fails on the way
the temporary directory is removed and the files already there are left as they were.
"""

from __future__ import annotations

import json
import os
import platform
import shutil
import sys
import tempfile
from importlib import metadata
from pathlib import Path

import pandas as pd
import tomli_w

from netsim.config import Config, to_dict

TABLES = ("positions", "links", "acks", "roles")


def versions() -> dict[str, str]:
    out = {"python": platform.python_version()}
    for dist in ("netsim-robots", "simpy", "numpy", "scipy", "networkx", "pandas", "pyarrow"):
        try:
            out[dist] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            out[dist] = "not installed"
    return out


def _plain(value):
    """JSON has no NaN or infinity: write them as null."""
    if isinstance(value, float) and (value != value or value in (float("inf"), float("-inf"))):
        return None
    return value


def write_run(
    out_dir: str | Path, config: Config, frames: dict[str, pd.DataFrame], summary: dict, manifest: dict
) -> list[Path]:
    """Write ``config.toml``, ``manifest.json``, ``summary.json`` and one Parquet file per table."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=".netsim-tmp-", dir=out))
    written = []
    try:
        (tmp / "config.toml").write_text(tomli_w.dumps(to_dict(config)))
        (tmp / "manifest.json").write_text(json.dumps({k: _plain(v) for k, v in manifest.items()}, indent=2) + "\n")
        (tmp / "summary.json").write_text(json.dumps({k: _plain(v) for k, v in summary.items()}, indent=2) + "\n")
        for name, frame in frames.items():
            frame.to_parquet(tmp / f"{name}.parquet", index=False)
        for f in sorted(tmp.iterdir()):
            os.replace(f, out / f.name)
            written.append(out / f.name)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return written


def manifest(config: Config, run: int, wall_s: float, argv=None) -> dict:
    return {
        "seed": config.seed,
        "run": run,
        "wall_s": round(wall_s, 3),
        "command": " ".join(argv if argv is not None else sys.argv),
        "platform": platform.platform(),
        "versions": versions(),
    }
