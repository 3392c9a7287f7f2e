"""The ``neighbour_beliefs`` table: which robots each robot believes live, beside which
truly reach it, by id (the ids behind ``beliefs.parquet``'s counts)."""

import os

import numpy as np
import pandas as pd
import pytest
from netsim.protocols.stack import NEIGHBOUR_BELIEFS_SCHEMA

from netsim.run import execute, tables
from tests.fixtures import clustering, make_config


def _ids(frame: pd.DataFrame, robot: int, column: str) -> list[int]:
    rows = frame[(frame["robot"] == robot) & frame[column]]
    return rows["neighbour"].tolist()


def test_stale_and_true_neighbours_by_id_per_direction():
    """Robot 0 (range 5 m) hears 1 (range 15 m, 10 m away) and 2 (range 50 m, 40 m away);
    1 hears 2; 2 hears nobody. When 2 jumps away, 0 and 1 still believe in it: stale,
    believed but not in range."""
    sim, stack = clustering([[0, 0], [10, 0], [0, 40]], core={"duration_s": 20.0, "range_m": [5.0, 15.0, 50.0]})
    sim.run(until_s=5.0)
    nb = stack.neighbour_beliefs(sim.now)
    assert nb[["robot", "neighbour", "believed", "in_range"]].values.tolist() == [
        [0, 1, True, True],
        [0, 2, True, True],
        [1, 2, True, True],
    ]
    sim.state.set_leg(2, sim.now, (0.0, 0.0), start_m=(500.0, 500.0))
    sim.run(until_s=5.5)
    nb = stack.neighbour_beliefs(sim.now)
    assert _ids(nb, 0, "believed") == [1, 2] and _ids(nb, 0, "in_range") == [1]
    assert _ids(nb, 1, "believed") == [2] and _ids(nb, 1, "in_range") == []
    # tau (3 s) after 2's last Ack the stale beliefs have expired.
    sim.run(until_s=12.0)
    nb = stack.neighbour_beliefs(sim.now)
    assert _ids(nb, 0, "believed") == [1] and not (nb["neighbour"] == 2).any()


def test_missing_neighbour_by_id():
    """A robot that arrives in range is truly a neighbour before its first Ack is heard."""
    sim, stack = clustering([[0, 0], [5, 0], [500, 500]], core={"duration_s": 20.0}, ack_jitter_s=0.0)
    sim.run(until_s=5.0)
    sim.state.set_leg(2, sim.now, (0.0, 0.0), start_m=(0.0, 5.0))
    nb = stack.neighbour_beliefs(sim.now)
    assert _ids(nb, 0, "in_range") == [1, 2] and _ids(nb, 0, "believed") == [1]
    assert _ids(nb, 2, "in_range") == [0, 1] and _ids(nb, 2, "believed") == []


def test_the_table_adds_up_to_the_beliefs_counts():
    """Per sample and robot: believed rows = believed_neighbours, in-range rows =
    true_neighbours, believed only = stale, in range only = missing; on a run with loss,
    jitter and motion, so that all four happen."""
    run = execute(
        make_config(
            seed=2,
            duration_s=40.0,
            world={"n_robots": 30, "side_m": 500.0},
            channel={"range_m": 120.0, "loss_probability": 0.3},
            mobility={"speed_max_mps": 10.0},
            protocol={"message_rate_hz": 0.0},
        )
    )
    nb, beliefs = run.frames["neighbour_beliefs"], run.frames["beliefs"]
    assert tables(run.sim.config)["neighbour_beliefs"] == NEIGHBOUR_BELIEFS_SCHEMA
    assert {c: str(t) for c, t in nb.dtypes.items()} == NEIGHBOUR_BELIEFS_SCHEMA
    per = (
        nb.assign(
            stale=nb["believed"] & ~nb["in_range"],
            missing=nb["in_range"] & ~nb["believed"],
        )
        .groupby(["t_s", "robot"])[["believed", "in_range", "stale", "missing"]]
        .sum()
    )
    b = beliefs.set_index(["t_s", "robot"])
    counts = b[["believed_neighbours", "true_neighbours", "stale_neighbours", "missing_neighbours"]]
    got = per.reindex(counts.index, fill_value=0).to_numpy()
    assert (got == counts.to_numpy()).all()
    assert (counts["stale_neighbours"] > 0).any() and (counts["missing_neighbours"] > 0).any()
    assert not nb.duplicated(["t_s", "robot", "neighbour"]).any() and (nb["robot"] != nb["neighbour"]).all()


def test_in_sorted_is_isin():
    """Membership in a sorted pool by binary search is np.isin, empty pool and ends included."""
    from tests.oracles.protocols import in_sorted

    rng = np.random.default_rng(8)
    for size in (0, 1, 5, 200):
        pool = np.sort(rng.choice(1000, size, replace=False)).astype(np.int64)
        values = rng.integers(-5, 1005, 300)
        assert in_sorted(values, pool).tolist() == np.isin(values, pool).tolist()


@pytest.mark.parametrize("expected", [1, 3, 40])
def test_samples_frame_is_every_sample_in_order(expected):
    """A sampled table is its samples' columns one after another, each row with its
    sample's time, dtypes as given: samples with no rows (the first too), buffers grown
    past their first estimate (``expected`` samples of the first one's rows) or never; a
    table taken before later samples is unchanged by them; samples added or written in
    room reserved for more rows than kept alike."""
    from netsim.samples import Samples

    rng = np.random.default_rng(41)
    samples = Samples(expected)
    times, chunks, early = [], [], None
    for k in range(30):
        m = 0 if k in (0, 7) else int(rng.integers(0, 60)) * (1 + k // 10)
        cols = {
            "robot": rng.integers(0, 9, m),
            "flag": rng.random(m) < 0.5,
            "role": rng.integers(0, 3, m).astype(np.int8),
        }
        if k % 3 == 1:  # written in place: room for more rows than kept, the rest scribbled on
            room = samples.reserve({c: x.dtype for c, x in cols.items()}, m + 5, samples.last_rows)
            for c, x in cols.items():
                room[c][:m], room[c][m:] = x, x[:1] if m else 1
            samples.commit(float(k), m)
        else:
            samples.add(float(k), cols)
        times.append(np.full(m, float(k)))
        chunks.append(cols)
        if k == 12:
            early, early_copy = samples.frame(), samples.frame().copy()
    want = pd.DataFrame({"t_s": np.concatenate(times)} | {c: np.concatenate([x[c] for x in chunks]) for c in chunks[0]})
    got = samples.frame()
    assert list(got.columns) == ["t_s", "robot", "flag", "role"]
    assert got.dtypes.tolist() == want.dtypes.tolist()
    assert got.equals(want) and len(got) > 500
    assert early.equals(early_copy) and len(early) > 0


def test_a_sample_larger_than_the_buffers_after_more_samples_than_expected_is_kept_whole():
    """Past the samples expected, a sample of more rows than the buffers have left grows
    them to hold it: every row is kept."""
    from netsim.samples import Samples

    samples = Samples(1)
    sizes = [1, 100, 300, 10_000]
    for k, m in enumerate(sizes):
        samples.add(float(k), {"robot": np.arange(m)})
    got = samples.frame()
    assert got["t_s"].tolist() == [float(k) for k, m in enumerate(sizes) for _ in range(m)]
    assert got["robot"].tolist() == [i for m in sizes for i in range(m)]


def test_columns_of_objects_are_sampled_in_numpys_arrays():
    """A column of Python objects (text) is held too, in numpy's own arrays (memory mapped
    buffers cannot hold references)."""
    from netsim.samples import Samples

    samples = Samples(2)
    samples.add(0.0, {"name": np.array(["a", "bb"], dtype=object)})
    samples.add(1.0, {"name": np.array(["ccc"], dtype=object)})
    assert samples.frame()["name"].tolist() == ["a", "bb", "ccc"]


@pytest.mark.skipif(not hasattr(os, "fork"), reason="needs fork")
def test_sampled_buffers_are_not_shared_with_a_forked_process():
    """A process forked while a run's samples are held (a sweep's worker, say) writes its
    own copy of their buffers: the parent's next rows are its own, not the child's."""
    from netsim.samples import Samples

    samples = Samples(10)
    samples.add(0.0, {"robot": np.arange(5)})
    pid = os.fork()
    if pid == 0:  # the child: a later sample of its own, then gone
        samples.add(1.0, {"robot": np.full(5, 111)})
        os._exit(0)
    os.waitpid(pid, 0)
    # The parent's buffer beyond its own rows, where the child wrote its copy's.
    assert 111 not in samples._buffers["robot"].tolist()
    samples.add(1.0, {"robot": np.full(5, 7)})
    assert samples.frame()["robot"].tolist() == [0, 1, 2, 3, 4, 7, 7, 7, 7, 7]
