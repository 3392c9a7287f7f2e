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
