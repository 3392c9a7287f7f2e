"""The full protocol stack as one plugin (``protocol.model = "clustering"``): Ack beacon,
neighbour tables, clustering (rules 1-6), relaying, leader commands, and what they
record: ``roles``, ``groups``, ``beliefs`` (and ``neighbour_beliefs``, the ids behind
them), ``ack_delivery``, ``messages`` and ``hops`` tables and summary figures."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from functools import partial
from typing import NamedTuple

import numpy as np
import pandas as pd
from netsim.protocols._kernels import (
    EMPTY,
    LAST_HEARD,
    ROLE,
    RX_POWER,
    Counts,
    Groups,
    Pairs,
    RoleArrays,
    Truth,
    X,
    Y,
)
from netsim.protocols.ack import ACK_DELIVERY_SCHEMA, ACKS_SCHEMA, AckBeacon, AckParams, AckTiming, check_tau
from netsim.protocols.clustering import Clustering, ElectionPolicy, JoinPolicy, MergePolicy
from netsim.protocols.flows import FLOWS_SCHEMA, PACKETS_SCHEMA, FlowTraffic, packet_delivery
from netsim.protocols.relay import HOPS_SCHEMA, MESSAGES_SCHEMA, Outcome, Relay, Routing, traffic
from netsim.protocols.roles import LABELS, LEADER, MEMBER, ROLE_NAMES, ROLES_SCHEMA

from netsim.compiled import cores, load, side_by_side
from netsim.cosim import Arrival
from netsim.errors import ConfigError
from netsim.params import finite, frame_size, non_negative, param, positive
from netsim.plugins import Parts, PluginSpec
from netsim.samples import Samples, ended_at
from netsim.topology import reach_lists

# From this many robots on, a compiled sample is taken in two halves at once, in two threads
# (on two cores or more): below it, a sample is too short for a thread's start to pay off.
SAMPLE_IN_TWO_ROBOTS = 1000


# The role labels by code, in the column pandas makes of a list of labels (its string
# dtype, object before pandas 3): taking from it turns a column of codes into a column of
# labels without a Python string per row.
_ROLE_LABELS = pd.Series(list(ROLE_NAMES)).array


def role_labels(codes: np.ndarray):
    """The column of role labels of a column of role codes."""
    return _ROLE_LABELS.take(codes.astype(np.int64)) if len(codes) else []


def beliefs_table(samples: Samples) -> pd.DataFrame:
    """The ``beliefs`` table of the per-robot counts of :meth:`Stack._sample_into`."""
    return samples.frame({"role": role_labels})


@dataclass(frozen=True)
class ClusteringParams(AckParams):
    """The clustering protocol's keys of ``[protocol]``: the Ack beacon's, the rules'
    policies and timing, and relaying."""

    join_policy: JoinPolicy = param(JoinPolicy.NEAREST, None, "rule 2: which leader an undecided robot joins")
    merge_policy: MergePolicy = param(
        MergePolicy.SMALLER_GROUP_YIELDS, None, "rule 5: which of two neighbouring leaders yields"
    )
    merge_delay_s: float = param(
        None,
        non_negative,
        "rule 5: how long two leaders must be linked, s",
        kind=float,
        derive=lambda p: 2.0 * p.ack_period_s,
        rule="2 x ack_period_s",
    )
    election_policy: ElectionPolicy = param(ElectionPolicy.LOWEST_ID, None, "rule 6: who replaces a lost leader")
    join_before_election: bool = param(
        False,
        None,
        "rule 6: a member whose leader timed out first joins another leader it knows, and holds the "
        "election only if it knows none (false: the election comes first)",
    )
    routing: Routing = param(Routing.BACKBONE, None, "message relaying: backbone flooding or oracle")
    distributed_gateways: bool = param(
        True, None, "members next to a member of another group relay too (keeps flooding connected)"
    )
    message_ttl: int = param(32, positive, "hops a relayed message may take")
    message_rate_hz: float = param(
        0.2, finite(non_negative), "messages sent per second, network-wide (random pairs)", schedules="run"
    )
    # One frame, whatever channel.max_frame_bytes: sized as the Ack's is (netsim.params.frame_size).
    message_bytes: int = param(
        512, frame_size, "size of a message (and leader command) frame on a shared medium (channel.mac), bytes"
    )


class Command(NamedTuple):
    leader: int
    seq: int
    payload: object


class Stack(AckTiming):
    """The clustering protocol of one run; its groups as a :class:`~netsim.groups.GroupView`."""

    role_names = ROLE_NAMES

    def __init__(self, params: ClusteringParams, parts: Parts):
        self.params = params
        self.env, self.state, self.channel = parts.env, parts.state, parts.channel
        self.streams, self.trace, self.output = parts.streams, parts.trace, parts.output
        self.duration_s = float(parts.duration_s)
        self.beacon = AckBeacon(params, parts)
        self.roles = self.beacon.roles
        self.table = self.beacon.table
        self.clustering = Clustering(params, parts, self.beacon)
        self.relay = Relay(params, parts, self.clustering)
        # The flows of traffic.flows, carried by the relay (None: none).
        self.flows = None
        if parts.traffic is not None:
            self.flows = FlowTraffic(
                parts.traffic, self.env, self.channel.frame_bytes, self._send_flow_frame, self.relay.shortest_hops
            )
        n = parts.state.n
        # Leader commands: each member keeps the latest command of its current leader.
        self.command: list[Command | None] = [None] * n
        self._command_seq = np.zeros(n, dtype=np.int64)
        self.on_command: list[Callable[[int, Command], None]] = []
        # The sampled tables, kept as arrays and made tables once, at the end: samples at 0,
        # interval, ... and at the end, each table's buffers sized for them.
        self._sample_interval_s = self.output.position_interval_s or params.ack_period_s
        interval = self._sample_interval_s
        expected = int(self.duration_s // interval) + 2 if interval > 0 else 1
        self._groups, self._beliefs, self._neighbour_beliefs = (Samples(expected) for _ in range(3))
        # The samples' loops (netsim.protocols._kernels), loaded for the run's size.
        self.kernels = load("netsim.protocols._kernels", n)
        self._roles = tuple(RoleArrays(self.roles.role, self.roles.leader))
        self._cores = cores()

    # -- the groups, for the rest of the run ------------------------------------------
    @property
    def role(self) -> np.ndarray:
        """Each robot's role code now (``role_names[code]``: its label)."""
        return self.roles.role

    @property
    def leader(self) -> np.ndarray:
        """Each robot's leader now: its own id for a leader, -1 for none."""
        return self.roles.leader

    def start(self, phase_s=None) -> None:
        """Start beacons, rules, traffic and sampling; ``phase_s`` overrides the Ack phases."""
        self.beacon.start(phase_s)
        self.channel.frame_bytes.update(data=self.params.message_bytes, command=self.params.message_bytes)
        self.clustering.start()
        p = self.params
        if p.message_rate_hz > 0:
            self.env.process(traffic(self.env, self.streams, self.state.n, self.relay, p.message_rate_hz))
        if self.flows is not None:
            self.flows.start(self.duration_s)
            self.trace.add_frame("packets", self.flows.packets_frame)
            self.trace.add_frame("flows", self.flows.flows_frame)
        self.env.process(self._sampler(self._sample_interval_s))
        self.trace.add_frame("messages", self.messages_frame)
        self.trace.add_frame("hops", self.relay.hops_frame)
        self.trace.add_frame("groups", self.groups_frame)
        self.trace.add_frame("beliefs", self.beliefs_frame)
        self.trace.add_frame("neighbour_beliefs", self.neighbour_beliefs_frame)

    def _send_flow_frame(self, src: int, dst: int, kind: str, on_outcome) -> int:
        return self.relay.send(src, dst, kind=kind, on_outcome=on_outcome)

    # -- leader commands ---------------------------------------------------------------
    def send_command(self, leader: int, payload) -> None:
        """Leader ``leader`` broadcasts a command; its members (and only they) adopt it."""
        self._command_seq[leader] += 1
        cmd = Command(leader, int(self._command_seq[leader]), payload)
        self.channel.broadcast(leader, cmd, self._on_command, kind="command")

    def _on_command(self, sender: int, receivers: np.ndarray, cmd: Command) -> None:
        st = self.roles
        for r in receivers[(st.role[receivers] == MEMBER) & (st.leader[receivers] == sender)].tolist():
            old = self.command[r]
            if old is None or old.leader != cmd.leader or old.seq < cmd.seq:
                self.command[r] = cmd
                for fn in self.on_command:
                    fn(r, cmd)

    # -- driven from outside (netsim.cosim) -------------------------------------------

    def heard(self, now: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """What the neighbour tables hold now (:class:`netsim.cosim.NeighbourView`)."""
        return self.table.heard(now)

    def link_quality(self, now: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The tables' live entries and their last power (:class:`netsim.cosim.LinkQualityView`)."""
        return self.table.link_quality(now)

    def send_message(self, src: int, dst: int, payload: object) -> int:
        """A message from outside, relayed as the traffic's (:class:`netsim.cosim.Messenger`)."""
        return self.relay.send(src, dst, payload, carried=True)

    def inbox(self, robot: int) -> list[Arrival]:
        return self.relay.inbox(robot)

    # -- what leaders know of each other (for coverage controllers) ------------------
    def heard_leaders(self, leader: int, now: float) -> tuple[np.ndarray, np.ndarray]:
        """The other leaders ``leader`` knows of and their last-heard positions: those it
        hears itself and those its live neighbours hear (a gateway's Ack reports them),
        the freshest report of each. Positions are as old as the Ack they came in."""
        table = self.table
        live = table.live_mask(now, leader)
        rows = [leader] + table.id[leader][live].tolist()
        ids = table.id[rows]
        data = table.data[rows]
        fresh = table.kernels.live_entries(data[:, :, LAST_HEARD].ravel(), float(now), table.tau_s)
        mask = fresh.reshape(ids.shape) & (data[:, :, ROLE] == LEADER) & (ids != leader)
        if not mask.any():
            return np.empty(0, dtype=np.int64), np.empty((0, 2))
        found, rec = ids[mask], data[mask]
        order = np.lexsort((-rec[:, LAST_HEARD], found))
        found, rec = found[order], rec[order]
        first = np.r_[True, found[1:] != found[:-1]]
        return found[first], rec[first][:, [X, Y]]

    def neighbourhood(self, now: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """What every robot knows of the robots around it from Acks: arrays ``(robot,
        other, position (k, 2))``, one row per robot ``other`` that ``robot`` hears or that
        a robot it hears hears (an Ack carries the positions in its sender's table). The
        relation is symmetric, as the forces built on it must be. A position is the one in
        ``other``'s latest Ack heard by anyone (all robots that heard that Ack hold it)."""
        from scipy.sparse import csr_matrix  # only coverage controllers ask: not imported by every run

        table, n = self.table, self.state.n
        live = table.live_mask(now)
        rows, slots = np.nonzero(live)
        heard = table.id[rows, slots]
        hears = csr_matrix((np.ones(len(rows)), (rows, heard)), shape=(n, n))
        known = (hears + hears @ hears).tocoo()
        other = known.row != known.col
        robot, other = known.row[other].astype(np.int64), known.col[other].astype(np.int64)
        last = table.data[rows, slots, LAST_HEARD]
        order = np.lexsort((-last, heard))
        freshest = order[np.r_[True, heard[order][1:] != heard[order][:-1]]] if len(order) else order
        xy = np.zeros((n, 2))
        xy[heard[freshest]] = table.data[rows[freshest], slots[freshest]][:, [X, Y]]
        order = np.lexsort((other, robot))
        return robot[order], other[order], xy[other[order]]

    def heard_acks(self, now: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Every robot's own record of the Acks it heard, live or expired (the latest of
        each sender, until its slot is reused): arrays ``(robot, sender, position the Ack
        carried (k, 2), reception time, power the robot received it at (dBm, NaN: not
        measured))``."""
        table = self.table
        rows, slots = np.nonzero(table.id != EMPTY)
        rec = table.data[rows, slots]
        return rows.astype(np.int64), table.id[rows, slots], rec[:, [X, Y]], rec[:, LAST_HEARD], rec[:, RX_POWER]

    # -- ground truth beside belief ----------------------------------------------------
    def belief_vs_truth(self, now: float) -> pd.DataFrame:
        """Per robot: its role and leader, whether the leader is truly in two-way range,
        how many neighbours it believes live and how many it truly has, and how many of
        its beliefs are stale (believed live, out of range) or missing (in range, not
        believed).

        Truth is per direction, as beliefs are: ``i`` believes ``j`` live when it holds a
        live Ack of ``j``, and that is true when ``j``'s transmissions reach ``i`` now
        (``|p_i - p_j| <= r_j``), whether or not ``i`` reaches ``j``. A member's leader is
        in range when the link is two-way (``<= min(r_i, r_j)``), as a member needs.
        """
        samples = Samples()
        self._sample_into(now, Samples(), Samples(), samples)
        return beliefs_table(samples)

    def neighbour_beliefs(self, now: float) -> pd.DataFrame:
        """The ids behind :meth:`belief_vs_truth`'s counts: one row per robot and other
        robot that it believes live or whose transmissions reach it now, ordered by robot
        and other; ``believed`` and ``in_range`` say which (stale: believed only; missing:
        in range only)."""
        samples = Samples()
        self._sample_into(now, Samples(), samples, Samples())
        return samples.frame()

    def _sampler(self, interval: float):
        # The instants of netsim.samples.sample_times, as positions.parquet's: k x interval
        # (a sum of intervals would name an instant a rounding error away), and the run's
        # end, whose sample _sample_at_end takes.
        env, k = self.env, 0
        while not ended_at([k * interval], self.duration_s):
            t = k * interval
            if t > env.now:
                yield env.timeout(t - env.now)
            self._take_sample(float(t))
            k += 1

    def _take_sample(self, now: float) -> None:
        self._sample_into(now, self._groups, self._neighbour_beliefs, self._beliefs)

    def _sample_at_end(self) -> None:
        """The last sample of the sampled tables, at the run's end ``T``, once the run has
        reached it, so that they end where the run does: the sampler's next event is due at
        ``T`` or after, and never processed (events due exactly at the end are not, SimPy's
        convention). It sees what every event before ``T`` made."""
        end = self.duration_s
        if self.env.now >= end and not ended_at(self._groups.times, end):
            self._take_sample(end)

    def _sample_into(self, now: float, groups_out: Samples, pairs_out: Samples, counts_out: Samples) -> None:
        """One sample of the ``groups``, ``neighbour_beliefs`` and ``beliefs`` tables, by
        one pass (:func:`netsim.protocols._kernels.sample_into`) writing straight into the
        tables' buffers, the truth decided in the neighbour lists of
        :func:`netsim.topology.reach_lists`. From :data:`SAMPLE_IN_TWO_ROBOTS` robots on, on
        two cores or more, two passes at once, each over half of the robots."""
        st, table, roles = self.state, self.table, self.roles
        pos, near_ptr, near = reach_lists(st, now, self.channel.reach_lists)
        n, slots = table.id.shape
        int64, flag = np.dtype(np.int64), np.dtype(np.bool_)
        groups = groups_out.reserve(
            {"robot": int64, "group": int64, "primary": flag}, n * (slots + 1), groups_out.last_rows
        )
        pairs = pairs_out.reserve(
            {"robot": int64, "neighbour": int64, "believed": flag, "in_range": flag},
            n * slots + len(near),
            pairs_out.last_rows,
        )
        counts = counts_out.reserve(
            {"robot": int64, "role": roles.role.dtype, "leader": roles.leader.dtype, "leader_in_range": flag}
            | dict.fromkeys(BELIEF_COLUMNS[5:], int64),
            n,
            n,
        )
        truth = tuple(Truth(pos, st.range_m, st.side_m if st.torus else 0.0, near_ptr, near))
        sample = partial(self.kernels.sample_into, table.view, now, self.clustering.symmetric, self._roles, truth)
        # The columns as the loop takes them, by name (the tables' columns are the records' fields).
        g, p, c = tuple(Groups(**groups)), tuple(Pairs(**pairs)), tuple(Counts(**counts))
        if n < SAMPLE_IN_TWO_ROBOTS or self._cores < 2:
            m, k = sample(g, p, c, 0, n)
        else:
            # Two halves at once, in two threads. The second writes its rows at the end of
            # each room, as far from its start as they may need, and they are moved up after
            # the first's: the same rows, in the same order.
            h = n // 2
            g_end = len(g[0]) - (n - h) * (slots + 1)
            p_end = len(p[0]) - (n - h) * slots - int(near_ptr[n] - near_ptr[h])
            g_tail, p_tail = tuple(col[g_end:] for col in g), tuple(col[p_end:] for col in p)
            (m, k), (m2, k2) = side_by_side(lambda: sample(g, p, c, 0, h), lambda: sample(g_tail, p_tail, c, h, n))
            for room, start, end, rows in ((g, m, g_end, m2), (p, k, p_end, k2)):
                for col in room:
                    col[start : start + rows] = col[end : end + rows]
            m, k = m + m2, k + k2
        groups_out.commit(now, m)
        pairs_out.commit(now, k)
        counts_out.commit(now, n)

    # -- outputs -----------------------------------------------------------------------
    def messages_frame(self) -> pd.DataFrame:
        df = pd.DataFrame(self.relay.outcomes(), columns=list(Outcome._fields))
        if self.channel.deferred:
            # A shared medium: what it lost of each message's frames, by cause.
            losses = self.relay.medium_losses
            for cause in self.channel.medium_causes:
                counts = [losses.get(mid, {}).get(cause, 0) for mid in df["msg_id"].tolist()]
                df[f"dropped_{cause}"] = np.array(counts, dtype=np.int64)
        return df

    def beliefs_frame(self) -> pd.DataFrame:
        kept, now = self._beliefs, self._sample_now()
        if not kept and now is None:
            return pd.DataFrame(columns=BELIEF_COLUMNS)
        return _joined([beliefs_table(s) for s in (kept, now and now[2]) if s])

    def neighbour_beliefs_frame(self) -> pd.DataFrame:
        kept, now = self._neighbour_beliefs, self._sample_now()
        if not kept and now is None:
            return pd.DataFrame({c: pd.Series(dtype=t) for c, t in NEIGHBOUR_BELIEFS_SCHEMA.items()})
        return _joined([s.frame() for s in (kept, now and now[1]) if s])

    def groups_frame(self) -> pd.DataFrame:
        kept, now = self._groups, self._sample_now()
        if not kept and now is None:
            return pd.DataFrame(columns=["t_s", "robot", "group", "primary"])
        return _joined([s.frame() for s in (kept, now and now[0]) if s])

    def _sample_now(self) -> tuple[Samples, Samples, Samples] | None:
        """The sampled tables end where the run stands: at its end, the last sample, kept
        (:meth:`_sample_at_end`); before it (a table asked for mid-run), a sample at ``now``
        when the latest is older, as the end's would be (every event before ``now``, none
        at it), handed out but not kept, so that the run records what it would have."""
        if not self._samples_now():
            return None
        now = float(self.env.now)
        groups, pairs, counts = Samples(), Samples(), Samples()
        self._sample_into(now, groups, pairs, counts)
        return groups, pairs, counts

    def _samples_now(self) -> bool:
        """Whether the sampled tables handed out now end with a sample at ``now`` that the
        run does not keep (:meth:`_sample_now`)."""
        self._sample_at_end()
        now = float(self.env.now)
        return not (now >= self.duration_s or ended_at(self._groups.times, now))

    def summary(self, frames: Mapping[str, pd.DataFrame], duration_s: float) -> dict:
        n = self.state.n
        roles = frames["roles"]
        out = leader_statistics(roles, n, duration_s)
        groups = frames["groups"]
        # The samples of the groups table handed out: those kept, and mid-run the one at now.
        samples = len(self._groups) + self._samples_now()
        if samples:
            out["gateways_mean"] = gateways_mean(groups["t_s"].to_numpy(), groups["robot"].to_numpy(), samples)
        acks = self.channel.counters_for("ack").sent.sum()
        # Every frame a robot relays: the random pairs' messages and the flows' frames.
        kinds = ["data", *sorted(self.flows.kinds if self.flows is not None else ())]
        data = sum(self.channel.counters_for(kind).sent.sum() for kind in kinds)
        out["acks_per_robot_per_s"] = float(acks / (n * duration_s)) if duration_s else math.nan
        out.update(self.beacon.summary(frames, duration_s))
        out["relays_per_robot_per_s"] = float(data / (n * duration_s)) if duration_s else math.nan
        msgs = frames["messages"]
        out["messages"] = len(msgs)
        out["message_delivery_ratio"] = float(msgs["delivered"].mean()) if len(msgs) else math.nan
        out.update(packet_delivery(frames))
        return out


BELIEF_COLUMNS = [
    "t_s",
    "robot",
    "role",
    "leader",
    "leader_in_range",
    "believed_neighbours",
    "true_neighbours",
    "stale_neighbours",
    "missing_neighbours",
]


def _joined(frames: list[pd.DataFrame]) -> pd.DataFrame:
    return frames[0] if len(frames) == 1 else pd.concat(frames, ignore_index=True)


def gateways_mean(t_s: np.ndarray, robot: np.ndarray, samples: int) -> float:
    """The mean number of robots in two groups or more per sample, over all ``samples``
    the ``groups`` table was sampled at, those where no group existed (no row) counting 0
    (its columns ``t_s`` and ``robot``: samples in time order, each ordered by robot): a
    robot's rows of one sample are consecutive."""
    same = (t_s[1:] == t_s[:-1]) & (robot[1:] == robot[:-1])
    # A gateway's rows after its first: each run of them is one gateway.
    gateways = int(np.count_nonzero(same[1:] & ~same[:-1])) + int(same[:1].sum())
    return gateways / samples


def leader_statistics(roles: pd.DataFrame, n: int, duration_s: float) -> dict:
    """Time-weighted mean number of leaders, role changes per robot per minute, and mean
    leader tenure, from the role-change records (a level statistic: exact, not sampled).

    Tenures still running at the end are cut there, so ``mean_leader_tenure_s`` is a
    lower bound when some are; ``leader_tenures_complete`` says how many ended.
    """
    if duration_s <= 0 or roles.empty:
        return {
            "leaders_time_mean": math.nan,
            "role_changes_per_robot_per_min": math.nan,
            "mean_leader_tenure_s": math.nan,
            "leader_tenures_complete": 0,
        }
    r = roles.reset_index(drop=True)
    r["order"] = np.arange(len(r))
    r = r.sort_values(["robot", "t_s", "order"], kind="stable")
    is_leader = (r["role"] == LABELS.leader).to_numpy()
    robot = r["robot"].to_numpy()
    same = np.r_[False, robot[1:] == robot[:-1]]
    was_leader = np.r_[False, is_leader[:-1]] & same
    delta = is_leader.astype(int) - was_leader.astype(int)
    t = r["t_s"].to_numpy(float)
    order = np.argsort(t, kind="stable")
    t_sorted, level = t[order], np.cumsum(delta[order])
    spans = np.diff(np.r_[t_sorted, duration_s])
    leaders_mean = float((level * spans).sum() / duration_s)
    changes = int((r["cause"] != "rule1_start").sum())
    starts = t[is_leader & ~was_leader]
    start_robot = robot[is_leader & ~was_leader]
    ends_mask = ~is_leader & was_leader
    ends, end_robot = t[ends_mask], robot[ends_mask]
    tenures, complete = [], 0
    for rb in np.unique(start_robot):
        s, e = starts[start_robot == rb], ends[end_robot == rb]
        for k, t0 in enumerate(s):
            if k < len(e):
                tenures.append(e[k] - t0)
                complete += 1
            else:
                tenures.append(duration_s - t0)
    return {
        "leaders_time_mean": leaders_mean,
        "role_changes_per_robot_per_min": changes / (n * duration_s / 60.0),
        "mean_leader_tenure_s": float(np.mean(tenures)) if tenures else math.nan,
        "leader_tenures_complete": complete,
    }


BELIEFS_SCHEMA = {
    "t_s": "float64",
    "robot": "int64",
    "role": "object",
    "leader": "int64",
    "leader_in_range": "bool",
    "believed_neighbours": "int64",
    "true_neighbours": "int64",
    "stale_neighbours": "int64",
    "missing_neighbours": "int64",
}
NEIGHBOUR_BELIEFS_SCHEMA = {
    "t_s": "float64",
    "robot": "int64",
    "neighbour": "int64",
    "believed": "bool",
    "in_range": "bool",
}
GROUPS_SCHEMA = {"t_s": "float64", "robot": "int64", "group": "int64", "primary": "bool"}


def check(params: ClusteringParams, config) -> None:
    """The Ack's rules (:func:`~netsim.protocols.ack.check_tau`), and the oracle's: where
    shadowing or walls decide the links, it routes on them as the run tracks them."""
    check_tau(params, config)
    if params.routing == "oracle" and config.radio_decides_links() and config.events.runtime_links == "off":
        raise ConfigError(
            "events.runtime_links",
            "off",
            "protocol.routing = 'oracle' routes on the links the channel makes under shadowing or walls, "
            "tracked during the run: set it to 'auto' or 'on'",
        )


def build(params: ClusteringParams, parts: Parts) -> Stack:
    stack = Stack(params, parts)
    stack.start()
    return stack


PLUGIN = PluginSpec(
    Params=ClusteringParams,
    build=build,
    check=check,
    tables={
        "roles": ROLES_SCHEMA,
        "acks": ACKS_SCHEMA,
        "ack_delivery": ACK_DELIVERY_SCHEMA,
        "groups": GROUPS_SCHEMA,
        "beliefs": BELIEFS_SCHEMA,
        "neighbour_beliefs": NEIGHBOUR_BELIEFS_SCHEMA,
        "messages": MESSAGES_SCHEMA,
        "hops": HOPS_SCHEMA,
        "flows": FLOWS_SCHEMA,
        "packets": PACKETS_SCHEMA,
    },
    default=True,
    forms_groups=True,
    role_labels=LABELS,
    carries_flows=True,
)
