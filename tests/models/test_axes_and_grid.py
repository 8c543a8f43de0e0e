"""The radio scene's vectorized capacity over relay poses against the independent per-link reference (property test)."""

import casadi as ca
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from aerorelay.models.antenna import DipolePattern, IsotropicPattern
from aerorelay.models.axes import axis_cone, tilted_axes
from aerorelay.models.geometry import rotation_zyx
from aerorelay.models.jammer import Jammer
from aerorelay.models.radio import Antenna, LinkBudget, Node, NodePose, RadioScene
from tests.reference_channel import end_to_end_capacity, link_sinr

coord = st.floats(-8.0, 8.0)
angle = st.floats(-0.6, 0.6)


@settings(max_examples=60, deadline=None)
@given(p1=st.tuples(coord, coord, st.floats(0.5, 18.0)), p2=st.tuples(coord, coord, st.floats(0.5, 18.0)),
       eta1=st.tuples(angle, angle, st.floats(-3.0, 3.0)), eta2=st.tuples(angle, angle, st.floats(-3.0, 3.0)),
       jam=st.floats(0.0, 3.0), d=st.floats(0.5, 2.0), iso_bs=st.booleans(), iso_src=st.booleans())
def test_relay_capacity_equals_the_link_by_link_channel(p1, p2, eta1, eta2, jam, d, iso_bs, iso_src):
    p1, p2 = np.array(p1), np.array(p2)
    pj, p0 = np.array([-6.95, -5.79, 1.72]), np.zeros(3)
    if min(np.linalg.norm(p1 - p2), np.linalg.norm(p1 - pj), np.linalg.norm(p1 - p0)) < 0.1:
        return
    R1, R2 = rotation_zyx(np.array(eta1)), rotation_zyx(np.array(eta2))
    relay = DipolePattern(d)
    src, bs = (IsotropicPattern(1.0) if iso_src else relay), (IsotropicPattern(1.0) if iso_bs else relay)
    kw = dict(tx_power=1.0, jam_power=jam, noise_power=1.0)
    g21 = link_sinr(p2, R2, p1, R1, pj, pattern=src, pattern_rx=relay, **kw)
    g10 = link_sinr(p1, R1, p0, np.eye(3), pj, pattern=relay, pattern_rx=bs, **kw)
    scene = RadioScene((Node("bs", "base_station", Antenna(bs), p0), Node("source", "source", Antenna(src)),
                        Node("relay", "relay", Antenna(relay))), (Jammer(pj, jam),), LinkBudget(1.0, 1.0))
    C = scene.relay_grid(0.0, p1[None], R1[:, 2][None], {"source": NodePose(p2, R2[:, 2])})
    assert np.isclose(C[0, 0], end_to_end_capacity(g21, g10), rtol=1e-9, atol=1e-15)


@settings(max_examples=30, deadline=None)
@given(limit=st.floats(0.0, 0.6), step=st.floats(0.03, 0.2))
def test_axis_cone_stays_inside_its_limit(limit, step):
    axes = axis_cone(limit, step)
    assert np.allclose(np.linalg.norm(axes, axis=1), 1.0)
    # the tilt by atan2(|xy|, z): arccos near 1 loses half the digits (cos(1.3e-8) rounds to 1 - 1.1e-16 -> 1.5e-8)
    assert np.all(np.arctan2(np.linalg.norm(axes[:, :2], axis=1), axes[:, 2]) <= limit + 1e-9)
    assert np.allclose(axes[0], [0, 0, 1])


@settings(max_examples=40, deadline=None)
@given(base=st.floats(0.0, 0.4), ripple=st.floats(0.0, 0.15), phase=st.floats(0.0, 6.3), step=st.floats(0.04, 0.2),
       boundary=st.booleans())
def test_axis_set_stays_inside_an_azimuth_dependent_limit_and_its_boundary_reaches_it(base, ripple, phase, step, boundary):
    """Every axis tilts no more than the limit toward its azimuth; with ``boundary`` every azimuth
    sampled along the limit has an axis within a quarter of a ring step of it (the rings alone
    miss it by up to a whole step: 0.83 of a 5 deg step in one case)."""
    from aerorelay.models.axes import axis_set

    az = np.radians(np.arange(0.0, 360.0, 10.0))
    limits = np.maximum(base + ripple * np.cos(3 * az + phase), 0.0)
    axes = axis_set(az, limits, step, boundary=boundary)
    assert np.allclose(np.linalg.norm(axes, axis=1), 1.0) and np.allclose(axes[0], [0, 0, 1])
    tilt = np.arccos(np.clip(axes[:, 2], -1, 1))
    a = np.arctan2(axes[:, 1], axes[:, 0]) % (2 * np.pi)
    lim = np.interp(a, az, limits, period=2 * np.pi)
    assert np.all(tilt <= lim + 1e-9)
    if boundary and limits.max() > 0:
        # the contract as documented: along the limit, about ``step`` apart, an axis at the limit itself
        # wherever the limit lies beyond its last ring by more than a tenth of a step. (Where it lies
        # within that tenth the ring is trusted, though an inner ring holds as few as 6-7 azimuths: a
        # known gap, fixing it changes the capacity planner's axes and so its numbers; docs/decisions.md.)
        n = max(6, int(np.ceil(2 * np.pi * np.sin(limits.max()) / step)))
        grid = 2 * np.pi * np.arange(n) / n
        want = np.interp(grid, az, limits, period=2 * np.pi)
        beyond = want - np.floor(want / step + 1e-9) * step > 0.1 * step
        for t_az, w in zip(grid[beyond & (want > 0)], want[beyond & (want > 0)], strict=True):
            hit = np.abs((a - t_az + np.pi) % (2 * np.pi) - np.pi) < 1e-9
            assert np.any(np.abs(tilt[hit] - w) < 1e-9), (t_az, w)


@given(st.floats(0.0, np.pi), st.floats(-2 * np.pi, 2 * np.pi))
def test_tilted_axes_is_one_definition_numerically_and_symbolically(tilt, azimuth):
    """The CasADi expression (the flyable path's NLP) evaluates to the numpy axis, a unit vector
    ``tilt`` from vertical whose horizontal part points toward ``azimuth``."""
    t, a = ca.SX.sym("t"), ca.SX.sym("a")
    f = ca.Function("axis", [t, a], [tilted_axes(t, a)])
    sym = np.asarray(f(tilt, azimuth)).ravel()
    num = tilted_axes(tilt, azimuth)
    np.testing.assert_allclose(sym, num, atol=1e-14)
    assert np.linalg.norm(num) == pytest.approx(1.0)
    assert np.arccos(np.clip(num[2], -1, 1)) == pytest.approx(tilt, abs=1e-7)
    if np.sin(tilt) > 1e-6:
        assert np.arctan2(num[1], num[0]) == pytest.approx(np.arctan2(np.sin(azimuth), np.cos(azimuth)), abs=1e-7)
