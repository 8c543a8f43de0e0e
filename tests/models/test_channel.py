import casadi as ca
import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from aerorelay.assembly.parts import node_patterns, relay_pattern
from aerorelay.models.channel import (
    end_to_end_capacity,
    inverse_capacity,
    misalignment,
    mutual_alignment,
    reachable_mutual_alignment,
    spectral_efficiency,
    surrogate_sinr,
)
from aerorelay.models.geometry import rotation_zyx
from tests.reference_channel import jammer_gain_sq, legitimate_gain_sq, link_sinr

I3 = np.eye(3)
P0 = np.zeros(3)
P1 = np.array([-6.95, 5.79, 1.72])
P2 = np.array([-3.04, 5.79, 1.72])
PJ = np.array([-6.95, -5.79, 1.72])
KW = dict(tx_power=1.0, jam_power=1.0, noise_power=1.0)

gammas = st.floats(0.0, 1e3, allow_nan=False)
coords = st.floats(-20.0, 20.0, allow_nan=False)
points = st.tuples(coords, coords, coords).map(np.array)
euler = st.tuples(*[st.floats(-1.2, 1.2)] * 3).map(np.array)


def test_spec_sanity_geometry():
    g21 = link_sinr(P2, I3, P1, I3, PJ, **KW)
    g10 = link_sinr(P1, I3, P0, I3, PJ, **KW)
    assert g21 == pytest.approx(0.0649, abs=5e-5)
    assert g10 == pytest.approx(0.0105, abs=5e-5)
    assert end_to_end_capacity(g21, g10) == pytest.approx(0.0129, abs=5e-5)


def test_sanity_link_21_by_hand():
    # horizontal link and horizontal jammer path: all gains 1 -> Gamma = (1/d^2) / (1/dJ^2 + 1)
    d2, dj2 = 3.91**2, 11.58**2
    assert link_sinr(P2, I3, P1, I3, PJ, **KW) == pytest.approx((1 / d2) / (1 / dj2 + 1), rel=1e-9)


def test_no_jammer_means_snr():
    snr = link_sinr(P2, I3, P1, I3, PJ, tx_power=1.0, jam_power=0.0, noise_power=1.0)
    assert snr == pytest.approx(1 / 3.91**2)


def test_batched_sinr_matches_loop():
    rng = np.random.default_rng(0)
    p1 = rng.normal(size=(7, 3)) * 5
    R = np.stack([rotation_zyx(e) for e in rng.uniform(-0.5, 0.5, (7, 3))])
    batch = link_sinr(p1, R, P0, I3, PJ, **KW)
    loop = [link_sinr(p1[k], R[k], P0, I3, PJ, **KW) for k in range(7)]
    np.testing.assert_allclose(batch, loop, rtol=1e-12)


@given(gammas, gammas)
def test_capacity_bounds_and_symmetry(g1, g2):
    a, b = np.log2(1 + g1), np.log2(1 + g2)
    c = end_to_end_capacity(g1, g2)
    assert c <= min(a, b) + 1e-12
    assert c >= 0.5 * min(a, b) - 1e-12
    assert c == pytest.approx(end_to_end_capacity(g2, g1), rel=1e-12, abs=1e-15)


@given(gammas, gammas, st.floats(1e-3, 10.0))
def test_capacity_monotone(g1, g2, dg):
    assert end_to_end_capacity(g1 + dg, g2) >= end_to_end_capacity(g1, g2) - 1e-15


def test_capacity_dead_link_is_zero_and_bandwidth_scales():
    assert end_to_end_capacity(0.0, 5.0) == 0.0
    assert end_to_end_capacity(1.0, 3.0, bandwidth=2.0) == pytest.approx(2 * 1 * 2 / 3)


@given(points, points, euler, euler)
def test_gains_bounded_by_g_bar(p, q, e1, e2):
    assume(np.linalg.norm(p - q) > 0.1)
    d2 = np.sum((p - q) ** 2)
    h2 = legitimate_gain_sq(p, rotation_zyx(e1), q, rotation_zyx(e2))
    assert 0.0 <= h2 * d2 <= 1.0 + 1e-12
    f2 = jammer_gain_sq(p, q, rotation_zyx(e2))
    assert 0.0 <= f2 * d2 <= 1.0 + 1e-12


@settings(max_examples=50)
@given(points, points, points, st.floats(-np.pi, np.pi))
def test_sinr_invariant_to_rotation_about_vertical(p_tx, p_rx, p_j, yaw):
    assume(min(np.linalg.norm(p_tx - p_rx), np.linalg.norm(p_j - p_rx)) > 0.1)
    Rz = rotation_zyx(np.array([0.0, 0.0, yaw]))
    g = link_sinr(p_tx, I3, p_rx, I3, p_j, **KW)
    g_rot = link_sinr(Rz @ p_tx, I3, Rz @ p_rx, I3, Rz @ p_j, **KW)
    assert g_rot == pytest.approx(g, rel=1e-9, abs=1e-15)


@settings(max_examples=50)
@given(points, points, euler)
def test_misalignment_range_and_surrogate_jammer_conservative(p, q, e):
    assume(np.linalg.norm(p - q) > 0.1)
    R = rotation_zyx(e)
    v = misalignment(p, R, q)
    assert 0.0 <= v <= 1.0 + 1e-12
    # the surrogate jammer gain sqrt(G_bar)/d upper-bounds the real one (eq. 12)
    assert jammer_gain_sq(p, q, R) <= 1.0 / np.sum((p - q) ** 2) + 1e-15


def test_misalignment_cases():
    assert misalignment(P0, I3, np.array([1.0, 0, 0])) == pytest.approx(0.0)
    assert misalignment(P0, I3, np.array([0, 0, 2.0])) == pytest.approx(1.0)
    assert mutual_alignment(0.5, 0.5) == pytest.approx(0.25)


def test_surrogate_by_hand_and_dual():
    mu = 0.2
    g = surrogate_sinr(P2, P1, [PJ], [1.0], mu=mu, g_bar=1.0, tx_power=1.0, noise_power=1.0)
    d2 = np.sum((P1 - P2) ** 2)
    dj2 = np.sum((PJ - P1) ** 2)
    assert g == pytest.approx((mu / d2) / (1 / dj2 + 1))
    a, b = ca.SX.sym("a", 3), ca.SX.sym("b", 3)
    f = ca.Function("f", [a, b], [inverse_capacity(a, b, P0, [PJ], [1.0], mu=mu, g_bar=1.0, tx_power=1.0, noise_power=1.0)])
    num = inverse_capacity(P1, P2, P0, [PJ], [1.0], mu=mu, g_bar=1.0, tx_power=1.0, noise_power=1.0)
    assert float(f(P1, P2)) == pytest.approx(num, rel=1e-12)
    s21 = spectral_efficiency(surrogate_sinr(P2, P1, [PJ], [1.0], mu=mu, g_bar=1.0, tx_power=1.0, noise_power=1.0))
    s10 = spectral_efficiency(surrogate_sinr(P1, P0, [PJ], [1.0], mu=mu, g_bar=1.0, tx_power=1.0, noise_power=1.0))
    assert num == pytest.approx(1 / s21 + 1 / s10)


def test_node_patterns_from_the_antenna_options():
    from aerorelay.assembly import parse_scenario
    from aerorelay.models.antenna import IsotropicPattern

    pat = node_patterns(parse_scenario({"antenna": {"bs_pattern": "isotropic", "directivity": 1.64}}).antenna)
    assert isinstance(pat.bs, IsotropicPattern) and pat.bs.gain_from_cos(np.array([1.0, 0.0])).tolist() == [1.0, 1.0]
    assert pat.relay.gain_from_cos(0.0) == pytest.approx(1.64) and pat.source is pat.relay
    assert pat.relay.gain_from_cos(1.0) == 0.0  # still a null on the axis


def test_directivity_scales_a_dipole_to_dipole_snr_by_its_square():
    from aerorelay.assembly import parse_scenario
    from aerorelay.models.geometry import rotation_zyx

    rng = np.random.default_rng(5)
    kw = dict(tx_power=1.0, jam_power=0.0, noise_power=1.0)
    for _ in range(10):
        p, q = rng.uniform(-5, 5, 3), rng.uniform(-5, 5, 3)
        Ra, Rb = rotation_zyx(rng.uniform(-0.5, 0.5, 3)), rotation_zyx(rng.uniform(-0.5, 0.5, 3))
        g = [link_sinr(p, Ra, q, Rb, PJ, pattern=relay_pattern(parse_scenario({"antenna": {"directivity": d}}).antenna), **kw)
             for d in (1.0, 1.64)]
        assert g[1] == pytest.approx(1.64**2 * g[0], rel=1e-12)


def test_isotropic_receiver_ignores_its_attitude():
    from aerorelay.models.antenna import IsotropicPattern
    from aerorelay.models.geometry import rotation_zyx

    iso = IsotropicPattern(1.0)
    a = link_sinr(P2, I3, P1, I3, PJ, pattern_rx=iso, **KW)
    b = link_sinr(P2, I3, P1, rotation_zyx(np.array([0.4, -0.3, 1.0])), PJ, pattern_rx=iso, **KW)
    assert a == pytest.approx(b, rel=1e-12)


def test_reachable_alignment_hand_values():
    """Relay at the origin, vertical axis: BS level with it (v_10 = 0); MRAV-2 straight above (v_12 = 1,
    alignment 0) or at 45 deg elevation (v_12 = 1/2, alignment 1/2); a horizontal axis along y is
    broadside to both links in the x-z plane (alignment 1)."""
    up, side = np.array([[0.0, 0.0, 1.0]]), np.array([[0.0, 1.0, 0.0]])
    path = np.array([[0.0, 0.0, 3.0], [2.0, 0.0, 2.0]])
    np.testing.assert_allclose(reachable_mutual_alignment([[0.0, 0.0, 0.0]], up, [5.0, 0.0, 0.0], path), [0.0, 0.5],
                               atol=1e-12)
    np.testing.assert_allclose(reachable_mutual_alignment([[0.0, 0.0, 0.0]], side, [5.0, 0.0, 0.0], path), [1.0, 1.0])
    both = np.vstack([up, side])  # the max over axes and positions
    pos = [[0.0, 0.0, 0.0], [0.0, 0.0, 10.0]]
    np.testing.assert_allclose(reachable_mutual_alignment(pos, both, [5.0, 0.0, 0.0], path), [1.0, 1.0])


@given(points, points, points)
def test_reachable_alignment_is_the_eq_11_alignment_maximized(p1, p0, p2):
    """Between 0 and 1; equal to eq. 11 at one axis; 1 with the axis normal to both links."""
    assume(min(np.linalg.norm(p0 - p1), np.linalg.norm(p2 - p1)) > 0.1)
    axis = np.array([[0.3, -0.2, 0.9]]) / np.linalg.norm([0.3, -0.2, 0.9])
    got = reachable_mutual_alignment([p1], axis, p0, [p2])[0]
    R = np.eye(3)  # eq. 10 through the body z axis: rotate e3 onto the axis
    z = axis[0]
    R[:, 2] = z
    R[:, 0] = np.cross([0.0, 1.0, 0.0], z) / np.linalg.norm(np.cross([0.0, 1.0, 0.0], z))
    R[:, 1] = np.cross(z, R[:, 0])
    want = float(mutual_alignment(misalignment(p1, R, p2), misalignment(p1, R, p0)))
    assert 0.0 <= got <= 1.0 + 1e-12 and got == pytest.approx(want, abs=1e-9)
    n = np.cross(p0 - p1, p2 - p1)
    assume(np.linalg.norm(n) > 1e-3 * np.linalg.norm(p0 - p1) * np.linalg.norm(p2 - p1))
    assert reachable_mutual_alignment([p1], [n / np.linalg.norm(n)], p0, [p2])[0] == pytest.approx(1.0, abs=1e-9)
