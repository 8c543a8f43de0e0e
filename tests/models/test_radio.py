"""The radio scene: the one channel against the independent reference, several / moving / directional jammers."""

import casadi as ca
import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from aerorelay.assembly import parse_scenario
from aerorelay.assembly.parts import build_scene
from aerorelay.config import ScenarioError
from aerorelay.models.antenna import CosinePattern, DipolePattern, IsotropicPattern
from aerorelay.models.geometry import rotation_zyx
from aerorelay.models.jammer import Jammer
from aerorelay.models.mission import LinearPath
from aerorelay.models.radio import Antenna, LinkBudget, Node, NodePose, RadioScene, link_gain, route_capacity
from tests.reference_channel import end_to_end_capacity, link_sinr

P0, P1, P2, PJ = np.zeros(3), np.array([-6.95, 5.79, 1.72]), np.array([-3.04, 5.79, 1.72]), np.array([-6.95, -5.79, 1.72])
coords = st.floats(-15.0, 15.0, allow_nan=False)
points = st.tuples(coords, coords, coords).map(np.array)
euler = st.tuples(*[st.floats(-1.2, 1.2)] * 3).map(np.array)


def scene(jammers=(), relay=DipolePattern(), bs=DipolePattern(), source=DipolePattern()):
    return RadioScene((Node("bs", "base_station", Antenna(bs), P0), Node("source", "source", Antenna(source)),
                       Node("relay", "relay", Antenna(relay))), tuple(jammers), LinkBudget(1.0, 1.0))


def poses(sc, p1, R1, p2, R2):
    return {"relay": sc.pose("relay", p1, R1), "source": sc.pose("source", p2, R2)}


def test_spec_sanity_values_at_the_initial_geometry():
    s = scene([Jammer(PJ, 1.0)])
    st_ = s.evaluate(0.0, poses(s, P1, np.eye(3), P2, np.eye(3)))
    assert float(st_.sinr[0]) == pytest.approx(0.0649, abs=5e-4) and float(st_.sinr[1]) == pytest.approx(0.0105, abs=5e-4)
    assert float(st_.capacity) == pytest.approx(0.0129, abs=5e-4)


@settings(max_examples=60, deadline=None)
@given(points, points, euler, euler, st.floats(0.0, 50.0))
def test_scene_equals_the_independent_reference(p1, p2, e1, e2, pj_power):
    assume(min(np.linalg.norm(p1 - p2), np.linalg.norm(p1 - PJ), np.linalg.norm(p1 - P0), np.linalg.norm(p2 - P0)) > 0.2)
    R1, R2 = rotation_zyx(e1), rotation_zyx(e2)
    s = scene([Jammer(PJ, pj_power)])
    state = s.evaluate(0.0, poses(s, p1, R1, p2, R2))
    kw = dict(tx_power=1.0, jam_power=pj_power, noise_power=1.0)
    g21, g10 = link_sinr(p2, R2, p1, R1, PJ, **kw), link_sinr(p1, R1, P0, np.eye(3), PJ, **kw)
    # abs: at a dipole's null the gain (1 - cos^2, of order 1) keeps an absolute rounding error of ~1e-16, so an SINR
    # of ~1e-19 there agrees only to ~1e-8 relative (hypothesis found 3.5081617e-19 against 3.5081619e-19)
    assert float(state.sinr[0]) == pytest.approx(g21, rel=1e-9, abs=1e-15)
    assert float(state.sinr[1]) == pytest.approx(g10, rel=1e-9, abs=1e-15)
    assert float(state.capacity) == pytest.approx(float(end_to_end_capacity(g21, g10)), rel=1e-9, abs=1e-15)


@settings(max_examples=40, deadline=None)
@given(points, euler, st.floats(0.1, 100.0), points)
def test_two_colocated_half_power_jammers_are_one_jammer(p1, e1, power, pj):
    assume(min(np.linalg.norm(p1 - pj), np.linalg.norm(p1 - P2), np.linalg.norm(p1 - P0), np.linalg.norm(pj - P0)) > 0.2)
    one, two = scene([Jammer(pj, power)]), scene([Jammer(pj, power / 2), Jammer(pj, power / 2, name="b")])
    a = one.evaluate(0.0, poses(one, p1, rotation_zyx(e1), P2, np.eye(3)))
    b = two.evaluate(0.0, poses(two, p1, rotation_zyx(e1), P2, np.eye(3)))
    for x, y in zip(a.sinr + (a.capacity,), b.sinr + (b.capacity,), strict=True):
        assert float(y) == pytest.approx(float(x), rel=1e-12)


@settings(max_examples=40, deadline=None)
@given(st.floats(-1.0, 1.0))
def test_cosine_pattern_limits(c):
    assert float(CosinePattern(1.0, 0.0, 1.0).gain_from_cos(c)) == 1.0  # g = 1, n = 0, back lobe 1: isotropic
    g = CosinePattern(10.0, 4.0, 0.01)
    assert float(g.gain_from_cos(c)) == pytest.approx(10.0 * max(max(c, 0.0) ** 4, 0.01))
    assert float(g.gain_from_cos(1.0)) == 10.0 and float(g.gain_from_cos(-1.0)) == pytest.approx(0.1)


def test_isotropic_cosine_jammer_equals_the_isotropic_one():
    iso = scene([Jammer(PJ, 5.0)])
    cos = scene([Jammer(PJ, 5.0, pattern=CosinePattern(1.0, 0.0, 1.0), point_at="bs")])
    R1 = rotation_zyx(np.array([0.2, -0.1, 0.5]))
    a, b = (s.evaluate(0.0, poses(s, P1, R1, P2, np.eye(3))) for s in (iso, cos))
    assert float(a.capacity) == float(b.capacity) and all(float(x) == float(y) for x, y in zip(a.sinr, b.sinr, strict=True))


def test_directional_jammer_hits_what_it_points_at():
    """A narrow beam at the BS: the BS sees g_max / d^2 P_J, the relay (off boresight) only the back lobe."""
    pat = CosinePattern(10.0, 20.0, 0.01)
    s = scene([Jammer(PJ, 2.0, pattern=pat, point_at="bs")], bs=IsotropicPattern(1.0), relay=IsotropicPattern(1.0))
    st_ = s.evaluate(0.0, poses(s, P1, np.eye(3), P2, np.eye(3)))
    assert float(st_.interference[1]) == pytest.approx(10.0 * 2.0 / float(PJ @ PJ), rel=1e-12)
    d = P1 - PJ
    c = float(d @ (-PJ / np.linalg.norm(PJ))) / np.linalg.norm(d)
    assert float(st_.interference[0]) == pytest.approx(float(pat.gain_from_cos(c)) * 2.0 / float(d @ d), rel=1e-12)
    tracking = scene([Jammer(PJ, 2.0, pattern=pat, point_at="relay")], relay=IsotropicPattern(1.0))
    t_ = tracking.evaluate(0.0, poses(tracking, P1, np.eye(3), P2, np.eye(3)))
    assert float(t_.interference[0]) == pytest.approx(10.0 * 2.0 / float(d @ d), rel=1e-12)


def test_moving_jammer_follows_its_waypoints():
    path = LinearPath([[0.0, -7.0, -3.0, 1.5], [10.0, 7.0, -3.0, 1.5]])
    j = Jammer(np.array([-7.0, -3.0, 1.5]), 1.0, path=path)
    np.testing.assert_allclose(j.position_at(5.0), [0.0, -3.0, 1.5])
    np.testing.assert_allclose(j.position_at(20.0), [7.0, -3.0, 1.5])
    s = scene([j], relay=IsotropicPattern(1.0))
    a, b = (float(s.evaluate(t, poses(s, P1, np.eye(3), P2, np.eye(3))).interference[0]) for t in (0.0, 5.0))
    assert a == pytest.approx(1.0 / float((P1 - [-7.0, -3.0, 1.5]) @ (P1 - [-7.0, -3.0, 1.5])), rel=1e-12)
    assert b == pytest.approx(1.0 / float((P1 - [0.0, -3.0, 1.5]) @ (P1 - [0.0, -3.0, 1.5])), rel=1e-12)


@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(0.0, 1e3), min_size=1, max_size=5), st.floats(0.1, 5.0))
def test_route_capacity_is_equal_time_shares(gammas, bw):
    se = [np.log2(1 + g) for g in gammas]
    expected = 0.0 if min(se) == 0 else bw / sum(1 / s for s in se)
    assert float(route_capacity(gammas, bw)) == pytest.approx(expected, rel=1e-12, abs=1e-300)
    if len(gammas) == 2:  # eq. 9 operation for operation
        a, b = np.log2(1 + np.array(gammas))
        assert float(route_capacity(gammas, bw)) == (bw * (a * b / (a + b)) if a + b > 0 else 0.0)


def test_grid_evaluation_equals_pose_by_pose():
    s = scene([Jammer(PJ, 3.0, pattern=CosinePattern(5.0, 2.0, 0.05), point_at="relay")])
    rng = np.random.default_rng(2)
    P = rng.uniform([-7, -6, 0.5], [7, 6, 19], (20, 3))
    B = rng.normal(size=(7, 3))
    B /= np.linalg.norm(B, axis=1, keepdims=True)
    src = NodePose(P2, np.array([0.0, 0.0, 1.0]))
    grid = s.relay_grid(1.0, P, B, {"source": src})
    for i in range(0, 20, 3):
        for k in range(7):
            one = s.evaluate(1.0, {"source": src, "relay": NodePose(P[i], B[k])}).capacity
            assert grid[i, k] == pytest.approx(float(one), rel=1e-12)


def test_symbolic_link_gain_matches_numeric():
    p, b = ca.SX.sym("p", 3), ca.SX.sym("b", 3)
    f = ca.Function("g", [p, b], [link_gain(P2, np.array([0.0, 0.0, 1.0]), DipolePattern(), p, b, DipolePattern())])
    b1 = np.array([0.1, 0.2, 0.97])
    b1 /= np.linalg.norm(b1)
    num = link_gain(P2, np.array([0.0, 0.0, 1.0]), DipolePattern(), P1, b1, DipolePattern())
    assert float(f(P1, b1)) == pytest.approx(float(num), rel=1e-5)  # the symbolic dipole is regularized by 1e-6


def test_scenario_jammer_tables():
    two = parse_scenario({"jammers": [{"position": [1.0, 1.0, 1.0]}, {"position": [2.0, 2.0, 1.0], "power_w": 3.0}]})
    s = build_scene(two)
    assert [j.name for j in s.jammers] == ["jammer1", "jammer2"] and s.jammers[1].power == 3.0
    assert len(build_scene(parse_scenario({})).jammers) == 1
    assert build_scene(parse_scenario({"jammers": []})).jammers == ()
    with pytest.raises(ScenarioError, match="either \\[jammer\\]"):
        parse_scenario({"jammer": {}, "jammers": [{}]})
    with pytest.raises(ScenarioError, match="jammer: Value error, a cosine jammer|a cosine jammer needs"):
        parse_scenario({"jammer": {"pattern": "cosine"}})
    with pytest.raises(ScenarioError, match=r"jammers\[0\]\.point_at: 'moon' is not a node \(bs, relay, source\)"):
        parse_scenario({"jammers": [{"pattern": "cosine", "point_at": "moon"}]})
    with pytest.raises(ScenarioError, match="jammer.back_lobe: must be in \\[0, 1\\]"):
        parse_scenario({"jammer": {"back_lobe": 2.0}})
    with pytest.raises(ScenarioError, match="strictly increasing"):
        parse_scenario({"jammer": {"waypoints": [[0, 1, 1, 1], [0, 2, 2, 2]]}})
    moving = parse_scenario({"jammer": {"waypoints": [[0, 1, 1, 1], [10, 2, 2, 2]]}})
    assert moving.jammer.position == [1, 1, 1]
    assert parse_scenario({}).with_updates({"jammers": [{"power_w": 2.0}], "jammer": None}).jammer_configs[0].power_w == 2.0
