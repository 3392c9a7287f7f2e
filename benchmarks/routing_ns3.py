"""netsim's aodv and olsr against ns-3's (the ns-3.44 wheel: ns.AodvHelper, ns.OlsrHelper) on
the same scenarios: a static line and grid, and a mobile team replayed from one ns-2 trace
(``netsim scenario generate``, read by netsim and by ns-3's Ns2MobilityHelper), range
propagation (a unit disk), no loss, light flows (from one end to the other of the line and
the grid; from robot 0 to four others of the team, whose routes break and change).
Compared: the flows' delivery ratio, their packets' mean hop count, and control packets
per second, network-wide; control messages per second are printed beside them (an OLSR
packet carries one or more). netsim's OLSR robots start at t = 0 like ns-3's nodes
(``protocol.start_spread_s = 0``).

    bash benchmarks/ns3_env.sh .ns3venv          # once: the ns-3 wheel (a few minutes)
    python benchmarks/routing_ns3.py --ns3-python .ns3venv/bin/python
    python benchmarks/routing_ns3.py --only line --protocols aodv
    python benchmarks/routing_ns3.py --only mobile --trace team.ns2   # a trace of your own
    python benchmarks/routing_ns3.py --only large                    # the speed of both

Each side also times its run alone: netsim's ``Simulation.run`` and ns-3's
``Simulator::Run`` (neither side's imports nor its building of the scenario), wall and CPU
seconds, printed beside the figures with their ratio (ns-3's over netsim's: above 1, netsim
is faster). ``large`` is a team of 100 on a square of 1,826 m (the mobile team's density),
ten flows between robots k and 99 - k: a workload to time (its figures are compared as the
others'). ``--mac csma`` runs netsim's side on its shared medium (CSMA/CA, as ns-3's
802.11 is) instead of its collision-free channel; its frames all go at netsim's
``channel.data_rate_bps`` (1 Mbit/s) without IP, UDP or MAC headers, where ns-3 sends
unicasts at 11 Mbit/s and broadcasts at 1 Mbit/s, with those headers and a MAC
acknowledgement on the air.

Each row runs netsim (this interpreter) and ns-3 (``--ns3-python``, this script with
``--side ns3``); the table says whether each figure is within its tolerance (TOLERANCE)
and the script exits 1 if any is not.

ns-3's side: 802.11b ad hoc at 11 Mbit/s, RangePropagationLossModel (MaxRange = the range),
constant positions (the mobile team: Ns2MobilityHelper), IPv4/UDP; each flow a UDP socket
sending ``--packet-bytes`` every ``--interval`` s; hops from the TTL the packet arrives with (65 - TTL, sent with 64);
control packets counted at every node's IPv4 Tx trace by their UDP port (654: AODV, 698:
OLSR); OLSR's messages counted at its Tx trace (the messages of each packet sent), AODV's
one per packet.

Address resolution: netsim has none (a frame goes to its next hop by id), so by default
(``--ns3-arp static``) every ns-3 node's ARP cache holds a permanent entry for every other
node before the run, and ARP sends nothing. ``--ns3-arp dynamic`` is ns-3's own ARP:
broadcast requests (lost in collisions like any frame), at most 3 packets waiting per
unresolved next hop, 3 retries a second apart, and an entry that failed them is dead for
100 s (ArpCache's DeadTimeout): every packet routed to that neighbour meanwhile is dropped
by ARP, with no word to the routing protocol (what that costs on the large team:
docs/performance.md).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

try:
    from netsim.tools.args import Parser
except ImportError:  # ns-3's own Python, where this script also runs (--side ns3), has no netsim
    from argparse import ArgumentParser as Parser

SCENARIOS = {
    # name: (positions, or the name of a moving team of TEAMS; range_m; flows (src, dst)).
    "line": ([(50.0 + 100.0 * i, 500.0) for i in range(6)], 120.0, ((0, 5),)),
    "grid": ([(50.0 + 100.0 * i, 50.0 + 100.0 * j) for i in range(4) for j in range(4)], 120.0, ((0, 15),)),
    "mobile": ("mobile", 250.0, ((0, 3), (0, 6), (0, 9), (0, 13))),
    "large": ("large", 250.0, tuple((k, 99 - k) for k in range(10))),
}
# The scenarios run unless --only names others: the comparison the docs quote.
DEFAULT = ("line", "grid", "mobile")
# The moving teams: random waypoint, written once by `netsim scenario generate` (its seed
# is --seed) and replayed by both. The large team keeps the mobile one's density.
MOBILE = {"n": 30, "side": 1000.0, "speed_min": 1.0, "speed_max": 5.0, "pause": 0.0}
TEAMS = {"mobile": MOBILE, "large": {**MOBILE, "n": 100, "side": 1826.0}}
# What may differ between the two: delivery ratio (absolute), mean hops (absolute), control
# packets per second (relative).
TOLERANCE = {"delivery_ratio": 0.05, "mean_hops": 0.25, "control_per_s": 0.30}
FIGURES = ("delivery_ratio", "mean_hops", "control_per_s", "messages_per_s")
# Each side's run alone (wall and CPU seconds), compared as a ratio.
TIMES = ("run_s", "run_cpu_s")


def write_trace(path: Path, args, team: str = "mobile") -> None:
    """A moving team's ns-2 trace (TEAMS), as `netsim scenario generate` writes it."""
    m = TEAMS[team]
    netsim = Path(sys.executable).with_name("netsim")
    flags = [f"--n={m['n']}", f"--side={m['side']}", f"--speed-min={m['speed_min']}", f"--speed-max={m['speed_max']}"]
    flags += [f"--pause={m['pause']}", f"--duration={args.duration}", f"--seed={args.seed}", "-o", str(path)]
    subprocess.run([str(netsim), "scenario", "generate", *flags], check=True, capture_output=True)


def trace_of(scenario: str, args) -> str:
    """The ns-2 trace of a moving team's scenario: ``--trace`` for the mobile team."""
    return args.trace if SCENARIOS[scenario][0] == "mobile" else args.traces[SCENARIOS[scenario][0]]


def netsim_side(scenario: str, protocol: str, args) -> dict:
    import time

    from netsim.config import from_dict
    from netsim.run import build, collect

    xy, range_m, flows = SCENARIOS[scenario]
    with tempfile.TemporaryDirectory() as tmp:
        if isinstance(xy, str):
            world = {"n_robots": TEAMS[xy]["n"], "side_m": TEAMS[xy]["side"]}
            mobility = {"model": "trace", "trace_file": trace_of(scenario, args), "ns2_semantics": "ns3"}
        else:
            path = Path(tmp) / "robots.csv"
            path.write_text("x_m,y_m\n" + "".join(f"{x},{y}\n" for x, y in xy))
            world = {"n_robots": len(xy), "side_m": 1000.0, "placement": str(path)}
            mobility = {"model": "static"}
        rate_bps = args.packet_bytes * 8 / args.interval
        config = from_dict(
            {
                "seed": args.seed,
                "duration_s": args.duration,
                "world": world,
                "mobility": mobility,
                "channel": {"range_m": range_m, "mac": getattr(args, "mac", "none")},
                # OLSR's robots all start at t = 0, as ns-3's nodes do.
                "protocol": {"model": protocol, **({"start_spread_s": 0.0} if protocol == "olsr" else {})},
                "traffic": {
                    "flows": [
                        {
                            "src": src,
                            "dst": dst,
                            "start_s": args.start,
                            "stop_s": args.duration,
                            "rate_bps": rate_bps,
                            "packet_bytes": args.packet_bytes,
                        }
                        for src, dst in flows
                    ]
                },
                "output": {"position_interval_s": 0.0},
            }
        )
        sim = build(config)
        wall, cpu = time.perf_counter(), time.process_time()
        sim.run()
        wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
        frames = collect(sim)
    packets = frames["packets"]
    got = packets[packets["delivered"]]
    return {
        "sent": len(packets),
        "delivered": len(got),
        "delivery_ratio": len(got) / len(packets),
        "mean_hops": float(got["hops"].mean()) if len(got) else float("nan"),
        "control_per_s": float(frames["control"]["sent"].sum()) / args.duration,
        "messages_per_s": float(frames["control"]["messages"].sum()) / args.duration,
        "run_s": wall,
        "run_cpu_s": cpu,
    }


NS3_CPP = r"""
#include "ns3/olsr-routing-protocol.h"
#include "ns3/arp-cache.h"
#include "ns3/ipv4-interface.h"
#include "ns3/ipv4-l3-protocol.h"
namespace routecmp {
using namespace ns3;
static uint64_t g_sent = 0, g_recv = 0, g_hops = 0, g_ctrl = 0, g_msgs = 0;
static uint16_t g_ctrl_port = 0;
uint64_t Sent() { return g_sent; }
uint64_t Received() { return g_recv; }
uint64_t HopSum() { return g_hops; }
uint64_t Control() { return g_ctrl; }
uint64_t OlsrMessages() { return g_msgs; }

static void OlsrTx(const olsr::PacketHeader& header, const olsr::MessageList& messages) {
    g_msgs += messages.size();
}

static void Tx(Ptr<const Packet> p, Ptr<Ipv4> ipv4, uint32_t iface) {
    Ptr<Packet> c = p->Copy();
    Ipv4Header ih;
    c->RemoveHeader(ih);
    if (ih.GetProtocol() != 17) return;
    UdpHeader uh;
    c->PeekHeader(uh);
    if (uh.GetDestinationPort() == g_ctrl_port) ++g_ctrl;
}

static void Recv(Ptr<Socket> s) {
    Ptr<Packet> p;
    while ((p = s->Recv())) {
        ++g_recv;
        SocketIpTtlTag tag;
        if (p->RemovePacketTag(tag)) g_hops += 65 - tag.GetTtl();
    }
}

struct Sender {
    Ptr<Socket> sock;
    uint32_t size;
    Time interval, stop;
    void Send() {
        if (Simulator::Now() >= stop) return;
        sock->Send(Create<Packet>(size));
        ++g_sent;
        Simulator::Schedule(interval, &Sender::Send, this);
    }
};

void Trace(uint16_t ctrl_port) {
    g_ctrl_port = ctrl_port;
    Config::ConnectWithoutContext("/NodeList/*/$ns3::Ipv4L3Protocol/Tx", MakeCallback(&Tx));
    Config::ConnectWithoutContextFailSafe("/NodeList/*/$ns3::olsr::RoutingProtocol/Tx", MakeCallback(&OlsrTx));
}

// A permanent ARP entry on every node for every other node: ARP never sends a request.
// Permanent rather than NeighborCacheHelper's auto-generated entries, which AODV's
// neighbour table does not read: with them a failed unicast would not break AODV's link.
void StaticArp(NodeContainer nodes) {
    for (uint32_t i = 0; i < nodes.GetN(); ++i) {
        Ptr<ArpCache> cache = nodes.Get(i)->GetObject<Ipv4L3Protocol>()->GetInterface(1)->GetArpCache();
        for (uint32_t j = 0; j < nodes.GetN(); ++j) {
            if (i == j) continue;
            Ptr<Ipv4L3Protocol> other = nodes.Get(j)->GetObject<Ipv4L3Protocol>();
            ArpCache::Entry* entry = cache->Add(other->GetAddress(1, 0).GetLocal());
            entry->SetMacAddress(other->GetInterface(1)->GetDevice()->GetAddress());
            entry->MarkPermanent();
        }
    }
}

void Install(NodeContainer nodes, uint32_t src, uint32_t dst, uint32_t size, double interval,
             double start, double stop) {
    TypeId tid = TypeId::LookupByName("ns3::UdpSocketFactory");
    Ptr<Socket> rx = Socket::CreateSocket(nodes.Get(dst), tid);
    rx->SetIpRecvTtl(true);
    rx->Bind(InetSocketAddress(Ipv4Address::GetAny(), 9));
    rx->SetRecvCallback(MakeCallback(&Recv));
    Ptr<Socket> tx = Socket::CreateSocket(nodes.Get(src), tid);
    Ipv4Address to = nodes.Get(dst)->GetObject<Ipv4>()->GetAddress(1, 0).GetLocal();
    tx->Connect(InetSocketAddress(to, 9));
    Sender* sender = new Sender{tx, size, Seconds(interval), Seconds(stop)};
    Simulator::Schedule(Seconds(start), &Sender::Send, sender);
}
}
"""


def ns3_side(scenario: str, protocol: str, args) -> dict:
    import time

    import cppyy
    from ns import ns

    cppyy.cppdef(NS3_CPP)
    xy, range_m, flows = SCENARIOS[scenario]
    ns.RngSeedManager.SetSeed(args.seed)
    nodes = ns.NodeContainer()
    if isinstance(xy, str):
        nodes.Create(TEAMS[xy]["n"])
        ns.Ns2MobilityHelper(trace_of(scenario, args)).Install()
    else:
        nodes.Create(len(xy))
        alloc = ns.CreateObject[ns.ListPositionAllocator]()
        for x, y in xy:
            alloc.Add(ns.Vector(x, y, 0.0))
        mob = ns.MobilityHelper()
        mob.SetPositionAllocator(alloc)
        mob.SetMobilityModel("ns3::ConstantPositionMobilityModel")
        mob.Install(nodes)
    wifi = ns.WifiHelper()
    wifi.SetStandard(ns.WIFI_STANDARD_80211b)
    rate = ns.StringValue("DsssRate11Mbps")
    wifi.SetRemoteStationManager("ns3::ConstantRateWifiManager", "DataMode", rate, "ControlMode", rate)
    chan = ns.YansWifiChannelHelper()
    chan.SetPropagationDelay("ns3::ConstantSpeedPropagationDelayModel")
    chan.AddPropagationLoss("ns3::RangePropagationLossModel", "MaxRange", ns.DoubleValue(range_m))
    phy = ns.YansWifiPhyHelper()
    phy.SetChannel(chan.Create())
    mac = ns.WifiMacHelper()
    mac.SetType("ns3::AdhocWifiMac")
    devices = wifi.Install(phy, mac, nodes)
    stack = ns.InternetStackHelper()
    if protocol == "aodv":
        routing, port = ns.AodvHelper(), 654
    else:
        routing, port = ns.OlsrHelper(), 698
    stack.SetRoutingHelper(routing)
    stack.Install(nodes)
    addresses = ns.Ipv4AddressHelper()
    addresses.SetBase(ns.Ipv4Address("10.0.0.0"), ns.Ipv4Mask("255.255.255.0"))
    addresses.Assign(devices)
    if args.ns3_arp == "static":
        cppyy.gbl.routecmp.StaticArp(nodes)
    cppyy.gbl.routecmp.Trace(port)
    for src, dst in flows:
        cppyy.gbl.routecmp.Install(nodes, src, dst, args.packet_bytes, args.interval, args.start, args.duration)
    ns.Simulator.Stop(ns.Seconds(args.duration))
    wall, cpu = time.perf_counter(), time.process_time()
    ns.Simulator.Run()
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    g = cppyy.gbl.routecmp
    sent, recv = int(g.Sent()), int(g.Received())
    out = {
        "sent": sent,
        "delivered": recv,
        "delivery_ratio": recv / sent if sent else float("nan"),
        "mean_hops": int(g.HopSum()) / recv if recv else float("nan"),
        "control_per_s": int(g.Control()) / args.duration,
        "messages_per_s": (int(g.OlsrMessages()) if protocol == "olsr" else int(g.Control())) / args.duration,
        "run_s": wall,
        "run_cpu_s": cpu,
    }
    ns.Simulator.Destroy()
    return out


def within(name: str, ours: float, theirs: float) -> bool:
    tol = TOLERANCE[name]
    if name == "control_per_s":
        return abs(ours - theirs) <= tol * theirs
    return abs(ours - theirs) <= tol


def main() -> int:
    p = Parser(description=__doc__.split("\n\n")[0])
    p.add_argument("--side", choices=["both", "netsim", "ns3"], default="both")
    p.add_argument("--ns3-python", default=".ns3venv/bin/python")
    p.add_argument("--only", nargs="*", default=list(DEFAULT), help=f"of {', '.join(SCENARIOS)}")
    p.add_argument("--protocols", nargs="*", default=["aodv", "olsr"])
    p.add_argument("--duration", type=float, default=100.0, help="simulated time, s")
    p.add_argument("--start", type=float, default=30.0, help="when the flow starts, s")
    p.add_argument("--interval", type=float, default=1.0, help="between two packets of the flow, s")
    p.add_argument("--packet-bytes", type=int, default=512)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--trace", default="", help="the mobile team's ns-2 trace (default: written anew)")
    p.add_argument("--mac", choices=["none", "csma"], default="none", help="netsim's channel.mac")
    p.add_argument(
        "--ns3-arp",
        choices=["static", "dynamic"],
        default="static",
        help="ns-3's ARP: every entry filled before the run (netsim has no ARP), or its own",
    )
    p.add_argument("--traces", type=json.loads, default={}, help=argparse.SUPPRESS)
    args = p.parse_args()
    unknown = [name for name in args.only if name not in SCENARIOS]
    if unknown or not args.only:
        p.error(f"--only: {' '.join(unknown) or 'nothing'}: give one or more of {', '.join(SCENARIOS)}")
    bad = [name for name in args.protocols if name not in ("aodv", "olsr")]
    if bad or not args.protocols:
        p.error(f"--protocols: {' '.join(bad) or 'nothing'}: give aodv, olsr or both")
    for flag, ok in (
        ("--duration", args.duration > 0),
        ("--interval", args.interval > 0),
        ("--packet-bytes", args.packet_bytes > 0),
        ("--start", 0 <= args.start < args.duration),
    ):
        if not ok:
            p.error(f"{flag} must be {'in [0, --duration)' if flag == '--start' else '> 0'}")
    if args.side != "both" and (len(args.only) != 1 or len(args.protocols) != 1):
        p.error(f"--side {args.side} runs one scenario and one protocol: give --only NAME --protocols NAME")
    if args.side == "both" and not Path(args.ns3_python).is_file():
        p.error(
            f"--ns3-python {args.ns3_python}: no such file (bash benchmarks/ns3_env.sh .ns3venv makes it;"
            " --side netsim --only NAME --protocols NAME runs netsim's side alone)"
        )
    with tempfile.TemporaryDirectory() as tmp:
        if "mobile" in args.only and not args.trace:
            args.trace = str(Path(tmp) / "mobile.ns2")
            write_trace(Path(args.trace), args)
        for team in TEAMS:
            if team != "mobile" and team in args.only and team not in args.traces:
                args.traces[team] = str(Path(tmp) / f"{team}.ns2")
                write_trace(Path(args.traces[team]), args, team)
        return compare(args)


def compare(args) -> int:
    """Run each scenario and protocol on both sides (or on one, ``--side``); print the table."""
    if args.side != "both":
        (scenario,), (protocol,) = args.only, args.protocols
        side = ns3_side if args.side == "ns3" else netsim_side
        print(json.dumps(side(scenario, protocol, args)))
        return 0
    common = [
        f"--duration={args.duration}",
        f"--start={args.start}",
        f"--interval={args.interval}",
        f"--packet-bytes={args.packet_bytes}",
        f"--seed={args.seed}",
        f"--ns3-arp={args.ns3_arp}",
        f"--trace={args.trace}",
        f"--traces={json.dumps(args.traces)}",
    ]
    ok = True
    print(f"{'scenario':8} {'protocol':8} {'figure':15} {'netsim':>9} {'ns-3':>9}  within")
    for scenario in args.only:
        for protocol in args.protocols:
            ours = netsim_side(scenario, protocol, args)
            run = [args.ns3_python, __file__, "--side=ns3", "--only", scenario, "--protocols", protocol, *common]
            theirs = json.loads(subprocess.run(run, check=True, capture_output=True, text=True).stdout.splitlines()[-1])
            for name in FIGURES:
                good = within(name, ours[name], theirs[name]) if name in TOLERANCE else None
                ok &= good is not False
                verdict = "" if good is None else str(good)
                print(f"{scenario:8} {protocol:8} {name:15} {ours[name]:9.3f} {theirs[name]:9.3f}  {verdict}")
            for name in TIMES:
                ratio = f"ns-3/netsim {theirs[name] / ours[name]:.2f}" if ours[name] > 0 else ""
                print(f"{scenario:8} {protocol:8} {name:15} {ours[name]:9.3f} {theirs[name]:9.3f}  {ratio}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
