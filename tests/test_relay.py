"""Relaying's bookkeeping: the true hop count of a message (its shortest_hops)."""

import numpy as np


def test_bfs_hops_equals_scipy_shortest_path():
    """The true hop count a message's shortest_hops records (a breadth-first search over the
    directed links) is scipy's unweighted shortest path, inf where unreachable, bit for bit:
    random directed graphs with repeated edges, isolated nodes and one-node graphs."""
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import shortest_path

    from tests.oracles.protocols import bfs_hops

    rng = np.random.default_rng(1)
    reached = 0
    for _ in range(200):
        n, m = int(rng.integers(1, 60)), int(rng.integers(0, 300))
        a, b = rng.integers(0, n, m), rng.integers(0, n, m)
        a, b = a[a != b], b[a != b]
        source = int(rng.integers(n))
        graph = csr_matrix((np.ones(len(a)), (a, b)), shape=(n, n))
        want = shortest_path(graph, indices=source, unweighted=True, directed=True)
        got = bfs_hops(a, b, n, source)
        assert got.tobytes() == want.tobytes()
        reached += int((got > 1).sum())
    assert reached > 500


def test_a_message_needs_two_different_robots_of_the_team():
    """The relay refuses a message from a robot to itself, or naming a robot outside the team
    (ids 0 to n - 1), before anything is sent."""
    import pytest

    from tests.fixtures import clustering

    _sim, stack = clustering([(0.0, 0.0), (5.0, 0.0), (10.0, 0.0)])
    for src, dst in ((1, 1), (3, 0), (0, 3), (-1, 0)):
        with pytest.raises(ValueError, match="need two different robots"):
            stack.relay.send(src, dst)
    assert stack.relay.outcomes() == []


def test_the_oracle_breaks_ties_between_shortest_paths_to_the_lowest_id():
    """docs/model.md 4.3's oracle sends a message along a shortest path of the true topology;
    of two neighbours equally few hops from the destination, the next hop is the lower id:
    around the diamond 0-{1, 2}-3 the message goes through 1."""
    from tests.fixtures import clustering

    sim, stack = clustering([(0.0, 0.0), (5.0, 5.0), (5.0, -5.0), (11.0, 0.0)], routing="oracle")
    mid = stack.relay.send(0, 3)
    sim.env.run(until=1.0)
    hops = stack.relay.hops_frame()
    path = hops[hops["msg_id"] == mid].sort_values("hop")
    assert path[["sender", "receiver"]].values.tolist() == [[0, 1], [1, 3]]
