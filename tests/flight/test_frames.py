"""ENU/FLU to NED/FRD at the autopilot's edge, against values worked by hand: a vehicle at rest
facing east (ENU yaw 0) faces east in NED (yaw +90 deg), north-east-up positions map to north-east-down,
a right-hand roll in FRD is a left-hand one in FLU; every conversion undone by its inverse (hypothesis)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from aerorelay.flight.frames import (
    enu_to_ned,
    flu_to_frd,
    frd_to_flu,
    matrix_from_wxyz,
    ned_to_enu,
    quaternion_xyzw,
    rotation_enu_flu_to_ned_frd,
    rotation_ned_frd_to_enu_flu,
    yaw_enu_to_ned,
    yaw_ned_to_enu,
)
from aerorelay.models.geometry import quaternion_wxyz, rotation_zyx


def test_positions_by_hand():
    assert np.array_equal(enu_to_ned([1.0, 2.0, 3.0]), [2.0, 1.0, -3.0])  # 1 m east, 2 m north, 3 m up
    assert np.array_equal(ned_to_enu([2.0, 1.0, -3.0]), [1.0, 2.0, 3.0])


def test_facing_east_in_enu_faces_east_in_ned():
    R = rotation_enu_flu_to_ned_frd(np.eye(3))
    assert np.allclose(R @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])  # body forward = NED east
    assert np.allclose(R @ [0.0, 0.0, 1.0], [0.0, 0.0, 1.0])  # body down (FRD z) = NED down
    q = quaternion_wxyz(R)  # a +90 deg yaw about NED down
    assert np.allclose(q, [np.cos(np.pi / 4), 0.0, 0.0, np.sin(np.pi / 4)])


def test_facing_north_in_enu_is_ned_yaw_zero():
    R_enu = rotation_zyx([0.0, 0.0, np.pi / 2])  # ENU yaw 90 deg: forward = north
    assert np.allclose(rotation_enu_flu_to_ned_frd(R_enu), np.eye(3))


def test_body_rates_by_hand():
    # the forward axis is shared (p keeps its sign); FLU left and up are FRD right and down (q and r flip)
    assert np.array_equal(flu_to_frd([0.1, 0.2, 0.3]), [0.1, -0.2, -0.3])
    assert np.array_equal(frd_to_flu([0.1, -0.2, -0.3]), [0.1, 0.2, 0.3])


angles = st.lists(st.floats(-3.0, 3.0), min_size=3, max_size=3)


@settings(max_examples=100, deadline=None)
@given(angles, st.lists(st.floats(-50, 50), min_size=3, max_size=3))
def test_round_trips(eta, v):
    R = rotation_zyx(np.asarray(eta))
    back = rotation_ned_frd_to_enu_flu(rotation_enu_flu_to_ned_frd(R))
    assert np.allclose(back, R, atol=1e-12)
    assert np.allclose(ned_to_enu(enu_to_ned(v)), v) and np.allclose(frd_to_flu(flu_to_frd(v)), v)
    q = quaternion_wxyz(R)
    assert abs(np.linalg.norm(q) - 1) < 1e-12 and q[0] >= 0
    assert np.allclose(matrix_from_wxyz(q), R, atol=1e-12)
    assert np.allclose(quaternion_xyzw(q), [*q[1:], q[0]])
    # a world vector seen in the body agrees in both conventions
    Rn = rotation_enu_flu_to_ned_frd(R)
    assert np.allclose(flu_to_frd(R.T @ np.asarray(v)), Rn.T @ enu_to_ned(v), atol=1e-9)


def test_headings_by_hand():
    assert yaw_enu_to_ned(0.0) == pytest.approx(np.pi / 2)  # facing east
    assert yaw_enu_to_ned(np.pi / 2) == pytest.approx(0.0)  # facing north
    assert yaw_ned_to_enu(yaw_enu_to_ned(0.3)) == pytest.approx(0.3)
