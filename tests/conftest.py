import numpy as np
import pytest

from netsim import config as cfgmod
from netsim.run import build


def make_config(**tree):
    """A validated Config from nested keyword tables, e.g. ``world={"n_robots": 5}``."""
    return cfgmod.from_dict(tree)


@pytest.fixture
def build_sim():
    def _build(**tree):
        return build(make_config(**tree))

    return _build


def rwp_density(x: float, y: float) -> float:
    """Exact stationary density of random waypoint on the unit square (Hyytiä et al. 2006)."""
    import math

    from scipy import integrate

    from mobility.random_waypoint import MEAN_LEG_UNIT_SQUARE

    def border(phi):
        c, s = math.cos(phi), math.sin(phi)
        ts = []
        if c > 0:
            ts.append((1 - x) / c)
        elif c < 0:
            ts.append(-x / c)
        if s > 0:
            ts.append((1 - y) / s)
        elif s < 0:
            ts.append(-y / s)
        return min(ts)

    def integrand(phi):
        a, b = border(phi), border(phi + math.pi)
        return a * b * (a + b)

    # The integrand has kinks where the direction points at a corner.
    corners = sorted(math.atan2(cy - y, cx - x) % math.pi for cx in (0, 1) for cy in (0, 1))
    return integrate.quad(integrand, 0, math.pi, points=corners, limit=200)[0] / MEAN_LEG_UNIT_SQUARE


@pytest.fixture
def rng():
    return np.random.default_rng(12345)
