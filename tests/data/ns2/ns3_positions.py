"""Positions of the nodes of ns-2 movement files as ns-3's Ns2MobilityHelper replays them:
the reference that tests/test_ns2_as_ns3.py compares netsim with.

Run with a Python that has the ns-3 wheel (``bash ../shared/benchmarks/ns3_env.sh`` or
``pip install ns3``), from this folder:

    python ns3_positions.py cases.json > ns3_positions.json

``cases.json`` lists ``{"file": ..., "nodes": N, "times": [...]}``; each case is replayed in
a process of its own (ns-3's simulator is global), and the output maps each file to
``{"times": [...], "positions": [[[x, y] per node] per time]}``.
"""

import json
import subprocess
import sys


def one(path: str, n: int, times: list[float]) -> dict:
    from ns import ns

    nodes = ns.NodeContainer()
    nodes.Create(n)
    ns.Ns2MobilityHelper(path).Install()
    out = []
    for t in times:
        # Stop takes a delay from now.
        ns.Simulator.Stop(ns.Seconds(t - ns.Simulator.Now().GetSeconds()))
        ns.Simulator.Run()
        out.append([[p.x, p.y] for p in (nodes.Get(i).GetObject[ns.MobilityModel]().GetPosition() for i in range(n))])
    ns.Simulator.Destroy()
    return {"times": times, "positions": out}


if __name__ == "__main__":
    if sys.argv[1] == "--one":
        print(json.dumps(one(sys.argv[2], int(sys.argv[3]), json.loads(sys.argv[4]))))
        sys.exit(0)
    result = {}
    for case in json.load(open(sys.argv[1])):
        proc = subprocess.run(
            [sys.executable, __file__, "--one", case["file"], str(case["nodes"]), json.dumps(case["times"])],
            capture_output=True,
            text=True,
            check=True,
        )
        result[case["file"]] = json.loads(proc.stdout.strip().splitlines()[-1])
    print(json.dumps(result, indent=1))
