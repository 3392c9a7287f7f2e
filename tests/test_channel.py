"""The channel: who receives, when, what is lost, and how it is counted."""

import math

import numpy as np
import pytest

from netsim.radio.channel import DROP_CAUSES
from netsim.radio.loss import DistanceLoss, GilbertElliottLoss
from netsim.run import build, simulation
from tests.fixtures import make_config, static_core


def _static_sim(positions, ranges=10.0, **channel):
    n = len(positions)
    cfg = make_config(
        world={"n_robots": n, "side_m": 1000.0},
        mobility={"model": "static"},
        channel={"range_m": ranges if np.isscalar(ranges) else list(ranges), **channel},
        protocol={"model": "none"},
    )
    sim = build(cfg)
    sim.state.place(np.asarray(positions, dtype=float))
    return sim


def test_broadcast_reaches_exactly_the_robots_in_range_at_send_time():
    sim = _static_sim([[0, 0], [10, 0], [10.0001, 0], [0, 9.99], [500, 500]])
    got = []
    sim.channel.broadcast(0, "hello", lambda s, r, p: got.append((sim.env.now, s, r.tolist(), p)))
    sim.env.run(until=1)
    assert got == [(pytest.approx(0.001), 0, [1, 3], "hello")]


def test_receivers_are_decided_at_send_time():
    """A robot that leaves the range while the message is in flight still receives it."""
    sim = _static_sim([[0, 0], [9, 0]], latency_s=0.5)
    got = []
    sim.channel.broadcast(0, None, lambda s, r, p: got.extend(r.tolist()))
    sim.state.set_leg(1, 0.0, (100.0, 0.0))  # gone from range in 0.01 s
    sim.env.run(until=1)
    assert got == [1]


def test_one_delivery_per_broadcast_without_jitter():
    """Without latency jitter a broadcast is one delivery: one entry scheduled, and the
    callback called once, with every receiver (not once per receiver)."""
    sim = _static_sim([[0, 0]] + [[1 + i * 0.1, 0] for i in range(20)])
    calls = []
    sim.channel.broadcast(0, None, lambda s, r, p: calls.append(r.tolist()))
    assert len(sim.channel.agenda) == 1
    sim.env.run(until=1)
    assert calls == [list(range(1, 21))]


def test_jitter_delays_each_reception_within_bounds():
    sim = _static_sim([[0, 0]] + [[1, 0]] * 50, latency_s=0.01, latency_jitter_s=0.02)
    times = []
    sim.channel.broadcast(0, None, lambda s, r, p: times.append(sim.env.now))
    sim.env.run(until=1)
    assert len(times) == 50
    assert min(times) >= 0.01 and max(times) <= 0.03 and len(set(times)) > 40


def test_unequal_ranges_give_one_way_links():
    sim = _static_sim([[0, 0], [10, 0]], ranges=[15.0, 5.0])
    heard = []
    sim.channel.broadcast(0, None, lambda s, r, p: heard.append((s, r.tolist())))
    sim.channel.broadcast(1, None, lambda s, r, p: heard.append((s, r.tolist())))
    sim.env.run(until=1)
    assert heard == [(0, [1])]


def test_unicast_out_of_range_is_a_counted_drop():
    sim = _static_sim([[0, 0], [50, 0], [5, 0]])
    assert not sim.channel.unicast(0, 1, None, lambda *a: None)
    assert sim.channel.unicast(0, 2, None, lambda *a: None)
    sim.env.run(until=1)
    c = sim.channel.counters_for("data")
    assert c.sent[0] == 2
    assert c.dropped[DROP_CAUSES.index("out_of_range"), 1] == 1
    assert c.received.tolist() == [0, 0, 1]


@pytest.mark.parametrize("torus", [False, True])
def test_a_unicast_reaches_exactly_whom_a_broadcast_reaches(torus):
    """Unicast and broadcast agree on "in range" where the distances are exact: robots
    exactly at the range (along an axis, on a 6-8-10 diagonal, across the torus's edge) hear
    both, robots a picometre beyond hear neither (the range is inclusive for both)."""
    x0 = 995.0 if torus else 0.0  # on the torus the receivers are across the edge, at x = 5
    x = 5.0 if torus else 10.0
    positions = [[x0, 7.0], [x, 7.0], [x + 1e-12, 7.0], [x - 4.0, 15.0], [x - 4.0, 15.0 + 1e-12]]
    cfg = make_config(
        world={"n_robots": len(positions), "side_m": 1000.0, "torus": torus},
        mobility={"model": "static"},
        channel={"range_m": 10.0},
        protocol={"model": "none"},
    )
    sim = build(cfg)
    sim.state.place(np.array(positions))
    heard = []
    sim.channel.broadcast(0, None, lambda s, rx, p: heard.extend(rx.tolist()))
    sim.env.run(until=1)
    by_unicast = [k for k in range(1, len(positions)) if sim.channel.unicast(0, k, None, lambda *a: None)]
    assert heard == by_unicast == [1, 3]


def test_a_unicast_measures_its_pair_as_the_range_query_does():
    """On a torus, with every receiver set exactly at the range the sender's range query
    measures to it (and then at the next float below), a unicast is heard exactly when the
    query finds the robot: one offset, one distance, one comparison."""
    rng = np.random.default_rng(5)
    n, side = 200, 100.0
    cfg = make_config(
        world={"n_robots": n, "side_m": side, "torus": True},
        mobility={"model": "static"},
        channel={"range_m": 30.0},
        protocol={"model": "none"},
    )
    sim = build(cfg)
    st = sim.state
    st.place(rng.uniform(0.0, side, (n, 2)))
    # Many robots cross the edges (their legs run on unfolded).
    st.set_legs(np.arange(n), 0.0, rng.uniform(-10.0, 10.0, (n, 2)))
    sim.env.run(until=13.3)
    for sender in range(3):
        ids, dist = sim.channel.index.within(sim.env.now, sender, 30.0)
        assert len(ids) > 30
        for k, d in zip(ids.tolist(), dist.tolist()):
            st.range_m[sender] = d
            assert sim.channel.unicast(sender, k, None, lambda *a: None)
            st.range_m[sender] = np.nextafter(d, 0.0)
            assert not sim.channel.unicast(sender, k, None, lambda *a: None)
    with pytest.raises(IndexError):
        sim.channel.index.pair_within(sim.env.now, 0, n, 30.0)


def test_switched_off_robot_is_a_counted_drop():
    sim = _static_sim([[0, 0], [5, 0], [6, 0]])
    sim.state.alive[2] = False
    got = []
    sim.channel.broadcast(0, None, lambda s, r, p: got.extend(r.tolist()))
    sim.env.run(until=1)
    assert got == [1]
    assert sim.channel.counters_for("ack").dropped[DROP_CAUSES.index("not_alive"), 2] == 1


def test_bernoulli_loss_counts_add_up():
    """Item 10 in the small: sent receptions = received + dropped, and the loss rate is p."""
    sim = _static_sim([[0, 0]] + [[1, 0]] * 100, loss_probability=0.3)
    for _ in range(100):
        sim.channel.broadcast(0, None, lambda *a: None)
    sim.env.run(until=1)
    c = sim.channel.counters_for("ack")
    total = c.received.sum() + c.dropped[0].sum()
    assert total == 100 * 100
    assert c.dropped[0].sum() / total == pytest.approx(0.3, abs=4 * math.sqrt(0.21 / total))


def test_distance_loss_follows_its_law():
    rng = np.random.default_rng(1)
    model = DistanceLoss(0.1, 2.0, np.array([10.0]), rng)
    for d in (0.0, 5.0, 9.0):
        keep = model(0, np.zeros(50_000, dtype=np.int64), np.full(50_000, d))
        p = 0.9 * (1 - (d / 10) ** 2)
        assert keep.mean() == pytest.approx(p, abs=4 * math.sqrt(p * (1 - p) / 50_000) + 1e-9)


def test_distance_loss_takes_the_senders_range():
    """With unequal ranges the law is the sender's: a sender of range 10 m reaching a
    robot of range 20 m at 8 m gets through with 0.9 (1 - 0.64), not 0.9 (1 - 0.16)."""
    model = DistanceLoss(0.1, 2.0, np.array([10.0, 20.0]), np.random.default_rng(3))
    keep = model(0, np.ones(50_000, dtype=np.int64), np.full(50_000, 8.0))
    p = 0.9 * (1 - 0.8**2)
    assert keep.mean() == pytest.approx(p, abs=4 * math.sqrt(p * (1 - p) / 50_000))


def test_gilbert_elliott_first_frame_on_a_link_is_lost_at_the_stationary_rate():
    """A link's first transmission starts the chain in its stationary law (no warm-up):
    over many links each seen once, the loss rate is pi_bad = p_gb / (p_gb + p_bg), as
    over one link's long run."""
    n = 50_001
    model = GilbertElliottLoss(0.05, 0.25, 0.0, 1.0, n, np.random.default_rng(4))
    lost = ~model(0, np.arange(1, n, dtype=np.int64), None)
    pi_bad = 0.05 / 0.30
    assert lost.mean() == pytest.approx(pi_bad, abs=4 * math.sqrt(pi_bad * (1 - pi_bad) / (n - 1)))


def test_distance_loss_under_shadowing_is_refused_by_name():
    """The distance law falls to no reception at the range; a shadowed radio hears beyond
    it, and every such frame was lost: refused, naming the key. Log-distance without
    shadowing (whose reach is the range) keeps it."""
    from netsim.errors import ConfigError

    shadowed = {"propagation": "log_distance", "shadowing_sigma_db": 6.0, "loss_model": "distance"}
    with pytest.raises(ConfigError, match=r"channel.loss_model = 'distance': falls to no reception at the range"):
        make_config(channel=shadowed)
    make_config(channel={"propagation": "log_distance", "loss_model": "distance"})


@pytest.mark.slow
def test_gilbert_elliott_loss_is_bursty_with_the_right_mean():
    """Long-run loss = pi_bad * loss_bad + pi_good * loss_good; losses cluster."""
    model = GilbertElliottLoss(0.05, 0.25, 0.0, 1.0, 2, np.random.default_rng(2))
    keep = np.array([model(0, np.array([1]), np.array([1.0]))[0] for _ in range(100_000)])
    lost = ~keep
    pi_bad = 0.05 / 0.30
    assert lost.mean() == pytest.approx(pi_bad, abs=0.01)
    after_loss = lost[1:][lost[:-1]].mean()
    assert after_loss == pytest.approx(0.75, abs=0.02)  # stays bad with 1 - p_bg
    assert after_loss > 3 * lost.mean()


@pytest.mark.slow
def test_observed_delivery_ratio_in_a_run():
    """Item 10: over all in-range pairs, the fraction of Ack receptions delivered is 1 - p,
    within its binomial confidence interval."""
    p = 0.25
    cfg = make_config(
        seed=3,
        duration_s=60.0,
        world={"n_robots": 60, "side_m": 400.0},
        channel={"loss_probability": p, "range_m": 100.0},
        output={"position_interval_s": 0.0},
    )
    sim = build(cfg)
    sim.run()
    c = sim.channel.counters_for("ack")
    received, lost = c.received.sum(), c.dropped[0].sum()
    n = received + lost
    assert n > 10_000
    assert received / n == pytest.approx(1 - p, abs=4 * math.sqrt(p * (1 - p) / n))


def test_loss_off_draws_nothing():
    """Turning loss off must not consume random numbers (other draws stay put)."""
    sim = simulation(make_config(world={"n_robots": 2}))
    before = sim.channel.survives.rng.bit_generator.state
    assert sim.channel.survives(0, np.array([1]), np.array([1.0])) is None
    assert sim.channel.survives.rng.bit_generator.state == before


def test_a_loss_model_set_after_the_channel_is_built_gets_the_distances():
    """The channel measures receivers' distances when its loss model reads them (a callable
    without ``uses_distances`` is taken to), also for one put in place after it was built;
    one that says it reads none gets None."""
    sim = static_core([[0.0, 0.0], [3.0, 0.0], [8.0, 0.0]], range_m=10.0)
    seen = []

    def near_only(sender, receivers, distances_m):
        seen.append(distances_m)
        return distances_m < 5.0

    sim.channel.survives = near_only
    got = sim.channel.broadcast(0, "x", lambda *a: None, kind="ack")
    assert got.tolist() == [1] and seen[-1].tolist() == [3.0, 8.0]

    def blind(sender, receivers, distances_m):
        seen.append(distances_m)
        return None

    blind.uses_distances = False  # type: ignore[attr-defined]
    sim.channel.survives = blind
    assert sim.channel.broadcast(0, "x", lambda *a: None, kind="ack").tolist() == [1, 2]
    assert seen[-1] is None
