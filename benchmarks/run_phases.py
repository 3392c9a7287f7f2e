"""Benchmark: where a whole ``netsim run`` process spends its time, on compare.py's workload.

Imports ``netsim.tools.cli`` (timed), then runs ``netsim run`` in the same process and
times the build (up to the simulation's start), the run itself, and what follows (the
tables written). Prints one line of wall seconds per phase and the process's CPU time.

    python benchmarks/run_phases.py --n 1000 --protocol ack
"""

from __future__ import annotations

import tempfile
import time

from netsim.tools.args import Parser

T0 = time.perf_counter()


def main() -> None:
    ap = Parser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=1000)
    ap.add_argument("--protocol", default="ack")
    ap.add_argument("--duration", type=float, default=100.0)
    args = ap.parse_args()
    from netsim.tools import cli

    t_imported = time.perf_counter()
    from compare import netsim_settings

    import netsim.sim

    run = netsim.sim.Simulation.run
    box: dict[str, float] = {}

    def timed_run(self, *a, **k):
        box["start"] = time.perf_counter()
        out = run(self, *a, **k)
        box["run"] = time.perf_counter() - box["start"]
        return out

    netsim.sim.Simulation.run = timed_run  # type: ignore[method-assign]
    with tempfile.TemporaryDirectory() as out:
        argv = ["run", "--out", out, "--no-progress", "--quiet"]
        for key, value in netsim_settings(args.n, args.protocol, args.duration).items():
            argv += ["--set", f"{key}={value}"]
        try:
            code = cli.main(argv)
        except SystemExit as e:
            code = e.code
        if code:
            raise SystemExit(code)  # netsim said why, in one line
        end = time.perf_counter()
    print(
        f"N = {args.n}, {args.protocol}: import {t_imported - T0:.2f} s, build {box['start'] - t_imported:.2f} s, "
        f"run {box['run']:.2f} s, after the run {end - box['start'] - box['run']:.2f} s, "
        f"whole {end - T0:.2f} s wall, {time.process_time():.2f} s CPU"
    )


if __name__ == "__main__":
    main()
