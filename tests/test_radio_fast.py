"""The compiled chain decides exactly as the generic loss chain, draws included."""

import numpy as np
import pytest

from netsim.radio.fast import CompiledChain
from netsim.radio.propagation import LogDistanceParams, Pairs, log_distance, unit_disk
from netsim.radio.shadowing import PairShadowing
from netsim.world.examples import SIDE_M
from netsim.world.free_space import sample_free
from netsim.world.maps import load_map
from tests.oracles import radio as oracle


@pytest.fixture(params=[1, 1000], ids=["plain", "compiled"])
def n_robots(request, monkeypatch):
    """The robots of the run a chain is made for: few (its loops plain Python), many
    (compiled), netsim.compiled.load deciding."""
    monkeypatch.delenv("NETSIM_COMPILED", raising=False)
    return request.param


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
def test_compiled_log_distance_equals_chain(params, with_map, n_robots):
    (generic, sh1), (compiled_prop, sh2) = _twins(params, with_map)
    compiled = CompiledChain(compiled_prop, n_robots)
    decided = 0
    for s, rec, pos, odo in _broadcasts(1):
        pairs = Pairs.between(np.full(len(rec), s), rec, pos, odo)
        a = generic.chain.receivable(pairs, generic.radio)
        b = compiled.receivable(pairs)
        assert np.array_equal(a, b)
        decided += int(a.sum())
    assert decided > 50  # the scenario links some pairs, and not all
    assert sh1.draws == sh2.draws
    assert np.array_equal(sh1._keys, sh2._keys) and np.array_equal(sh1._x, sh2._x)


@pytest.mark.parametrize("ranges", [25.0, np.linspace(10.0, 40.0, 120)])
@pytest.mark.parametrize("with_map", [True, False])
def test_compiled_unit_disk_equals_chain(ranges, with_map, n_robots):
    m = load_map("office") if with_map else None
    generic = unit_disk(ranges, m)
    compiled = CompiledChain(unit_disk(ranges, m), n_robots)
    for s, rec, pos, odo in _broadcasts(2, calls=30):
        pairs = Pairs.between(np.full(len(rec), s), rec, pos, odo)
        assert np.array_equal(generic.chain.receivable(pairs, generic.radio), compiled.receivable(pairs))


def test_unknown_chain_is_refused():
    from netsim.radio.propagation import LossChain, Propagation, Radio, ShadowingLoss

    sh = PairShadowing(4.0, 10.0, np.random.default_rng(1))
    with pytest.raises(ValueError, match="no compiled form"):
        CompiledChain(Propagation(LossChain(ShadowingLoss(sh)), Radio(0.0, -1.0), 1.0, 1.0), 1)


def test_a_chain_of_built_in_terms_is_decided_by_the_compiled_pass_whoever_built_it(monkeypatch):
    """A chain of the built-in terms takes the compiled pass even when the propagation that
    holds it names no ``fast`` (a rule is never decided by two paths); a chain with a
    model's own term takes the generic one."""
    from netsim.radio.fast import GenericChain, one_pass
    from netsim.radio.propagation import LogDistanceLoss, LossChain, Propagation, RangeLoss
    from netsim.radio.reception import Reception
    from netsim.state import RobotState

    class Own:
        lowest_db = 0.0

        def loss_db(self, pairs):
            return np.zeros(len(pairs.a))

    p = LogDistanceParams()
    st = RobotState(3, 100.0, 100.0)
    for chain, compiled in (
        (LossChain(LogDistanceLoss(p)), True),
        (LossChain(RangeLoss(30.0)), True),
        (LossChain(LogDistanceLoss(p), Own()), False),
    ):
        prop = Propagation(chain, p.radio, 100.0, 100.0)
        assert (one_pass(prop) is CompiledChain) is compiled
        assert isinstance(Reception(prop, st).compiled, CompiledChain if compiled else GenericChain)
        # A library call decides as the run's channel does: term by term only for a model's own terms.
        pairs = Pairs.between([0, 0], [1, 2], [[0.0, 0.0], [20.0, 0.0], [120.0, 0.0]])
        with monkeypatch.context() as m:
            m.setattr(LossChain, "receivable", lambda *a: pytest.fail("a built-in chain decided term by term"))
            if compiled:
                assert prop.receivable(pairs).tolist() == [True, False]
        if not compiled:
            assert prop.receivable(pairs).tolist() == [True, False]


@pytest.mark.parametrize("term", ["log-distance", "shadowing", "walls", "unit disk", "sight"])
def test_a_subclass_of_a_built_in_term_is_decided_by_its_own_law(term):
    """A term that subclasses a built-in one brings its own ``loss_db``: the run's channel
    evaluates it term by term, never by the compiled pass of the class it extends."""
    from netsim.radio.fast import GenericChain, one_pass
    from netsim.radio.propagation import (
        LineOfSightLoss,
        LogDistanceLoss,
        LossChain,
        Propagation,
        RangeLoss,
        ShadowingLoss,
        WallLoss,
    )
    from netsim.radio.reception import Reception
    from netsim.state import RobotState

    def deafening(base):
        class Own(base):
            def loss_db(self, pairs):
                return np.full(len(pairs.a), np.inf)

        return Own

    p = LogDistanceParams(shadowing_sigma_db=4.0)
    office = load_map("office")
    terms = {
        "log-distance": (deafening(LogDistanceLoss)(p),),
        "shadowing": (LogDistanceLoss(p), deafening(ShadowingLoss)(PairShadowing(4.0, 10.0, np.random.default_rng(1)))),
        "walls": (LogDistanceLoss(p), deafening(WallLoss)(office, 5.0)),
        "unit disk": (deafening(RangeLoss)(30.0),),
        "sight": (RangeLoss(30.0), deafening(LineOfSightLoss)(office)),
    }[term]
    prop = Propagation(LossChain(*terms), p.radio, 100.0, 100.0)
    assert one_pass(prop) is None
    assert isinstance(Reception(prop, RobotState(3, 100.0, 100.0)).compiled, GenericChain)
    pairs = Pairs.between([0], [1], [[50.0, 50.0], [51.0, 50.0]])
    assert prop.receivable(pairs).tolist() == [False]


def _moving_state(seed, n=150, side=400.0, legs=4):
    """Robots on a few legs each, the last ones still running: odometers and leg starts differ."""
    from netsim.state import RobotState

    rng = np.random.default_rng(seed)
    st = RobotState(n, side, 100.0)
    st.place(rng.uniform(0, side, (n, 2)))
    t = 0.0
    for _ in range(legs):
        t += 1.0
        for i in rng.choice(n, n // 2, replace=False).tolist():
            st.set_leg(i, t + rng.random(), rng.normal(0, 2.0, 2) * (rng.random() < 0.8))
    return st, t + 2.0, rng


@pytest.mark.parametrize("step_m", [0.0, 0.5])
def test_pair_clock_kernel_equals_numpy(step_m):
    from netsim.radio._kernels import pair_clock
    from netsim.radio.shadowing import pair_keys

    st, t, rng = _moving_state(3)
    sh = PairShadowing(4.0, 30.0, np.random.default_rng(0), step_m)
    for sender in rng.choice(st.n, 20, replace=False).tolist():
        rec = np.delete(np.arange(st.n), sender)
        travel = st.travelled_m(t, rec) + float(st.travelled_m(t, [sender])[0])
        keys, clock = np.empty(len(rec), dtype=np.int64), np.empty(len(rec))
        speed = np.array([np.abs(st.velocity_c[i : i + 1])[0] for i in range(st.n)])
        pair_clock(sender, rec, st.odometer_m, speed, st.t0_s, t, step_m, keys, clock)
        assert np.array_equal(clock, sh.anchor(travel))
        assert np.array_equal(keys, pair_keys(np.full(len(rec), sender), rec))
    assert np.ptp(st.odometer_m) > 0  # the robots did travel, unequally


CHAINS = {
    "shadowing + walls": (6.0, 4.0, True),
    "shadowing": (6.0, 4.0, False),
    "walls": (0.0, 4.0, True),
    "path loss": (0.0, 0.0, False),
    "unit disk + line of sight": (None, None, True),
    "unit disk, ranges per robot + line of sight": ("ranges", None, True),
}


@pytest.mark.parametrize("chain", CHAINS)
@pytest.mark.parametrize("dense", [True, False])
def test_transmission_equals_chain(chain, dense, n_robots):
    """The channel's per-frame call decides, draws and stores exactly as the generic chain."""
    sigma, wall_db, with_map = CHAINS[chain]
    m = load_map("office") if with_map else None
    st, t, rng = _moving_state(4, n=120, side=SIDE_M if with_map else 400.0)
    made = []
    for _ in range(2):
        sh = None
        if isinstance(sigma, float):
            params = LogDistanceParams(shadowing_sigma_db=sigma, sensitivity_dbm=-70.0, wall_loss_db=wall_db)
            if sigma > 0:
                sh = PairShadowing(sigma, 30.0, np.random.default_rng(5), 0.0, n_robots=st.n if dense else None)
            made.append((log_distance(params, sh, m), sh))
        else:
            ranges = 30.0 if sigma is None else np.linspace(10.0, 60.0, st.n)
            made.append((unit_disk(ranges, m), None))
    (generic, sh1), (prop, sh2) = made
    fast = CompiledChain(prop, n_robots)
    heard = 0
    for sender in rng.choice(st.n, 60).tolist():
        rec = np.delete(np.arange(st.n), sender)
        d = st.displacement(st.positions_at(t, rec), st.positions_at(t, [sender]))
        dist = np.hypot(d[:, 0], d[:, 1])
        pairs = Pairs(
            np.full(len(rec), sender),
            rec,
            np.broadcast_to(st.positions_at(t, [sender]), (len(rec), 2)),
            st.positions_at(t, rec),
            dist,
            st.travelled_m(t, rec) + float(st.travelled_m(t, [sender])[0]),
        )
        a = generic.chain.receivable(pairs, generic.radio)
        b = fast.transmission(st, t, sender, rec, dist)
        assert np.array_equal(a, b)
        heard += int(a.sum())
        t += 0.25
    assert 0 < heard < 60 * (st.n - 1)
    if sh1 is not None:
        assert sh1.draws == sh2.draws > 0
        every = np.triu_indices(st.n, 1)
        assert np.array_equal(sh1.state(*every)[0], sh2.state(*every)[0], equal_nan=True)


def test_normals_come_in_stream_order():
    """Normals handed out in blocks are the stream's, in order, however many each batch asks."""
    sh = PairShadowing(4.0, 30.0, np.random.default_rng(11))
    taken = []
    for k in [3, 0, 5000, 17, 4096, 1]:
        z = sh.normals(k)[:k].copy()
        sh.consume(k)
        taken.append(z)
    assert np.array_equal(np.concatenate(taken), np.random.default_rng(11).standard_normal(sh.draws))


@pytest.mark.parametrize("compiled", ["0", "1"])
def test_link_changes_equal_the_oracle(compiled, monkeypatch):
    """The link record's loops (plain and compiled) find the oracle's changed and touched
    links, decision by decision."""
    from netsim.radio.reception import LinkRecorder

    monkeypatch.setenv("NETSIM_COMPILED", compiled)
    rng = np.random.default_rng(8)
    n = 40
    t0 = np.zeros(n)  # legs' starts: some touches, not all
    got, want = LinkRecorder(n, t0), LinkRecorder(n, t0)
    want._kernel, want._touch_kernel = oracle.link_changes, oracle.link_touches
    t = 0.0
    for _ in range(400):
        t0[rng.random(n) < 0.05] = t
        s = int(rng.integers(n))
        rec = np.sort(rng.choice(np.delete(np.arange(n), s), int(rng.integers(0, n - 1)), replace=False))
        linked = rng.random(len(rec)) < 0.6
        got.observe(t, s, rec, linked)
        want.observe(t, s, rec, linked)
        assert np.array_equal(got.up, want.up)
        t += 0.1
    a, b = got.intervals(t), want.intervals(t)
    assert len(a) > 100
    assert a.equals(b)
    touches = got.touches()
    assert 20 < len(touches) and touches.equals(want.touches())


def _touched(recorder):
    return [tuple(row) for row in recorder.touches()[["a", "b", "t_s"]].itertuples(index=False)]


def test_a_link_record_that_knows_no_legs_touches_on_every_success_on_a_link_up():
    """Without the robots' leg starts (``t0_s`` None) a success on a link already up is
    always a touch (the pair may have left the reach since); a failure is none, nor is the
    success that brings a link up."""
    from netsim.radio.reception import LinkRecorder

    recorder = LinkRecorder(3)
    recorder.observe(1.0, 0, np.array([1, 2]), np.array([True, True]))
    recorder.observe(2.0, 0, np.array([1, 2]), np.array([True, False]))
    assert _touched(recorder) == [(0, 1, 2.0)]


def test_on_a_torus_every_success_on_a_link_up_is_a_touch():
    """A pair's distance on a torus is not convex in time: a link up may have left the reach
    between two successes even when neither robot changed course, so every success on it is
    a touch; in the plane only one after a leg's start is. The channel's record is made so
    for a torus run."""
    from netsim.radio.reception import Reception
    from netsim.state import RobotState

    touched = {}
    for torus in (False, True):
        st = RobotState(2, 400.0, 100.0, torus=torus)
        st.place(np.array([[10.0, 10.0], [30.0, 10.0]]))
        sh = PairShadowing(4.0, 30.0, np.random.default_rng(5), 0.0, n_robots=2)
        reception = Reception(log_distance(LogDistanceParams(shadowing_sigma_db=4.0), sh), st, record=True)
        for t in (1.0, 2.0, 3.0):
            assert reception.decide(t, 0, np.array([1]), np.array([20.0])).tolist() == [True]
        touched[torus] = _touched(reception.recorder)
    assert touched == {False: [], True: [(0, 1, 2.0), (0, 1, 3.0)]}


def test_a_unicasts_success_on_a_link_up_after_a_leg_started_is_a_touch():
    """A decision on one pair alone (a unicast) touches its link as a broadcast's does: a
    success on the link up after one of the two started a leg since the pair's last
    decision; not one with no leg started since."""
    from netsim.radio.reception import LinkRecorder

    t0 = np.zeros(3)
    recorder = LinkRecorder(3, t0)
    recorder.observe(1.0, 0, np.array([1, 2]), np.array([True, True]))
    recorder.observe_pair(2.0, 0, 1, True)
    t0[1] = 2.5
    recorder.observe_pair(3.0, 0, 1, True)
    assert _touched(recorder) == [(0, 1, 3.0)]


def test_the_early_drop_keeps_a_pair_the_whole_sum_would_hear():
    """One rule of early drop for the compiled pass and the chain term by term: a pair whose
    loss so far, plus the least the terms left can add, is the budget up to rounding stays;
    one clearly over it leaves; on a number or an array alike."""
    from netsim.radio._kernels import may_be_heard, with_slack

    budget = 100.0
    assert may_be_heard(100.0 + 1e-12, 0.0, with_slack(budget))
    assert not may_be_heard(100.001, 0.0, with_slack(budget))
    assert may_be_heard(np.array([90.0, 95.0]), 6.0, with_slack(budget)).tolist() == [True, False]
