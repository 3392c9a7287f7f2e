"""Before and after: this working tree against an earlier commit, whole ``netsim run``
processes, alternated on the same machine.

The earlier commit is checked out in a temporary git worktree. Both sides run with this
environment's Python and libraries, each from its own tree: a small start-up script puts
the tree first on the path and maps the packages its own ``pyproject.toml`` places under
``netsim`` (``netsim.mobility`` from ``mobility/`` and so on), so that no module of one
side is taken from the other (an editable install maps those packages to this tree, and a
plain ``PYTHONPATH`` would leave them there). Plugins are found by the entry points this
environment installed, so a base whose ``pyproject.toml`` declares other entry points
needs an environment of its own: ``--base-python`` names a Python in which the base commit
is installed (from a clean checkout of it), and the base then runs from there. Each side
keeps its own compiled-loop cache.

Cases (``--cases``; the workload of ``compare.py``: random waypoint, mean degree 10, an Ack
a second, 100 simulated seconds):

- ``small``: the default scenario with 10 robots;
- ``ack-1k``, ``clustering-1k``, ``ack-10k``, ``clustering-10k``: the workload at N = 1,000
  and 10,000 with ``protocol.model = "ack"`` and ``"clustering"``;
- ``cold``: ``clustering-1k`` with an empty compiled-loop cache, as a machine's first run;
- ``aodv-300``: the workload at N = 300 under AODV, carrying 50 random pairs' messages a
  second.

One unmeasured run of each case warms each side's caches; then every round runs each case
on both sides, the side that goes first alternating between rounds. The table gives the
median wall and CPU seconds of each side and the ratios after/before (below 1: faster).
CPU time is the steadier figure on a shared machine. The last column pairs each round's two
CPU times: the median of the per-round ratios, and the interval between order statistics
that holds that median with at least 95 % confidence, whatever the noise's law as long as
the rounds are independent and alike (from 6 rounds on: with fewer, not even the smallest
and largest ratios hold it at 95 %). An interval containing 1 is a change within the noise
this machine showed.

    python benchmarks/ab.py --base HEAD~1                      # small, ack-1k, clustering-1k
    python benchmarks/ab.py --base d200a91 --base-python ../d200/.venv/bin/python --rounds 10 \
        --cases small ack-1k clustering-1k ack-10k clustering-10k cold
"""

from __future__ import annotations

import math
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
import tomllib
from pathlib import Path

from compare import measured, netsim_settings
from scipy.stats import quantile_test

from netsim.tools.args import Parser

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent

# Runs `netsim` from the tree given as the first argument, whatever is installed.
START = """
import importlib.util, os, sys, tomllib
root = sys.argv.pop(1)
sys.path.insert(0, root)
with open(root + "/pyproject.toml", "rb") as f:
    project = tomllib.load(f)
dirs = project.get("tool", {}).get("setuptools", {}).get("package-dir", {})
import netsim
for name, folder in dirs.items():
    where = root + "/" + folder
    if not os.path.isdir(where):
        continue
    spec = importlib.util.spec_from_file_location(name, where + "/__init__.py", submodule_search_locations=[where])
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    setattr(netsim, name.rpartition(".")[2], module)
    spec.loader.exec_module(module)
where, _, name = project["project"]["scripts"]["netsim"].partition(":")
sys.argv[0] = "netsim"
sys.exit(getattr(importlib.import_module(where), name)())
"""

CASES = {
    "small": ["world.n_robots=10"],
    **{
        f"{protocol}-{n // 1000}k": [f"{k}={v}" for k, v in netsim_settings(n, protocol).items()]
        for protocol in ("ack", "clustering")
        for n in (1000, 10000)
    },
}
CASES["cold"] = CASES["clustering-1k"]
# Routed traffic: AODV carrying random pairs' messages across a moving team of 300.
CASES["aodv-300"] = [f"{k}={v}" for k, v in netsim_settings(300, "aodv").items() if k != "protocol.ack_period_s"] + [
    "protocol.message_rate_hz=50"
]


def git(*args: str) -> str:
    return subprocess.run(["git", "-C", str(ROOT), *args], capture_output=True, text=True, check=True).stdout.strip()


def entry_points(tree: Path) -> dict:
    """The plugins' entry points ``tree``'s ``pyproject.toml`` declares."""
    with open(tree / "pyproject.toml", "rb") as f:
        return tomllib.load(f).get("project", {}).get("entry-points", {})


def installed_tree(python: str) -> Path:
    """The tree whose ``netsim`` ``python`` imports."""
    code = "import netsim, os; print(os.path.dirname(os.path.dirname(os.path.realpath(netsim.__file__))))"
    done = subprocess.run([python, "-c", code], capture_output=True, text=True, check=True, cwd="/")
    tree = done.stdout.strip()
    if not tree or not (Path(tree) / "pyproject.toml").is_file() or not (Path(tree) / "netsim").is_dir():
        raise OSError(tree)
    return Path(tree)


def one(python: str, tree: Path, case: str, cache: Path, out: Path) -> tuple[float, float]:
    """Wall and CPU seconds of one ``netsim run`` of ``case`` from ``tree``."""
    if case == "cold":
        shutil.rmtree(cache, ignore_errors=True)
    shutil.rmtree(out, ignore_errors=True)
    cmd = ["env", f"NUMBA_CACHE_DIR={cache}", python, "-c", START, str(tree), "run"]
    cmd += ["--quiet", "--no-progress", "--out", str(out)]
    for item in CASES[case]:
        cmd += ["--set", item]
    wall, _, _, cpu = measured(cmd)
    if not (out / "manifest.json").is_file():
        raise SystemExit(f"ab.py: {python} ran no netsim run from {tree} (no manifest.json written)")
    return wall, cpu


def median_interval(values: list[float], confidence: float = 0.95) -> tuple[float, float] | None:
    """The distribution-free interval of order statistics around the median of ``values``
    (covers it with at least ``confidence``), or ``None`` when there are too few values."""
    interval = quantile_test(values, q=statistics.median(values), p=0.5).confidence_interval(confidence)
    return (
        None if math.isnan(interval.low) or math.isnan(interval.high) else (float(interval.low), float(interval.high))
    )


def main(argv=None) -> int:
    try:
        return measure(argv)
    except KeyboardInterrupt:
        print("ab.py: interrupted; nothing measured is printed", file=sys.stderr)
        return 130


def measure(argv=None) -> int:
    ap = Parser(description=__doc__.splitlines()[0])
    ap.add_argument("--base", required=True, help="the commit to measure this working tree against")
    ap.add_argument("--base-python", help="a Python in which the base commit is installed (other entry points)")
    ap.add_argument("--rounds", type=int, default=7, help="measured rounds, alternated (default 7)")
    ap.add_argument("--cases", nargs="+", default=["small", "ack-1k", "clustering-1k"], choices=list(CASES))
    args = ap.parse_args(argv)
    if args.rounds < 1:
        print(f"ab.py: --rounds must be at least 1, not {args.rounds}", file=sys.stderr)
        return 2
    try:
        base = git("rev-parse", "--verify", "--quiet", f"{args.base}^{{commit}}")
    except subprocess.CalledProcessError:
        print(f"ab.py: --base {args.base}: not a commit of {ROOT}", file=sys.stderr)
        return 2
    if args.base_python:
        args.base_python = os.path.abspath(args.base_python)
    pythons = {"before": args.base_python or sys.executable, "after": sys.executable}
    if args.base_python:
        try:
            installed = installed_tree(args.base_python)
            at = subprocess.run(["git", "-C", str(installed), "rev-parse", "HEAD"], capture_output=True, text=True)
        except (OSError, subprocess.CalledProcessError):
            print(f"ab.py: --base-python {args.base_python}: not a Python that imports netsim", file=sys.stderr)
            return 2
        if at.stdout.strip() != base:
            print(f"ab.py: --base-python imports netsim from {installed}, not at {args.base}", file=sys.stderr)
            return 2
    elif tomllib.loads(git("show", f"{base}:pyproject.toml")).get("project", {}).get("entry-points", {}) != (
        entry_points(ROOT)
    ):
        print(
            f"ab.py: {args.base} declares other plugins' entry points than this tree:"
            " install it in an environment of its own and pass --base-python",
            file=sys.stderr,
        )
        return 2
    with tempfile.TemporaryDirectory(prefix="netsim-ab-") as tmp:
        work = Path(tmp)
        base_tree = installed if args.base_python else work / "base"
        try:
            if not args.base_python:
                git("worktree", "add", "--detach", str(base_tree), base)
            trees = {"before": base_tree, "after": ROOT}
            times: dict[tuple[str, str], list[tuple[float, float]]] = {}
            for side, tree in trees.items():
                for case in dict.fromkeys(c if c != "cold" else "clustering-1k" for c in args.cases):
                    print(f"warming {side}: {case}", file=sys.stderr, flush=True)
                    one(pythons[side], tree, case, work / f"cache-{side}", work / "out")
            for r in range(args.rounds):
                print(f"round {r + 1}/{args.rounds}", file=sys.stderr, flush=True)
                order = list(trees) if r % 2 == 0 else list(trees)[::-1]
                for side in order:
                    for case in args.cases:
                        cache = work / (f"cold-{side}" if case == "cold" else f"cache-{side}")
                        took = one(pythons[side], trees[side], case, cache, work / "out")
                        print(f"  {side} {case}: {took[0]:.3f} s, {took[1]:.3f} s CPU", file=sys.stderr, flush=True)
                        times.setdefault((side, case), []).append(took)
        finally:
            if not args.base_python:
                subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(base_tree)], check=False)
                subprocess.run(["git", "-C", str(ROOT), "worktree", "prune"], check=False)
    head = git("rev-parse", "--short", "HEAD") + (" with uncommitted changes" if git("status", "--porcelain") else "")
    print(f"before: {base[:9]} ({args.base}); after: the working tree of {ROOT} at {head}")
    print(f"{os.cpu_count()} cores, {platform.machine()}, Python {platform.python_version()}; {args.rounds} rounds")
    print(f"command: python benchmarks/ab.py {' '.join(argv if argv is not None else sys.argv[1:])}")
    print()
    print(
        "| case | before wall s | after wall s | after/before | before CPU s | after CPU s | after/before"
        " | median of per-round CPU after/before [95 % interval] |"
    )
    print("| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    for case in args.cases:
        b, a = times[("before", case)], times[("after", case)]
        bw, aw = statistics.median(t[0] for t in b), statistics.median(t[0] for t in a)
        bc, ac = statistics.median(t[1] for t in b), statistics.median(t[1] for t in a)
        paired = [after[1] / before[1] for before, after in zip(b, a)]
        interval = median_interval(paired)
        spread = f"[{interval[0]:.3f}, {interval[1]:.3f}]" if interval else "[no interval: --rounds 6 or more]"
        ratios = f"{statistics.median(paired):.3f} {spread}"
        print(f"| {case} | {bw:.3f} | {aw:.3f} | {aw / bw:.3f} | {bc:.3f} | {ac:.3f} | {ac / bc:.3f} | {ratios} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
