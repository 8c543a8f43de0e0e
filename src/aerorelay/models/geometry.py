"""Rotations and Euler-angle kinematics (ZYX convention, world z up). *Dual* numpy/CasADi.

``R = Rz(psi) Ry(theta) Rx(phi)`` maps body-frame vectors to the world frame; Euler angles
``eta = (phi, theta, psi)`` in rad; ``eta_dot = T(eta) omega`` with ``omega`` in the body frame.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
from scipy.spatial.transform import Rotation

from .backend import is_symbolic, ops

E3 = np.array([0.0, 0.0, 1.0])


def _assemble(rows, symbolic: bool):
    if symbolic:
        return ca.vertcat(*[ca.horzcat(*r) for r in rows])
    return np.array(rows, dtype=float)


def rotation_zyx(eta):
    """Body-to-world rotation ``R(eta) = Rz(psi) Ry(theta) Rx(phi)`` (paper eq. 1), 3x3."""
    sym = is_symbolic(eta)
    o = ops(eta)
    phi, th, psi = eta[0], eta[1], eta[2]
    cf, sf, ct, st, cp, sp = o.cos(phi), o.sin(phi), o.cos(th), o.sin(th), o.cos(psi), o.sin(psi)
    rows = [
        [cp * ct, cp * st * sf - sp * cf, cp * st * cf + sp * sf],
        [sp * ct, sp * st * sf + cp * cf, sp * st * cf - cp * sf],
        [-st, ct * sf, ct * cf],
    ]
    return _assemble(rows, sym)


def euler_rate_matrix(eta):
    """``T(eta)`` with ``eta_dot = T(eta) omega`` for ZYX angles and body rates (paper eq. 1)."""
    sym = is_symbolic(eta)
    o = ops(eta)
    phi, th = eta[0], eta[1]
    cf, sf, ct, tt = o.cos(phi), o.sin(phi), o.cos(th), o.tan(th)
    rows = [
        [1.0, sf * tt, cf * tt],
        [0.0, cf, -sf],
        [0.0, sf / ct, cf / ct],
    ]
    return _assemble(rows, sym)


def thrust_direction(eta):
    """World-frame body z axis ``rho = R(eta) e3`` (paper eq. 13), i.e. the third column of R."""
    R = rotation_zyx(eta)
    if is_symbolic(eta):
        return R[:, 2]
    return R[:, 2].copy()


def thrust_direction_from_acceleration(acceleration, gravity: float) -> np.ndarray:
    """Unit thrust direction ``(a + g e3)/|a + g e3|`` of a vehicle accelerating at ``a`` (m/s^2,
    world): the body z of a coplanar vehicle, and the paper's ``rho_d`` (eq. 20)."""
    thrust = np.asarray(acceleration, float) + gravity * E3
    return thrust / np.linalg.norm(thrust)


def align_with_thrust(axis, acceleration, gravity: float, inverse: bool = False) -> np.ndarray:
    """``axis`` (unit, world) turned by the rotation that takes ``e3`` to the thrust direction of
    ``acceleration`` (shortest arc): a hover antenna axis carried along when the vehicle tilts to
    accelerate. Zero acceleration returns ``axis``; ``inverse``: the rotation back (thrust to ``e3``)."""
    axis = np.asarray(axis, float)
    f = thrust_direction_from_acceleration(acceleration, gravity)
    if f[2] <= 0.0:
        raise ValueError(f"acceleration {np.round(acceleration, 3).tolist()} m/s^2 needs a downward thrust: "
                         "no multirotor attitude flies it (a_z must exceed -g)")
    k = np.cross(E3, f)
    s, c = float(np.linalg.norm(k)), float(f[2])
    if s < 1e-12:
        return axis.copy()
    k /= s
    s = -s if inverse else s
    # Rodrigues' formula
    return axis * c + np.cross(k, axis) * s + k * (k @ axis) * (1.0 - c)


def realign_with_thrust(axis, acceleration_from, acceleration_to, gravity: float) -> np.ndarray:
    """An antenna axis carried along with the thrust for ``acceleration_from`` (``align_with_thrust``)
    carried instead with the thrust for ``acceleration_to`` (m/s^2, world): the same axis relative to
    the thrust, e.g. a relay leaning into the wind (the thrust counters an external acceleration too)."""
    return align_with_thrust(align_with_thrust(axis, acceleration_from, gravity, inverse=True), acceleration_to, gravity)


def attitude_from_thrust(direction, yaw: float = 0.0) -> np.ndarray:
    """ZYX Euler angles (rad) whose body z axis points along ``direction`` with the given yaw.

    Used for MRAV-2, a coplanar vehicle whose body z follows ``(a + g e3)/|a + g e3|``.
    Works on ``(..., 3)`` arrays.
    """
    d = np.asarray(direction, dtype=float)
    d = d / np.linalg.norm(d, axis=-1, keepdims=True)
    cy, sy = np.cos(yaw), np.sin(yaw)
    # Undo yaw: express d in the yaw-rotated frame, then R = Ry(theta) Rx(phi) maps e3 to d'.
    dx = cy * d[..., 0] + sy * d[..., 1]
    dy = -sy * d[..., 0] + cy * d[..., 1]
    dz = d[..., 2]
    phi = np.arcsin(np.clip(-dy, -1.0, 1.0))
    theta = np.arctan2(dx, dz)
    return np.stack([phi, theta, np.full_like(phi, yaw)], axis=-1)


def rotation_batch(eta: np.ndarray) -> np.ndarray:
    """Vectorized ``rotation_zyx`` for ``(n, 3)`` Euler angles, returns ``(n, 3, 3)``."""
    eta = np.atleast_2d(np.asarray(eta, dtype=float))
    phi, th, psi = eta[:, 0], eta[:, 1], eta[:, 2]
    cf, sf, ct, st, cp, sp = np.cos(phi), np.sin(phi), np.cos(th), np.sin(th), np.cos(psi), np.sin(psi)
    R = np.empty((eta.shape[0], 3, 3))
    R[:, 0] = np.stack([cp * ct, cp * st * sf - sp * cf, cp * st * cf + sp * sf], axis=-1)
    R[:, 1] = np.stack([sp * ct, sp * st * sf + cp * cf, sp * st * cf - cp * sf], axis=-1)
    R[:, 2] = np.stack([-st, ct * sf, ct * cf], axis=-1)
    return R


def clip_norm(v: np.ndarray, limit: float) -> np.ndarray:
    """``v`` scaled down to Euclidean norm ``limit`` where it is longer (numpy)."""
    n = float(np.linalg.norm(v))
    return v if n <= limit else v * (limit / n)


def constant_acceleration_path(p, v, a, tk: np.ndarray) -> np.ndarray:
    """Positions ``(3, len(tk))`` (m) at the times ``tk`` (s) from ``p`` (m), ``v`` (m/s), ``a`` (m/s^2):
    ``p + v t + a t^2 / 2`` (how the NMPC predicts MRAV-2 and a fleet's sources over its horizon)."""
    p, v, a = (np.asarray(x, float) for x in (p, v, a))
    return p[:, None] + v[:, None] * tk + 0.5 * a[:, None] * tk**2


def quaternion_wxyz(R) -> np.ndarray:
    """The unit quaternion ``(w, x, y, z)`` of a rotation matrix, ``w >= 0``."""
    x, y, z, w = Rotation.from_matrix(np.asarray(R, float)).as_quat()
    q = np.array([w, x, y, z])
    return q if q[0] >= 0 else -q
