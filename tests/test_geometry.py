"""The geometry's own rules, beyond its examples."""

import numpy as np

from netsim.geometry import SPEED_OF_LIGHT_MPS, drivable


def test_a_robot_may_be_driven_at_the_speed_of_light_itself_and_no_faster():
    at, past = [SPEED_OF_LIGHT_MPS, 0.0], [0.0, np.nextafter(SPEED_OF_LIGHT_MPS, np.inf)]
    assert drivable([at, past, [-SPEED_OF_LIGHT_MPS, 0.0]]).tolist() == [True, False, True]
