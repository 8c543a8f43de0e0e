"""Yawing a tilted platform under the antenna axis it wants (``planning.platform_yaw``)."""

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from aerorelay.assembly import load_scenario
from aerorelay.assembly.parts import build
from aerorelay.assembly.vehicle import build_vehicle
from aerorelay.models.axes import axis_set
from aerorelay.planning.platform_yaw import PlatformYaw, rotate_z

AZ = np.radians(np.arange(0.0, 360.0, 10.0))
# a limit with peaks 120 deg apart, like the nominal tilted hexarotor's (9.6-17.8 deg)
LIMITS = np.radians(10.0 + 8.0 * np.maximum(np.cos(3 * (AZ - np.pi / 2)), 0.0) ** 4)
BODY = axis_set(AZ, LIMITS, np.radians(5.0))


def _tilt_and_limit(axis, psi):
    b = rotate_z(axis, -psi)
    az = np.arctan2(b[1], b[0]) % (2 * np.pi)
    return np.arccos(np.clip(b[2], -1, 1)), np.interp(az, AZ, LIMITS, period=2 * np.pi)


@given(st.floats(-np.pi, np.pi), st.floats(-np.pi, np.pi))
def test_rotate_z_turns_about_the_vertical_and_back(a, b):
    v = np.array([[0.3, -0.4, 0.866], [1.0, 0.0, 0.0]])
    r = rotate_z(v, a)
    np.testing.assert_allclose(np.linalg.norm(r, axis=1), np.linalg.norm(v, axis=1))
    np.testing.assert_allclose(r[:, 2], v[:, 2])
    np.testing.assert_allclose(rotate_z(rotate_z(v, a), b), rotate_z(v, a + b), atol=1e-12)
    np.testing.assert_allclose(rotate_z(r, -a), v, atol=1e-12)


@given(st.floats(0.0, np.radians(40.0)), st.floats(0.0, 2 * np.pi), st.floats(-np.pi / 3, np.pi / 3))
def test_clip_returns_an_axis_the_platform_holds_at_the_measured_yaw(tilt, azimuth, psi):
    yaw = PlatformYaw(BODY, AZ, LIMITS, rate=np.radians(10.0))
    axis = np.array([np.sin(tilt) * np.cos(azimuth), np.sin(tilt) * np.sin(azimuth), np.cos(tilt)])
    out = yaw.clip(axis, psi)
    t_out, limit = _tilt_and_limit(out, psi)
    assert abs(np.linalg.norm(out) - 1.0) < 1e-12
    assert t_out <= limit + 1e-9
    if _tilt_and_limit(axis, psi)[0] <= limit:
        np.testing.assert_allclose(out, axis)  # a holdable axis is left as it is
    else:  # only the tilt is reduced: the azimuth stays
        assert abs(np.arctan2(out[1], out[0]) - np.arctan2(axis[1], axis[0])) < 1e-9


def test_goal_moves_only_for_a_gain_and_the_reference_follows_at_its_rate():
    yaw = PlatformYaw(BODY, AZ, LIMITS, rate=np.radians(10.0))
    n = len(BODY)
    assert len(yaw.all_axes()) == n * len(yaw.yaws) and np.isclose(yaw.yaws.max(), np.radians(60.0))
    c = np.ones(n * len(yaw.yaws))
    c[3 * n + 2] = 1.004  # +0.4%: below the 0.5% it takes
    assert yaw.choose(c, 1.0) is None and yaw.goal == 0.0
    c[5 * n + 1] = 1.02
    assert yaw.choose(c, 1.0) == 5 * n + 1 and np.isclose(yaw.goal, yaw.yaws[5])
    refs = [yaw.advance(0.1) for _ in range(100)]
    assert np.max(np.abs(np.diff([0.0, *refs]))) <= np.radians(10.0) * 0.1 + 1e-12
    assert np.isclose(refs[-1], yaw.goal)


def test_yawing_relay_stays_on_its_reference_and_inside_its_limits():
    """Nominal tilted, capacity planner allowed to yaw at 10 deg/s (first 12 s, where it turns by
    ~60 deg): clipping the axis at the measured yaw keeps it on its position reference (without
    the clip, at the reference's yaw, it swung 2-6 m off)."""
    sc = load_scenario("scenarios/nominal_tilted.toml").with_updates(
        {"controller.planner": "capacity", "sim.duration_s": 12.0, "controller.capacity.yaw_rate_deg_s": 10.0})
    res = build(sc).closed_loop().run()
    log = res.log
    assert np.ptp(log["relay.psi"]) > np.radians(30.0)  # it does turn
    err = np.hypot(np.hypot(log["relay.p_x"] - log["relay.pd_x"], log["relay.p_y"] - log["relay.pd_y"]), log["relay.p_z"] - log["relay.pd_z"])
    assert err.max() < 1.0
    assert res.qp_failures == 0 and not log["relay.fallback"].any() and not log["relay.safety_violation"].any()
    veh = build_vehicle(sc.platform)
    speeds = np.column_stack([log[f"relay.Omega_{i}"] for i in range(1, 7)])
    assert speeds.min() >= veh.omega_min - 1e-3 and speeds.max() <= veh.omega_max + 1e-3


def test_a_fleet_yaws_its_relays_when_told_and_stays_on_its_references():
    """The network study's two relays at 120 m (tilted hexarotors, the jammer to the south-east), the fleet's capacity
    planner allowed to yaw at 30 deg/s for 8 s: a relay turns (its tilt toward the jammer's null is held only at some
    yaws), on its position reference, without a fallback or a safety violation; told 0 deg/s, no relay turns by more
    than the NMPC's own drift (the setting is honoured, not ignored, for a fleet). Measured 2026-12-06: 29.7 deg
    turned at 30 deg/s, 6.2 deg at 0. "On its reference" is within 1.25 m: since the route's three first guesses
    (2026-12-07) r1's reference at 0 deg/s stops at (9.0, 2.7, 9.1) m from t = 4.3 to 6.0 s right after braking
    with its antenna at 14.7 deg (0.85 of its hover limit there), and r1 sinks 1.1 m before it holds (1.19 m at
    most, every QP solved; 0.40 m at 30 deg/s): a known weakness of the NMPC at a lean near the limit
    (docs/results/networks.md), not of the yaw."""
    relays = [{"name": "r1", "start": [8.0, 2.0, 6.0]}, {"name": "r2", "start": [4.0, -2.0, 6.0]}]
    turned = {}
    for rate in (0.0, 30.0):
        sc = load_scenario("scenarios/long_inspection.toml", set={
            "controller.planner": "capacity", "relays": relays, "controller.workspace.max": [124.0, 12.0, 20.0],
            "sim.duration_s": 8.0, "controller.capacity.yaw_rate_deg_s": rate,
            "sources": [{"name": "inspector", "mission": {"waypoints": [[0.0, 6.0, 3.0, 10.0], [38.0, 120.0, 3.0, 12.0]]}}]})
        log = build(sc).closed_loop().run().log
        turned[rate] = max(float(np.ptp(log[f"{r}.psi"])) for r in ("r1", "r2"))
        for r in ("r1", "r2"):
            err = np.sqrt(sum((log[f"{r}.p_{a}"] - log[f"{r}.pd_{a}"]) ** 2 for a in "xyz"))
            assert err.max() < 1.25, (rate, r, float(err.max()))
            assert not log[f"{r}.fallback"].any() and not log[f"{r}.safety_violation"].any()
    assert turned[30.0] > np.radians(20.0) and turned[0.0] < np.radians(15.0), turned
