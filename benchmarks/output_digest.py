"""Fingerprints of every output table over a set of scenarios: the before/after check of a
change that must not change behaviour (a refactor, a speed-up, a new model whose default
must reproduce today's runs).

Each scenario is small (most have 30 robots and 60 simulated seconds) and the set covers every mobility
model, placement, protocol (the clustering, and the aodv, olsr and greedy routing protocols
with random pairs' messages and flows), policy, loss model, propagation model (log-distance,
shadowing, walls from the office and cave maps), coverage mode (spread and follow, exact and
grid area) and controller, and every table (the replay's ``legs`` and ``hops``, and the
flows' ``packets`` and ``flows``, included).
For each scenario the script runs it, converts every output table to Parquet in memory
and records the SHA-256 of its bytes (with pandas' metadata: a changed dtype or column
order changes the digest too). The run's wall time and the package versions are not part
of the fingerprint.

    python benchmarks/output_digest.py --write digests.json     # before the change
    python benchmarks/output_digest.py --check digests.json     # after: prints a table
    python benchmarks/output_digest.py --list                   # the scenarios
    python benchmarks/output_digest.py --check digests.json --ignore legs.cause

``--check`` exits with status 1 if any table differs, and names the tables that do.
``--ignore TABLE.COLUMN`` (repeatable) fingerprints a table without one of its columns
(``summary.KEY``: the summary without that key): the check of a change that adds a column
or a summary figure and must leave everything else as it was.
"""

from __future__ import annotations

import hashlib
import io
import json
import sys
import tempfile
from pathlib import Path

from netsim.tools.args import Parser

BASE = ["world.n_robots=30", "duration_s=60", "world.side_m=500", "channel.range_m=120"]
COVERAGE = [
    "world.n_robots=30",
    "duration_s=80",
    "world.side_m=800",
    "world.placement=centre",
    "world.centre_side_m=200",
    "mobility.model=static",
    "channel.range_m=100",
    "coverage.enabled=true",
    "protocol.message_rate_hz=0",
]

# The local plan on the office map from a connected start.
OFFICE_LOCAL = COVERAGE + [
    "world.n_robots=12",
    "world.map=office",
    "world.side_m=200",
    "world.placement=connected",
    "world.centre_side_m=60",
    "coverage.plan=local",
    "duration_s=60",
]

# A flow across the team: packets of three frames every half second.
FLOW = "{src = 0, dst = 29, start_s = 10.0, stop_s = 50.0, rate_bps = 64000.0, packet_bytes = 4000}"

OFFICE = ["world.map=office", "world.side_m=200", "channel.range_m=40", "mobility.stationary_start=false"]

SCENARIOS: dict[str, list[str]] = {
    "rwp_clustering": [],
    "rwp_fresh_start": ["mobility.stationary_start=false", "world.placement=grid"],
    "rwp_ack_only": ["protocol.model=ack"],
    "rwp_no_protocol": ["protocol.model=none"],
    "random_direction": ["mobility.model=random_direction", "mobility.pause_s=1"],
    "random_direction_torus": [
        "mobility.model=random_direction",
        "world.torus=true",
        "mobility.turn_interval_s=7",
    ],
    "static_grid": ["mobility.model=static", "world.placement=grid"],
    "trace_replay": ["mobility.model=trace", "mobility.trace_file={trace}"],
    "join_first_heard": ["protocol.join_policy=first_heard"],
    "join_lowest_id": ["protocol.join_policy=lowest_id"],
    "merge_lowest_id": ["protocol.merge_policy=lowest_id_wins"],
    "merge_highest_degree": ["protocol.merge_policy=highest_degree_wins"],
    "election_degree": ["protocol.election_policy=highest_degree"],
    "election_none": ["protocol.election_policy=none"],
    "oracle_routing": ["protocol.routing=oracle", "protocol.message_rate_hz=1"],
    "strict_backbone": ["protocol.distributed_gateways=false", "protocol.message_rate_hz=1"],
    "bernoulli_loss_jitter": ["channel.loss_probability=0.2", "channel.latency_jitter_s=0.01"],
    "distance_loss": ["channel.loss_model=distance", "channel.loss_probability=0.05"],
    "gilbert_elliott": ["channel.loss_model=gilbert_elliott"],
    "unequal_ranges": ["channel.range_m=[{ranges}]"],
    "coverage_spring": COVERAGE,
    "coverage_repulsion_global": COVERAGE + ["coverage.law=repulsion", "coverage.knowledge=global"],
    "coverage_inverse_square": COVERAGE + ["coverage.law=inverse_square"],
    "coverage_grid_area": COVERAGE + ["coverage.area_method=grid", "coverage.grid_cells=100"],
    "coverage_follow": COVERAGE + ["coverage.members=follow"],
    "coverage_follow_global": COVERAGE
    + ["coverage.members=follow", "coverage.knowledge=global", "coverage.law=repulsion"],
    "coverage_local_shadowing": COVERAGE
    + ["coverage.plan=local", "channel.propagation=log_distance", "channel.shadowing_sigma_db=4"],
    "controllers": COVERAGE + ['control.controllers=["avoid_collisions", "log_separation"]'],
    "hooks_without_coverage": ['control.controllers=["log_separation"]', "control.options={min_separation_m = 5.0}"],
    "overtaken_acks": ["channel.latency_jitter_s=1.5", "protocol.tau_s=4", "protocol.message_rate_hz=1"],
    "placement_centre_rwp": ["mobility.stationary_start=false", "world.placement=centre", "world.centre_side_m=200"],
    "placement_csv": ["mobility.model=static", "world.placement={csv}"],
    "no_positions_sampled": ["output.position_interval_s=0"],
    # The radio (channel.propagation, shadowing, walls from a map).
    "log_distance": ["channel.propagation=log_distance"],
    "log_distance_shadowing": ["channel.propagation=log_distance", "channel.shadowing_sigma_db=6"],
    "receptions_shadowing": [
        "channel.propagation=log_distance",
        "channel.shadowing_sigma_db=6",
        "output.receptions=true",
    ],
    "receptions_unicast": [
        "channel.propagation=log_distance",
        "protocol.message_rate_hz=1",
        "output.receptions=true",
    ],
    # The shared medium: collisions on the unit disk; SINR and capture under a power radio.
    "mac_aloha": ["channel.mac=aloha", "protocol.message_rate_hz=1"],
    "mac_csma_power_receptions": [
        "channel.mac=csma",
        "channel.propagation=log_distance",
        "channel.shadowing_sigma_db=6",
        "protocol.message_rate_hz=1",
        "output.receptions=true",
    ],
    "office_unit_disk": OFFICE,
    "office_log_distance_shadowing": OFFICE
    + ["channel.propagation=log_distance", "channel.shadowing_sigma_db=4", "channel.sensitivity_dbm=-68"],
    "office_random_direction_log_distance": OFFICE
    + ["mobility.model=random_direction", "channel.propagation=log_distance", "channel.sensitivity_dbm=-68"],
    "office_coverage_local": OFFICE_LOCAL + ["channel.range_m=30"],
    # The local plan's links certified through walls (log-distance, 5 dB a wall).
    "office_coverage_local_through_walls": OFFICE_LOCAL
    + ["channel.propagation=log_distance", "channel.wall_loss_db=5", "channel.sensitivity_dbm=-64.3"],
    # The global plan's kept links under shadowing and walls together (the range at both).
    "office_coverage_walls_shadowing": COVERAGE
    + [
        "world.n_robots=20",
        "world.map=office",
        "world.side_m=200",
        "world.centre_side_m=40",
        "channel.propagation=log_distance",
        "channel.shadowing_sigma_db=4",
        "channel.wall_loss_db=5",
        "channel.sensitivity_dbm=-64.3",
        "duration_s=60",
    ],
    "cave_coverage": COVERAGE
    + ["world.map=cave", "world.side_m=200", "world.centre_side_m=60", "channel.range_m=30", "duration_s=40"],
    # The routing protocols with random pairs' messages, and flows of packets of several
    # frames under the clustering's relay and under AODV on a shared medium.
    "aodv_pairs": ["protocol.model=aodv", "protocol.message_rate_hz=2"],
    "olsr_pairs": ["protocol.model=olsr", "protocol.message_rate_hz=2"],
    "greedy_pairs": ["protocol.model=greedy", "protocol.message_rate_hz=2"],
    "clustering_flows": [f"traffic.flows=[{FLOW}]"],
    "aodv_flows_csma": ["protocol.model=aodv", "channel.mac=csma", f"traffic.flows=[{FLOW}]"],
}


def _trace_file(directory: Path) -> Path:
    from netsim.tools.cli import main

    path = directory / "trace.tcl"
    if not path.exists():
        args = "--n 30 --side 500 --speed-min 1 --speed-max 4 --pause 1 --duration 60 --seed 4"
        main(["scenario", "generate", *args.split(), "-o", str(path)])
    return path


def _csv_file(directory: Path) -> Path:
    path = directory / "placement.csv"
    if not path.exists():
        rows = [f"{50.0 + 13.0 * (i % 6) + i:.1f},{40.0 + 11.0 * (i // 6):.1f}" for i in range(30)]
        path.write_text("x_m,y_m\n" + "\n".join(rows) + "\n")
    return path


def overrides(name: str, directory: Path) -> list[str]:
    out = []
    for text in BASE + SCENARIOS[name]:
        if "{trace}" in text:
            text = text.format(trace=_trace_file(directory))
        if "{csv}" in text:
            text = text.format(csv=_csv_file(directory))
        if "{ranges}" in text:
            text = text.format(ranges=", ".join(str(80.0 + 3 * (i % 20)) for i in range(30)))
        out.append(text)
    return out


def digest(name: str, directory: Path, ignore: tuple[str, ...] = ()) -> dict[str, str]:
    """SHA-256 of each output table of scenario ``name``, and of its summary (minus wall
    time); ``ignore`` lists ``table.column`` names left out of the fingerprint."""
    from netsim import load
    from netsim.run import execute

    result = execute(load(None, overrides(name, directory)))
    out = {}
    for table, frame in sorted(result.frames.items()):
        dropped = [c.partition(".")[2] for c in ignore if c.partition(".")[0] == table]
        frame = frame.drop(columns=[c for c in dropped if c in frame.columns])
        buf = io.BytesIO()
        frame.to_parquet(buf, index=False)
        out[table] = hashlib.sha256(buf.getvalue()).hexdigest()[:16]
    summary = {k: v for k, v in result.summary.items() if k != "wall_s" and f"summary.{k}" not in ignore}
    out["summary"] = hashlib.sha256(json.dumps(summary, sort_keys=True, default=str).encode()).hexdigest()[:16]
    return out


def main(argv=None) -> int:
    p = Parser(description=__doc__.splitlines()[0])
    g = p.add_mutually_exclusive_group(required=True)
    g.add_argument("--write", metavar="FILE", help="write the digests of every scenario to FILE")
    g.add_argument("--check", metavar="FILE", help="compare with FILE; exit 1 on any difference")
    g.add_argument("--list", action="store_true", help="list the scenarios and their overrides")
    p.add_argument("--only", nargs="*", help="scenarios to run (default: all)")
    p.add_argument(
        "--ignore", action="append", default=[], metavar="TABLE.COLUMN", help="leave a column out of the fingerprints"
    )
    args = p.parse_args(argv)
    names = args.only or list(SCENARIOS)
    with tempfile.TemporaryDirectory() as tmp:
        directory = Path(tmp)
        if args.list:
            for name in names:
                print(name, " ".join(overrides(name, directory)))
            return 0
        got = {}
        for name in names:
            got[name] = digest(name, directory, tuple(args.ignore))
            print(f"{name:<28} {len(got[name])} tables", file=sys.stderr)
    if args.write:
        Path(args.write).write_text(json.dumps(got, indent=1, sort_keys=True) + "\n")
        print(f"wrote {args.write}: {len(got)} scenarios")
        return 0
    want = json.loads(Path(args.check).read_text())
    differ = 0
    print(f"{'scenario':<28} {'table':<12} result")
    for name in names:
        old, new = want.get(name, {}), got[name]
        for table in sorted(set(old) | set(new)):
            if old.get(table) == new.get(table):
                status = "same"
            elif table not in old:
                status = "new table"
            elif table not in new:
                status = "MISSING"
                differ += 1
            else:
                status = "DIFFERENT"
                differ += 1
            if status != "same":
                print(f"{name:<28} {table:<12} {status}")
    print(f"{len(names)} scenarios: {'identical' if not differ else f'{differ} tables differ'}")
    return 1 if differ else 0


if __name__ == "__main__":
    sys.exit(main())
