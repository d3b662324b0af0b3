"""The leg contacts' solver parts (rlq/envs/lunar/physics/contacts.py) on hand-computed cases."""

import numpy as np
import pytest

from rlq.envs.lunar.physics.contacts import block_impulses

K = (2.0, 1.0, 2.0)  # k11, k12, k22


@pytest.mark.parametrize(
    "accumulated,normal_velocity,expected",
    [
        ((0.0, 0.0), (-3.0, -3.0), (1.0, 1.0)),  # both points push: K x = -b
        ((0.0, 0.0), (-3.0, 3.0), (1.5, 0.0)),  # the second would pull: the first alone, x0 = -b0 / k11
        ((0.0, 0.0), (1.0, 1.0), (0.0, 0.0)),  # both separate: no impulse
        ((1.0, 0.0), (1.0, 1.0), (0.5, 0.0)),  # b = vn - K a = (-1, 0): the first point alone
    ],
)
def test_block_impulses_enumerate_the_two_point_lcp(accumulated, normal_velocity, expected):
    x = block_impulses(*K, *accumulated, *normal_velocity)
    np.testing.assert_allclose(np.asarray(x, np.float64), expected, atol=1e-6)
