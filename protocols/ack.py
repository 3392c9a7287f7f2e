"""The Ack beacon (docs/model.md section 4): every robot broadcasts an Ack every ``t`` seconds.

Each robot starts at a random phase, uniform on ``[0, t)``, and each period is
``t + U(-jitter, +jitter)``. An Ack carries the sender's id, role, leader, a sequence
number, its position, its group size, its degree (live neighbours that list it in their
own Acks: two-way links only), and the ids it has heard within ``tau`` (so that a
receiver can tell a two-way link from a one-way one).

Receivers record the Ack in their neighbour table. Protocols built on the beacon (the
clustering) subscribe to :attr:`AckBeacon.listeners` and see every delivery, in bulk. With
latency jitter an Ack can be overtaken by the sender's next one: a receiver that already
holds a newer Ack from that sender ignores the older (the table keeps the newest, the
listeners are not told; :attr:`AckBeacon.stale_acks` counts them).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from netsim.timers import urgent_timeout
from protocols.neighbours import HEARS_ME, NeighbourTable, ack_record


class Ack(NamedTuple):
    sender: int
    role: int
    leader: int
    seq: int
    x_m: float
    y_m: float
    group_size: int
    heard: np.ndarray  # ids the sender has heard within tau, ascending
    resign: bool = False
    record: np.ndarray | None = None  # the fields packed for neighbour tables


# listener(now, ack, receivers, hears_me)
AckListener = Callable[[float, Ack, np.ndarray, np.ndarray], None]


def ack_beacon(sim, i: int, period_s: float, jitter_s: float, phase_s: float, rng: np.random.Generator, send):
    """Robot ``i``'s beacon: first Ack at ``phase_s``, then one every period."""
    yield urgent_timeout(sim.env, phase_s)
    while True:
        send(i)
        step = period_s + (rng.uniform(-jitter_s, jitter_s) if jitter_s > 0 else 0.0)
        yield urgent_timeout(sim.env, step)


class AckBeacon:
    """Ack beacons and neighbour tables of all robots."""

    def __init__(self, sim):
        p = sim.config.protocol
        self.sim = sim
        self.period_s = p.ack_period_s
        self.table = NeighbourTable(sim.state.n, p.tau_s)
        self.seq = np.zeros(sim.state.n, dtype=np.int64)
        # Robots the protocol above counts as members of each robot's group (1: alone).
        self.group_size = np.ones(sim.state.n, dtype=np.int64)
        # What each robot announced in its last Ack: its role and two-way degree.
        self.role_sent = np.full(sim.state.n, -1, dtype=np.int64)
        self.degree_sent = np.zeros(sim.state.n, dtype=np.int64)
        # Leaders that announce they are giving up leadership set this for their next Ack.
        self.resign_pending = np.zeros(sim.state.n, dtype=bool)
        self.listeners: list[AckListener] = []
        # Called as hook(i, now) just before robot i's Ack is built (to refresh its fields).
        self.before_send: list[Callable[[int, float], None]] = []
        self.phase_s = np.zeros(sim.state.n)
        # Receptions ignored because a newer Ack of the same sender had arrived first.
        self.stale_acks = 0

    def start(self, phase_s=None) -> None:
        """Start every robot's beacon; ``phase_s`` (one per robot) overrides the random phases."""
        sim = self.sim
        p = sim.config.protocol
        if phase_s is None:
            self.phase_s = sim.streams.get("ack.phase").uniform(0.0, p.ack_period_s, sim.state.n)
        else:
            self.phase_s = np.asarray(phase_s, dtype=float)
        jitter_rng = sim.streams.get("ack.jitter")
        for i in range(sim.state.n):
            sim.env.process(ack_beacon(sim, i, p.ack_period_s, p.ack_jitter_s, self.phase_s[i], jitter_rng, self.send))
        sim.trace.add_frame("acks", lambda: sim.channel.frame("ack"))

    def make_ack(self, i: int) -> Ack:
        now = self.sim.env.now
        for hook in self.before_send:
            hook(i, now)
        st = self.sim.state
        x, y = st.position(i, now)
        self.seq[i] += 1
        resign = bool(self.resign_pending[i])
        self.resign_pending[i] = False
        seq, role, leader, size = int(self.seq[i]), int(st.role[i]), int(st.leader[i]), int(self.group_size[i])
        live = self.table.live_mask(now, i)
        heard = np.sort(self.table.id[i][live])
        degree = int((live & (self.table.data[i, :, HEARS_ME] != 0)).sum())
        self.role_sent[i], self.degree_sent[i] = role, degree
        return Ack(i, role, leader, seq, x, y, size, heard, resign, ack_record(seq, role, leader, x, y, size, degree))

    def send(self, i: int) -> None:
        if not self.sim.state.alive[i]:
            return
        self.sim.channel.broadcast(i, self.make_ack(i), self.deliver, kind="ack")

    def deliver(self, sender: int, receivers: np.ndarray, ack: Ack) -> None:
        now = self.sim.env.now
        heard = ack.heard
        if len(heard):
            at = np.minimum(heard.searchsorted(receivers), len(heard) - 1)
            hears_me = heard[at] == receivers
        else:
            hears_me = np.zeros(len(receivers), dtype=bool)
        fresh = self.table.update(now, sender, receivers, hears_me, ack.record)
        if not fresh.all():
            self.stale_acks += int((~fresh).sum())
            receivers, hears_me = receivers[fresh], hears_me[fresh]
            if len(receivers) == 0:
                return
        for listener in self.listeners:
            listener(now, ack, receivers, hears_me)

    def summary(self, frames, duration_s: float) -> dict:
        return {"acks_overtaken": int(self.stale_acks)}


def install(sim) -> AckBeacon:
    beacon = AckBeacon(sim)
    beacon.start()
    return beacon
