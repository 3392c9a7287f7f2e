"""The ns-2 movement-scenario format, as written by ns-2's ``setdest`` and BonnMotion.

::

    $node_(0) set X_ 120.5
    $node_(0) set Y_ 33.0
    $node_(0) set Z_ 0.0
    $ns_ at 2.0 "$node_(0) setdest 400.0 250.0 3.5"

Semantics (as ns-2 and ns-3's ``Ns2MobilityHelper``): ``setdest X Y S`` at time T makes
the node leave its current position at T in a straight line toward (X, Y) at S m/s and
stop on arrival; a later ``setdest`` replaces the current one from wherever the node is.
``$ns_ at T "$node_(i) set X_ x"`` moves the node to x at T and stops it. A node no
command names stands where it starts, so a file of starting positions only (no ``$ns_ at``
line) is a team at rest. ``$god_`` lines (setdest's hop counts), ``Z_`` and comments are
ignored. The nodes are 0 to the highest id the file names; as in ns-3, a coordinate a node
is never given (no ``$node_(i) set X_``) is 0, and a warning names those nodes.
"""

from __future__ import annotations

import math
import re
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from netsim.errors import NetsimInputError

_NUM = r"([-+0-9.eEinfa]+)"
_INIT = re.compile(r"^\$node_\((\d+)\)\s+set\s+([XYZ])_\s+" + _NUM + r"\s*$")
_SETDEST = re.compile(
    r"^\$ns_\s+at\s+" + _NUM + r'\s+"\$node_\((\d+)\)\s+setdest\s+' + _NUM + r"\s+" + _NUM + r"\s+" + _NUM + r'\s*"\s*$'
)
_SETPOS = re.compile(r"^\$ns_\s+at\s+" + _NUM + r'\s+"\$node_\((\d+)\)\s+set\s+([XYZ])_\s+' + _NUM + r'\s*"\s*$')


_COMMAND_DTYPES = {
    "t_s": "float64",
    "robot": "int64",
    "kind": "object",
    "x_m": "float64",
    "y_m": "float64",
    "speed_mps": "float64",
    "line": "int64",
}


@dataclass(frozen=True)
class Scenario:
    """A parsed movement file: initial positions and time-ordered commands.

    ``commands`` has columns ``t_s, robot, kind ("setdest" | "set"), x_m, y_m, speed_mps``;
    for ``set`` rows, the coordinate not set is NaN.
    """

    initial_m: np.ndarray
    commands: pd.DataFrame

    @property
    def n_robots(self) -> int:
        return len(self.initial_m)


def _number(text: str, path: str | Path, lineno: int, what: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise NetsimInputError(f"{path}:{lineno}: {what} {text!r} is not a number") from None
    if not math.isfinite(v):
        raise NetsimInputError(f"{path}:{lineno}: {what} {text!r} must be finite")
    return v


# Without world.n_robots the team is 0 to the highest node the file names: a bound on that
# number keeps a stray huge one from asking for gigabytes of positions.
MAX_INFERRED_NODES = 1_000_000


def read(path: str | Path, n_robots: int | None = None) -> Scenario:
    """Parse an ns-2 movement file; raise :class:`NetsimInputError` naming the bad line.

    With ``n_robots``, a node numbered ``n_robots`` or above is an error naming it (nodes
    are numbered from 0), rather than a gap in the initial positions. Without it, the team
    is 0 to the highest node named, at most :data:`MAX_INFERRED_NODES` nodes."""
    path = Path(path)
    if not path.is_file():
        raise NetsimInputError(f"{str(path)!r}: no such file")
    initial: dict[int, dict[str, float]] = {}
    rows = []
    try:
        lines = path.read_text().splitlines()
    except UnicodeDecodeError:
        raise NetsimInputError(f"{path}: not a text file") from None

    def node_id(text: str, lineno: int) -> int:
        if len(text) > 9:
            raise NetsimInputError(f"{path}:{lineno}: node number {text[:20]} is too large")
        node = int(text)
        if n_robots is not None and node >= n_robots:
            raise NetsimInputError(
                f"{path}:{lineno}: node {node} is beyond world.n_robots = {n_robots} "
                f"(nodes are numbered 0 to {n_robots - 1})"
            )
        if n_robots is None and node >= MAX_INFERRED_NODES:
            raise NetsimInputError(
                f"{path}:{lineno}: node {node} is beyond the {MAX_INFERRED_NODES:,} nodes a file may name "
                "when the number of robots is not given"
            )
        return node

    for lineno, raw in enumerate(lines, 1):
        line = raw.strip()
        if not line or line.startswith("#") or "$god_" in line:
            continue
        if m := _INIT.match(line):
            node, axis = node_id(m[1], lineno), m[2]
            initial.setdefault(node, {})[axis] = _number(m[3], path, lineno, f"{axis}_")
        elif m := _SETDEST.match(line):
            t = _number(m[1], path, lineno, "time")
            x, y, s = (_number(m[k], path, lineno, w) for k, w in ((3, "X"), (4, "Y"), (5, "speed")))
            if t < 0 or s < 0:
                raise NetsimInputError(f"{path}:{lineno}: negative time or speed in {line!r}")
            rows.append((t, node_id(m[2], lineno), "setdest", x, y, s, lineno))
        elif m := _SETPOS.match(line):
            t = _number(m[1], path, lineno, "time")
            if t < 0:
                raise NetsimInputError(f"{path}:{lineno}: negative time in {line!r}")
            v = _number(m[4], path, lineno, f"{m[3]}_")
            if m[3] == "Z":
                continue
            x, y = (v, math.nan) if m[3] == "X" else (math.nan, v)
            rows.append((t, node_id(m[2], lineno), "set", x, y, 0.0, lineno))
        else:
            raise NetsimInputError(f"{path}:{lineno}: not an ns-2 movement command: {line!r}")
    # Typed columns: a file of starting positions only has no commands, and an empty
    # table must still hold numbers (its robots stand still, as in ns-3).
    commands = pd.DataFrame(rows, columns=list(_COMMAND_DTYPES)).astype(_COMMAND_DTYPES)
    ids = list(initial) + commands["robot"].tolist()
    if not ids:
        raise NetsimInputError(f'{path}: no nodes ($node_(i) set X_ ... or $ns_ at T "$node_(i) ...")')
    n = max(ids) + 1
    named = set(ids)
    if n_robots is None and n - len(named) > max(1000, len(named)):
        # Without world.n_robots the nodes are 0 to the highest number named: a stray huge
        # number would make a team of mostly never-named robots.
        gaps = [i for i in range(12) if i not in named][:10]
        raise NetsimInputError(
            f"{path}: node(s) {gaps} ... are never named, up to node {n - 1}: "
            "number the nodes from 0 without large gaps"
        )
    # Count the nodes lacking a coordinate without walking range(n): a stray huge node
    # number must not make the check itself enormous.
    complete = sum(1 for xy in initial.values() if "X" in xy and "Y" in xy)
    if complete < n:
        first = []
        for i in range(n):
            if "X" not in initial.get(i, {}) or "Y" not in initial.get(i, {}):
                first.append(i)
                if len(first) == 10:
                    break
        more = f" and {n - complete - len(first)} more" if n - complete > len(first) else ""
        warnings.warn(
            f"{path}: node(s) {first}{more} have no initial X_ or Y_: they start at 0 on that axis,"
            " as in ns-3's Ns2MobilityHelper",
            stacklevel=2,
        )
    commands = commands.sort_values(["t_s", "line"], kind="stable").drop(columns="line").reset_index(drop=True)
    init = np.array([[initial.get(i, {}).get(axis, 0.0) for axis in "XY"] for i in range(n)])
    return Scenario(init, commands)


def write(path: str | Path, legs: pd.DataFrame, n_robots: int, duration_s: float, header: str = "") -> None:
    """Write legs (as :meth:`RobotState.legs` gives) as an ns-2 movement file.

    Each moving leg becomes a ``setdest`` toward where the leg ends (the start of the
    robot's next leg, or its position at ``duration_s``). Numbers are written with
    Python's shortest round-trip ``repr``, so a replay reproduces the positions.
    """
    lines = [f"# {line}" for line in header.splitlines()]
    legs = legs.sort_values(["robot", "t_s"], kind="stable")
    t = legs["t_s"].to_numpy(float)
    robot = legs["robot"].to_numpy(np.int64)
    p = legs[["x_m", "y_m"]].to_numpy(float)
    v = legs[["vx_mps", "vy_mps"]].to_numpy(float)
    for i in range(n_robots):
        first = np.searchsorted(robot, i)
        x, y = p[first].tolist()
        lines += [f"$node_({i}) set X_ {x!r}", f"$node_({i}) set Y_ {y!r}", f"$node_({i}) set Z_ 0.0"]
    events = []
    for k in range(len(t)):
        speed = math.hypot(v[k, 0], v[k, 1])
        if speed == 0.0 or t[k] >= duration_s:
            continue
        last = k + 1 >= len(t) or robot[k + 1] != robot[k]
        t_end = duration_s if last else min(t[k + 1], duration_s)
        dx, dy = (p[k] + v[k] * (t_end - t[k])).tolist()
        tk, rk = float(t[k]), int(robot[k])
        events.append((tk, rk, f'$ns_ at {tk!r} "$node_({rk}) setdest {dx!r} {dy!r} {speed!r}"'))
    events.sort(key=lambda e: (e[0], e[1]))
    lines += [e[2] for e in events]
    Path(path).write_text("\n".join(lines) + "\n")
