import os
import signal
from pathlib import Path

# The compiled kernels' cache of the tests, apart from the user's: netsim.kernel_cache keys
# it by the kernels' sources under this directory (also for the commands the tests start).
_ROOT = Path(__file__).resolve().parent.parent
os.environ.setdefault("NUMBA_CACHE_DIR", str(_ROOT / ".pytest_cache" / "numba"))

import numpy as np  # noqa: E402
import pytest  # noqa: E402
from hypothesis import settings  # noqa: E402

import netsim.run  # noqa: E402


def _check_coverage_tables(collect):
    """``collect`` that also asserts a run's coverage table has, at every sample, the
    components of the network of its ``links`` table (one notion of link everywhere)."""
    from netsim.metrics import components_in_links_table

    def checked(sim, emit=None, progress=False):
        frames = collect(sim, emit, progress)
        cov, links = frames.get("coverage"), frames.get("links")
        if cov is not None and len(cov) and {"t_s", "components"} <= set(cov.columns) and links is not None:
            times = cov["t_s"].to_numpy(float)
            real = components_in_links_table(links, sim.state.n, times)
            wrong = np.flatnonzero(cov["components"].to_numpy() != real)
            assert not len(wrong), f"coverage table's components untrue at t = {times[wrong][:5].tolist()} s"
        return frames

    return checked


# Every run a test makes in this process goes through the check above: installed before
# anything imports ``collect`` by name (tests.fixtures loads netsim.tools.validate, which does).
netsim.run.collect = _check_coverage_tables(netsim.run.collect)

from netsim.run import build  # noqa: E402
from tests.fixtures import make_config  # noqa: E402

# Property tests draw the same examples on every run, so that a red CI always means a
# change in the code; HYPOTHESIS_PROFILE=explore draws new ones (to hunt for bugs).
settings.register_profile("deterministic", derandomize=True)
settings.register_profile("explore", derandomize=False)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "deterministic"))


@pytest.fixture
def build_sim():
    def _build(**tree):
        return build(make_config(**tree))

    return _build


@pytest.fixture
def rng():
    return np.random.default_rng(12345)


def pytest_configure(config):
    # A shell that starts the tests in the background hands them SIGINT ignored, and every
    # process they start inherits that: the Ctrl-C tests' children would never see theirs.
    if signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    # Spread over workers (`-n`), the long tests would otherwise start wherever collection
    # puts them and the last one can run alone at the end: they go first (below), and a
    # worker that runs out of tests takes half of another's queue instead of waiting.
    if getattr(config.option, "dist", "no") == "load":
        config.option.dist = "worksteal"


# The longest test of all (it plays the README's every command), started before the others.
LONGEST = "test_readme.py::test_every_readme_command_runs"


def pytest_collection_modifyitems(config, items):
    items.sort(key=lambda item: (not item.nodeid.endswith(LONGEST), item.get_closest_marker("slow") is None))
