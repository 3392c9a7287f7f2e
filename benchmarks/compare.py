"""Benchmark: netsim beside the references a user would otherwise pick, in one invocation.

The periodic-beacon workload: N robots, random waypoint with speeds U[1, 5] m/s and a 2 s
pause, starting uniformly at rest, unit disk of range 100 m on a square whose side gives a
mean degree of 10, one beacon (Ack) per robot per second, 100 simulated seconds. Cases:

- ``netsim ack``: the whole ``netsim run`` process (import, build, run, writing the tables)
  with ``protocol.model = "ack"``;
- ``netsim clustering``: the same with the full clustering protocol (Acks, roles, relaying);
- ``simpy reference``: ``simpy_reference_beacon.py``, the workload written in plain SimPy as
  a user writes it (a process per robot for motion and for beacons, an O(N) scan per send,
  one event per reception); its whole process, and its run alone;
- ``simpy reference, numpy scan``: the same program finding a sender's receivers with one
  numpy test over an array of the robots' legs (``--scan numpy``): the same receptions;
- ``ns-3 direct``: ``ns3_beacon.py --mode direct`` (ns-3 3.44 through its Python wheel, a C++
  O(N) scan and one event per reception), only with ``--ns3-python`` (a Python that has
  ns-3: ``bash benchmarks/ns3_env.sh .ns3venv``); its ``Simulator::Run`` alone, and its whole
  process (importing ns-3 and compiling the workload's C++ takes about 7-13 s, which a
  compiled ns-3 program does not pay: the run alone is the figure to compare);
- ``ns-3 grid``: ``--mode grid``, the same C++ with the robots filed in a grid of cells
  once per simulated second, so that a send looks at the 3 x 3 cells around it: the same
  receptions, the strongest reference.

One unmeasured run comes first, as a user's first, which writes the bytecode and compiled
loops' caches that later runs find (the measured processes run without
PYTHONDONTWRITEBYTECODE, as on a user's machine).

Every case runs in its own process; peak memory is that process's maximum RSS, CPU time
its user + system time (the machine may be shared: CPU time is the steadier figure). The
table gives wall and CPU seconds, receptions per wall second, peak memory, each case's wall
time over netsim ack's, and netsim ack's receptions per wall second over the case's (above
1: netsim's whole process receives more per second). The plain-SimPy reference scans every
robot on every send (O(N^2) in Python): it runs up to ``--simpy-max-n``, its numpy scan up to
``--simpy-numpy-max-n``; ns-3 grid up to ``--ns3-max-n``, ns-3 direct (O(N^2) in C++) up to
``--ns3-direct-max-n``; the clustering up to ``--clustering-max-n``.

Then a small run (``netsim run`` with 10 robots for 30 simulated seconds, three times) and
the sweep throughput: ``--sweep-runs`` runs of the default scenario (the clustering
protocol) with 50 robots for 300 simulated seconds, through ``netsim sweep`` on 2 workers,
as runs per minute (0 leaves it out). ``--repeat K`` runs each N's cases K times in turn
(alternated) and gives the median of each figure.

    python benchmarks/compare.py                          # N = 100 and 1,000
    python benchmarks/compare.py --n 100 1000 10000 100000 --ns3-python .ns3venv/bin/python
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import tempfile
from pathlib import Path

from netsim.tools.args import Parser

HERE = Path(__file__).resolve().parent
RANGE_M, DEGREE, DURATION_S, PERIOD_S = 100.0, 10.0, 100.0, 1.0
SPEED_MIN, SPEED_MAX, PAUSE_S = 1.0, 5.0, 2.0


def side_for(n: int) -> float:
    return RANGE_M * math.sqrt(n * math.pi / DEGREE)


# Every case runs as on a user's machine, where Python caches the bytecode of what it imports:
# a shell that sets PYTHONDONTWRITEBYTECODE would have every netsim process compile its own
# sources again (about 0.2 s of a 2 s process).
USER_ENV = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}


def measured(cmd: list[str]) -> tuple[float, int, str, float]:
    """Wall seconds, peak RSS (KiB), standard output and CPU seconds of ``cmd``, run alone
    in a fresh wrapper process (so that the RSS and CPU time are that command's)."""
    wrapper = (
        "import resource, subprocess, sys, time, json\n"
        "t = time.perf_counter()\n"
        "p = subprocess.run(sys.argv[1:], capture_output=True, text=True)\n"
        "wall = time.perf_counter() - t\n"
        "sys.stderr.write(p.stderr)\n"
        "print(json.dumps({'rc': p.returncode, 'wall': wall, "
        "'rss': resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss, 'out': p.stdout,\n"
        "'cpu': resource.getrusage(resource.RUSAGE_CHILDREN).ru_utime"
        " + resource.getrusage(resource.RUSAGE_CHILDREN).ru_stime}))\n"
    )
    res = subprocess.run(
        [sys.executable, "-c", wrapper, *cmd], capture_output=True, text=True, check=True, env=USER_ENV
    )
    got = json.loads(res.stdout.strip().splitlines()[-1])
    if got["rc"] != 0:
        raise SystemExit(f"compare.py: {' '.join(cmd)} failed:\n{res.stderr}")
    return got["wall"], got["rss"], got["out"], got["cpu"]


def netsim_settings(n: int, protocol: str, duration_s: float = DURATION_S) -> dict:
    """The ``netsim run --set`` keys of the workload."""
    return {
        "seed": 1,
        "duration_s": duration_s,
        "world.n_robots": n,
        "world.side_m": side_for(n),
        "channel.range_m": RANGE_M,
        "mobility.speed_min_mps": SPEED_MIN,
        "mobility.speed_max_mps": SPEED_MAX,
        "mobility.pause_s": PAUSE_S,
        "mobility.stationary_start": "false",
        "protocol.model": protocol,
        "protocol.ack_period_s": PERIOD_S,
        "output.position_interval_s": 0,
    }


def median_case(runs: list[dict]) -> dict:
    """One case's figures over its rounds: the median wall, CPU and run seconds, the
    largest peak memory (the receptions are the same every round)."""
    import statistics

    run_s = [r["run_s"] for r in runs if r["run_s"] is not None]
    return {
        "wall_s": statistics.median(r["wall_s"] for r in runs),
        "cpu_s": statistics.median(r["cpu_s"] for r in runs),
        "run_s": statistics.median(run_s) if run_s else None,
        "received": runs[0]["received"],
        "rss_kib": max(r["rss_kib"] for r in runs),
    }


def netsim_case(n: int, protocol: str) -> dict:
    import pandas as pd

    netsim = str(Path(sys.executable).with_name("netsim"))
    with tempfile.TemporaryDirectory() as out:
        sets = netsim_settings(n, protocol)
        cmd = [netsim, "run", "--out", out, "--no-progress", "--quiet"]
        for key, value in sets.items():
            cmd += ["--set", f"{key}={value}"]
        wall, rss, _, cpu = measured(cmd)
        received = int(pd.read_parquet(os.path.join(out, "acks.parquet"))["received"].sum())
    return {"wall_s": wall, "cpu_s": cpu, "run_s": None, "received": received, "rss_kib": rss}


def reference_case(n: int, scan: str = "python") -> dict:
    cmd = [sys.executable, str(HERE / "simpy_reference_beacon.py"), "--n", str(n), "--sim-time", str(DURATION_S)]
    cmd += ["--scan", scan]
    cmd += ["--rc", str(RANGE_M), "--period", str(PERIOD_S), "--vmin", str(SPEED_MIN), "--vmax", str(SPEED_MAX)]
    wall, rss, out, cpu = measured(cmd + ["--pause", str(PAUSE_S)])
    got = json.loads(out.strip().splitlines()[-1])
    return {"wall_s": wall, "cpu_s": cpu, "run_s": got["wall_run_s"], "received": got["received"], "rss_kib": rss}


def ns3_case(n: int, python: str, mode: str = "direct") -> dict:
    cmd = [python, str(HERE / "ns3_beacon.py"), "--n", str(n), "--sim-time", str(DURATION_S), "--mode", mode]
    cmd += ["--rc", str(RANGE_M), "--period", str(PERIOD_S), "--vmin", str(SPEED_MIN), "--vmax", str(SPEED_MAX)]
    wall, rss, out, cpu = measured(cmd + ["--pause", str(PAUSE_S)])
    got = json.loads(out.strip().splitlines()[-1])
    return {"wall_s": wall, "cpu_s": cpu, "run_s": got["wall_run_s"], "received": got["received"], "rss_kib": rss}


def sweep_case(runs: int, workers: int = 2) -> dict:
    """``runs`` runs of the default scenario with 50 robots for 300 simulated seconds through
    ``netsim sweep`` on ``workers`` workers: wall seconds and runs per minute."""
    netsim = str(Path(sys.executable).with_name("netsim"))
    with tempfile.TemporaryDirectory() as tmp:
        spec = Path(tmp) / "throughput.toml"
        spec.write_text(
            'name = "throughput"\n'
            f"replications = {runs}\n"
            "[base]\nduration_s = 300.0\n[base.world]\nn_robots = 50\n"
            "[base.output]\nposition_interval_s = 0.0\n[grid]\nseed = [1]\n"
        )
        cmd = [netsim, "sweep", str(spec), "--workers", str(workers), "--out", str(Path(tmp) / "out"), "--no-progress"]
        wall, rss, _, cpu = measured(cmd)
    return {"runs": runs, "workers": workers, "wall_s": wall, "cpu_s": cpu, "per_min": 60.0 * runs / wall}


def warm_up() -> None:
    """Runs as a user's first, unmeasured: 200 robots with the clustering, then with Acks
    alone (whose compiled loops differ), so that the bytecode of every module a run imports
    and the compiled loops' caches are on disk."""
    netsim = str(Path(sys.executable).with_name("netsim"))
    for protocol in ("clustering", "ack"):
        with tempfile.TemporaryDirectory() as out:
            cmd = [netsim, "run", "--out", out, "--no-progress", "--quiet"]
            for key, value in netsim_settings(200, protocol, 10.0).items():
                cmd += ["--set", f"{key}={value}"]
            measured(cmd)


def small_case() -> dict:
    """``netsim run`` with 10 robots for 30 simulated seconds (otherwise the default
    scenario): the whole process, imports included."""
    netsim = str(Path(sys.executable).with_name("netsim"))
    with tempfile.TemporaryDirectory() as out:
        cmd = [netsim, "run", "--out", out, "--no-progress", "--quiet"]
        wall, rss, _, cpu = measured(cmd + ["--set", "world.n_robots=10", "--set", "duration_s=30"])
    return {"wall_s": wall, "cpu_s": cpu, "rss_kib": rss}


def _has_ns3(python: str) -> bool:
    """Whether ``python`` runs and finds ns-3's package (found, not imported: that takes seconds)."""
    probe = "import importlib.util; print(importlib.util.find_spec('ns') is not None)"
    try:
        return subprocess.run([python, "-c", probe], capture_output=True, text=True).stdout.strip() == "True"
    except OSError:
        return False


def main() -> None:
    ap = Parser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, nargs="+", default=[100, 1000])
    ap.add_argument("--simpy-max-n", type=int, default=1000, help="largest N for the O(N^2) SimPy reference")
    ap.add_argument(
        "--simpy-numpy-max-n", type=int, default=10000, help="largest N for the SimPy reference's numpy scan"
    )
    ap.add_argument("--ns3-max-n", type=int, default=10000, help="largest N for ns-3 grid")
    ap.add_argument(
        "--ns3-direct-max-n", type=int, default=1000, help="largest N for ns-3 direct (an O(N) scan per send)"
    )
    ap.add_argument("--clustering-max-n", type=int, default=10000, help="largest N for netsim clustering")
    ap.add_argument("--ns3-python", default=None, help="a Python with ns-3 (bash benchmarks/ns3_env.sh .ns3venv)")
    ap.add_argument("--sweep-runs", type=int, default=8, help="runs of the sweep throughput case (0: none)")
    ap.add_argument(
        "--repeat", type=int, default=1, help="rounds of each N's cases, alternated; the table gives medians"
    )
    args = ap.parse_args()
    if any(n < 2 for n in args.n):
        ap.error("every --n must be at least 2")
    if args.ns3_python and not (Path(args.ns3_python).is_file() and os.access(args.ns3_python, os.X_OK)):
        ap.error(f"--ns3-python: {args.ns3_python} is not a Python to run (bash benchmarks/ns3_env.sh .ns3venv)")
    if args.ns3_python and not _has_ns3(args.ns3_python):
        ap.error(f"--ns3-python: {args.ns3_python} has no ns-3 to import (bash benchmarks/ns3_env.sh .ns3venv)")
    if args.sweep_runs < 0:
        ap.error("--sweep-runs must be at least 0")
    if args.repeat < 1:
        ap.error("--repeat must be at least 1")
    warm_up()
    rows = []
    for n in args.n:
        cases = [("netsim ack (whole process)", lambda n=n: netsim_case(n, "ack"))]
        if n <= args.clustering_max_n:
            cases.append(("netsim clustering (whole process)", lambda n=n: netsim_case(n, "clustering")))
        if n <= args.simpy_max_n:
            cases.append(("simpy reference", lambda n=n: reference_case(n)))
        if n <= args.simpy_numpy_max_n:
            cases.append(("simpy reference, numpy scan", lambda n=n: reference_case(n, "numpy")))
        if args.ns3_python and n <= args.ns3_direct_max_n:
            cases.append(("ns-3 direct", lambda n=n: ns3_case(n, args.ns3_python)))
        if args.ns3_python and n <= args.ns3_max_n:
            cases.append(("ns-3 grid", lambda n=n: ns3_case(n, args.ns3_python, "grid")))
        # Rounds of all the cases in turn, so that a slow spell of a shared machine falls on
        # every case alike; each figure is then the median over the rounds.
        got: dict[str, list[dict]] = {name: [] for name, _ in cases}
        for _ in range(args.repeat):
            for name, run in cases:
                r = run()
                got[name].append(r)
                print(f"N = {n}: {name}: {r['wall_s']:.1f} s wall, {r['cpu_s']:.1f} s CPU", file=sys.stderr)
        base = None
        for name, _ in cases:
            r = median_case(got[name])
            base = base or r
            rows.append((n, name, r, base))
    print(
        "| N | case | wall s | CPU s | run s | receptions | receptions / wall s | peak MiB "
        "| wall / netsim ack | netsim ack's rate / this |"
    )
    print("| ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    for n, name, r, base in rows:
        run_s = f"{r['run_s']:.2f}" if r["run_s"] is not None else ""
        rate = r["received"] / r["wall_s"]
        base_rate = base["received"] / base["wall_s"]
        print(
            f"| {n:,} | {name} | {r['wall_s']:.2f} | {r['cpu_s']:.2f} | {run_s} | {r['received']:,} | {rate:,.0f} | "
            f"{r['rss_kib'] / 1024:.0f} | {r['wall_s'] / base['wall_s']:.2f} | {base_rate / rate:.2f} |"
        )
        if r["run_s"]:
            run_rate = r["received"] / r["run_s"]
            print(
                f"| {n:,} | {name}, run alone | {r['run_s']:.2f} | | | | {run_rate:,.0f} | | "
                f"{r['run_s'] / base['wall_s']:.2f} | {base_rate / run_rate:.2f} |"
            )
    small = [small_case() for _ in range(3)]
    print()
    print("| small run: netsim run, 10 robots, 30 s | wall s | CPU s | peak MiB |")
    print("| --- | ---: | ---: | ---: |")
    for k, r in enumerate(small, 1):
        print(f"| run {k} of 3 | {r['wall_s']:.2f} | {r['cpu_s']:.2f} | {r['rss_kib'] / 1024:.0f} |")
    if args.sweep_runs:
        sw = sweep_case(args.sweep_runs)
        print()
        print("| sweep | runs | workers | wall s | CPU s | runs / minute |")
        print("| --- | ---: | ---: | ---: | ---: | ---: |")
        print(
            f"| 50 robots, 300 s, clustering | {sw['runs']} | {sw['workers']} | {sw['wall_s']:.1f} | "
            f"{sw['cpu_s']:.1f} | {sw['per_min']:.1f} |"
        )


if __name__ == "__main__":
    main()
