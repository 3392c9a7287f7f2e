"""A command imports what it needs when it needs it: a small ``netsim run`` loads neither
networkx (the live graph and snapshots) nor numba (the compiled loops pay off past
netsim.compiled.SMALL_RUN_ROBOTS robots), nor matplotlib."""

import shutil
import subprocess
import sys

import pytest

SHADOWING = ["--set", "channel.propagation=log_distance", "--set", "channel.shadowing_sigma_db=4"]
# The local plan under shadowing: its fade-margin rule asks the radio's laws of (n, n) pairs.
LOCAL_FADE = [
    *SHADOWING,
    *("--set coverage.enabled=true --set mobility.model=static --set coverage.plan=local".split()),
    *("--set channel.loss_probability=0 --set duration_s=40".split()),
]


@pytest.mark.slow
@pytest.mark.parametrize(
    "world",
    [[], ["--set", "world.torus=true"], SHADOWING, LOCAL_FADE],
    ids=["plane", "torus", "shadowing", "local-plan-shadowing"],
)
def test_small_run_imports_no_graph_jit_or_plotting(tmp_path, world):
    """``netsim run`` with 10 robots, on the plane, on a torus (whose positions are folded
    for the sampled tables too) and under shadowing (whose pairs are keyed as the team's):
    networkx, numba and matplotlib stay unloaded; and a local plan's coverage under shadowing
    (whose laws run over pairs of the team)."""
    code = (
        "import sys\n"
        "from netsim.tools.cli import main\n"
        "try:\n"
        f"    main(['run', '--out', {str(tmp_path)!r}, '--no-progress', '--quiet',"
        f" '--set', 'world.n_robots=10', '--set', 'duration_s=5', *{world!r}])\n"
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


@pytest.mark.slow
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


@pytest.mark.slow
def test_the_library_leaves_the_garbage_collector_as_it_found_it(tmp_path):
    """Importing netsim, loading its compiled loops and running a simulation through
    ``main`` change nothing of the garbage collector: on stays on, off stays off, nothing
    is frozen, and the user's frozen objects stay frozen."""
    code = (
        "import gc, sys\n"
        "gc.disable() if sys.argv[1] == 'off' else None\n"
        "keep = [[i] for i in range(1000)]\n"
        "gc.freeze() if sys.argv[2] == 'frozen' else None\n"
        "before = (gc.isenabled(), gc.get_freeze_count() > 0)\n"
        "import netsim\n"
        "from netsim.compiled import load\n"
        "load('netsim._kernels', 100)\n"
        "from netsim.tools.cli import main\n"
        f"code = main(['run', '--out', {str(tmp_path)!r}, '--no-progress', '--quiet', '--set', 'world.n_robots=30',"
        " '--set', 'duration_s=2'])\n"
        "print(code, (gc.isenabled(), gc.get_freeze_count() > 0) == before)\n"
    )
    # Each setting of each switch once: on and nothing frozen, off and the user's frozen.
    for state, frozen in (("on", "plain"), ("off", "frozen")):
        out = subprocess.run(
            [sys.executable, "-c", code, state, frozen], capture_output=True, text=True, check=True, env=_env()
        )
        assert out.stdout.strip().splitlines()[-1] == "0 True", (state, frozen)
        shutil.rmtree(tmp_path)
        tmp_path.mkdir()


@pytest.mark.slow
def test_the_command_freezes_what_it_loaded_and_ends_at_once():
    """The ``netsim`` command (netsim.tools.cli.command), whose process is its own, freezes
    what its imports loaded out of the collector's passes, then ends the process at once
    with main's exit code."""
    code = (
        "import gc, os, sys\n"
        "from netsim.tools import cli\n"
        "def ended(code):\n"
        "    print(gc.get_freeze_count() > 0, code, flush=True)\n"
        "    sys.exit(0)\n"
        "os._exit = ended\n"
        "sys.argv = ['netsim', 'run', '--set', 'world.n_robots=-3']\n"
        "cli.command()\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=_env())
    assert out.stdout.strip().splitlines()[-1] == "True 2"


@pytest.mark.slow
def test_importing_the_package_loads_no_library_and_the_console_script_pauses_the_collector():
    """``import netsim`` (and the console script's module, netsim.tools.command) load none
    of numpy, pandas or pyarrow, so that the ``netsim`` command can pause the garbage
    collector while they load; its names still come on demand. The console script loads
    the command with the collector off and leaves it as it found it."""
    code = (
        "import gc, os, sys\n"
        "import netsim, netsim.tools.command\n"
        "print(sorted(m for m in ('numpy', 'pandas', 'pyarrow', 'netsim.config') if m in sys.modules))\n"
        "seen = []\n"
        "class Watch:\n"
        "    def find_spec(self, name, path=None, target=None):\n"
        "        if name == 'pandas':\n"
        "            seen.append(gc.isenabled())\n"
        "sys.meta_path.insert(0, Watch())\n"
        "def ended(code):\n"
        "    print(seen, gc.isenabled(), code)\n"
        "    print(netsim.load.__module__, netsim.Simulation.__name__, flush=True)\n"
        "    sys.exit(0)\n"
        "os._exit = ended\n"
        "sys.argv = ['netsim', 'run', '--set', 'world.n_robots=-3']\n"
        "netsim.tools.command.command()\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=_env())
    assert out.stdout.strip().splitlines() == ["[]", "[False] True 2", "netsim.config Simulation"]
