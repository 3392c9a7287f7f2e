import numpy as np
import pytest

from netsim import config as cfgmod
from netsim.run import build
from netsim.tools.validate import rwp_density  # noqa: F401  (used by the tests)


def make_config(**tree):
    """A validated Config from nested keyword tables, e.g. ``world={"n_robots": 5}``."""
    return cfgmod.from_dict(tree)


@pytest.fixture
def build_sim():
    def _build(**tree):
        return build(make_config(**tree))

    return _build


@pytest.fixture
def rng():
    return np.random.default_rng(12345)
