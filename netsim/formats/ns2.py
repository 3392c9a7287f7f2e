"""The ns-2 movement-scenario format, read as ns-2 replays it (or as ns-3's
``Ns2MobilityHelper`` does), and written as ns-2's ``setdest`` writes it.

::

    $node_(0) set X_ 120.5
    $node_(0) set Y_ 33.0
    $node_(0) set Z_ 0.0
    $ns_ at 2.0 "$node_(0) setdest 400.0 250.0 3.5"

The lines are understood as ns-3's helper understands them, line for line; what they
then do follows ns-2 by default (``semantics = "ns2"``) or ns-3 (``"ns3"``, so that a file
replays to the positions ns-3 gives: the tests compare with ns-3 itself). The two differ in
a scheduled ``set X_``, a ``setdest`` to where the node is and lines out of time order:

- Everything after a ``#`` is a comment; blanks and ``;`` at a line's ends are dropped. A
  line is then split on blanks and understood only in one of three shapes (the quotes may
  touch the last word or stand alone):
  ``$node_(i) set X_ x`` (also ``Y_``, ``Z_``; an initial position, wherever it stands in
  the file), ``$ns_ at T "$node_(i) setdest X Y S"`` and ``$ns_ at T "$node_(i) set X_ x"``.
  Every other line is skipped, as ns-3 skips it: blank and comment lines, ``$god_`` lines
  (setdest's hop counts: they name no ``(i)``), ``set god_ [God instance]``, any other Tcl
  of a simulation script, lines with a wrong number of words, a time that is not a number
  or is negative. ``Z_`` is ignored.
- ``setdest X Y S`` at ``T``: the node leaves at ``T`` toward ``(X, Y)`` at ``S`` m/s and
  stops on arrival. A later ``setdest`` starts from where the node is then (if it had not
  arrived) or from where it was heading. ``S = 0`` stops the node at ``T``; a negative
  speed does nothing. A ``setdest`` to where the node already is stops it (``"ns2"``); with
  ``"ns3"`` it schedules nothing but still cancels the stop of the ``setdest`` before it, so
  a node still moving moves on past that stop (as ns-3's helper does).
- ``set X_ x`` at ``T``: with ``"ns2"`` the node jumps at ``T`` (its other coordinate
  where it is then) and stops. With ``"ns3"`` (ns-3's handling) the coordinate is changed
  at once, when the file is read, so the node starts there; at ``T`` the node is put at
  that position again (its other coordinate as it was when the line was read) and stops.
  Either way a later ``setdest`` leaves from there.
- Lines out of time order: applied in time order (``"ns2"``, as ns-2's scheduler does;
  equal times in file order) or in file order (``"ns3"``).
- Nodes are 0 to the highest id the file names (ns-3 uses the nodes it is given); a node
  that is never given an initial ``X_`` or ``Y_`` starts at 0 on that axis, and a warning
  names those nodes. A file with initial positions only is a team standing still. A file
  with no line understood at all is an error, and so is a non-finite number (ns-3 would
  move a node to NaN).
"""

from __future__ import annotations

import math
import re
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from netsim.area import Bounds, as_bounds
from netsim.errors import NetsimInputError, listed, not_a_file
from netsim.geometry import speeds_mps
from netsim.trajectory import LegTable

_NODE = re.compile(r"\(([^()]*)\)")
_COORDS = ("X_", "Y_", "Z_")
SEMANTICS = ("ns2", "ns3")
# A line that names a node's movement (a setdest, or a set of a coordinate): one not
# understood is counted in a warning, as is a movement line cut short, where other Tcl is
# skipped without a word.
_MOVEMENT = re.compile(r"setdest|\$node_\([^)]*\)\s+set\s+[XYZ]_")
# How a node's movement line begins: a scheduled command, or a node's own set.
_MOVEMENT_START = re.compile(r"\s*(\$ns_\s+at\b|\$node_\()")
_QUOTE = re.compile(r'(?<!\\)"')  # a quote not escaped
# Lines named in a warning, at most.
_SHOWN = 5
# Without world.n_robots the team is 0 to the highest node the file names: a bound on that
# number keeps a stray huge one from asking for gigabytes of positions.
MAX_INFERRED_NODES = 1_000_000


@dataclass(frozen=True)
class Scenario:
    """A parsed movement file: the positions at t = 0 and the events that change the
    nodes' motion, in the order they happen.

    ``events`` has columns ``t_s, robot, kind, x_m, y_m, line``: ``kind`` is ``"velocity"``
    (from ``t_s`` on the node moves at ``(x_m, y_m)`` m/s from where it is), ``"stop"`` (it
    arrives where its ``setdest`` was heading, and stops) or ``"position"`` (the node is
    put at ``(x_m, y_m)`` and stops); ``line`` is the file's line that made the event.
    """

    initial_m: np.ndarray
    events: pd.DataFrame

    @property
    def n_robots(self) -> int:
        return len(self.initial_m)


def _strtod(text: str) -> float | None:
    """The number C's ``strtod`` reads from the whole of ``text``, or None."""
    t = text.strip()
    if t != text or not t or "_" in t:
        return None
    try:
        return float(t)
    except ValueError:
        pass
    body = t.lstrip("+-")
    if body[:2].lower() == "0x":
        try:
            v = float.fromhex(body)
        except ValueError:
            return None
        return -v if t.startswith("-") else v
    return None


def _node_id(token: str) -> str | None:
    """The id between the first ``(`` and the first ``)`` when ns-3 takes it for one (a
    number ``strtod`` reads whole, with no ``.`` and no leading ``-``), as ns-3 then reads
    it: its leading digits (``1e3`` is node 1), or 0 when it has none (``inf``)."""
    a, b = token.find("("), token.find(")")
    if a < 0 or b < 0:
        return None
    inner = token[a + 1 : b]
    v = _strtod(inner)
    if v is None or "." in inner or inner.startswith("-"):
        return None
    digits = re.match(r"\+?(\d*)", inner)
    return (digits[1] if digits else "") or "0"


def _tokens(raw: str) -> list[str]:
    """A line's words as ns-3's helper splits them (module notes)."""
    line = raw.split("#", 1)[0].lstrip(" \t").rstrip(" \t;")
    while line and line[-1] in " \t;":
        line = line[:-1]
    if _node_id(line) is None:
        return []
    words = line.split()
    if not words:
        return []
    if len(words) in (7, 8) and words[-1].endswith('"'):
        # A quote standing alone here leaves an empty word, and the line is not understood.
        words[-1] = words[-1][:-1]
    elif len(words) == 9 and words[-1] == '"':
        words.pop()
    return words


@dataclass
class _Heading:
    """What ns-3's helper remembers of a node's last movement (its DestinationPoint)."""

    start: np.ndarray = field(default_factory=lambda: np.zeros(2))
    velocity: np.ndarray = field(default_factory=lambda: np.zeros(2))
    final: np.ndarray = field(default_factory=lambda: np.zeros(2))
    stop_event: int = -1
    travel_start_s: float = 0.0
    arrival_s: float = 0.0


def read(path: str | Path, n_robots: int | None = None, semantics: str = "ns2") -> Scenario:
    """Parse an ns-2 movement file and replay it as ns-2 (``semantics = "ns2"``) or ns-3
    (``"ns3"``) does (module notes); raise :class:`NetsimInputError` naming the line for
    what cannot be simulated, and warn (one warning each) of nodes without an initial
    position, lines out of time order and lines skipped.

    With ``n_robots``, a node numbered ``n_robots`` or above is an error naming it (nodes
    are numbered from 0), rather than a gap in the initial positions. Without it, the team
    is 0 to the highest node named, at most :data:`MAX_INFERRED_NODES` nodes."""
    if semantics not in SEMANTICS:
        raise ValueError(f"semantics must be one of {SEMANTICS}, not {semantics!r}")
    as_ns2 = semantics == "ns2"
    path = Path(path)
    if not path.is_file():
        raise NetsimInputError(f"{str(path)!r}: {not_a_file(path)}")
    try:
        text = path.read_text()
    except UnicodeDecodeError:
        raise NetsimInputError(f"{path}: not a text file") from None
    lines = text.splitlines()
    # A file cut short ends inside its last line, without the newline that ends every line.
    cut_short = len(lines) if text and not text.endswith(("\n", "\r")) else 0

    def node(text: str, lineno: int) -> int:
        if len(text) > 9:
            raise NetsimInputError(f"{path}:{lineno}: node number {text[:20]} is too large")
        i = int(text)
        if n_robots is not None and i >= n_robots:
            raise NetsimInputError(
                f"{path}:{lineno}: node {i} is beyond world.n_robots = {n_robots} "
                f"(nodes are numbered 0 to {n_robots - 1})"
            )
        if n_robots is None and i >= MAX_INFERRED_NODES:
            raise NetsimInputError(
                f"{path}:{lineno}: node {i} is beyond the {MAX_INFERRED_NODES:,} nodes a file may name "
                "when the number of robots is not given"
            )
        return i

    def finite(v: float, lineno: int, what: str) -> float:
        if not math.isfinite(v):
            raise NetsimInputError(f"{path}:{lineno}: {what} {v} must be finite")
        return v

    # The lines understood, in file order: ("init" | "setdest" | "set", lineno, node, values).
    parsed: list[tuple[str, int, int, tuple[Any, ...]]] = []
    skipped: list[int] = []
    ends_open = False  # the file's last line is a movement line understood, without its newline
    for lineno, raw in enumerate(lines, 1):
        movement_like = _MOVEMENT_START.match(raw) is not None
        if _understood(_tokens(raw), lineno, parsed, node, finite, as_ns2):
            ends_open = lineno == cut_short and movement_like
            continue
        # A movement line cut short: a scheduled command whose quote is left open, or the
        # file's last line begun as a movement line (other Tcl is skipped without a word).
        cut = movement_like and (len(_QUOTE.findall(raw)) % 2 == 1 or lineno == cut_short)
        if _MOVEMENT.search(raw.split("#", 1)[0]) or cut:
            skipped.append(lineno)
    if not parsed:
        raise NetsimInputError(
            f'{path}: no ns-2 movement line ($node_(i) set X_ x, $ns_ at T "$node_(i) setdest X Y S" '
            'or $ns_ at T "$node_(i) set X_ x")'
        )
    # A setdest with a negative speed is understood (ns-3 reads it) but moves nothing.
    skipped += [ln for kind, ln, _i, vals in parsed if kind == "setdest" and vals[3] < 0]
    ids = [p[2] for p in parsed]
    n = max(ids) + 1
    named = set(ids)
    if n_robots is None and n - len(named) > max(1000, len(named)):
        gaps = [i for i in range(12) if i not in named][:10]
        raise NetsimInputError(
            f"{path}: node(s) {gaps} ... are never named, up to node {n - 1}: "
            "number the nodes from 0 without large gaps"
        )

    # Where each node is as the file is read (ns-3 moves a node at once for a scheduled set).
    now = np.zeros((n, 2))
    given: dict[int, set[str]] = {}
    heading: dict[int, _Heading] = {}
    for kind, _lineno, i, vals in parsed:
        if kind == "init" and vals[0] != "Z_":
            now[i, 0 if vals[0] == "X_" else 1] = vals[1]
            given.setdefault(i, set()).add(str(vals[0]))
        if kind == "init":
            heading[i] = _Heading(final=now[i].copy())
    initial = now.copy()
    scheduled = [p for p in parsed if p[0] != "init"]
    late = _out_of_order(scheduled)
    if as_ns2:
        scheduled.sort(key=lambda p: p[3][0])
        events = _ns2_events(scheduled, heading)
    else:
        events = _ns3_events(scheduled, heading, now)
        initial = now

    warn = lambda text: warnings.warn(f"{path}: {text}", stacklevel=3)  # noqa: E731
    lacking = [i for i in range(n) if not {"X_", "Y_"} <= given.get(i, set())]
    if lacking:
        more = f" and {len(lacking) - 10} more" if len(lacking) > 10 else ""
        warn(
            f"node(s) {lacking[:10]}{more} have no initial X_ or Y_: they start at 0 on that axis,"
            " as in ns-2 and ns-3's Ns2MobilityHelper"
        )
    if late:
        lines_late = [ln for ln, _i in late]
        nodes = sorted({i for _ln, i in late})
        how = (
            "applied in time order, as ns-2's scheduler does"
            if as_ns2
            else "read in file order, as ns-3's Ns2MobilityHelper reads them (mobility.ns2_semantics = 'ns3'): "
            "a setdest read after a later one cancels that one's stop"
        )
        warn(
            f"line(s) {listed(lines_late, _SHOWN)} (node(s) {nodes[:10]}) are earlier than a line before "
            f"them for the same node: {how}"
        )
    if ends_open:
        warn(
            f"line {cut_short}, the last, ends the file without a newline: if the file was cut short there, "
            "its values may be cut too"
        )
    if skipped:
        skipped.sort()
        warn(
            f"{len(skipped)} movement line(s) not understood (a line cut short, a word missing or extra, a time "
            f"or number that is not one, a negative speed) are skipped: line(s) {listed(skipped, _SHOWN)}"
        )
    live = sorted((e for e in events if not e[6]), key=lambda e: (e[0], e[1]))
    frame = pd.DataFrame(
        [(e[0], e[2], e[3], e[4], e[5], e[7]) for e in live],
        columns=["t_s", "robot", "kind", "x_m", "y_m", "line"],
    ).astype({"t_s": float, "robot": np.int64, "x_m": float, "y_m": float, "line": np.int64})
    return Scenario(initial, frame)


def _understood(w: list[str], lineno: int, parsed: list, node: Any, finite: Any, as_ns2: bool) -> bool:
    """Add the line of words ``w`` to ``parsed`` if it is one of the three shapes (module
    notes); whether it was."""
    if len(w) == 4:
        nid = _node_id(w[0])
        value = _strtod(w[3])
        if nid is not None and w[1] == "set" and w[2] in _COORDS and value is not None:
            parsed.append(("init", lineno, node(nid, lineno), (w[2], finite(value, lineno, w[2]))))
            return True
        return False
    if len(w) not in (7, 8) or w[0] != "$ns_" or w[1] != "at":
        return False
    nid = _node_id(w[3])
    t = _strtod(w[2])
    if nid is None or t is None or t < 0:
        return False
    t = finite(t, lineno, "time")
    if len(w) == 8 and w[4] == "setdest":
        xs = [_strtod(v) for v in w[5:8]]
        if None in xs:
            return False
        vals = tuple(finite(v, lineno, k) for v, k in zip(xs, ("X", "Y", "speed")))  # type: ignore[arg-type]
        parsed.append(("setdest", lineno, node(nid, lineno), (t, *vals)))
        return True
    if len(w) == 7 and w[4] == "set" and w[5] in _COORDS:
        value = _strtod(w[6])
        if value is None and as_ns2:
            return False
        # ns-3 does not check the value: one that is not a number counts as 0.
        parsed.append(("set", lineno, node(nid, lineno), (t, w[5], finite(value or 0.0, lineno, w[5]))))
        return True
    return False


def _out_of_order(scheduled: list) -> list[tuple[int, int]]:
    """``(line, node)`` of each scheduled line whose time is earlier than one before it in
    the file for the same node."""
    latest: dict[int, float] = {}
    late = []
    for _kind, lineno, i, vals in scheduled:
        if vals[0] < latest.get(i, -math.inf):
            late.append((lineno, i))
        else:
            latest[i] = vals[0]
    return late


def _where(h: _Heading, t: float) -> np.ndarray:
    """Where a node on heading ``h`` is at ``t`` (not before its start)."""
    return h.start + h.velocity * (t - h.travel_start_s) if h.arrival_s > t else h.final.copy()


class _Events(list):
    """``[t, seq, robot, kind, x, y, cancelled, line]`` rows."""

    def add(self, t: float, i: int, kind: str, xy: Any, line: int) -> int:
        self.append([t, len(self), i, kind, float(xy[0]), float(xy[1]), False, line])
        return len(self) - 1


def _head_to(events: _Events, new: _Heading, i: int, t: float, x: float, y: float, speed: float, lineno: int) -> bool:
    """A ``setdest``'s leg, in both readings: ``new`` (standing at ``new.final`` at ``t``)
    heads for ``(x, y)`` at ``speed``, with its velocity event and the stop at its arrival;
    False (nothing added) when there is no travel."""
    travel = math.hypot(x - new.final[0], y - new.final[1]) / speed if speed > 0 else 0.0
    if not travel > 0:
        return False
    v = np.array([(x - new.final[0]) / travel, (y - new.final[1]) / travel])
    new.velocity = v
    events.add(t, i, "velocity", v, lineno)
    new.stop_event = events.add(t + travel, i, "stop", (0.0, 0.0), lineno)
    new.final = new.final + v * travel
    new.arrival_s = t + travel
    return True


def _ns2_events(scheduled: list, heading: dict[int, _Heading]) -> _Events:
    """The events of the scheduled lines, taken in time order, as ns-2 applies them."""
    events = _Events()
    for kind, lineno, i, vals in scheduled:
        h = heading.setdefault(i, _Heading())
        t = vals[0]
        if kind == "setdest" and vals[3] < 0:
            continue
        if kind == "set" and vals[1] == "Z_":
            continue
        here = _where(h, t)
        if h.arrival_s > t and h.stop_event >= 0:
            events[h.stop_event][6] = True
        new = _Heading(start=here.copy(), final=here.copy(), travel_start_s=t, arrival_s=t)
        if kind == "set":
            here[0 if vals[1] == "X_" else 1] = vals[2]
            new.start, new.final = here.copy(), here.copy()
            events.add(t, i, "position", here, lineno)
        else:
            _t, x, y, speed = vals
            if not _head_to(events, new, i, t, x, y, speed, lineno):
                events.add(t, i, "velocity", (0.0, 0.0), lineno)
        heading[i] = new
    return events


def _ns3_events(scheduled: list, heading: dict[int, _Heading], now: np.ndarray) -> _Events:
    """The events of the scheduled lines, read in file order as ns-3's helper reads them;
    ``now`` (where each node is as the file is read) is moved by each ``set``."""
    events = _Events()
    for kind, lineno, i, vals in scheduled:
        h = heading.setdefault(i, _Heading())
        if kind == "setdest":
            t, x, y, speed = vals
            if h.arrival_s > t:
                h.final = h.start + h.velocity * (t - h.travel_start_s)
                if h.stop_event >= 0:
                    events[h.stop_event][6] = True
            new = _Heading(start=h.final.copy(), final=h.final.copy(), travel_start_s=t, arrival_s=t)
            if speed == 0:
                new.stop_event = events.add(t, i, "velocity", (0.0, 0.0), lineno)
            elif speed > 0:
                _head_to(events, new, i, t, x, y, speed, lineno)
            heading[i] = new
        else:
            t, coord, value = vals
            if coord != "Z_":
                now[i, 0 if coord == "X_" else 1] = value
            h.final = now[i].copy()
            events.add(t, i, "position", now[i], lineno)
            if h.arrival_s > t and h.stop_event >= 0:
                events[h.stop_event][6] = True
            h.arrival_s = h.travel_start_s = t
    return events


# How far inside the area a destination on its border is written: ns-2 refuses the border
# itself, and a subnormal float (the least one inside) is one that some readers refuse.
BORDER_GAP_M = 1e-9


def write(
    path: str | Path,
    legs: pd.DataFrame,
    n_robots: int,
    duration_s: float,
    header: str = "",
    area: float | Bounds | None = None,
) -> None:
    """Write legs (as :meth:`RobotState.legs` gives) as an ns-2 movement file.

    Each moving leg becomes a ``setdest`` toward where the leg ends (the start of the
    robot's next leg, or its position at ``duration_s``). ns-2 refuses a destination on
    its area's border or beyond (``MobileNode::set_destination``): with ``area`` (the
    run's), a destination on a border (a robot that turned at a wall) is written
    :data:`BORDER_GAP_M` inside it. A leg that starts elsewhere than
    where the robot's previous leg put it (a jump) starts with a scheduled ``set X_`` and
    ``set Y_``, which ns-2, and this reader by default, take as a jump at that instant
    (``semantics = "ns3"`` does not: ns-3 places the node when it reads the file). Numbers
    are written with Python's shortest round-trip ``repr``, so a replay reproduces the
    positions.
    """
    lines = [f"# {line}" for line in header.splitlines()]
    table = LegTable(legs, n_robots)
    t, robot, p = table.t, table.robot, table.p
    for i in range(n_robots):
        x, y = p[table.first[i]].tolist()
        lines += [f"$node_({i}) set X_ {x!r}", f"$node_({i}) set Y_ {y!r}", f"$node_({i}) set Z_ 0.0"]
    events: list[tuple[float, int, int, str]] = []
    speeds = speeds_mps(table.v)
    _, ends, jump = table.ends(duration_s)
    if area is not None:
        b = as_bounds(area)
        inside = np.maximum(BORDER_GAP_M, 4 * np.spacing(np.abs(np.r_[b.lo, b.hi]).max()))
        ends = np.clip(ends, b.lo + inside, b.hi - inside)
    for k in range(len(t)):
        tk, rk = float(t[k]), int(robot[k])
        if tk >= duration_s:
            continue
        at = f'$ns_ at {tk!r} "$node_({rk})'
        if k > table.first[rk] and jump[k - 1]:
            x, y = p[k].tolist()
            events += [(tk, rk, len(events), f'{at} set X_ {x!r}"'), (tk, rk, len(events) + 1, f'{at} set Y_ {y!r}"')]
        speed = float(speeds[k])
        if speed != 0.0:
            dx, dy = ends[k].tolist()
            events.append((tk, rk, len(events), f'{at} setdest {dx!r} {dy!r} {speed!r}"'))
    events.sort(key=lambda e: e[:3])
    lines += [e[3] for e in events]
    Path(path).write_text("\n".join(lines) + "\n")
