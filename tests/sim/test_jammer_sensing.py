"""A short flight estimating the jammer: the readings are the true interference plus noise through
the detector (recomputed independently from the logged poses), the estimate and its covariance are
logged, the planner is not handed a jammer before the estimate is confident, and the scenario
settings are checked before any work."""

import numpy as np
import pytest

import aerorelay as ar
from aerorelay.assembly.parts import build
from aerorelay.config import ScenarioError
from aerorelay.models.geometry import rotation_batch
from aerorelay.sim.jammer_sensing import match_estimates
from aerorelay.sim.metrics import estimation_metrics
from tests.reference_channel import DIPOLE

UPDATES = {"jammer.localization": "estimated", "jammer.inr_db_at_relay_start": 10.0, "estimation.use_bs": True,
           "sim.duration_s": 4.0}


@pytest.fixture(scope="module")
def flown():
    sc = ar.load_scenario("scenarios/nominal_tilted.toml").with_updates(UPDATES)
    return sc, ar.simulate(sc)


def test_inr_sets_the_power_at_the_relays_start(flown):
    """Jammer and relay start at the same height: a broadside dipole (gain 1) at d, so P = INR N d^2."""
    sc, _ = flown
    d2 = float(np.sum((np.array(sc.nodes.relay) - np.array(sc.jammer.position)) ** 2))
    assert build(sc).scene.jammers[0].power == pytest.approx(10.0 * 1.0 * d2, rel=1e-9)


def test_readings_are_the_true_interference_through_the_detector(flown):
    sc, res = flown
    df = res.timeseries
    power = 10.0 * float(np.sum((np.array(sc.nodes.relay) - np.array(sc.jammer.position)) ** 2))
    p1 = df[["relay.p_x", "relay.p_y", "relay.p_z"]].to_numpy()
    axis = rotation_batch(df[["relay.phi", "relay.theta", "relay.psi"]].to_numpy())[:, :, 2]
    d = np.array(sc.jammer.position) - p1
    n2 = np.sum(d * d, axis=1)
    expected = 1.0 + power * DIPOLE.gain_from_cos(np.sum(d * axis, axis=1) / np.sqrt(n2)) / n2
    ratio = df["meas_relay_w"].to_numpy() / expected
    assert ratio.mean() == pytest.approx(1.0, abs=4 * 0.1 / np.sqrt(len(ratio)))  # n = 100: std 0.1 per reading
    assert ratio.std() == pytest.approx(0.1, rel=0.15)
    c = sc.jammer.position[2] / np.linalg.norm(sc.jammer.position)  # the BS dipole stands vertical at the origin
    bs = 1.0 + power * DIPOLE.gain_from_cos(c) / float(np.sum(np.array(sc.jammer.position) ** 2))
    assert df["meas_bs_w"].mean() == pytest.approx(bs, rel=4 * 0.1 / np.sqrt(len(df)))


def test_estimate_and_covariance_are_logged(flown):
    _, res = flown
    df, m = res.timeseries, res.metrics
    for q in ("x", "y", "z", "power_w", "on_prob", "std_m", "err_m", "cov_xx", "cov_yy", "cov_zz", "cov_xy", "cov_xz", "cov_yz"):
        assert np.all(np.isfinite(df[f"est_jammer_{q}"])), q
    cov = df[["est_jammer_cov_xx", "est_jammer_cov_yy", "est_jammer_cov_zz"]].to_numpy()
    assert np.all(df["est_jammer_std_m"] ** 2 >= cov.max(axis=1) * (1 - 1e-9))  # largest eigenvalue >= each diagonal entry
    truth = np.array(ar.load_scenario("scenarios/nominal_tilted.toml").jammer.position)
    err = np.linalg.norm(df[["est_jammer_x", "est_jammer_y", "est_jammer_z"]].to_numpy() - truth, axis=1)
    np.testing.assert_allclose(df["est_jammer_err_m"], err, atol=1e-9)
    assert {"estimation_first_within_1m_s", "estimation_within_1m_after_10s", "estimator_ms"} <= set(m)


def test_cramer_rao_bound_only_tightens_and_starts_at_the_box_prior(flown):
    """Each measurement adds information: the logged bound never grows; before the first one it is
    the search box's own spread (side / sqrt 12 on the widest axis); the bound at the end equals
    the metric's (worst jammer, one jammer here)."""
    sc, res = flown
    bound = res.timeseries["est_jammer_crlb_m"].to_numpy()
    assert np.all(np.isfinite(bound)) and np.all(np.diff(bound) <= 1e-12)
    sens = build(sc).sensing
    assert bound[0] <= np.max(sens.estimator.hi - sens.estimator.lo) / np.sqrt(12.0) + 1e-9
    assert bound[-1] < bound[0]
    assert res.metrics["estimation_crlb_10s_m"] == pytest.approx(bound[-1])  # a 4 s flight: its last value


def test_planner_gets_no_jammer_before_a_confident_estimate():
    sc = ar.load_scenario("scenarios/nominal_tilted.toml").with_updates(UPDATES)
    parts = build(sc)
    positions, powers, _ = parts.sensing.estimate.planner_view(senses_state=False)
    assert powers.tolist() == [0.0] and positions.shape == (1, 3)  # nothing measured yet: the prior, no power


@pytest.mark.parametrize("updates, fragment", [
    ({"jammers": [{"localization": "estimated"}, {"position": [1.0, -4.0, 1.0]}], "jammer": None},
     "every jammer must use the same mode"),
    ({"jammer.power_dbm": 30.0, "jammer.inr_db_at_relay_start": 10.0}, "not both"),
    ({"estimation.search_min_m": [0.0, 0.0, 0.0]}, "both search_min_m and search_max_m"),
    ({"estimation.search_min_m": [0.0, 0.0, 0.0], "estimation.search_max_m": [1.0, -1.0, 1.0]}, "below search_max_m"),
    ({"jammer.inr_db_at_relay_start": 60.0}, "jammer.inr_db_at_relay_start: must be in [-40, 40]"),
])
def test_bad_estimation_settings_are_named(updates, fragment):
    with pytest.raises(ScenarioError, match=fragment.replace("[", r"\[").replace("]", r"\]")):
        ar.load_scenario("scenarios/nominal_tilted.toml").with_updates(updates)


def test_estimates_are_matched_to_jammers_by_least_total_distance():
    """The estimator's order is not the scene's: swapped estimates are scored against their own jammers;
    a greedy nearest match would give both estimates to the first jammer here."""
    truth = np.array([[0.0, 0.0, 0.0], [10.0, 0.0, 0.0]])
    match, err = match_estimates(truth, np.array([[9.0, 0.0, 0.0], [0.5, 0.0, 0.0]]))
    assert match.tolist() == [1, 0]
    np.testing.assert_allclose(err, [0.5, 1.0])
    match, err = match_estimates(truth, np.array([[4.0, 0.0, 0.0], [1.0, 0.0, 0.0]]))  # greedy: both near jammer 0
    assert match.tolist() == [1, 0]
    np.testing.assert_allclose(err, [1.0, 6.0])


def test_estimation_metrics_against_a_hand_made_log():
    """Two jammers over 0-20 s at 1 s steps: errors and bounds chosen so each metric is read off by hand."""
    t = np.arange(21.0)
    log = {"t": t, "estimator_ms": np.full(t.size, 0.1),
           "est_a_err_m": np.where(t >= 4, 0.5, 3.0), "est_a_std_m": np.ones(t.size), "est_a_crlb_m": np.where(t >= 8, 0.9, 2.0),
           "est_b_err_m": np.where((t >= 12) & (t != 15), 0.5, 3.0), "est_b_std_m": np.ones(t.size),
           "est_b_crlb_m": np.where(t >= 11, 0.8, 4.0)}
    m = estimation_metrics(log, 1.0)
    assert m["estimation_first_within_1m_s"] == 12.0  # the worst jammer's first
    assert m["estimation_within_1m_after_10s"] == pytest.approx(8 / 11)  # b over 10-20: 12-14, 16-20
    assert m["estimation_crlb_first_1m_s"] == 11.0 and m["estimation_crlb_10s_m"] == 4.0
    assert m["estimation_within_1m_after_bound"] == pytest.approx(8 / 10)  # b over 11-20: 12-14, 16-20
    log["est_b_crlb_m"] = np.full(t.size, np.nan)  # a jammer the bound is not defined for: no bound metrics
    assert "estimation_crlb_first_1m_s" not in estimation_metrics(log, 1.0)


def test_cramer_rao_bound_of_a_jammer_on_a_linear_path():
    """A jammer driving a straight road: its bound (velocity unknown, so it first grows with the time
    the position is asked at) is logged and tightens once the path has shown the motion (measured:
    7.8 m at take-off, 2.1 m at 10 s, 0.8 m at 15 s in the full study run); on a curved path (minimum
    jerk between the same waypoints) the constant-velocity model does not hold and no bound is logged."""
    updates = {"jammer.localization": "estimated", "jammer.inr_db_at_relay_start": 10.0, "sim.duration_s": 15.0,
               "estimation.jammer_speed_m_s": 0.5, "controller.planner": "capacity"}
    res = ar.simulate(ar.load_scenario("scenarios/moving_jammer.toml").with_updates(updates))
    bound = res.timeseries["est_truck_crlb_m"].to_numpy()
    assert np.all(np.isfinite(bound)) and bound[-1] < 0.5 * bound[0] and bound[-1] < 2.0
    curved = ar.simulate(ar.load_scenario("scenarios/moving_jammer.toml").with_updates({**updates, "jammer.path": "minimum_jerk",
                                                                                        "sim.duration_s": 1.0}))
    assert np.all(np.isnan(curved.timeseries["est_truck_crlb_m"]))
