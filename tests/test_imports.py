"""A command imports what it needs when it needs it: a small ``netsim run`` loads neither
networkx (the live graph and snapshots) nor numba (the compiled loops pay off past
netsim.compiled.SMALL_RUN_ROBOTS robots), nor matplotlib."""

import shutil
import subprocess
import sys


def test_small_run_imports_no_graph_jit_or_plotting(tmp_path):
    """``netsim run`` with 10 robots: networkx, numba and matplotlib stay unloaded."""
    code = (
        "import sys\n"
        "from netsim.tools.cli import main\n"
        "try:\n"
        f"    main(['run', '--out', {str(tmp_path)!r}, '--no-progress', '--quiet',"
        " '--set', 'world.n_robots=10', '--set', 'duration_s=5'])\n"
        "except SystemExit as exc:\n"
        "    assert not exc.code, exc.code\n"
        "print(sorted(m for m in ('networkx', 'numba', 'matplotlib') if m in sys.modules))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=_env())
    assert out.stdout.strip().splitlines()[-1] == "[]"


def _env():
    import os

    env = dict(os.environ)
    env.pop("NETSIM_COMPILED", None)
    return env


def test_large_run_imports_no_kd_tree_or_scipy_linalg(tmp_path):
    """``netsim run`` with 60 robots (compiled loops): the candidate pairs come from the
    compiled grid, so scipy.spatial stays unloaded, and numba's probe for BLAS does not
    load scipy.linalg; which imports as usual afterwards, with numba's loops still right."""
    code = (
        "import sys\n"
        "from netsim.tools.cli import main\n"
        "try:\n"
        f"    main(['run', '--out', {str(tmp_path)!r}, '--no-progress', '--quiet',"
        " '--set', 'world.n_robots=60', '--set', 'duration_s=5', '--set', 'protocol.model=ack'])\n"
        "except SystemExit as exc:\n"
        "    assert not exc.code, exc.code\n"
        "print(sorted(m for m in ('numba', 'scipy.spatial', 'scipy.linalg') if m in sys.modules))\n"
        "import numpy as np, scipy.linalg.cython_blas\n"
        "from netsim import _kernels\n"
        "print(_kernels.near_pairs(np.array([[0.0, 0.0], [1.0, 0.0], [5.0, 0.0]]), 2.0, 0.0).tolist())\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=_env())
    loaded, pairs = out.stdout.strip().splitlines()[-2:]
    assert loaded == "['numba']"
    assert pairs == "[[0, 1]]"


def test_collector_paused_while_loading_and_frozen_only_by_the_command_line(tmp_path):
    """Importing netsim and loading its compiled loops leave the garbage collector as they
    found it (on, nothing frozen; off stays off); the command line, whose process is its
    own, freezes what it has loaded."""
    code = (
        "import gc, sys\n"
        "gc.disable() if sys.argv[1] == 'off' else None\n"
        "import netsim\n"
        "from netsim.compiled import load\n"
        "load('netsim._kernels', 100)\n"
        "print(gc.isenabled(), gc.get_freeze_count())\n"
        "from netsim.tools.cli import main\n"
        "try:\n"
        f"    main(['run', '--out', {str(tmp_path)!r}, '--no-progress', '--quiet', '--set', 'world.n_robots=30',"
        " '--set', 'duration_s=2'])\n"
        "except SystemExit as exc:\n"
        "    assert not exc.code, exc.code\n"
        "print(gc.isenabled(), gc.get_freeze_count() > 0)\n"
    )
    for state, first in (("on", "True 0"), ("off", "False 0")):
        out = subprocess.run(
            [sys.executable, "-c", code, state], capture_output=True, text=True, check=True, env=_env()
        )
        library, command_line = out.stdout.strip().splitlines()[-2:]
        assert library == first
        assert command_line == f"{state == 'on'} True"
        shutil.rmtree(tmp_path)
        tmp_path.mkdir()


def test_what_netsim_loads_goes_to_the_oldest_generation_unfrozen():
    """After ``import netsim`` (collector on) what it loaded sits in the collector's oldest
    generation, not among the young objects that the next pass would walk, and nothing is
    frozen; where the user had frozen objects, they stay frozen."""
    code = (
        "import gc, sys\n"
        "if sys.argv[1] == 'frozen':\n"
        "    keep = [[i] for i in range(1000)]\n"
        "    gc.freeze()\n"
        "before = gc.get_freeze_count()\n"
        "import netsim\n"
        "young = len(gc.get_objects(0)) + len(gc.get_objects(1))\n"
        "print(gc.isenabled(), (gc.get_freeze_count() > 0) == (before > 0), young < 0.1 * len(gc.get_objects(2)))\n"
    )
    for state, want in (("plain", "True True True"), ("frozen", "True True False")):
        out = subprocess.run(
            [sys.executable, "-c", code, state], capture_output=True, text=True, check=True, env=_env()
        )
        assert out.stdout.strip().splitlines()[-1] == want, state
