"""Connected coverage by virtual forces among leaders (paper section 1.4; docs/model.md section 5).

Every control period each leader computes the resultant of the forces from the
neighbouring leaders it knows of (see :mod:`mobility.forces`) and the border's push, and
asks for the velocity ``gain x force``, capped at ``speed_max_mps`` (below
``stop_speed_mps`` it holds). Its members follow its commands. The plan is then made safe
for connectivity by :func:`plan_step`:

- the groups are the nodes of a graph whose edges are the links between groups: a
  *gateway* (a member in range of another leader, i.e. in the lens the two leaders' disks
  share) or a member-to-member link; a minimum spanning forest of that graph, preferring
  gateways, is the set of bridges to keep;
- a bridging gateway rides toward the centroid of the leaders it bridges (their planned
  positions), as far as it can while staying within ``r_c - margin`` of each; every other
  member translates with its leader, so it stays in its leader's range;
- each leader shortens its own step, and holds its position if it must, so that at the
  end of the step it is still within ``r_c - margin`` of the gateways it relies on
  (where they are now, which is where a gateway that cannot move stays), and the
  member-to-member bridges stay within range (each side keeps to its half);
- every robot moves in a straight line over the step and the distance between two robots
  moving in straight lines over the same interval is a convex function of time, so a
  kept link that holds at both ends of the step holds throughout it.

So with a loss-free channel a network that is connected when control starts stays
connected at every instant, and the number of components never grows. Under loss a
member that misses its leader's command holds its position, and connectivity is measured
rather than guaranteed.

Leaders learn of the other leaders from Acks (``knowledge = "acks"``): the leaders they
hear themselves and those their neighbours hear (as a gateway's Ack would report them),
at the positions last heard, so up to about an Ack period stale; or from the true
positions (``"global"``), for comparison. The connectivity rules use the positions of the
leader's own members and gateways, which it knows exactly: they move only as it commands.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
import pandas as pd
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import minimum_spanning_tree
from scipy.spatial import cKDTree

from mobility.forces import LAWS, SQRT3, border_force, resultant
from netsim import coverage as metrics
from netsim.control import ControlStep, GroupView, control_loop
from netsim.errors import ConfigError
from netsim.run import distance_travelled
from netsim.state import LEADER, MEMBER
from netsim.topology import geometric_pairs

# Weights of the candidate bridges: any gateway is preferred to any member-to-member link.
_GATEWAY_WEIGHT, _LINK_WEIGHT = 1e-3, 1.0
# Steps are cut a hair short of a constraint's boundary, against rounding.
_SAFETY = 1.0 - 1e-9


class Plan(NamedTuple):
    velocity_mps: np.ndarray  # (N, 2) over the step
    commander: np.ndarray  # leader whose command a robot needs to move (-1: none)
    held: np.ndarray  # leaders whose step was shortened for connectivity
    bridges: int  # kept bridges between groups


def _step_limit(offset: np.ndarray, radius: np.ndarray, move: np.ndarray) -> np.ndarray:
    """Largest ``s`` in [0, 1] with ``|offset + s move| <= radius``, row-wise (``|offset|
    <= radius`` holds: standing still is always allowed)."""
    a = np.einsum("ij,ij->i", move, move)
    b = np.einsum("ij,ij->i", offset, move)
    c = np.einsum("ij,ij->i", offset, offset) - radius**2
    with np.errstate(divide="ignore", invalid="ignore"):
        s = (-b + np.sqrt(np.maximum(b * b - a * c, 0.0))) / a
    s = np.where(a > 0, s, 1.0)
    return np.clip(s * _SAFETY, 0.0, 1.0)


def _box_limit(pos: np.ndarray, move: np.ndarray, side_m: float) -> np.ndarray:
    """Largest ``s`` in [0, 1] keeping ``pos + s move`` inside the square, row-wise."""
    with np.errstate(divide="ignore", invalid="ignore"):
        hi = np.where(move > 0, (side_m - pos) / move, np.where(move < 0, -pos / move, np.inf))
    return np.clip(hi.min(axis=1) * _SAFETY, 0.0, 1.0)


def plan_step(
    pos: np.ndarray,
    role: np.ndarray,
    leader: np.ndarray,
    desired_mps: np.ndarray,
    period_s: float,
    range_m: float,
    margin_m: float,
    speed_max_mps: float,
    side_m: float,
) -> Plan:
    """Velocities for one control step that keep every bridge between groups (module notes).

    ``desired_mps`` holds the leaders' wished velocities (other rows are ignored). The
    result moves leaders along their wish, shortened where a bridge or the area's border
    requires; members with their leader; bridging gateways toward the middle of the
    leaders they bridge; undecided robots not at all.
    """
    n = len(pos)
    ids = np.arange(n)
    keep_m = range_m - margin_m
    is_leader = role == LEADER
    lead = np.where((role == MEMBER) & (leader >= 0), leader, ids)
    to_leader = np.hypot(*(pos - pos[lead]).T)
    follows = (role == MEMBER) & (leader >= 0) & is_leader[lead] & (to_leader <= range_m)
    # Each robot's group: its own id for a leader; its leader's for a member in range of
    # it; for anyone else (undecided, or a member cut off from its leader) a group of its own.
    group = np.where(follows, lead, ids)
    mobile = is_leader | follows

    a, b, d = geometric_pairs(pos, range_m)
    cross = group[a] != group[b]
    a, b, d = a[cross], b[cross], d[cross]
    # Candidate bridges: gateway (member x in range of the other group's leader) or link.
    gw_a = follows[a] & is_leader[b]
    gw_b = follows[b] & is_leader[a]
    cand_u = np.concatenate([a[gw_a], b[gw_b], a])
    cand_v = np.concatenate([b[gw_a], a[gw_b], b])
    is_gw = np.concatenate([np.ones(int(gw_a.sum() + gw_b.sum()), bool), np.zeros(len(a), bool)])
    mid = 0.5 * (pos[group[cand_u]] + pos[group[cand_v]])
    weight = np.where(
        is_gw,
        _GATEWAY_WEIGHT * (1.0 + np.hypot(*(pos[cand_u] - mid).T) / range_m),
        _LINK_WEIGHT + np.concatenate([d[gw_a], d[gw_b], d]) / range_m,
    )
    ga, gb = group[cand_u], group[cand_v]
    key = np.minimum(ga, gb) * n + np.maximum(ga, gb)
    order = np.lexsort((weight, key))
    first = order[np.r_[True, key[order][1:] != key[order][:-1]]] if len(order) else order
    tree = minimum_spanning_tree(
        coo_matrix((weight[first], (np.minimum(ga, gb)[first], np.maximum(ga, gb)[first])), shape=(n, n)).tocsr()
    ).tocoo()
    kept_key = np.minimum(tree.row, tree.col) * n + np.maximum(tree.row, tree.col)
    chosen = first[np.isin(key[first], kept_key)]
    gw_edges = chosen[is_gw[chosen]]
    link_edges = chosen[~is_gw[chosen]]

    # Bridging gateways and the leaders each one must stay with (its own and the others).
    gw_robot = cand_u[gw_edges]
    bridging = np.zeros(n, bool)
    bridging[gw_robot] = True
    pinned = ~mobile
    link_u, link_v = cand_u[link_edges], cand_v[link_edges]
    # A bridging gateway that is also the end of a member-to-member bridge stays put.
    pinned[link_u[bridging[link_u]]] = True
    pinned[link_v[bridging[link_v]]] = True
    rigid = mobile & ~bridging & ~pinned
    gw_pairs_robot = np.concatenate([gw_robot, np.unique(gw_robot)])
    gw_pairs_leader = np.concatenate([cand_v[gw_edges], group[np.unique(gw_robot)]])

    # Leaders' wished steps, capped.
    move = np.zeros((n, 2))
    move[is_leader] = desired_mps[is_leader] * period_s
    length = np.hypot(*move.T)
    cap = speed_max_mps * period_s
    over = length > cap
    move[over] *= (cap / length[over])[:, None]

    # Constraints on leaders' steps: |offset + s move_k| <= radius.
    rows_k, rows_off, rows_r = [], [], []
    off = pos[gw_pairs_leader] - pos[gw_pairs_robot]
    rows_k.append(gw_pairs_leader)
    rows_off.append(off)
    rows_r.append(np.maximum(keep_m, np.hypot(*off.T)))
    both = rigid[link_u] & rigid[link_v]
    m = 0.5 * (pos[link_u] + pos[link_v])
    for x, y in ((link_u, link_v), (link_v, link_u)):
        half = both
        alone = rigid[x] & ~rigid[y]
        centre = np.where(half[:, None], m, pos[y])
        sel = half | alone
        o = pos[x[sel]] - centre[sel]
        rows_k.append(group[x[sel]])
        rows_off.append(o)
        rows_r.append(np.maximum(np.where(half[sel], keep_m / 2, keep_m), np.hypot(*o.T)))
    k = np.concatenate(rows_k).astype(np.int64)
    s = np.ones(n)
    if len(k):
        np.minimum.at(s, k, _step_limit(np.concatenate(rows_off), np.concatenate(rows_r), move[k]))
    # Members translate with their leader: the whole group stays inside the area.
    r_idx = np.flatnonzero(rigid)
    np.minimum.at(s, group[r_idx], _box_limit(pos[r_idx], move[group[r_idx]], side_m))
    wished = np.hypot(*move.T) > 0
    held = is_leader & wished & (s < _SAFETY)
    move *= s[:, None]

    step = np.zeros((n, 2))
    step[rigid] = move[group[rigid]]
    # Gateways: toward the centroid of their leaders' planned positions.
    gw = np.flatnonzero(bridging & ~pinned)
    if len(gw):
        planned = pos[gw_pairs_leader] + move[gw_pairs_leader]
        cnt = np.bincount(gw_pairs_robot, minlength=n)
        cx = np.bincount(gw_pairs_robot, weights=planned[:, 0], minlength=n)
        cy = np.bincount(gw_pairs_robot, weights=planned[:, 1], minlength=n)
        target = np.column_stack([cx[gw] / cnt[gw], cy[gw] / cnt[gw]])
        want = target - pos[gw]
        length = np.hypot(*want.T)
        over = length > cap
        want[over] *= (cap / length[over])[:, None]
        full = np.zeros((n, 2))
        full[gw] = want
        o = pos[gw_pairs_robot] - planned
        lim = _step_limit(o, np.maximum(keep_m, np.hypot(*o.T)), full[gw_pairs_robot])
        sg = np.ones(n)
        np.minimum.at(sg, gw_pairs_robot, lim)
        sg[gw] = np.minimum(sg[gw], _box_limit(pos[gw], want, side_m))
        step[gw] = want * sg[gw, None]
    velocity = step / period_s
    moving = np.hypot(*velocity.T) > 0
    commander = np.where(moving & ~is_leader, group, -1)
    return Plan(velocity, commander, held, len(chosen))


def wished_velocities(
    pos_now: np.ndarray,
    leaders: np.ndarray,
    neighbours: list[np.ndarray],
    law_name: str,
    range_m: float,
    gain: float,
    side_m: float,
) -> np.ndarray:
    """``gain x (resultant + border push)`` for each leader, from the neighbour positions it knows."""
    law = LAWS[law_name]
    out = np.zeros((len(leaders), 2))
    for k, (i, nb) in enumerate(zip(leaders.tolist(), neighbours)):
        p = pos_now[i]
        # Every law is zero from 2 r_c on, so farther leaders need no filtering here.
        out[k] = resultant(p, nb, law, range_m, gain) + border_force(p, side_m, range_m, gain)
    return out


def true_neighbours(pos: np.ndarray, leaders: np.ndarray, range_m: float) -> list[np.ndarray]:
    """For each leader, the true positions of the other leaders closer than ``2 r_c``."""
    lp = pos[leaders]
    tree = cKDTree(lp)
    return [lp[[j for j in js if j != k]] for k, js in enumerate(tree.query_ball_point(lp, 2 * range_m))]


class StepRecord(NamedTuple):
    t_s: float
    leaders: int
    moving_leaders: int
    held_leaders: int
    bridges: int
    components: int
    max_wished_speed_mps: float


class CoverageController:
    """The coverage controller of one run: proposes, then secures, each control step."""

    def __init__(self, sim, view: GroupView | None):
        self.sim = sim
        self.view = view
        self.cfg = sim.config.coverage
        self.range_m = float(np.min(sim.state.range_m))
        self.quiet_since = np.full(sim.state.n, np.nan)
        self.settled_s = math.nan
        self.got_command = np.zeros(sim.state.n, bool)
        self.commander = np.full(sim.state.n, -1)
        self.steps: list[StepRecord] = []
        self.samples: list[dict] = []
        self._max_wish = 0.0
        self.sample_at_start: dict | None = None

    # -- the two stages of a step --------------------------------------------------
    def propose(self, step: ControlStep) -> None:
        """Order 0: each leader's wished velocity from the forces it knows of."""
        now = self.sim.env.now
        leaders = np.flatnonzero(step.role == LEADER)
        pos_now = self.sim.state.positions_at(now)
        if self.cfg.knowledge == "global" or self.view is None:
            neighbours = true_neighbours(pos_now, leaders, self.range_m) if len(leaders) else []
        else:
            neighbours = [self.view.heard_leaders(i, now)[1] for i in leaders.tolist()]
        wished = wished_velocities(pos_now, leaders, neighbours, self.cfg.law, self.range_m, self.cfg.gain, step.side_m)
        speed = np.hypot(*wished.T) if len(leaders) else np.zeros(0)
        quiet = speed < self.cfg.stop_speed_mps
        wished[quiet] = 0.0
        step.velocity_mps[:] = 0.0
        step.velocity_mps[leaders] = wished
        qs = self.quiet_since[leaders]
        self.quiet_since[:] = np.nan
        self.quiet_since[leaders] = np.where(quiet, np.where(np.isnan(qs), now, qs), np.nan)
        if len(leaders) and quiet.all() and now - np.nanmax(self.quiet_since[leaders]) >= self.cfg.stop_hold_s:
            self.settled_s = now
            control_loop(self.sim).stop()
        self._max_wish = float(speed.max()) if len(speed) else 0.0

    def secure(self, step: ControlStep) -> None:
        """Order 100: make the plan keep every bridge; leaders send their commands."""
        c = self.cfg
        plan = plan_step(
            step.positions_m,
            step.role,
            step.leader,
            step.velocity_mps,
            step.period_s,
            self.range_m,
            c.margin_m,
            c.speed_max_mps,
            step.side_m,
        )
        step.velocity_mps[:] = plan.velocity_mps
        self.commander = plan.commander
        self.got_command[:] = False
        for leader in np.unique(plan.commander[plan.commander >= 0]).tolist():
            self.sim.channel.broadcast(leader, step.t_s, self._deliver, kind="command")
        comps = metrics.components(step.positions_m, self.range_m)
        leaders = step.role == LEADER
        self.steps.append(
            StepRecord(
                step.t_s,
                int(leaders.sum()),
                int((np.hypot(*plan.velocity_mps[leaders].T) > 0).sum()),
                int(plan.held.sum()),
                plan.bridges,
                int(comps.max() + 1) if len(comps) else 0,
                self._max_wish,
            )
        )

    def _deliver(self, sender: int, receivers: np.ndarray, _payload) -> None:
        self.got_command[receivers[self.commander[receivers] == sender]] = True

    def obey(self, step: ControlStep) -> None:
        """At the step's start: a robot that did not hear its leader's command holds."""
        missed = (self.commander >= 0) & ~self.got_command
        step.velocity_mps[missed] = 0.0

    # -- metrics over time -----------------------------------------------------------
    def sample(self, t: float) -> dict:
        st, c = self.sim.state, self.cfg
        pos = st.positions_at(t)
        radius = c.radius_m or self.range_m
        leaders = pos[st.role == LEADER]
        cov_l, err_l = metrics.covered_fraction(leaders, radius, st.side_m, c.grid_cells)
        cov_a, err_a = metrics.covered_fraction(pos, radius, st.side_m, c.grid_cells)
        comps = metrics.components(pos, self.range_m)
        spacing = metrics.nearest_spacing(leaders)
        travelled = distance_travelled(st.legs(), t)
        return {
            "t_s": t,
            "leaders": len(leaders),
            "covered_fraction_leaders": cov_l,
            "covered_fraction_all": cov_a,
            "covered_error_bound_leaders": err_l,
            "covered_error_bound_all": err_a,
            "components": int(comps.max() + 1),
            "connected": bool(comps.max() == 0),
            "spacing_median_ratio": float(np.median(spacing) / (SQRT3 * self.range_m))
            if len(leaders) > 1
            else math.nan,
            "hexagonality": metrics.hexagonality(leaders, SQRT3 * self.range_m),
            "distance_mean_m": float(travelled.mean()) if len(travelled) else 0.0,
        }

    def sampler(self):
        env = self.sim.env
        while True:
            self.samples.append(self.sample(env.now))
            yield env.timeout(self.cfg.metrics_interval_s)

    # -- outputs -----------------------------------------------------------------------
    def coverage_frame(self) -> pd.DataFrame:
        return pd.DataFrame(self.samples)

    def travel_frame(self) -> pd.DataFrame:
        """Distance each robot travelled over the run (the energy it spent moving)."""
        st = self.sim.state
        return pd.DataFrame({"robot": np.arange(st.n), "distance_m": distance_travelled(st.legs(), self.sim.env.now)})

    def control_frame(self) -> pd.DataFrame:
        return pd.DataFrame(self.steps, columns=list(StepRecord._fields))

    def summary(self, frames: dict[str, pd.DataFrame], duration_s: float) -> dict:
        last = self.sample(duration_s)
        steps = self.control_frame()
        start = self.sample_at_start
        return {
            "coverage_law": self.cfg.law,
            "coverage_knowledge": self.cfg.knowledge,
            "leaders_final": last["leaders"],
            "covered_fraction_leaders_start": start["covered_fraction_leaders"] if start else math.nan,
            "covered_fraction_leaders_final": last["covered_fraction_leaders"],
            "covered_fraction_all_start": start["covered_fraction_all"] if start else math.nan,
            "covered_fraction_all_final": last["covered_fraction_all"],
            "covered_error_bound_all": last["covered_error_bound_all"],
            "components_start": start["components"] if start else math.nan,
            "components_final": last["components"],
            "components_max_during_control": int(steps["components"].max()) if len(steps) else math.nan,
            "connected_final": last["connected"],
            "spacing_median_ratio_final": last["spacing_median_ratio"],
            "hexagonality_final": last["hexagonality"],
            "distance_mean_m": last["distance_mean_m"],
            "control_steps": len(steps),
            "control_settled_s": self.settled_s,
        }

    def _mark_start(self):
        yield self.sim.env.timeout(self.cfg.start_s)
        self.sample_at_start = self.sample(self.sim.env.now)


def install(sim) -> CoverageController:
    """The ``coverage`` controller plugin: wires the protocol's view into the control loop."""
    view = sim.models.get("protocol")
    if sim.config.coverage.knowledge == "acks" and not callable(getattr(view, "heard_leaders", None)):
        raise ConfigError(
            "coverage.knowledge",
            "acks",
            f"needs a protocol that tells which leaders were heard (protocol.model = 'clustering'), "
            f"not {sim.config.protocol.model!r}",
        )
    ctl = CoverageController(sim, view)
    loop = control_loop(sim)
    loop.add(ctl.propose, order=0)
    loop.add(ctl.secure, order=100)
    loop.before_apply.append(ctl.obey)
    sim.env.process(ctl.sampler())
    sim.env.process(ctl._mark_start())
    sim.trace.add_frame("coverage", ctl.coverage_frame)
    sim.trace.add_frame("control", ctl.control_frame)
    sim.trace.add_frame("travel", ctl.travel_frame)
    return ctl
