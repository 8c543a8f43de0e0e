"""Frames at the autopilot's edge. Inside aerorelay the world is ENU (x east, y north, z up) and the
body FLU (x forward, y left, z up); PX4 and ArduPilot speak NED (x north, y east, z down) and FRD
(x forward, y right, z down). Vectors: ``v_ned = T v_enu`` with ``T`` swapping x and y and negating z
(its own inverse); body vectors ``v_frd = B v_flu`` with ``B = diag(1, -1, -1)``. Attitudes (body to
world): ``R_ned_frd = T R_enu_flu B``. Quaternions are scalar first ``(w, x, y, z)``, as MAVLink's
``SET_ATTITUDE_TARGET.q`` (ROS messages are scalar last: ``quaternion_xyzw``).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial.transform import Rotation

ENU_TO_NED = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
FLU_TO_FRD = np.diag([1.0, -1.0, -1.0])


def enu_to_ned(v) -> np.ndarray:
    """A world vector (position m, velocity m/s, acceleration m/s^2) from ENU to NED; ``(..., 3)``."""
    return np.asarray(v, float) @ ENU_TO_NED.T


def ned_to_enu(v) -> np.ndarray:
    """A world vector from NED to ENU (the same swap: ``T`` is its own inverse)."""
    return np.asarray(v, float) @ ENU_TO_NED.T


def yaw_enu_to_ned(yaw: float) -> float:
    """A heading (rad) from ENU (from east, counter-clockwise) to NED (from north, clockwise); its own inverse."""
    return math.pi / 2 - yaw


def yaw_ned_to_enu(yaw: float) -> float:
    """A heading (rad) from NED to ENU (the same reflection)."""
    return yaw_enu_to_ned(yaw)


def flu_to_frd(v) -> np.ndarray:
    """A body vector (body rates rad/s, forces) from FLU to FRD; ``(..., 3)``."""
    return np.asarray(v, float) @ FLU_TO_FRD.T


def frd_to_flu(v) -> np.ndarray:
    return np.asarray(v, float) @ FLU_TO_FRD.T


def rotation_enu_flu_to_ned_frd(R) -> np.ndarray:
    """``R_ned_frd = T R_enu_flu B`` (body to world rotation matrices)."""
    return ENU_TO_NED @ np.asarray(R, float) @ FLU_TO_FRD


def rotation_ned_frd_to_enu_flu(R) -> np.ndarray:
    return ENU_TO_NED @ np.asarray(R, float) @ FLU_TO_FRD


def matrix_from_wxyz(q) -> np.ndarray:
    w, x, y, z = np.asarray(q, float)
    return Rotation.from_quat([x, y, z, w]).as_matrix()


def quaternion_xyzw(q_wxyz) -> np.ndarray:
    """Scalar-first to scalar-last (ROS ``geometry_msgs/Quaternion`` order)."""
    w, x, y, z = np.asarray(q_wxyz, float)
    return np.array([x, y, z, w])


def euler_zyx(R) -> np.ndarray:
    """ZYX Euler angles (roll, pitch, yaw; rad) of a body-to-world rotation (``models.geometry.rotation_zyx``'s inverse)."""
    R = np.asarray(R, float)
    return np.array([math.atan2(R[2, 1], R[2, 2]), -math.asin(max(-1.0, min(1.0, R[2, 0]))), math.atan2(R[1, 0], R[0, 0])])
