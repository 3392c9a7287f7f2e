"""A command imports what it needs when it needs it: a small ``netsim run`` loads neither
networkx (the live graph and snapshots) nor numba (the compiled loops pay off past
netsim.compiled.SMALL_RUN_ROBOTS robots), nor matplotlib."""

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
        "except SystemExit:\n"
        "    pass\n"
        "print(sorted(m for m in ('networkx', 'numba', 'matplotlib') if m in sys.modules))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=_env())
    assert out.stdout.strip().splitlines()[-1] == "[]"


def _env():
    import os

    env = dict(os.environ)
    env.pop("NETSIM_COMPILED", None)
    return env
