"""The medium's signal power: what the radio found for each pair (docs/radio.md, "Shared medium")."""

import numpy as np
import pytest

from netsim.radio.propagation import LogDistanceParams, log_distance
from netsim.radio.reception import Reception
from netsim.radio.shadowing import PairShadowing
from netsim.world.examples import SIDE_M
from netsim.world.maps import load_map
from tests.test_radio_fast import _moving_state


@pytest.mark.parametrize(("sigma_db", "wall_db", "with_map"), [(6.0, 4.0, True), (6.0, 0.0, False), (0.0, 4.0, True)])
def test_received_power_is_at_the_sensitivity_exactly_for_the_pairs_the_radio_keeps(sigma_db, wall_db, with_map):
    """Reception.received_dbm, right after a decision, is the power that decision compared
    with the sensitivity (path loss + the pair's shadowing + walls): at or above it for the
    kept receivers, below it for the others."""
    params = LogDistanceParams(shadowing_sigma_db=sigma_db, sensitivity_dbm=-70.0, wall_loss_db=wall_db)
    st, t, rng = _moving_state(4, n=120, side=SIDE_M if with_map else 400.0)
    sh = PairShadowing(sigma_db, 30.0, np.random.default_rng(5), 0.0, n_robots=st.n) if sigma_db > 0 else None
    rec = Reception(log_distance(params, sh, load_map("office") if with_map else None), st)
    kept_total = 0
    for sender in rng.choice(st.n, 40).tolist():
        ids = np.delete(np.arange(st.n), sender)
        d = st.displacement(st.positions_at(t, ids), st.positions_at(t, [sender]))
        dist = np.hypot(d[:, 0], d[:, 1])
        kept = rec.decide(t, sender, ids, dist)
        dbm = rec.received_dbm(t, sender, ids, dist)
        assert np.array_equal(dbm >= params.sensitivity_dbm, kept)
        kept_total += int(kept.sum())
        t += 0.25
    assert kept_total > 0


def test_received_power_takes_the_shadowing_clipped_as_the_decision_does(monkeypatch):
    """A pair's loss takes its shadowing clipped to 4 sigma (the stored state is not):
    the power reported for a pair whose shadowing lies beyond the clip is the power at the
    clip, so that it agrees with the decision."""
    params = LogDistanceParams(shadowing_sigma_db=6.0, sensitivity_dbm=-70.0)
    st, t, _ = _moving_state(4, n=20, side=400.0)
    sh = PairShadowing(6.0, 30.0, np.random.default_rng(5), 0.0, n_robots=st.n)
    rec = Reception(log_distance(params, sh), st)
    ids = np.arange(1, st.n)
    d = st.displacement(st.positions_at(t, ids), st.positions_at(t, [0]))
    dist = np.hypot(d[:, 0], d[:, 1])
    rec.decide(t, 0, ids, dist)

    def power_at(x_db):
        monkeypatch.setattr(rec.compiled.shadow, "state", lambda a, b: (np.full(len(b), x_db), np.zeros(len(b))))
        return rec.received_dbm(t, 0, ids, dist)

    assert sh.clip_db == 24.0
    assert np.array_equal(power_at(1e3), power_at(24.0))
    assert np.array_equal(power_at(-1e3), power_at(-24.0))
    assert not np.array_equal(power_at(24.0), power_at(0.0))


def test_a_robot_senses_the_medium_idle_only_with_no_frame_on_the_air_and_none_of_its_own():
    """The one rule of an idle medium (netsim.radio._mac_kernels.senses_idle), as the frame's
    start, its end and a new contention all read it: idle iff no other sender's frame covers
    the robot and it sends none itself."""
    from netsim.compiled import load

    cover = np.array([0, 1, 0, 2])
    sending = np.array([False, False, True, True])
    for kernels in (load("netsim.radio._mac_kernels", 1), load("netsim.radio._mac_kernels", 1000)):
        out = np.empty(4, dtype=bool)
        kernels.idle_among(cover, sending, np.arange(4), out)
        assert out.tolist() == [True, False, False, False]
        assert [bool(kernels.senses_idle(cover, sending, c)) for c in range(4)] == out.tolist()
