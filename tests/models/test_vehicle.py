import casadi as ca
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from aerorelay.models.geometry import attitude_from_thrust, euler_rate_matrix, rotation_batch, rotation_zyx
from aerorelay.models.vehicle import HoverInfeasibleError, hexarotor

M, G, CXI = 2.57, 9.81, 1.18e-3


def random_state(rng, veh):
    x = np.concatenate([
        rng.normal(size=3),
        rng.uniform(-0.5, 0.5, size=3),
        rng.normal(size=3),
        rng.normal(scale=0.5, size=3),
        rng.uniform(30, 90, size=veh.n_rotors),
    ])
    return x


def test_coplanar_hover_speed_matches_hand_value():
    # m g = 6 c_xi Omega^2  =>  Omega = sqrt(m g / (6 c_xi)) = 59.67 Hz
    expected = np.sqrt(M * G / (6 * CXI))
    assert expected == pytest.approx(59.67, abs=0.01)
    np.testing.assert_allclose(hexarotor(0.0).hover_speeds(), expected, rtol=1e-9)


def test_tilted_hover_speed_accounts_for_cosine_loss():
    alpha = np.radians(20.0)
    expected = np.sqrt(M * G / (6 * CXI * np.cos(alpha)))
    np.testing.assert_allclose(hexarotor(20.0).hover_speeds(), expected, rtol=1e-9)


@pytest.mark.parametrize("tilt,rank", [(0.0, 4), (20.0, 6)])
def test_allocation_rank(tilt, rank):
    F, Mm = hexarotor(tilt).allocation()
    assert F.shape == (3, 6) and Mm.shape == (3, 6)
    assert np.linalg.matrix_rank(np.vstack([F, Mm])) == rank


def test_coplanar_allocation_by_hand():
    veh = hexarotor(0.0, arm_length=0.35)
    F, Mm = veh.allocation()
    np.testing.assert_allclose(F, np.vstack([np.zeros((2, 6)), CXI * np.ones(6)]), atol=1e-15)
    # rotor 1 (index 1) at 60 deg: p = L(cos60, sin60, 0); p x e3 = (py, -px, 0); yaw = s c_tau, s = -1
    L = 0.35
    np.testing.assert_allclose(Mm[:, 1], [CXI * L * np.sin(np.pi / 3), -CXI * L * np.cos(np.pi / 3), -2.5e-5], atol=1e-15)


def test_hover_is_an_equilibrium():
    for tilt in (0.0, 20.0):
        veh = hexarotor(tilt)
        x = veh.hover_state([1.0, -2.0, 3.0])
        np.testing.assert_allclose(veh.dynamics(x, np.zeros(6)), 0.0, atol=1e-12)


def test_free_fall_with_rotors_stopped():
    veh = hexarotor(20.0)
    x = np.zeros(veh.nx)
    x[3:6] = [0.3, -0.2, 1.0]
    xd = veh.dynamics(x, np.zeros(6))
    np.testing.assert_allclose(xd[6:9], [0, 0, -G], atol=1e-12)


def test_roll_torque_direction_by_hand():
    # Speeding up the rotor on +y (index 1 and 2 have y>0) rolls the coplanar vehicle positively.
    veh = hexarotor(0.0)
    x = veh.hover_state()
    x[12 + 1] += 5.0
    x[12 + 2] += 5.0
    x[12 + 4] -= 5.0
    x[12 + 5] -= 5.0
    wdot = veh.dynamics(x, np.zeros(6))[9:12]
    assert wdot[0] > 0 and abs(wdot[1]) < 1e-9


def test_hover_infeasible_is_reported():
    veh = hexarotor(0.0, omega_max=50.0)
    with pytest.raises(HoverInfeasibleError, match="outside the allowed range"):
        veh.hover_speeds()


def test_numpy_and_casadi_dynamics_agree():
    rng = np.random.default_rng(0)
    veh = hexarotor(20.0)
    xs, us = ca.SX.sym("x", veh.nx), ca.SX.sym("u", 6)
    f = ca.Function("f", [xs, us], [veh.dynamics(xs, us)])
    for _ in range(5):
        x, u = random_state(rng, veh), rng.normal(scale=100, size=6)
        np.testing.assert_allclose(np.array(f(x, u)).ravel(), veh.dynamics(x, u), rtol=1e-12, atol=1e-10)


def test_casadi_jacobian_matches_finite_differences():
    rng = np.random.default_rng(1)
    veh = hexarotor(20.0)
    xs, us = ca.SX.sym("x", veh.nx), ca.SX.sym("u", 6)
    jac = ca.Function("J", [xs, us], [ca.jacobian(veh.dynamics(xs, us), ca.vertcat(xs, us))])
    x, u = random_state(rng, veh), rng.normal(size=6)
    J = np.array(jac(x, u))
    z0 = np.concatenate([x, u])
    h = 1e-6
    fd = np.zeros_like(J)
    for i in range(z0.size):
        dz = np.zeros_like(z0)
        dz[i] = h
        fp = veh.dynamics((z0 + dz)[: veh.nx], (z0 + dz)[veh.nx :])
        fm = veh.dynamics((z0 - dz)[: veh.nx], (z0 - dz)[veh.nx :])
        fd[:, i] = (fp - fm) / (2 * h)
    np.testing.assert_allclose(J, fd, rtol=1e-5, atol=1e-6)


def test_rk4_matches_adaptive_integrator():
    rng = np.random.default_rng(2)
    veh = hexarotor(20.0)
    x, u = random_state(rng, veh), rng.normal(scale=50, size=6)
    dt, steps = 1e-3, 50
    xk = x.copy()
    for _ in range(steps):
        xk = veh.rk4_step(xk, u, dt)
    ref = solve_ivp(lambda t, y: veh.dynamics(y, u), (0, dt * steps), x, rtol=1e-11, atol=1e-11).y[:, -1]
    np.testing.assert_allclose(xk, ref, rtol=1e-7, atol=1e-8)


def test_rotation_is_proper_and_euler_rates_consistent():
    rng = np.random.default_rng(3)
    for _ in range(10):
        eta = rng.uniform(-1.2, 1.2, size=3)
        R = rotation_zyx(eta)
        np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
        assert np.linalg.det(R) == pytest.approx(1.0)
        np.testing.assert_allclose(rotation_batch(eta[None])[0], R, atol=1e-14)
        # R_dot = R [omega]_x with eta_dot = T(eta) omega
        w = rng.normal(size=3)
        h = 1e-6
        Rdot = (rotation_zyx(eta + h * euler_rate_matrix(eta) @ w) - rotation_zyx(eta - h * euler_rate_matrix(eta) @ w)) / (2 * h)
        wx = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
        np.testing.assert_allclose(Rdot, R @ wx, atol=1e-6)


def test_attitude_from_thrust_points_body_z():
    rng = np.random.default_rng(4)
    for _ in range(10):
        d = rng.normal(size=3)
        d[2] = abs(d[2]) + 0.5
        yaw = rng.uniform(-np.pi, np.pi)
        eta = attitude_from_thrust(d, yaw)
        np.testing.assert_allclose(rotation_zyx(eta)[:, 2], d / np.linalg.norm(d), atol=1e-12)
        assert eta[2] == pytest.approx(yaw)


def test_hover_tilt_limits_are_the_largest_holdable_tilts_and_follow_the_vehicle():
    """Toward each azimuth the limit is holdable and 0.2 deg more is not (the LP itself, not the limit's code); an
    equal vehicle gets the same (kept) limits, a heavier one its own: the kept value follows what decides it."""
    from dataclasses import replace

    az = np.radians([0.0, 30.0, 75.0])
    veh = hexarotor(20.0)
    limits = veh.hover_tilt_limits(az)
    for a, lim in zip(az, limits, strict=True):
        assert veh.can_hover_tilted(lim, a) and not veh.can_hover_tilted(lim + np.radians(0.2), a)
    assert np.array_equal(hexarotor(20.0).hover_tilt_limits(az), limits)
    heavy = replace(veh, mass=1.3 * veh.mass)
    assert not np.array_equal(heavy.hover_tilt_limits(az), limits)
    for a, lim in zip(az, heavy.hover_tilt_limits(az), strict=True):
        assert heavy.can_hover_tilted(lim, a) and not heavy.can_hover_tilted(lim + np.radians(0.2), a)


def test_the_hover_tilt_limit_is_the_best_azimuths_and_follows_the_vehicle():
    """The yaw-free limit is holdable toward some azimuth of its 72 and 0.2 deg more toward none; an equal vehicle
    gets the same, a heavier one its own (0 for a coplanar layout)."""
    from dataclasses import replace

    az = np.radians(np.arange(0.0, 360.0, 5.0))
    for veh in (hexarotor(20.0), replace(hexarotor(20.0), mass=3.3)):
        lim = veh.hover_tilt_limit
        assert any(veh.can_hover_tilted(lim, a) for a in az)
        assert not any(veh.can_hover_tilted(lim + np.radians(0.2), a) for a in az)
    assert hexarotor(20.0).hover_tilt_limit == hexarotor(20.0).hover_tilt_limit != replace(hexarotor(20.0), mass=3.3).hover_tilt_limit
    assert hexarotor(0.0).hover_tilt_limit == 0.0
