"""Parasitic drag of a multirotor in moving air (RotorPy's quadrotor drag model, body frame).

With the air velocity seen by the body ``v_b = R' (v - w)`` (``v`` the vehicle's velocity and ``w``
the wind's, m/s, world) the drag force is ``F_b = -|v_b| C v_b`` with ``C = diag(c_x, c_y, c_z)``,
``c_i = 0.5 rho (C_d A)_i`` (kg/m), and the acceleration it gives ``a_D = R F_b / m`` (m/s^2, world).
Rotor drag (linear in the airspeed, from blade flapping) is not modelled. *Dual*: numpy or CasADi.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from .backend import is_symbolic, ops
from .geometry import rotation_zyx


def drag_coefficients(drag_area_m2, air_density_kg_m3: float) -> np.ndarray:
    """``c = 0.5 rho C_d A`` per body axis (kg/m) from the drag areas (m^2) and the air density (kg/m^3)."""
    return 0.5 * float(air_density_kg_m3) * np.asarray(drag_area_m2, float)


def drag_acceleration(eta, v, wind, coeff, mass: float):
    """``a_D = -R |v_b| C v_b / m`` (m/s^2, world) with ``v_b = R' (v - wind)``; ``eta`` ZYX Euler
    angles (rad), ``coeff`` ``c`` per body axis (kg/m), ``mass`` kg."""
    o = ops(eta, v, wind)
    R = rotation_zyx(eta)
    vb = o.matTvec(R, v - wind)
    c = ca.DM(np.asarray(coeff, float)) if is_symbolic(eta, v, wind) else np.asarray(coeff, float)
    return o.matvec(R, -o.norm(vb) * (c * vb)) / mass
