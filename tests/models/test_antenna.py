import casadi as ca
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from aerorelay.models.antenna import DipolePattern, SinPowerPattern, TabulatedPattern, dipole_gain, elevation_angle
from aerorelay.models.geometry import rotation_zyx

angles = st.floats(0.0, np.pi, allow_nan=False)


def test_dipole_limits_and_known_value():
    assert dipole_gain(np.pi / 2) == pytest.approx(1.0)
    assert dipole_gain(0.0) == 0.0 and dipole_gain(np.pi) == 0.0
    # theta = 60 deg: cos(pi/2 * 1/2)^2 / sin^2(60) = 0.5 / 0.75
    assert dipole_gain(np.pi / 3) == pytest.approx(2.0 / 3.0)
    assert dipole_gain(np.pi / 2, g_bar=1.64) == pytest.approx(1.64)


def test_dipole_is_vectorized_and_continuous_at_axis():
    th = np.array([0.0, 1e-9, 1e-4, np.pi / 2, np.pi - 1e-4, np.pi])
    g = dipole_gain(th)
    assert g.shape == th.shape
    assert np.all(g[[0, 1, -1]] < 1e-8) and g[2] < 1e-7


@given(angles)
def test_dipole_symmetric_and_bounded(th):
    g = dipole_gain(th)
    assert 0.0 <= g <= 1.0 + 1e-12
    assert g == pytest.approx(dipole_gain(np.pi - th), abs=1e-12)


@given(st.floats(1e-4, np.pi - 1e-4), st.floats(0.5, 6.0))
def test_sin_power_pattern(th, n):
    # evaluated from cos(theta): within ~1e-6 rad of the axis cos() rounds to 1 and the gain to 0,
    # so the comparison keeps 1e-4 rad away from the axis
    g = SinPowerPattern(n).gain_from_cos(np.cos(th))
    assert g == pytest.approx(np.sin(th) ** n, abs=1e-9)


def test_tabulated_pattern_interpolates():
    pat = TabulatedPattern((0.0, 90.0, 180.0), (0.0, 2.0, 0.0))
    assert pat.g_bar == 2.0
    assert pat.gain_from_cos(np.cos(np.radians(45.0))) == pytest.approx(1.0)


def test_elevation_angle_level_and_tilted():
    p_i, p_j = np.zeros(3), np.array([3.0, 0.0, 0.0])
    assert elevation_angle(p_i, np.eye(3), p_j) == pytest.approx(np.pi / 2)
    assert elevation_angle(p_i, np.eye(3), np.array([0, 0, 5.0])) == pytest.approx(0.0)
    # pitch by +30 deg tilts body z toward +x: the horizontal link is now 60 deg off the axis
    R = rotation_zyx(np.array([0.0, np.radians(30.0), 0.0]))
    assert elevation_angle(p_i, R, p_j) == pytest.approx(np.radians(60.0))


def test_elevation_angle_dual():
    p, q, eta = ca.SX.sym("p", 3), ca.SX.sym("q", 3), ca.SX.sym("e", 3)
    f = ca.Function("f", [p, eta, q], [elevation_angle(p, rotation_zyx(eta), q)])
    rng = np.random.default_rng(0)
    for _ in range(5):
        a, b, e = rng.normal(size=3), rng.normal(size=3), rng.uniform(-1, 1, 3)
        assert float(f(a, e, b)) == pytest.approx(elevation_angle(a, rotation_zyx(e), b), abs=1e-12)


def test_dipole_pattern_protocol_default():
    assert DipolePattern().g_bar == 1.0
