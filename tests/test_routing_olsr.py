"""OLSR (RFC 3626): multipoint relays, topology control and the routing table."""

import networkx as nx
import numpy as np
import pytest
from netsim.protocols.olsr import select_mprs

from netsim.errors import ConfigError
from netsim.run import build, collect
from tests.fixtures import make_config


def _two_hop(graph, i):
    """``(two_hop_via, N2)`` of node ``i`` of ``graph``, as OLSR's HELLOs give them."""
    n1 = set(graph[i])
    via = {n: set(graph[n]) - {i} for n in n1}
    n2 = set().union(*via.values()) - n1 - {i} if via else set()
    return via, n2


def test_mprs_cover_every_two_hop_neighbour():
    """The MPRs a robot selects reach every one of its two-hop neighbours (RFC 3626 8.3.1),
    and are symmetric neighbours: random geometric graphs, every node."""
    rng = np.random.default_rng(11)
    checked = 0
    for _ in range(40):
        n = int(rng.integers(5, 40))
        pos = rng.uniform(0, 1, (n, 2))
        graph = nx.random_geometric_graph(n, 0.3, pos=dict(enumerate(pos)))
        for i in graph:
            via, n2 = _two_hop(graph, i)
            mprs = select_mprs(via, n2)
            assert mprs <= set(via)
            covered = set().union(*(via[m] for m in mprs)) if mprs else set()
            assert n2 <= covered
            checked += len(n2)
    assert checked > 1000


def test_mprs_take_a_neighbour_that_alone_reaches_a_two_hop_neighbour():
    """A neighbour that alone reaches some two-hop neighbour is an MPR before any other is
    chosen (8.3.1, step 3): here those two cover everything, and the neighbour that covers
    most is not needed."""
    via = {1: {10, 11, 12, 13}, 2: {10, 11, 14}, 3: {12, 13, 15}}
    assert select_mprs(via, set(range(10, 16))) == {2, 3}


def _run(tmp_path, xy, flows, duration_s=40.0, **protocol):
    path = tmp_path / "robots.csv"
    path.write_text("x_m,y_m\n" + "".join(f"{x},{y}\n" for x, y in xy))
    config = make_config(
        seed=6,
        duration_s=duration_s,
        world={"n_robots": len(xy), "side_m": 1000.0, "placement": str(path)},
        mobility={"model": "static"},
        channel={"range_m": 120.0},
        protocol={"model": "olsr", **protocol},
        traffic={"flows": flows},
        output={"position_interval_s": 0.0},
    )
    sim = build(config)
    sim.run()
    return sim, collect(sim)


def test_olsr_routes_shortest_paths_on_a_static_grid(tmp_path):
    """Once HELLOs and TCs have spread, every robot of a static 4 x 4 grid has a route to
    every other, of the grid's hop distance, and a flow corner to corner is delivered in 6
    hops."""
    xy = [(50 + 100 * i, 50 + 100 * j) for i in range(4) for j in range(4)]
    flow = {"src": 0, "dst": 15, "start_s": 30.0, "stop_s": 35.0, "rate_bps": 8000.0, "packet_bytes": 1000}
    sim, frames = _run(tmp_path, xy, [flow])
    olsr = sim.models["protocol"]
    for i in range(16):
        routes = olsr.routes(i)
        assert set(routes) == set(range(16)) - {i}
    packets = frames["packets"]
    assert packets["delivered"].all() and (packets["hops"] == 6).all()
    assert set(frames["control"]["kind"]) == {"hello", "tc"}


def test_olsr_parameter_out_of_range_is_refused():
    """A neighbour hold time not longer than the HELLO interval is refused, naming the key."""
    with pytest.raises(ConfigError, match="protocol.neighb_hold_time_s = 2.0"):
        make_config(protocol={"model": "olsr", "neighb_hold_time_s": 2.0})
