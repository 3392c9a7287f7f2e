import os

import numpy as np
import pytest
from hypothesis import settings

# Property tests draw the same examples on every run, so that a red CI always means a
# change in the code; HYPOTHESIS_PROFILE=explore draws new ones (to hunt for bugs).
settings.register_profile("deterministic", derandomize=True)
settings.register_profile("explore", derandomize=False)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "deterministic"))

from netsim.run import build  # noqa: E402  (after the hypothesis profile is loaded)
from tests.fixtures import make_config  # noqa: E402


@pytest.fixture
def build_sim():
    def _build(**tree):
        return build(make_config(**tree))

    return _build


@pytest.fixture
def rng():
    return np.random.default_rng(12345)
