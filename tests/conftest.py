import hashlib
import os
from pathlib import Path

# numba checks a cached loop against its own source file only: a loop that calls one of
# another module (protocols' kernels call netsim's) would keep the old callee after an
# edit of that module alone. The tests use a cache of their own per version of every
# kernel module, so that they always check the code as it is.
_ROOT = Path(__file__).resolve().parent.parent
_KERNELS = sorted(p for d in ("netsim", "protocols", "mobility") for p in (_ROOT / d).rglob("*_kernels.py"))
_VERSION = hashlib.sha256(b"".join(p.read_bytes() for p in _KERNELS)).hexdigest()[:16]
os.environ.setdefault("NUMBA_CACHE_DIR", str(_ROOT / ".pytest_cache" / "numba" / _VERSION))

import numpy as np  # noqa: E402
import pytest  # noqa: E402
from hypothesis import settings  # noqa: E402

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
