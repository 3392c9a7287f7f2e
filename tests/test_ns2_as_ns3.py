"""ns-2 movement files replay to the positions ns-3's Ns2MobilityHelper gives them, when
read as ns-3 reads them (``mobility.ns2_semantics = "ns3"``).

The reference positions (``tests/data/ns2/ns3_positions.json``) were made by ns-3 itself
(the ns-3.44 wheel) with ``tests/data/ns2/ns3_positions.py`` from the files beside it:
setdest's output with its ``$god_`` lines and statistics, a whole Tcl simulation script
around the movement lines, BonnMotion's ns-2 export, and files with scheduled ``set X_``
lines, quotes apart from the last number, comments after ``;``, lines out of time order,
times that are not numbers or negative, a zero and a negative speed.
"""

import contextlib
import json
from pathlib import Path

import numpy as np
import pytest

from netsim.run import build
from netsim.trajectory import sample_positions
from tests.fixtures import make_config

DATA = Path(__file__).parent / "data" / "ns2"
REFERENCE = json.loads((DATA / "ns3_positions.json").read_text())
# Lines ns-3 skips (a time that is not a number or is negative, a negative speed, a `set`
# without its number): netsim skips them too, and says which.
SKIPPED_LINE = {"script.tcl": "26, 27", "setdest.tcl": "26", "sets.tcl": "7"}


@pytest.mark.parametrize("name", sorted(REFERENCE))
def test_ns2_file_replays_to_ns3s_positions(name):
    """With ns2_semantics = "ns3", every position is ns-3's, to 1e-6 m."""
    ref = REFERENCE[name]
    times = np.array(ref["times"], dtype=float)
    expected = np.array(ref["positions"])
    n = expected.shape[1]
    skipped = SKIPPED_LINE.get(name)
    said = pytest.warns(UserWarning, match=f"line\\(s\\) {skipped}$") if skipped else contextlib.nullcontext()
    with said:
        sim = build(
            make_config(
                duration_s=float(times.max()) + 1.0,
                world={"n_robots": n, "side_m": 1000.0},
                mobility={"model": "trace", "trace_file": str(DATA / name), "ns2_semantics": "ns3"},
                protocol={"model": "none"},
            )
        )
    sim.run()
    got = sample_positions(sim.state.legs(), n, times)[["x_m", "y_m"]].to_numpy().reshape(len(times), n, 2)
    assert np.abs(got - expected).max() < 1e-6
