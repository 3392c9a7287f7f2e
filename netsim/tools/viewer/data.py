"""A run directory packed for the replay page: a small JSON header and one binary blob.

The blob is every array the page needs, little-endian, each aligned to 8 bytes,
concatenated, gzip-compressed and base64-encoded; the header names each array's type,
offset and length. The page decompresses it with the browser's own ``DecompressionStream``
and reads the arrays as typed arrays without copying.

What is packed (``N`` robots):

- motion: ``legs.parquet`` when the run has it (exact: the page evaluates each robot's
  leg at the cursor), else ``positions.parquet`` (interpolated linearly between samples);
- ``links``: every link lifetime, sorted by the time it came up (a link still up at the
  end stays up through the last instant);
- ``roles``: every role change in order, and each group's colour for the whole run
  (:func:`netsim.tools.style.run_group_slots`, as in the figures); ``groups``: the
  gateways' memberships per sample; ``beliefs``: believed, true, stale and missing
  neighbours of every robot per sample, and with ``neighbour_beliefs`` their ids;
- ``messages`` and ``hops``: every relayed message and each robot's first reception of it
  (a routing protocol's run: its packets, :func:`routed_packets`);
- the strip chart's series (:func:`series`) and, when the run has a map, its occupancy grid
  (:class:`MapGrid`).
"""

from __future__ import annotations

import base64
import gzip
import math
from pathlib import Path
from typing import NamedTuple

import numpy as np
import pandas as pd

from netsim import config as cfgmod
from netsim.config import world_bounds
from netsim.errors import NetsimInputError
from netsim.geometry import row_starts
from netsim.metrics import components_in_links_table
from netsim.plugins import RoleLabels
from netsim.tools import style
from netsim.tools.output import existing_dir, load_run_config, read_run_summary, read_run_table, run_map
from netsim.trajectory import sample_positions


def role_codes(labels: RoleLabels | None) -> dict[str, int]:
    """The page's role codes (0 undecided, 1 member, 2 leader) of the run's role labels."""
    return {} if labels is None else {labels.undecided: 0, labels.member: 1, labels.leader: 2}


# Points of the sampled chart series (components of the network).
CHART_POINTS = 600


class MapGrid(NamedTuple):
    """An occupancy grid drawn under the robots: ``occupied[row, col]`` is true for a wall,
    row 0 at the bottom (``y = origin_m[1]``), cells ``resolution_m`` wide (the ROS
    ``map_server`` convention once its image is flipped upside down)."""

    occupied: np.ndarray
    resolution_m: float
    origin_m: tuple[float, float]


class Blob:
    """Arrays laid end to end, each 8-byte aligned, and their index for the page."""

    CODES = {
        np.dtype("<f8"): "f64",
        np.dtype("<f4"): "f32",
        np.dtype("<i4"): "i32",
        np.dtype("<i2"): "i16",
        np.dtype("<u2"): "u16",
        np.dtype("u1"): "u8",
        np.dtype("i1"): "i8",
    }

    def __init__(self):
        self.parts: list[bytes] = []
        self.index: dict[str, list] = {}
        self.size = 0

    def add(self, name: str, values, dtype: str) -> None:
        arr = np.ascontiguousarray(np.asarray(values).ravel(), dtype=np.dtype(dtype).newbyteorder("<"))
        raw = arr.tobytes()
        self.index[name] = [self.CODES[arr.dtype], self.size, int(arr.size)]
        pad = -len(raw) % 8
        self.parts.append(raw + b"\0" * pad)
        self.size += len(raw) + pad

    def encoded(self) -> str:
        # mtime=0: the same run gives the same page, byte for byte.
        return base64.b64encode(gzip.compress(b"".join(self.parts), compresslevel=6, mtime=0)).decode("ascii")


def _small_uint(values: np.ndarray) -> str:
    return "<u2" if values.size == 0 or int(values.max()) < 2**16 else "<i4"


def _read(run_dir: Path, name: str, n: int) -> pd.DataFrame | None:
    return read_run_table(run_dir, name, n)


def leaders_series(roles: pd.DataFrame, leader_label: str) -> tuple[np.ndarray, np.ndarray]:
    """The number of leaders after each role change (a step function, exact)."""
    if roles.empty:
        return np.zeros(1), np.zeros(1)
    r = roles.reset_index(drop=True)
    is_leader = (r["role"] == leader_label).to_numpy()
    robot = r["robot"].to_numpy(np.int64)
    was = np.zeros(int(robot.max()) + 1, dtype=bool)
    delta = np.empty(len(r), dtype=np.int64)
    for k, (i, now) in enumerate(zip(robot.tolist(), is_leader.tolist())):
        delta[k] = int(now) - int(was[i])
        was[i] = now
    return r["t_s"].to_numpy(float), np.cumsum(delta)


def series(
    config: cfgmod.Config,
    links: pd.DataFrame,
    roles: pd.DataFrame,
    ack_delivery: pd.DataFrame | None,
    messages: pd.DataFrame | None,
    coverage: pd.DataFrame | None,
    blob: Blob,
    labels: RoleLabels | None = None,
    noun: str = "message",
) -> list[dict]:
    """The strip chart: what each series is, and its arrays in ``blob``; ``noun``: what
    ``messages`` lists (a routing protocol's packets)."""
    n, duration = config.world.n_robots, config.duration_s
    out = []

    def add(name, label, t, v, kind, axis):
        blob.add(f"s_{name}_t", t, "<f8")
        blob.add(f"s_{name}_v", v, "<f8")
        out.append({"name": name, "label": label, "kind": kind, "axis": axis})

    if labels is not None and not roles.empty:
        add("leaders", "leaders", *leaders_series(roles, labels.leader), "step", "count")
    times = np.linspace(0.0, duration, CHART_POINTS + 1)
    add("components", "components", times, components_in_links_table(links, n, times), "sample", "count")
    if coverage is not None and len(coverage):
        t = coverage["t_s"].to_numpy(float)
        for who, label in (("leaders", "leaders' disks"), ("all", "all robots' disks")):
            v = coverage[f"covered_fraction_{who}"]
            add(f"covered_{who}", f"covered fraction ({label})", t, v, "line", "fraction")
    if ack_delivery is not None and len(ack_delivery):
        # A step over each interval of send time [t_s, t_s + dt): the ratio of the Acks sent in it.
        t = ack_delivery["t_s"].to_numpy(float)
        add("ack_delivery", "Ack delivery ratio", t, ack_delivery["delivery_ratio"], "step", "fraction")
    if messages is not None and len(messages):
        # At each send and each arrival: of the messages sent by then, those arrived by then
        # (a message counts once it has arrived, not from its sending on, as the side panel).
        sent = np.sort(messages["t_sent_s"].to_numpy(float))
        arrived = np.sort(messages.loc[messages["delivered"].to_numpy(bool), "t_delivered_s"].to_numpy(float))
        t = np.unique(np.concatenate([sent, arrived]))
        ratio = np.searchsorted(arrived, t, "right") / np.searchsorted(sent, t, "right")
        add("delivered", f"{noun}s delivered (of those sent so far)", t, ratio, "step", "fraction")
    return out


def first_receptions(hops: pd.DataFrame, messages: pd.DataFrame) -> pd.DataFrame:
    """Each robot's first reception of each message (the source's excluded), sorted by
    the time its transmission was sent: the tree along which the message spread. The
    page draws these; the repeats (a robot hearing a copy it already has) would only bury
    it, many times over in a dense flood."""
    h = hops.sort_values("t_received_s", kind="stable").drop_duplicates(["msg_id", "receiver"])
    src = messages.set_index("msg_id")["src"].reindex(h["msg_id"]).to_numpy()
    return h[h["receiver"].to_numpy() != src].sort_values(["t_sent_s", "t_received_s"], kind="stable")


def routed_packets(run_dir: Path, hops: pd.DataFrame | None, n: int) -> tuple[pd.DataFrame | None, pd.DataFrame | None]:
    """A routing protocol's run has no messages table: its packets (packets.parquet) are
    the replay's messages, ``msg_id`` a packet's place in order of sending, and each hop
    (which names its packet's ``flow`` and ``packet``) is put under its packet's id; a
    packet of several frames shows the hops of all of them. ``(None, hops)`` for a run
    without packets; no hops for one whose hops name no packet (written before they did)."""
    packets = _read(run_dir, "packets", n)
    if packets is None:
        return None, hops
    packets = packets.sort_values("t_sent_s", kind="stable").reset_index(drop=True)
    packets["msg_id"] = np.arange(len(packets), dtype=np.int64)
    if hops is None or not {"flow", "packet"} <= set(hops.columns):
        return packets, None
    ids = packets.set_index(["flow", "packet"])["msg_id"]
    key = pd.MultiIndex.from_frame(hops[["flow", "packet"]])
    if not key.isin(ids.index).all():
        raise NetsimInputError(f"{run_dir}/hops.parquet: names a packet packets.parquet does not list")
    return packets, hops.assign(msg_id=ids.reindex(key).to_numpy())


def _motion(run_dir: Path, n: int, blob: Blob) -> str:
    legs = _read(run_dir, "legs", n)
    if legs is not None and len(legs):
        legs = legs.sort_values(["robot", "t_s"], kind="stable")
        robot = legs["robot"].to_numpy(np.int64)
        first = row_starts(robot, n)
        if np.any(first[1:] == first[:-1]):
            raise NetsimInputError(f"{run_dir}/legs.parquet: some robot has no leg")
        blob.add("legs_first", first, "<i4")
        for col, name in (("t_s", "t"), ("x_m", "x"), ("y_m", "y"), ("vx_mps", "vx"), ("vy_mps", "vy")):
            blob.add(f"legs_{name}", legs[col], "<f8")
        return "legs"
    pos = _read(run_dir, "positions", n)
    if pos is None or pos.empty:
        raise NetsimInputError(f"{run_dir}: no legs.parquet and no sampled positions.parquet to draw robots from")
    pos = pos.sort_values(["t_s", "robot"], kind="stable")
    times = np.unique(pos["t_s"].to_numpy(float))
    if len(pos) != len(times) * n:
        raise NetsimInputError(f"{run_dir}/positions.parquet: expected {n} robots at every sample")
    blob.add("pos_t", times, "<f8")
    blob.add("pos_xy", pos[["x_m", "y_m"]].to_numpy(), "<f8")
    return "positions"


def _torus_side(config: cfgmod.Config) -> float | None:
    return config.world.torus_side_m


def _colouring_positions(run_dir: Path, config: cfgmod.Config) -> pd.DataFrame:
    """The instants the groups' colours are decided at: the sampled positions, as the
    figures use (the legs at every Ack period when positions were not sampled)."""
    n = config.world.n_robots
    pos = _read(run_dir, "positions", n)
    if pos is not None and len(pos):
        return pos
    legs = _read(run_dir, "legs", n)
    if legs is None or legs.empty:
        return pd.DataFrame({"t_s": [], "robot": [], "x_m": [], "y_m": []})
    step = cfgmod.to_dict(config)["protocol"].get("ack_period_s", 1.0)
    times = np.arange(int(math.floor(config.duration_s / step + 1e-9)) + 1) * step
    return sample_positions(legs, n, times, config.world.side_m, config.world.torus)


def _pack_neighbour_beliefs(run_dir: Path, nb: pd.DataFrame, times: np.ndarray, n: int, blob: Blob) -> None:
    """Each robot's neighbours by id at the beliefs samples, as runs: robot ``i``'s runs
    are ``nb_first[i]`` to ``nb_first[i + 1]``, sorted by neighbour, each one neighbour
    ``nb_id`` with the same flags (1: believed, 2: in range) from sample ``nb_k0`` to
    ``nb_k1``. A neighbour table changes far less often than it is sampled: runs take a
    fraction of the space of the rows."""
    t = nb["t_s"].to_numpy(float)
    k = np.searchsorted(times, t)
    if len(nb) and (np.any(k >= len(times)) or np.any(times[np.minimum(k, len(times) - 1)] != t)):
        raise NetsimInputError(f"{run_dir}/neighbour_beliefs.parquet: sampled at other times than beliefs.parquet")
    robot = nb["robot"].to_numpy(np.int64)
    other = nb["neighbour"].to_numpy(np.int64)
    flags = nb["believed"].to_numpy(bool) * 1 + nb["in_range"].to_numpy(bool) * 2
    order = np.lexsort((k, other, robot))
    robot, other, k, flags = robot[order], other[order], k[order], flags[order]
    start = np.ones(len(k), dtype=bool)
    start[1:] = (
        (robot[1:] != robot[:-1]) | (other[1:] != other[:-1]) | (k[1:] != k[:-1] + 1) | (flags[1:] != flags[:-1])
    )
    first = np.flatnonzero(start)
    last = np.r_[first[1:], len(k)][: len(first)] - 1
    blob.add("nb_first", row_starts(robot[first], n), "<i4")
    blob.add("nb_id", other[first], _small_uint(other))
    blob.add("nb_k0", k[first], _small_uint(k))
    blob.add("nb_k1", k[last], _small_uint(k))
    blob.add("nb_flags", flags[first], "u1")


def _empty_links() -> pd.DataFrame:
    return pd.DataFrame(
        {"a": np.empty(0, np.int64), "b": np.empty(0, np.int64), "t_up_s": np.empty(0), "t_down_s": np.empty(0)}
        | {"censored_end": np.empty(0, bool)}
    )


def pack(run_dir: str | Path, map_grid: MapGrid | None = None) -> dict:
    """Everything the page shows of the run in ``run_dir``: ``{"meta": ..., "blob": ...}``."""
    run_dir = existing_dir(run_dir)
    config = load_run_config(run_dir)
    n, duration = config.world.n_robots, config.duration_s
    blob = Blob()
    motion = _motion(run_dir, n, blob)

    ranges = np.broadcast_to(np.asarray(config.ranges_m(), float), (n,))
    blob.add("range_m", ranges, "<f8")

    links = _read(run_dir, "links", n)
    links = _empty_links() if links is None or links.empty else links.sort_values("t_up_s", kind="stable")
    blob.add("link_a", links["a"], "<i4")
    blob.add("link_b", links["b"], "<i4")
    blob.add("link_up", links["t_up_s"], "<f8")
    blob.add("link_down", np.where(links["censored_end"].to_numpy(bool), np.inf, links["t_down_s"]), "<f8")

    roles = _read(run_dir, "roles", n)
    if roles is None:
        roles = pd.DataFrame({"t_s": [], "robot": [], "role": [], "leader": []})
    roles = roles.sort_values("t_s", kind="stable")
    blob.add("role_t", roles["t_s"], "<f8")
    blob.add("role_robot", roles["robot"], "<i4")
    labels = config.protocol.plugin.role_labels
    blob.add("role_code", roles["role"].map(role_codes(labels)).fillna(0), "i1")
    blob.add("role_leader", roles["leader"], "<i4")
    colour_of = np.full(n, -1)
    if labels is not None:
        slots = style.run_group_slots(
            roles, _colouring_positions(run_dir, config), labels.leader, float(ranges.min()), _torus_side(config)
        )
        colour_of[list(slots)] = list(slots.values())
    blob.add("colour_of", colour_of, "<i2")

    groups = _read(run_dir, "groups", n)
    has_groups = groups is not None and len(groups) > 0
    if has_groups:
        times = np.unique(groups["t_s"].to_numpy(float))
        count = groups.groupby(["t_s", "robot"])["group"].transform("size")
        gw = groups[count > 1].sort_values(["t_s", "robot", "group"], kind="stable")
        blob.add("grp_t", times, "<f8")
        blob.add("grp_first", np.searchsorted(gw["t_s"].to_numpy(float), np.r_[times, np.inf], "left"), "<i4")
        blob.add("grp_robot", gw["robot"], "<i4")
        blob.add("grp_group", gw["group"], "<i4")
        blob.add("grp_primary", gw["primary"].to_numpy(bool), "u1")

    beliefs = _read(run_dir, "beliefs", n)
    has_beliefs = beliefs is not None and len(beliefs) > 0
    if has_beliefs:
        b = beliefs.sort_values(["t_s", "robot"], kind="stable")
        bel_times = np.unique(b["t_s"].to_numpy(float))
        if len(b) != len(bel_times) * n:
            raise NetsimInputError(f"{run_dir}/beliefs.parquet: expected {n} robots at every sample")
        blob.add("bel_t", bel_times, "<f8")
        for col in ("believed", "true", "stale", "missing"):
            v = b[f"{col}_neighbours"].to_numpy(np.int64)
            blob.add(f"bel_{col}", v, _small_uint(v))
        blob.add("bel_leader_in_range", b["leader_in_range"].to_numpy(bool), "u1")
    nb = _read(run_dir, "neighbour_beliefs", n) if has_beliefs else None
    has_neighbour_beliefs = nb is not None
    if has_neighbour_beliefs:
        _pack_neighbour_beliefs(run_dir, nb, bel_times, n, blob)

    messages = _read(run_dir, "messages", n)
    hops = _read(run_dir, "hops", n)
    routed = False
    if messages is None:
        messages, hops = routed_packets(run_dir, hops, n)
        routed = messages is not None
    has_messages = messages is not None and len(messages) > 0
    if has_messages:
        m = messages.sort_values("msg_id", kind="stable")
        blob.add("msg_src", m["src"], "<i4")
        blob.add("msg_dst", m["dst"], "<i4")
        blob.add("msg_t", m["t_sent_s"], "<f8")
        blob.add("msg_delivered", m["delivered"].to_numpy(bool), "u1")
        blob.add("msg_t_delivered", m["t_delivered_s"].astype(float), "<f8")
    has_hops = has_messages and hops is not None and len(hops) > 0
    if has_hops:
        h = first_receptions(hops, messages)
        blob.add("hop_msg", h["msg_id"], "<i4")  # indexes the messages arrays (ids 0, 1, ... in order)
        blob.add("hop_n", h["hop"], "<i4")
        blob.add("hop_sender", h["sender"], "<i4")
        blob.add("hop_receiver", h["receiver"], "<i4")
        blob.add("hop_t_sent", h["t_sent_s"], "<f8")
        blob.add("hop_t_received", h["t_received_s"], "<f8")

    coverage = _read(run_dir, "coverage", n)
    ack_delivery = _read(run_dir, "ack_delivery", n)
    # A routing protocol's replay draws packets where the clustering's draws messages.
    noun = "packet" if routed else "message"
    chart = series(config, links, roles, ack_delivery, messages, coverage, blob, labels, noun)

    map_meta = None
    if map_grid is None and config.world.map:
        m = run_map(run_dir, config)
        map_grid = MapGrid(m.occupied, m.resolution_m, m.origin_m)
    if map_grid is not None:
        occ = np.asarray(map_grid.occupied, dtype=bool)
        if occ.ndim != 2:
            raise ValueError(f"an occupancy grid has two dimensions, got shape {occ.shape}")
        blob.add("map_occupied", occ, "u1")
        map_meta = {
            "width": int(occ.shape[1]),
            "height": int(occ.shape[0]),
            "resolution_m": float(map_grid.resolution_m),
            "origin_m": [float(map_grid.origin_m[0]), float(map_grid.origin_m[1])],
        }

    summary = read_run_summary(run_dir)
    interval = config.output.position_interval_s
    # Keys of the run's models, where they have them.
    tree = cfgmod.to_dict(config)
    mobility, protocol, cover = tree["mobility"], tree["protocol"], tree.get("coverage", {})
    meta = {
        "format": 1,
        "title": run_dir.resolve().name,
        "n": n,
        "side_m": config.world.side_m,
        "bounds_m": world_bounds(config.world).as_list(),
        "torus": config.world.torus,
        "duration_s": duration,
        "step_s": interval if interval > 0 else protocol.get("ack_period_s", 1.0),
        "motion": motion,
        "coverage_radius_m": cover.get("radius_m", 0.0) or float(ranges.min()),
        "coverage": bool(cover.get("enabled", False)),
        "protocol": config.protocol.model,
        "mobility": config.mobility.model,
        "seed": config.seed,
        "message_noun": noun,
        "has": {
            "roles": not roles.empty,
            "groups": has_groups,
            "beliefs": has_beliefs,
            "neighbour_beliefs": has_neighbour_beliefs,
            "messages": has_messages,
            "hops": has_hops,
        },
        "scenario": {
            "n_robots": n,
            "speed_min_mps": mobility.get("speed_min_mps"),
            "speed_max_mps": mobility.get("speed_max_mps"),
            "duration_s": duration,
            "range_m": float(ranges.min()) if np.all(ranges == ranges[0]) else [float(r) for r in ranges],
            "side_m": config.world.side_m,
            "mobility": config.mobility.model,
            "seed": config.seed,
        },
        # Plain figures only; JSON has no NaN or infinity.
        "summary": {
            k: v for k, v in summary.items() if isinstance(v, str) or (isinstance(v, int | float) and math.isfinite(v))
        },
        "palette": style.as_json(),
        "series": chart,
        "map": map_meta,
        "arrays": blob.index,
    }
    return {"meta": meta, "blob": blob.encoded()}
