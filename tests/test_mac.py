"""The shared medium (channel.mac): airtime, collisions, half duplex, carrier sense, queues."""

import math

import numpy as np
import pytest

from netsim.errors import ConfigError
from netsim.radio.channel import DROP_CAUSES
from netsim.radio.mac import MAC_DROP_CAUSES, airtime_s
from netsim.radio.receptions import ReceptionLog
from netsim.run import execute, tables
from netsim.simpy_internals import kernel_queue
from netsim.tools import mac_checks
from tests.fixtures import make_config

T = 1e-3  # airtime of the test frames: 125 bytes at 1 Mb/s, no preamble


def _medium(xs, mac="aloha", range_m=50.0, **channel):
    pos = np.column_stack([np.asarray(xs, dtype=float) + 100.0, np.full(len(xs), 100.0)])
    keys = {"preamble_s": 0.0, "data_rate_bps": 1e6, "latency_s": 0.0, **channel}
    sim = mac_checks.medium_run(pos, mac, range_m=range_m, **keys)
    sim.channel.frame_bytes["f"] = 125
    return sim


def _send_at(sim, t, sender, log=None, dest=-1):
    def deliver(s, r, _p):
        if log is not None:
            log.append((sim.env.now, s, r.tolist()))

    ev = sim.env.timeout(t)
    if dest < 0:
        ev.callbacks.append(lambda _e: sim.channel.broadcast(sender, None, deliver, kind="f"))
    else:
        ev.callbacks.append(lambda _e: sim.channel.unicast(sender, dest, None, deliver, kind="f"))


def _dropped(sim, cause, robot=None):
    c = sim.channel.counters_for("f")
    row = c.dropped[sim.channel.causes.index(cause)]
    return int(row.sum() if robot is None else row[robot])


def test_airtime_is_bytes_times_eight_over_the_rate_plus_the_preamble():
    """A frame occupies the medium for preamble + 8 bytes / rate."""
    assert airtime_s(64, 1e6, 192e-6) == pytest.approx(704e-6)
    assert airtime_s(1500, 11e6, 0.0) == pytest.approx(1500 * 8 / 11e6)


def test_a_frame_is_delivered_at_its_end_plus_the_latency():
    """Delivery happens at the frame's end (+ latency), to every robot in range."""
    sim = _medium([0, 10, 20], latency_s=0.002)
    log = []
    _send_at(sim, 0.5, 0, log)
    sim.env.run()
    assert log == [(pytest.approx(0.5 + T + 0.002), 0, [1, 2])]


def test_the_busy_fraction_counts_a_frame_still_on_the_air():
    """Medium.busy_fraction: the share of the run each robot sensed the medium busy, its own
    frame and the stretch not over yet included; a robot out of range never."""
    sim = _medium([0, 10, 100])
    _send_at(sim, 0.5, 0)
    sim.env.run(until=0.5 + T / 2)
    now = sim.env.now
    busy = sim.channel.mac.busy_fraction(now)
    assert busy.tolist() == [(now - 0.5) / now, (now - 0.5) / now, 0.0]
    sim.env.run(until=1.0)
    assert sim.channel.mac.busy_fraction(1.0).tolist() == pytest.approx([T, T, 0.0], rel=1e-12)


def test_overlapping_frames_collide_at_a_common_receiver():
    """Unit disk: a receiver in range of two overlapping transmissions loses both."""
    sim = _medium([0, 40, 80])  # 0 and 2 out of each other's range, 1 hears both
    log = []
    _send_at(sim, 0.0, 0, log)
    _send_at(sim, T / 2, 2, log)
    sim.env.run()
    assert _dropped(sim, "collision", robot=1) == 2
    assert sim.channel.counters_for("f").received.sum() == 0


def test_frames_that_do_not_overlap_both_arrive():
    """Back to back (the second starts when the first ends) is not an overlap."""
    sim = _medium([0, 40, 80])
    _send_at(sim, 0.0, 0)
    _send_at(sim, T * 1.0001, 2)
    sim.env.run()
    assert _dropped(sim, "collision") == 0
    assert sim.channel.counters_for("f").received[1] == 2


def test_a_robot_cannot_receive_while_it_transmits():
    """Half duplex: a robot that transmits during a frame loses it (cause half_duplex)."""
    sim = _medium([0, 10])
    _send_at(sim, 0.0, 0)
    _send_at(sim, T / 2, 1)
    sim.env.run()
    assert _dropped(sim, "half_duplex", robot=1) == 1
    assert _dropped(sim, "half_duplex", robot=0) == 1
    assert _dropped(sim, "collision") == 0


def test_a_larger_interference_range_disturbs_beyond_the_range():
    """channel.interference_range_m > range: a sender out of range still collides."""
    for interference, lost in ((0.0, 0), (100.0, 1)):
        sim = _medium([0, 40, 120], interference_range_m=interference)  # 2 is 80 m from 1
        _send_at(sim, 0.0, 0)
        _send_at(sim, T / 2, 2)
        sim.env.run()
        assert _dropped(sim, "collision", robot=1) == lost


def test_the_default_interference_range_covers_the_reach_under_shadowing():
    """log_distance, interference_range_m = 0: the range where the mean power meets the noise
    floor, or the radio's reach where that is farther (strong shadowing): a robot the frame
    could reach is among those it disturbs, and the medium says which range it uses."""
    for sigma_db, beyond in ((0.0, False), (6.0, True)):
        sim = _medium([0, 600], propagation="log_distance", shadowing_sigma_db=sigma_db)
        medium, reach = sim.channel.mac, sim.channel.reception.reach_m
        noise_range = medium.power.noise_range_m
        assert medium.interference_range_m == max(noise_range, reach)
        assert (reach > noise_range) == beyond  # only strong shadowing reaches past the noise floor
        _send_at(sim, 0.0, 0)
        sim.env.run(until=T / 2)
        assert medium.cover[1] == int(beyond)  # robot 1, 600 m away, senses the frame


def test_the_stronger_frame_survives_under_log_distance():
    """log_distance: reception needs SINR >= capture threshold; the near sender captures."""
    keys = {"propagation": "log_distance", "capture_threshold_db": 10.0}
    sim = _medium([0, 5, 90], **keys)  # 1 is 5 m from 0, 85 m from 2
    _send_at(sim, 0.0, 0)
    _send_at(sim, T / 2, 2)
    sim.env.run()
    c = sim.channel.counters_for("f")
    assert c.received[1] == 1  # 0's frame, 25 dB above 2's
    assert _dropped(sim, "collision", robot=1) == 1  # 2's frame
    # Equal distances: neither captures.
    sim = _medium([0, 45, 90], **keys)
    _send_at(sim, 0.0, 0)
    _send_at(sim, T / 2, 2)
    sim.env.run()
    assert _dropped(sim, "collision", robot=1) == 2


def test_capture_counts_the_noise_floor_in_the_sinr():
    """log_distance: a frame is received iff rx / (noise + interference) >= capture
    threshold. Robot 1 gets 0's frame 1.4 dB above the sensitivity (-80 dBm), 16.4 dB over
    the noise floor (-95 dBm); a far sender, 2, overlaps it and reaches 1 at -94.7 dBm,
    about the noise floor. With the threshold at its largest (15 dB: sensitivity less
    noise), 0's frame alone is received, but noise plus 2's frame gives an SINR of 13.2 dB:
    a collision. Over the interference alone (16.1 dB) it would pass: a medium that left the
    noise out of the SINR received it."""
    keys = {"propagation": "log_distance", "sensitivity_dbm": -80.0, "noise_floor_dbm": -95.0}
    keys["capture_threshold_db"] = 15.0
    sim = _medium([0, 90, 400], **keys)  # 1 is 90 m from 0, 310 m from 2; 0 and 2 are 400 m apart
    assert sim.channel.mac.interference_range_m > 310.0  # 2's frame counts at 1
    _send_at(sim, 0.0, 0)
    sim.env.run()
    assert sim.channel.counters_for("f").received.tolist() == [0, 1, 0]  # noise alone: kept
    sim = _medium([0, 90, 400], **keys)
    sim.channel.receptions = log = ReceptionLog(sim.channel)
    got = []
    _send_at(sim, 0.0, 0, got)
    _send_at(sim, T / 2, 2, got)
    sim.env.run()
    assert got == [] and sim.channel.counters_for("f").received.sum() == 0
    assert _dropped(sim, "collision", robot=1) == 1
    rows = log.frame(sim.state.legs(), sim.state.n)
    assert rows[["src", "dst", "cause"]].values.tolist() == [[0, 1, "collision"]]
    signal, sinr = rows.rx_power_dbm[0], rows.sinr_db[0]
    jam_dbm = 20.0 - 40.0 - 30.0 * np.log10(310.0)  # 2's frame at 1: P_t, loss at 1 m, exponent 3
    assert signal == pytest.approx(20.0 - 40.0 - 30.0 * np.log10(90.0), abs=1e-9)
    assert sinr == pytest.approx(signal - 10 * np.log10(10 ** (-9.5) + 10 ** (jam_dbm / 10)), abs=1e-9)
    assert sinr < 15.0 < signal - jam_dbm  # below the threshold with the noise, above it without


def test_capture_decides_on_the_sinr_it_records():
    """log_distance: the SINR a reception records is the number the capture threshold is
    compared with, so a frame whose SINR equals the threshold is received and its row says
    so (received iff sinr_db >= capture_threshold_db, to the last bit). Robot 2's frame
    overlaps 0's at 1; the threshold is set to 0's SINR there, at a position of 2 where
    comparing the powers in mW instead (rx < capture (noise + I)) rounds the other way."""
    keys = {"propagation": "log_distance", "sensitivity_dbm": -80.0, "noise_floor_dbm": -95.0}
    power = _medium([0, 90], **keys).channel.mac.power
    signal = float(power.received_mw(np.array([90.0]))[0])
    for far in np.arange(300.0, 330.0, 0.01):
        jam = float(power.received_mw(np.array([far]))[0])
        # The medium's sums: the load at 1 while both frames are on the air, less 0's own.
        interference = max((signal + jam) - signal, 0.0)
        sinr_db = float(10.0 * np.log10(signal / (power.noise_mw + interference)))
        if signal < 10.0 ** (sinr_db / 10.0) * (power.noise_mw + interference):
            break
    else:
        pytest.fail("no position where the two comparisons round apart")
    assert 0.0 < sinr_db < 15.0
    sim = _medium([0, 90, 90 + far], capture_threshold_db=sinr_db, **keys)
    assert sim.channel.mac.interference_range_m > far  # 2's frame counts at 1
    sim.channel.receptions = log = ReceptionLog(sim.channel)
    _send_at(sim, 0.0, 0)
    _send_at(sim, T / 2, 2)
    sim.env.run()
    rows = log.frame(sim.state.legs(), sim.state.n)
    row = rows[(rows["src"] == 0) & (rows["dst"] == 1)].iloc[0]
    assert row["sinr_db"] == sinr_db
    assert bool(row["received"]) and sim.channel.counters_for("f").received[1] == 1


class _Draws:
    """A stand-in for the CSMA stream: hands out the given backoffs in order."""

    def __init__(self, *slots):
        self.slots = list(slots)

    def integers(self, high):
        k = self.slots.pop(0)
        assert 0 <= k < high
        return k


SLOT, DIFS = 20e-6, 50e-6


def test_csma_defers_while_the_medium_is_busy():
    """CSMA: a robot that senses a frame on the air waits for its end, DIFS and its backoff."""
    sim = _medium([0, 10, 20], mac="csma")
    sim.channel.mac.rng = _Draws(0, 5)
    log = []
    _send_at(sim, 0.0, 0, log)
    _send_at(sim, T / 2, 1, log)
    sim.env.run()
    assert _dropped(sim, "collision") == 0 and _dropped(sim, "half_duplex") == 0
    (t0, s0, _), (t1, s1, _) = log
    assert (s0, s1) == (0, 1)
    start1 = t1 - T
    assert start1 >= t0 + 50e-6 - 1e-12
    slots = (start1 - t0 - 50e-6) / 20e-6
    assert slots == pytest.approx(5, abs=1e-6)  # its whole draw: it never counted before 0's frame


@pytest.mark.parametrize(
    ("b_at", "c_at", "slots_left"),
    [
        # C's frame starts 2.5 slots into B's countdown: two idle slots and the busy period
        # count, B resumes with k - 3.
        (0.0, 2.5 * SLOT, 7),
        # C's frame starts during B's DIFS: nothing counted, B resumes with k.
        (DIFS / 2, 0.0, 10),
    ],
)
def test_csma_freezes_the_backoff_and_resumes_it_after_difs(b_at, c_at, slots_left):
    """CSMA freeze rule: B (backoff k = 10) counts down after DIFS of idle medium; when C's
    frame starts, B keeps the slots left minus one for the busy period (none if still in
    DIFS), and transmits at end_C + DIFS + slots_left slots."""
    sim = _medium([0, 10], mac="csma", latency_s=0.0)
    draws = {0: 10, 1: 0}  # B is 0, C is 1 (C sends DIFS after its hand-over)
    order = sorted(draws, key=lambda r: (b_at, c_at)[r])
    sim.channel.mac.rng = _Draws(*(draws[r] for r in order))
    log = []
    _send_at(sim, b_at, 0, log)
    _send_at(sim, c_at, 1, log)
    sim.env.run()
    (end_c, s_c, _), (end_b, s_b, _) = log
    assert (s_c, s_b) == (1, 0)
    assert end_c == pytest.approx(c_at + DIFS + T, abs=1e-12)
    assert end_b - T == pytest.approx(end_c + DIFS + slots_left * SLOT, abs=1e-12)


def test_csma_a_frame_queued_behind_the_head_frame_leaves_its_backoff_as_drawn():
    """CSMA draws a backoff for a robot's head frame only: a frame queued while the head
    frame counts down waits its turn and takes its own draw when the head frame leaves the
    air. Robot 0 hands over A (backoff 5), then B two slots into A's countdown: A goes out
    after DIFS and its 5 slots, B after A, DIFS and its own 3. A second draw for A when B
    was queued restarted A's countdown."""
    sim = _medium([0, 10], mac="csma")
    sim.channel.mac.rng = draws = _Draws(5, 3, 3)
    log = []
    _send_at(sim, 0.0, 0, log)
    _send_at(sim, DIFS + 2.5 * SLOT, 0, log)
    sim.env.run()
    (end_a, _, _), (end_b, _, _) = log
    assert end_a == pytest.approx(DIFS + 5 * SLOT + T, abs=1e-12)
    assert end_b == pytest.approx(end_a + DIFS + 3 * SLOT + T, abs=1e-12)
    assert draws.slots == [3]  # two draws, one per frame


def test_aloha_does_not_defer():
    """ALOHA transmits at once, busy medium or not."""
    sim = _medium([0, 10, 20])
    log = []
    _send_at(sim, 0.0, 0, log)
    _send_at(sim, T / 2, 1, log)
    sim.env.run()
    assert _dropped(sim, "half_duplex") == 2


def test_a_full_queue_drops_the_frame_at_the_sender():
    """channel.queue_frames bounds a robot's queue; a frame beyond it counts queue_full at its sender's row."""
    sim = _medium([0, 10], mac="csma", queue_frames=2)
    for _ in range(3):
        _send_at(sim, 0.0, 0)
    sim.env.run()
    assert _dropped(sim, "queue_full", robot=0) == 1
    assert sim.channel.counters_for("f").received[1] == 2


def test_a_unicast_is_retried_up_to_the_retry_limit():
    """CSMA: a unicast that fails is sent again, at most retry_limit times, then dropped (retry_limit)."""
    sim = _medium([0, 10, 200], mac="csma", retry_limit=3)
    log = []
    _send_at(sim, 0.0, 0, log, dest=2)  # out of range: every attempt fails
    sim.channel.notify_empty.add("f")
    sim.env.run()
    assert sim.channel.mac.attempts == 4
    assert _dropped(sim, "out_of_range", robot=2) == 4
    assert _dropped(sim, "retry_limit", robot=0) == 1
    assert log and log[0][2] == []


class _Highs:
    """A stand-in for the medium's generator that records each backoff's range and draws 0."""

    def __init__(self):
        self.highs = []

    def integers(self, high):
        self.highs.append(int(high))
        return 0


def test_csma_backoff_is_uniform_on_0_to_cw_and_cw_doubles_per_failed_try():
    """802.11's backoff: uniform on 0..CW, both ends included (cw_min = 31 gives 32 values),
    CW doubling (2 CW + 1) after each failed try of a unicast, up to cw_max."""
    sim = _medium([0, 10, 200], mac="csma", retry_limit=3, cw_min=15, cw_max=63)
    sim.channel.mac.rng = draws = _Highs()
    _send_at(sim, 0.0, 0, dest=2)  # out of range: every try fails
    sim.env.run()
    assert draws.highs == [16, 32, 64, 64]


def test_aloha_sends_a_failed_unicast_once():
    """ALOHA: a unicast that reaches nobody is not sent again, and counts no retry_limit drop."""
    sim = _medium([0, 10, 200], mac="aloha")
    log = []
    _send_at(sim, 0.0, 0, log, dest=2)  # out of range: the attempt fails
    sim.channel.notify_empty.add("f")
    sim.env.run()
    assert sim.channel.mac.attempts == 1
    assert _dropped(sim, "out_of_range", robot=2) == 1
    assert _dropped(sim, "retry_limit") == 0
    assert log and log[0][2] == []


def test_a_frame_costs_a_bounded_number_of_kernel_events():
    """O(1) kernel events per frame, whatever the number of receivers or contenders: at most
    a wake-up (handing it over can move the earliest transmit instant), its end and its
    delivery; never one per backoff slot or per contender."""
    n = 60
    sim = _medium(np.linspace(0, 10, n), mac="csma")
    for i in range(n):
        sim.channel.broadcast(i, None, lambda s, r, p: None, kind="f")
    steps = 0
    while kernel_queue(sim.env):
        sim.env.step()
        steps += 1
    assert sim.channel.mac.attempts == n
    assert steps <= 3 * n


def test_mac_none_is_the_channel_of_infinite_capacity():
    """channel.mac = "none": no medium, the channel's own drop causes and tables."""
    cfg = make_config(channel={"mac": "none"})
    assert cfg.channel.mac == "none"
    assert tables(cfg) == tables(make_config())
    res = execute(make_config(world={"n_robots": 8}, duration_s=5.0, protocol={"model": "ack"}))
    assert res.sim.channel.mac is None
    assert list(res.frames["acks"].columns) == ["robot", "sent", "received"] + [f"dropped_{c}" for c in DROP_CAUSES]
    assert "channel_utilisation" not in res.summary


@pytest.mark.slow
@pytest.mark.parametrize("mac", ["aloha", "csma"])
def test_the_protocol_runs_on_any_mac(mac):
    """Clustering and relaying run unchanged on a medium; the tables gain its drop causes."""
    cfg = make_config(
        world={"n_robots": 20, "side_m": 300.0},
        duration_s=20.0,
        channel={"range_m": 100.0, "mac": mac},
        protocol={"message_rate_hz": 1.0},
    )
    res = execute(cfg)
    acks = res.frames["acks"]
    assert list(acks.columns)[3:] == [f"dropped_{c}" for c in MAC_DROP_CAUSES]
    assert list(res.frames["medium"].columns) == list(tables(cfg)["medium"])
    assert list(res.frames["ack_delivery"].columns) == list(tables(cfg)["ack_delivery"])
    msgs = res.frames["messages"]
    assert list(msgs.columns) == list(tables(cfg)["messages"])
    assert msgs[[f"dropped_{c}" for c in MAC_DROP_CAUSES[3:]]].to_numpy().min() >= 0
    s = res.summary
    assert 0 < s["channel_utilisation"] < 1 and 0 <= s["collision_ratio"] < 1
    medium = res.frames["medium"]
    collided = int(medium["dropped_collision"].sum())
    decided = collided + int(medium[["received", "dropped_half_duplex"]].sum().sum())
    assert s["receptions_dropped_collision"] == collided
    assert s["collision_ratio"] == pytest.approx(collided / decided)
    assert s["messages"] > 0 and s["acks_received"] > 0
    again = execute(cfg)
    pd_equal = [res.frames[k].equals(again.frames[k]) for k in res.frames]
    assert all(pd_equal)  # the same seed, the same outputs


@pytest.mark.parametrize(
    ("keys", "bad"),
    [
        ({"mac": "tdma"}, "channel.mac"),
        ({"mac": "csma", "cw_min": 30}, "channel.cw_min"),
        ({"mac": "csma", "cw_min": 0}, "channel.cw_min"),  # 2^0 - 1: no backoff at all
        ({"mac": "csma", "cw_min": 63, "cw_max": 31}, "channel.cw_max"),
        ({"mac": "csma", "range_m": 100.0, "interference_range_m": 50.0}, "channel.interference_range_m"),
        ({"mac": "aloha", "propagation": "log_distance", "noise_floor_dbm": -85.0}, "channel.noise_floor_dbm"),
        ({"mac": "aloha", "data_rate_bps": 0}, "channel.data_rate_bps"),
        ({"mac": "csma", "propagation": "log_distance", "interference_range_m": 10.0}, "channel.interference_range_m"),
        ({"mac": "csma", "data_rate_bps": 1.0}, "channel.data_rate_bps"),  # an Ack would take 512 s
    ],
)
def test_medium_keys_are_validated(keys, bad):
    """A bad medium key is an error naming the key."""
    with pytest.raises(ConfigError, match=bad.replace(".", r"\.")) as err:
        make_config(channel=keys)
    assert err.value.key == bad


def test_an_interference_range_of_at_least_the_reach_is_accepted_under_log_distance():
    """log_distance: interference_range_m may be 0 (the noise-floor distance) or at least the reach."""
    for r in (0.0, 100.0, 400.0):
        assert make_config(channel={"mac": "csma", "propagation": "log_distance", "interference_range_m": r})


@pytest.mark.slow
def test_aloha_periodic_success_follows_the_closed_form():
    """ALOHA, periodic frames at random phases: success (1 - 2T/t)^(n-1)."""
    c = mac_checks.aloha_periodic(n=8, airtime_ratio=0.03, rounds=200, seed=3)
    assert abs(c.measured - c.theory) <= c.tolerance


@pytest.mark.slow
def test_aloha_poisson_success_follows_the_closed_form():
    """ALOHA, Poisson load G: success e^(-2G)."""
    c = mac_checks.aloha_poisson(n=30, load=0.3, frames=8000, seed=4)
    assert abs(c.measured - c.theory) <= c.tolerance


@pytest.mark.slow
def test_hidden_terminals_lose_like_an_aloha_pair():
    """Hidden terminals under CSMA: B loses like an ALOHA pair; A and B alone, both sending,
    lose at most the same-slot bound. Under ALOHA the control fails (B's own frames)."""
    hidden, alone = mac_checks.hidden_terminals(airtime_ratio=0.05, rounds=500, seed=5)
    assert abs(hidden.measured - hidden.theory) <= hidden.tolerance
    assert alone.tolerance < 0.01 and abs(alone.measured - alone.theory) <= alone.tolerance
    _, aloha = mac_checks.hidden_terminals(airtime_ratio=0.05, rounds=500, seed=5, mac="aloha")
    assert abs(aloha.measured - aloha.theory) > aloha.tolerance
    assert aloha.measured == pytest.approx(1 - 2 * 0.05, abs=4 * math.sqrt(0.1 * 0.9 / 500))


def test_same_slot_bound():
    """The control's bound: 2 (DIFS + cw slot) / t / (cw + 1)."""
    assert mac_checks.same_slot_bound(1.0, 50e-6, 20e-6, 31) == pytest.approx(2 * (50e-6 + 31 * 20e-6) / 32)


@pytest.mark.slow
@pytest.mark.parametrize("n", [3, 15, 40])
def test_csma_saturation_throughput_matches_bianchi(n):
    """802.11 DCF saturation throughput within 5 % of Bianchi's model."""
    c = mac_checks.csma_saturation(n, duration_s=15.0, seed=7)
    assert abs(c.measured - c.theory) <= 0.05 * c.theory


def test_bianchi_model_limits():
    """Bianchi's tau: 2/(W+1) for one station; p grows with n."""
    tau, p = mac_checks.bianchi_tau(1, 32, 5)
    assert tau == pytest.approx(2 / 33) and p == 0
    ps = [mac_checks.bianchi_tau(n, 32, 5)[1] for n in (5, 10, 50)]
    assert ps == sorted(ps) and not any(math.isnan(x) for x in ps)


@pytest.mark.parametrize("routing", ["backbone", "oracle"])
def test_relaying_accounts_for_every_frame_on_a_medium(routing):
    """Under a medium a flood's copies are counted per frame (one delivery per frame, to
    nobody when nobody got it): no message has negative copies in flight, and every
    message is delivered or has no copy left (but those still on the air at the end)."""
    cfg = make_config(
        world={"n_robots": 25, "side_m": 300.0},
        duration_s=30.0,
        channel={"range_m": 100.0, "mac": "aloha"},
        protocol={"message_rate_hz": 2.0, "routing": routing},
    )
    res = execute(cfg)
    relay = res.sim.models["protocol"].relay
    pending = np.array(list(relay._pending.values()))
    assert (pending >= 0).all()
    msgs = res.frames["messages"]
    assert len(msgs) > 20 and 0 < msgs.delivered.mean() <= 1
    # What the medium lost of each message's frames, per message, adds up to the data kind's counts.
    data = res.sim.channel.counters_for("data")
    for cause in ("collision", "half_duplex"):
        assert msgs[f"dropped_{cause}"].sum() == data.dropped[res.sim.channel.causes.index(cause)].sum()
    assert msgs.dropped_collision.sum() + msgs.dropped_half_duplex.sum() > 0
    if routing == "oracle":
        # Unicast copies under ALOHA (no retry): each frame has one fate at its one receiver,
        # and every copy a message counts is a frame of the medium.
        data = res.frames["medium"].query("kind == 'data'")
        fates = data["received"].sum() + data[[f"dropped_{c}" for c in MAC_DROP_CAUSES]].sum().sum()
        assert data["sent"].sum() == fates == msgs["transmissions"].sum()
        assert res.summary["mac_transmissions"] == res.summary["mac_frames"]


@pytest.mark.parametrize("mac", ["aloha", "csma"])
def test_a_frame_the_radio_keeps_never_fails_on_noise_alone_under_shadowing(mac):
    """log_distance with shadowing: the SINR signal is the pair's own received power (path
    loss + its shadowing), so one sender with no other traffic loses nothing to collisions,
    also beyond the mean range (where only favourable shadowing lets a frame through)."""
    angles = np.linspace(0.0, 2 * np.pi, 40, endpoint=False)
    rings = [np.column_stack([r * np.cos(angles), r * np.sin(angles)]) for r in (150.0, 170.0, 200.0)]
    pos = np.vstack([[[0.0, 0.0]], *rings]) + 1000.0
    keys = {"propagation": "log_distance", "shadowing_sigma_db": 6.0, "preamble_s": 0.0, "data_rate_bps": 1e6}
    sim = mac_checks.medium_run(pos, mac, latency_s=0.0, **keys)
    sim.channel.frame_bytes["f"] = 125
    for k in range(3):
        _send_at(sim, 0.1 * k, 0)
    sim.env.run()
    assert sim.channel.counters_for("f").received.sum() > 0
    assert _dropped(sim, "collision") == 0


def test_mac_none_reproduces_the_channel_before_the_medium():
    """channel.mac = "none" is the channel of infinite capacity as it was before the medium
    (commit 724cc35, with rule 6 in its order): a clustering run's Ack counts, role changes
    and every table's row count equal the record of that commit
    (tests/data/mac_none_724cc35.json)."""
    from netsim.config import from_dict
    from netsim.tools.validate import mac_none_mismatches, mac_none_record, mac_none_tree

    record = mac_none_record()
    assert record is not None
    res = execute(from_dict(mac_none_tree(record)))
    assert res.sim.channel.mac is None
    assert mac_none_mismatches(record, res.frames) == []


def test_drop_events_on_a_medium_come_once_per_cause_at_their_instant():
    """On a medium a drop subscriber sees: collision at the frames' end, for the receiver;
    queue_full at the hand-over and retry_limit at the last attempt's end, with no receiver
    (the frame's sender is not a receiver)."""
    sim = _medium([0, 40, 80, 200], mac="csma", queue_frames=1, retry_limit=0)
    sim.channel.mac.rng = _Draws(*([0] * 10))
    drops = []
    sim.events.on("drop", lambda d: drops.append((d.t_s, d.sender, d.receivers.tolist(), d.cause)))
    _send_at(sim, 0.0, 0)  # 0 and 2 are hidden from each other: both collide at 1
    _send_at(sim, 0.0, 2)
    _send_at(sim, 0.0, 2)  # 2's queue holds one frame
    _send_at(sim, 0.01, 3, dest=0)  # out of range, no retry
    sim.env.run()
    end = round(DIFS + T, 9)
    assert sorted((round(t, 9), *rest) for t, *rest in drops) == sorted(
        [
            (0.0, 2, [], "queue_full"),
            (end, 0, [1], "collision"),
            (end, 2, [1], "collision"),
            (round(0.01 + DIFS, 9), 3, [0], "out_of_range"),
            (round(0.01 + DIFS + T, 9), 3, [], "retry_limit"),
        ]
    )


def test_acks_lost_to_a_hidden_jammer_time_the_neighbour_out_at_tau():
    """Collided Acks are simply not heard: A's Acks all collide at B with a jammer hidden from
    A, and B's entry for A expires tau_s after the last Ack B received from A."""
    from netsim.config import from_dict
    from netsim.run import build

    cfg = from_dict(
        {
            "world": {"n_robots": 3, "side_m": 10_000.0},
            "mobility": {"model": "static"},
            "channel": {"mac": "aloha", "range_m": 50.0, "latency_s": 0.0},
            "protocol": {"model": "ack"},
            "output": {"position_interval_s": 0.0},
        }
    )
    sim = build(cfg)
    sim.state.place(np.array([[100.0, 100.0], [140.0, 100.0], [180.0, 100.0]]))  # A, B, jammer
    ch, env = sim.channel, sim.env
    ch.frame_bytes["jam"] = 1000
    ch.notify_empty.add("jam")

    def jam(_s, _r, _p):
        ch.broadcast(2, None, jam, kind="jam")  # the next frame starts as this one ends

    start = 5.0
    env.timeout(start).callbacks.append(lambda _e: jam(None, None, None))
    table, tau = sim.models["protocol"].table, cfg.protocol.params.tau_s
    env.run(until=start)
    assert 0 in table.live_ids(env.now, 1)
    last = float(table.last_heard_s[1, table.entry(1, 0)])
    env.run(until=last + tau - 1e-6)
    assert 0 in table.live_ids(env.now, 1)
    env.run(until=last + tau + 1e-6)
    assert 0 not in table.live_ids(env.now, 1)
    assert float(table.last_heard_s[1, table.entry(1, 0)]) == last  # nothing heard from A since
    acks = ch.counters_for("ack")
    assert acks.dropped[ch.causes.index("collision"), 1] >= 2  # A's Acks at B, jammed


def test_coverage_runs_on_csma():
    """Coverage's leader commands go through the medium like any frame: every frame handed
    over is sent or dropped at a full queue, and commands are received."""
    cfg = make_config(
        world={"n_robots": 30},
        duration_s=15.0,
        mobility={"model": "static"},
        channel={"mac": "csma"},
        coverage={"enabled": True},
        output={"position_interval_s": 0.0},
    )
    res = execute(cfg)
    medium, s = res.frames["medium"], res.summary
    by_kind = medium.groupby("kind")[["sent", "received"]].sum()
    assert by_kind.loc["command", "sent"] > 0 and by_kind.loc["command", "received"] > 0
    assert s["mac_frames"] + s["frames_dropped_queue_full"] == medium["sent"].sum()
    assert len(res.frames["coverage"]) > 0


def test_an_oracle_message_a_full_queue_refuses_is_dropped_once():
    """Oracle routing on a medium whose queue holds one frame, fed faster than it drains: a
    message whose next hop's frame the full queue refuses is told dropped once (the medium
    tells it through the delivery with no receiver, and the refused unicast must not tell
    it again)."""
    flow = {"src": 0, "dst": 5, "start_s": 1.0, "stop_s": 10.0, "rate_bps": 200000.0, "packet_bytes": 4000}
    cfg = make_config(
        world={"n_robots": 10, "side_m": 400.0},
        duration_s=10.0,
        channel={"mac": "csma", "queue_frames": 1},
        protocol={"routing": "oracle"},
        traffic={"flows": [flow]},
    )
    dropped: list[tuple[int, str]] = []

    def built(sim):
        sim.events.on("message_dropped", lambda e: dropped.append((e.msg_id, e.cause)))

    res = execute(cfg, built=built)
    full = res.sim.channel.causes.index("queue_full")
    assert sum(int(c.dropped[full].sum()) for c in res.sim.channel.counters.values()) > 10
    ids = [m for m, _ in dropped]
    assert len(ids) > 10 and len(ids) == len(set(ids))


def test_the_busy_fraction_runs_on_through_a_frame_that_starts_while_the_robot_transmits():
    """A robot busy with its own frame when another's starts within range stays busy from
    its own frame's start until the medium is idle again at the other's end: 1.5 T for both
    (a busy stretch restarted by the second frame would count T)."""
    sim = _medium([0, 10])
    _send_at(sim, 0.0, 0)
    _send_at(sim, T / 2, 1)
    sim.env.run(until=1.0)
    assert sim.channel.mac.busy_fraction(1.0).tolist() == pytest.approx([1.5 * T, 1.5 * T], rel=1e-12)


def test_each_unicast_gets_its_own_retry_limit():
    """CSMA: a frame's retries start from zero whatever the frame before it spent: two
    unicasts to a robot out of range each take 1 + retry_limit attempts, each then dropped
    (retry_limit); the second was dropped at its first failure, the first's retries kept."""
    sim = _medium([0, 10, 200], mac="csma", retry_limit=3)
    sim.channel.notify_empty.add("f")
    _send_at(sim, 0.0, 0, dest=2)
    _send_at(sim, 0.0, 0, dest=2)
    sim.env.run()
    assert sim.channel.mac.attempts == 8
    assert _dropped(sim, "retry_limit", robot=0) == 2


def test_a_contention_window_fixed_at_one_size_is_accepted():
    """cw_max may equal cw_min (a window that never grows), down to the smallest window, 1
    (k = 1 in 2^k - 1)."""
    for cw in (1, 31, 1023):
        channel = make_config(channel={"mac": "csma", "cw_min": cw, "cw_max": cw}).channel
        assert (channel.cw_min, channel.cw_max) == (cw, cw)


@pytest.mark.parametrize("mac", ["aloha", "csma"])
def test_a_frames_airtime_on_the_medium_is_its_preamble_and_its_bytes_at_the_rate(mac):
    """The airtime the configuration gives a frame (which the protocols' checks hold an
    Ack's period against) is the medium's own: preamble + 8 bytes / rate."""
    channel = make_config(channel={"mac": mac, "preamble_s": 1e-3, "data_rate_bps": 1e6}).channel
    assert channel.airtime_s(125) == pytest.approx(2e-3)
    assert airtime_s(125, 1e6, 1e-3) == pytest.approx(2e-3)
