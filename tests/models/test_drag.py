"""The parasitic drag (models/drag.py) from its formula by hand: a level vehicle in a headwind, a
vehicle yawed 90 deg (the body axes swap), the numeric and symbolic forms agreeing, and the drag
always opposing the air velocity (hypothesis)."""

from __future__ import annotations

import casadi as ca
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from aerorelay.models.drag import drag_acceleration, drag_coefficients

C = np.array([0.03, 0.05, 0.07])  # kg/m per body axis
MASS = 2.0


def test_coefficients_are_half_rho_cd_a():
    assert np.allclose(drag_coefficients([0.1, 0.2, 0.4], 1.2), [0.06, 0.12, 0.24])


def test_level_vehicle_in_wind_is_pushed_downwind():
    # at rest, level, wind 5 m/s toward +x: air velocity -5 x in the body, force c_x 25 toward +x
    a = drag_acceleration(np.zeros(3), np.zeros(3), np.array([5.0, 0.0, 0.0]), C, MASS)
    assert np.allclose(a, [C[0] * 25.0 / MASS, 0.0, 0.0])


def test_yawed_vehicle_meets_the_wind_on_its_y_axis():
    # yaw 90 deg: world x is body -y, so the body y coefficient acts
    a = drag_acceleration(np.array([0.0, 0.0, np.pi / 2]), np.zeros(3), np.array([4.0, 0.0, 0.0]), C, MASS)
    assert np.allclose(a, [C[1] * 16.0 / MASS, 0.0, 0.0])


def test_climbing_in_still_air_is_braked_on_body_z():
    a = drag_acceleration(np.zeros(3), np.array([0.0, 0.0, 3.0]), np.zeros(3), C, MASS)
    assert np.allclose(a, [0.0, 0.0, -C[2] * 9.0 / MASS])


def test_symbolic_matches_numeric():
    eta, v, w = np.array([0.1, -0.2, 0.7]), np.array([1.0, -2.0, 0.5]), np.array([3.0, 1.0, -0.4])
    se, sv, sw = ca.SX.sym("e", 3), ca.SX.sym("v", 3), ca.SX.sym("w", 3)
    f = ca.Function("f", [se, sv, sw], [drag_acceleration(se, sv, sw, C, MASS)])
    assert np.allclose(np.asarray(f(eta, v, w)).ravel(), drag_acceleration(eta, v, w, C, MASS), rtol=1e-12, atol=1e-15)


vec = st.lists(st.floats(-10, 10), min_size=3, max_size=3).map(np.array)
angle = st.lists(st.floats(-1.2, 1.2), min_size=3, max_size=3).map(np.array)


@settings(max_examples=200, deadline=None)
@given(angle, vec, vec)
def test_drag_opposes_the_air_velocity(eta, v, w):
    a = drag_acceleration(eta, v, w, C, MASS)
    # the work rate against the air is never positive: a . (v - w) <= 0
    assert float(a @ (v - w)) <= 1e-12
    # and its size lies between the smallest and largest coefficient's
    speed2 = float((v - w) @ (v - w))
    n = float(np.linalg.norm(a))
    assert C.min() * speed2 / MASS - 1e-9 <= n <= C.max() * speed2 / MASS + 1e-9
