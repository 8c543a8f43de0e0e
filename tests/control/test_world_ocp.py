"""The NMPC's model with the observer's external acceleration and its keep-out rows: the
disturbance enters the RK4 step exactly (a constant acceleration adds ``a Ts`` to the velocity and
``a Ts^2 / 2`` to the position; zero changes nothing), a keep-out row is ``n . p - c`` (the plane's
formula), and an OCP without either keeps its layout and cache key."""

from __future__ import annotations

import casadi as ca
import numpy as np

from aerorelay.control.ocp import OcpSpec
from aerorelay.models.vehicle import hexarotor

VEH = hexarotor(20.0)
BASE = dict(vehicle=VEH, horizon=5, ts=0.02, constrained=True, bs_position=(0.0, 0.0, 0.0),
            workspace_min=(-10.0, -10.0, 0.0), workspace_max=(10.0, 10.0, 20.0))


def _step(spec: OcpSpec, xa, w, values) -> np.ndarray:
    xs, ws, ps = ca.SX.sym("x", spec.nx), ca.SX.sym("w", spec.nw), spec.params.symbol()
    f = ca.Function("f", [xs, ws, ps], [spec.discrete_dynamics(xs, ws, ps)])
    return np.asarray(f(xa, w, spec.params.matrix(1, values)[:, 0])).ravel()


def _values(spec: OcpSpec, **extra):
    vals = {n: 0.0 for n in spec.params.names if n not in spec.params.internal}
    return {**vals, "rho_d": [0.0, 0.0, 1.0], **extra}


def test_the_external_acceleration_enters_the_model_exactly():
    plain, dist = OcpSpec(**BASE), OcpSpec(**BASE, disturbance=True)
    rng = np.random.default_rng(0)
    xa = np.r_[VEH.hover_state([1.0, 2.0, 3.0]) + 0.05 * rng.standard_normal(VEH.nx), np.zeros(VEH.n_rotors)]
    w = np.r_[rng.normal(0, 20, VEH.n_rotors), np.zeros(plain.ns)]
    x0 = _step(plain, xa, w, _values(plain))
    assert np.array_equal(_step(dist, xa, w, _values(dist, a_ext=[0.0, 0.0, 0.0])), x0)
    a = np.array([0.7, -0.4, 0.25])
    x1 = _step(dist, xa, w, _values(dist, a_ext=a))
    assert np.allclose(x1[6:9] - x0[6:9], a * 0.02, rtol=0, atol=1e-12)
    assert np.allclose(x1[0:3] - x0[0:3], a * 0.02**2 / 2, rtol=0, atol=1e-12)
    assert np.array_equal(x1[3:6], x0[3:6]) and np.array_equal(x1[9:], x0[9:])


def test_a_keep_out_row_is_the_planes_formula():
    spec = OcpSpec(**BASE, obstacles=2)
    assert [c.name for c in spec.constraints][-1] == "obstacles" and spec.ng == 1 + 2
    n1, c1, n2, c2 = np.array([0.6, 0.8, 0.0]), 1.5, np.array([0.0, 0.0, -1.0]), -7.0
    planes = np.r_[n1, c1, n2, c2]
    xa = np.r_[VEH.hover_state([2.0, -1.0, 4.0]), np.zeros(VEH.n_rotors)]
    w = np.zeros(spec.nw)
    xs, ws, ps = ca.SX.sym("x", spec.nx), ca.SX.sym("w", spec.nw), spec.params.symbol()
    h = ca.Function("h", [xs, ws, ps], [spec.constraint_expr(xs, ws, ps)])
    rows = np.asarray(h(xa, w, spec.params.matrix(1, _values(spec, obstacle_planes=planes))[:, 0])).ravel()
    p = np.array([2.0, -1.0, 4.0])
    assert np.allclose(rows[-2:], [n1 @ p - c1, n2 @ p - c2])


def test_an_ocp_without_wind_or_obstacles_keeps_its_layout_and_key():
    plain = OcpSpec(**BASE)
    assert "a_ext" not in plain.params.names and "obstacle_planes" not in plain.params.names
    assert OcpSpec(**BASE, disturbance=False, obstacles=0).key() == plain.key()
    assert OcpSpec(**BASE, disturbance=True).key() != plain.key()


def test_the_supervisor_flags_a_state_inside_an_obstacle_and_not_its_margin():
    from aerorelay.control.supervisor import SafetyEnvelope
    from aerorelay.models.obstacles import VerticalCylinder

    pole = VerticalCylinder((0.0, 0.0), 0.5, 0.0, 10.0)  # the obstacle itself: the supervisor's has no margin
    env = SafetyEnvelope.for_vehicle(VEH, (-10, -10, 0), (10, 10, 20), obstacles=(pole,))
    assert env.violations(VEH.hover_state([0.3, 0.0, 5.0])) == ["0.20 m inside obstacle 0"]
    assert env.violations(VEH.hover_state([0.6, 0.0, 5.0])) == []
