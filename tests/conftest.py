import numpy as np
import pytest

from netsim.run import build
from tests.fixtures import make_config


@pytest.fixture
def build_sim():
    def _build(**tree):
        return build(make_config(**tree))

    return _build


@pytest.fixture
def rng():
    return np.random.default_rng(12345)
