"""Record ``mac_none_724cc35.json``: the integer tables of a small clustering run without a medium.

Run it on the code before the shared medium existed (commit 724cc35), e.g.::

    git worktree add /tmp/base 724cc35
    PYTHONPATH=/tmp/base python tests/data/record_mac_none.py > tests/data/mac_none_724cc35.json

Self-contained (it must run on that commit). Integer columns and row counts only, no
floats: the fixture pins the default channel path (``channel.mac`` unset, i.e. ``"none"``)
without depending on the last bit of a time.
"""

import json

from netsim.config import from_dict
from netsim.run import execute

TREE = {
    "seed": 11,
    "world": {"n_robots": 30, "side_m": 400.0},
    "duration_s": 30.0,
    "channel": {"range_m": 120.0},
    "protocol": {"model": "clustering"},
    "output": {"position_interval_s": 0.0},
}
COLUMNS = {
    "acks": ["robot", "sent", "received", "dropped_loss", "dropped_not_alive", "dropped_out_of_range"],
    "roles": ["robot", "role", "leader", "cause"],
}


def integer_tables(frames) -> dict:
    """The fixture's content from a run's tables: the chosen columns in row order, and
    every table's row count."""
    out = {name: {c: [v if isinstance(v, str) else int(v) for v in frames[name][c]] for c in cols}
           for name, cols in COLUMNS.items()}  # fmt: skip
    out["rows"] = {name: len(df) for name, df in sorted(frames.items())}
    return out


if __name__ == "__main__":
    print(json.dumps({"config": TREE, **integer_tables(execute(from_dict(TREE)).frames)}, indent=None))
