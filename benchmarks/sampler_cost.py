"""Benchmark: what the clustering's once-a-second sample costs, on compare.py's workload.

Runs ``netsim run`` with the clustering protocol in this process, times each step of
:meth:`netsim.protocols.stack.Stack._sampler` (one sample: what it does between two yields, wall
and CPU), and of that the range index's neighbour lists asked for (a rebuild of them when
due: the channel's range queries would have done it otherwise), and counts the process's
minor page faults over the whole run and within the samples. Prints one line.
To compare with another checkout, run this same file from each checkout's own virtual
environment (each with ``pip install -e .``: the models install under ``netsim``'s
namespace from their folders, so ``PYTHONPATH`` alone would mix the two trees), alternating:

    .venv/bin/python benchmarks/sampler_cost.py --n 10000
    /path/to/other/checkout/.venv/bin/python benchmarks/sampler_cost.py --n 10000
"""

from __future__ import annotations

import resource
import tempfile
import time

from netsim.tools.args import Parser


def main() -> None:
    ap = Parser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=10000)
    ap.add_argument("--duration", type=float, default=100.0)
    args = ap.parse_args()
    import netsim.protocols.stack
    from compare import netsim_settings

    import netsim.radio.spatial
    from netsim.tools import cli

    sampler, lists = netsim.protocols.stack.Stack._sampler, netsim.radio.spatial.RangeIndex.lists
    spent = {"wall": 0.0, "cpu": 0.0, "samples": 0, "lists": 0.0, "sampling": False, "faults": 0}

    def timed_sampler(self, interval):
        steps = sampler(self, interval)
        while True:
            w, c = time.perf_counter(), time.process_time()
            f = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
            spent["sampling"] = True
            event = next(steps)
            spent["sampling"] = False
            spent["faults"] += resource.getrusage(resource.RUSAGE_SELF).ru_minflt - f
            spent["wall"] += time.perf_counter() - w
            spent["cpu"] += time.process_time() - c
            spent["samples"] += 1
            yield event

    def timed_lists(self, t):
        w = time.perf_counter()
        out = lists(self, t)
        if spent["sampling"]:
            spent["lists"] += time.perf_counter() - w
        return out

    netsim.protocols.stack.Stack._sampler = timed_sampler  # type: ignore[method-assign]
    netsim.radio.spatial.RangeIndex.lists = timed_lists  # type: ignore[method-assign]
    with tempfile.TemporaryDirectory() as out:
        argv = ["run", "--out", out, "--no-progress", "--quiet"]
        for key, value in netsim_settings(args.n, "clustering", args.duration).items():
            argv += ["--set", f"{key}={value}"]
        faults = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
        w, c = time.perf_counter(), time.process_time()
        try:
            cli.main(argv)
        except SystemExit as e:
            if e.code:
                raise
        wall, cpu = time.perf_counter() - w, time.process_time() - c
        faults = resource.getrusage(resource.RUSAGE_SELF).ru_minflt - faults
    k = max(spent["samples"], 1)
    print(
        f"{netsim.protocols.stack.__file__}: N = {args.n}, {spent['samples']} samples: "
        f"{1e3 * spent['wall'] / k:.2f} ms wall, {1e3 * spent['cpu'] / k:.2f} ms CPU per sample "
        f"(the lists {1e3 * spent['lists'] / k:.2f} ms wall); "
        f"netsim run {wall:.2f} s wall, {cpu:.2f} s CPU, {faults} minor page faults ({spent['faults']} in the samples)"
    )


if __name__ == "__main__":
    main()
