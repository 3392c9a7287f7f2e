"""The compiled chain decides exactly as the generic loss chain, draws included."""

import numpy as np
import pytest

from netsim.radio.examples import SIDE_M
from netsim.radio.fast import CompiledChain
from netsim.radio.free_space import sample_free
from netsim.radio.maps import load_map
from netsim.radio.propagation import LogDistanceParams, Pairs, log_distance, unit_disk
from netsim.radio.shadowing import PairShadowing

pytest.importorskip("numba")


def _broadcasts(seed, n=120, calls=60):
    """Random broadcasts among moving robots in the office: (sender, receivers, positions, odometers)."""
    rng = np.random.default_rng(seed)
    m = load_map("office")
    pos = sample_free(m, rng, n, SIDE_M)
    odo = np.zeros(n)
    for _ in range(calls):
        step = rng.normal(0, 1.0, (n, 2)) * (rng.random((n, 1)) < 0.7)
        moved = np.clip(pos + step, 0.0, SIDE_M)
        odo += np.hypot(*(moved - pos).T)
        pos = moved
        s = int(rng.integers(n))
        receivers = np.delete(np.arange(n), s)
        yield s, receivers, pos.copy(), odo.copy()


def _twins(params, with_map, step_m=0.0):
    m = load_map("office") if with_map else None
    made = []
    for _ in range(2):
        sh = PairShadowing(
            params.shadowing_sigma_db, params.shadowing_decorrelation_m, np.random.default_rng(5), step_m
        )
        made.append((log_distance(params, sh, m), sh))
    return made


@pytest.mark.parametrize(
    "params, with_map",
    [
        (LogDistanceParams(shadowing_sigma_db=6.0, sensitivity_dbm=-65.0), True),
        (LogDistanceParams(shadowing_sigma_db=6.0, sensitivity_dbm=-65.0), False),
        (LogDistanceParams(sensitivity_dbm=-65.0, wall_loss_db=3.0), True),
        (LogDistanceParams(sensitivity_dbm=-65.0), False),
    ],
)
def test_compiled_log_distance_equals_chain(params, with_map):
    (generic, sh1), (compiled_prop, sh2) = _twins(params, with_map)
    compiled = CompiledChain(compiled_prop)
    decided = 0
    for s, rec, pos, odo in _broadcasts(1):
        pairs = Pairs.between(np.full(len(rec), s), rec, pos, odo)
        a = generic.receivable(pairs)
        b = compiled.receivable(pairs)
        assert np.array_equal(a, b)
        decided += int(a.sum())
    assert decided > 50  # the scenario links some pairs, and not all
    assert sh1.draws == sh2.draws
    assert np.array_equal(sh1._keys, sh2._keys) and np.array_equal(sh1._x, sh2._x)


@pytest.mark.parametrize("ranges", [25.0, np.linspace(10.0, 40.0, 120)])
@pytest.mark.parametrize("with_map", [True, False])
def test_compiled_unit_disk_equals_chain(ranges, with_map):
    m = load_map("office") if with_map else None
    generic = unit_disk(ranges, m)
    compiled = CompiledChain(unit_disk(ranges, m))
    for s, rec, pos, odo in _broadcasts(2, calls=30):
        pairs = Pairs.between(np.full(len(rec), s), rec, pos, odo)
        assert np.array_equal(generic.receivable(pairs), compiled.receivable(pairs))


def test_unknown_chain_is_refused():
    from netsim.radio.propagation import LossChain, Propagation, ShadowingLoss

    sh = PairShadowing(4.0, 10.0, np.random.default_rng(1))
    with pytest.raises(ValueError, match="no compiled form"):
        CompiledChain(Propagation(LossChain(ShadowingLoss(sh)), 0.0, -1.0, 1.0, 1.0))
