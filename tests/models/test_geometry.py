"""Geometry helpers against independent properties (hypothesis)."""

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from aerorelay.models.geometry import E3, align_with_thrust, realign_with_thrust, thrust_direction_from_acceleration


@settings(max_examples=200, deadline=None)
@given(st.lists(st.floats(-1, 1), min_size=3, max_size=3), st.lists(st.floats(-15, 15), min_size=2, max_size=2),
       st.floats(-9.0, 15.0))
def test_align_with_thrust_carries_a_hover_axis_along_with_the_thrust(axis, accel_xy, accel_z):
    accel = [*accel_xy, accel_z]  # a_z > -g: the thrust points up
    a = np.asarray(axis)
    assume(np.linalg.norm(a) > 1e-3)
    a = a / np.linalg.norm(a)
    acc = np.asarray(accel)
    out = align_with_thrust(a, acc, 9.81)
    f = thrust_direction_from_acceleration(acc, 9.81)
    assert abs(np.linalg.norm(out) - 1.0) < 1e-9
    assert abs(out @ f - a @ E3) < 1e-9  # the axis keeps its angle to the thrust
    np.testing.assert_allclose(align_with_thrust(E3, acc, 9.81), f, atol=1e-12)  # e3 goes to the thrust
    np.testing.assert_allclose(align_with_thrust(a, np.zeros(3), 9.81), a, atol=1e-15)


def test_align_with_thrust_refuses_a_downward_thrust():
    with pytest.raises(ValueError, match="downward thrust"):
        align_with_thrust(E3, np.array([0.0, 0.0, -10.0]), 9.81)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.floats(-1, 1), min_size=3, max_size=3), st.lists(st.floats(-8, 8), min_size=3, max_size=3),
       st.lists(st.floats(-8, 8), min_size=3, max_size=3))
def test_realign_keeps_the_axis_relative_to_the_thrust(axis, acc_from, acc_to):
    a = np.asarray(axis)
    assume(np.linalg.norm(a) > 1e-3)
    a = a / np.linalg.norm(a)
    f0, f1 = np.asarray(acc_from), np.asarray(acc_to)
    carried = align_with_thrust(a, f0, 9.81)
    np.testing.assert_allclose(align_with_thrust(carried, f0, 9.81, inverse=True), a, atol=1e-12)  # the inverse undoes it
    moved = realign_with_thrust(carried, f0, f1, 9.81)
    np.testing.assert_allclose(moved, align_with_thrust(a, f1, 9.81), atol=1e-12)
    assert abs(moved @ thrust_direction_from_acceleration(f1, 9.81) - a @ E3) < 1e-9
