"""What a scenario file can say: a sector (cosine) base-station antenna pointed by tilt and
azimuth, a jammer path that repeats, and the jammers' true positions in the log."""

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import aerorelay as ar
from aerorelay.assembly import load_scenario
from aerorelay.config import ScenarioError

ROOT = Path(__file__).resolve().parent.parent
NOMINAL = ROOT / "scenarios" / "nominal_tilted.toml"


def _bs_gain_toward(sc, direction):
    """The base station's antenna gain toward a relay 5 m away along ``direction``, as the scene's
    SINR sees it against an isotropic base station of gain 1 (no jammer, same geometry)."""
    pos = np.array(sc.nodes.bs, float) + 5.0 * np.asarray(direction, float) / np.linalg.norm(direction)
    ref = sc.with_updates({"antenna.bs_pattern": "isotropic", "antenna.g_bar": 1.0})
    out = []
    for s in (sc, ref):
        scene = ar.build_scene(s)
        poses = {"relay": scene.pose("relay", pos, np.eye(3)), "source": scene.pose("source", np.array(s.mission.start), np.eye(3)),
                 "bs": scene.fixed_pose("bs")}
        out.append(float(scene.evaluate(0.0, poses, jammer_powers=np.zeros(len(scene.jammers))).sinr[1]))
    return out[0] / out[1]


@settings(max_examples=15, deadline=None)
@given(tilt=st.floats(min_value=5.0, max_value=60.0), az=st.floats(min_value=-180.0, max_value=180.0),
       g_max=st.floats(min_value=1.0, max_value=20.0), n=st.floats(min_value=0.5, max_value=6.0))
def test_a_cosine_base_station_has_its_peak_on_its_boresight_and_the_cosine_law_off_it(tilt, az, g_max, n):
    sc = load_scenario(NOMINAL, set={"antenna.bs_pattern": "cosine", "antenna.bs_tilt_deg": tilt, "antenna.bs_azimuth_deg": az,
                                     "antenna.bs_g_max": g_max, "antenna.bs_exponent": n, "antenna.bs_back_lobe": 0.001,
                                     "nodes.bs": [0.0, 0.0, 30.0], "world.ground_z_m": 0.0})
    t, a = math.radians(tilt), math.radians(az)
    boresight = [math.cos(t) * math.cos(a), math.cos(t) * math.sin(a), -math.sin(t)]
    assert _bs_gain_toward(sc, boresight) == pytest.approx(g_max, rel=1e-9)
    # 40 deg off the boresight, above it in the vertical plane through it (never straight down, where the
    # relay's own dipole has its null): g_max cos(40 deg)^n
    up = t - math.radians(40)
    off = [math.cos(up) * math.cos(a), math.cos(up) * math.sin(a), -math.sin(up)]
    assert _bs_gain_toward(sc, off) == pytest.approx(g_max * max(math.cos(math.radians(40)) ** n, 0.001), rel=1e-9)


def test_a_cosine_base_station_is_pointed_by_tilt_and_azimuth_only():
    with pytest.raises(ScenarioError, match="bs_axis"):
        load_scenario(NOMINAL, set={"antenna.bs_pattern": "cosine", "antenna.bs_axis": [1.0, 0.0, 0.0]})


@settings(max_examples=30, deadline=None)
@given(t=st.floats(min_value=0.0, max_value=30.0), laps=st.integers(min_value=1, max_value=5))
def test_a_repeating_jammer_is_where_it_was_one_lap_earlier(t, laps):
    wps = [[2.0, -6.95, -5.79, 1.72], [5.0, -3.0, -5.79, 1.72], [7.0, -3.0, -2.0, 1.72], [9.0, -6.95, -5.79, 1.72]]
    sc = load_scenario(NOMINAL, set={"jammer.waypoints": wps, "jammer.repeat": True})
    j = ar.build_scene(sc).jammers[0]
    lap = 7.0
    later = j.position_at(2.0 + t + laps * lap)
    np.testing.assert_allclose(later, j.position_at(2.0 + t), atol=1e-9)
    np.testing.assert_allclose(j.position_at(1.0), wps[0][1:])  # before its first waypoint: held there


@pytest.mark.parametrize("sets,needle", [
    ({"jammer.waypoints": [[0, -6.95, -5.79, 1.72], [3, -3.0, -5.79, 1.72]], "jammer.repeat": True}, "loop"),
    ({"jammer.repeat": True}, "needs waypoints"),
])
def test_a_repeat_that_is_no_loop_is_named(sets, needle):
    with pytest.raises(ScenarioError, match=f"jammer: .*{needle}"):
        load_scenario(NOMINAL, set=sets)


def test_true_and_estimated_jammer_positions_are_logged_per_step():
    sc = load_scenario(ROOT / "scenarios" / "moving_jammer.toml", set={"sim.duration_s": 1.0, "jammer.localization": "estimated"})
    df = ar.simulate(sc).timeseries
    name = sc.jammer_configs[0].name
    j = ar.build_scene(sc).jammers[0]
    for k in (0, len(df) // 2, len(df) - 1):
        np.testing.assert_allclose(df.loc[k, [f"jam_{name}_x", f"jam_{name}_y", f"jam_{name}_z"]].to_numpy(float),
                                   j.position_at(float(df.loc[k, "t"])))
    assert {f"est_{name}_x", f"est_{name}_y", f"est_{name}_z"} <= set(df.columns)
