import json

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from aerorelay.assembly import parse_scenario
from aerorelay.assembly.parts import build
from aerorelay.assembly.vehicle import build_vehicle
from aerorelay.cli import app
from aerorelay.models.geometry import rotation_batch
from aerorelay.sim.closed_loop import known_jammers
from aerorelay.sim.log_schema import log_columns
from aerorelay.sim.metrics import compute_metrics
from tests.reference_channel import end_to_end_capacity, link_sinr

SHORT = parse_scenario({}).with_updates({"sim.duration_s": 3.0})
LOG_COLUMNS = log_columns({"relay": 6}, ["source"], build(SHORT).scene)


@pytest.fixture(scope="module")
def short_run():
    return build(SHORT).closed_loop().run()


def test_short_mission_runs_without_failures(short_run):
    log = short_run.log
    assert len(log["t"]) == int(3.0 / 0.015) + 1
    assert short_run.qp_failures == 0
    for c in LOG_COLUMNS:
        if c not in ("relay.qp_ok", "relay.qp_status", "relay.fallback", "jammer_on"):
            assert np.all(np.isfinite(log[c])), c


def test_bounds_never_violated(short_run):
    log, veh = short_run.log, build_vehicle(SHORT.platform)
    speeds = np.column_stack([log[f"relay.Omega_{i}"] for i in range(1, 7)])
    rates = np.column_stack([log[f"relay.u_{i}"] for i in range(1, 7)])
    assert speeds.min() >= veh.omega_min - 1e-6 and speeds.max() <= veh.omega_max + 1e-6
    assert rates.min() >= veh.omega_dot_min - 1e-9 and rates.max() <= veh.omega_dot_max + 1e-9
    ws = SHORT.controller.workspace
    for i, a in enumerate("xyz"):
        assert ws.min[i] - 1e-3 <= log[f"relay.p_{a}"].min() and log[f"relay.p_{a}"].max() <= ws.max[i] + 1e-3


def test_logged_capacity_equals_recomputation_from_logged_states(short_run):
    log = short_run.log
    p1 = np.column_stack([log["relay.p_x"], log["relay.p_y"], log["relay.p_z"]])
    p2 = np.column_stack([log["source.p_x"], log["source.p_y"], log["source.p_z"]])
    R1 = rotation_batch(np.column_stack([log["relay.phi"], log["relay.theta"], log["relay.psi"]]))
    R2 = rotation_batch(np.column_stack([log["source.phi"], log["source.theta"], log["source.psi"]]))
    pj = np.array(SHORT.jammer.position)
    kw = dict(tx_power=1.0, jam_power=1.0, noise_power=1.0)  # always-on jammer, P_J = 1 W
    g21 = link_sinr(p2, R2, p1, R1, pj, **kw)
    g10 = link_sinr(p1, R1, np.zeros(3), np.eye(3), pj, **kw)
    np.testing.assert_allclose(log["sinr.source.relay"], g21, rtol=1e-9)
    np.testing.assert_allclose(log["sinr.relay.bs"], g10, rtol=1e-9)
    np.testing.assert_allclose(log["capacity"], end_to_end_capacity(g21, g10), rtol=1e-9)


def test_metrics_from_log(short_run):
    m = compute_metrics(short_run.log, relays={"relay": build_vehicle(SHORT.platform)}, sources=["source"], period_s=SHORT.control_period_s,
                        outage_threshold=SHORT.channel.outage, mu=SHORT.controller.mu, wall_s=1.0, sim_s=3.0)
    assert m["c_min"] == pytest.approx(np.min(short_run.log["capacity"]))
    assert 0 <= m["outage_fraction"] <= 1 and m["infeasible_fraction"] == 0
    # hover-dominated 3 s: energy close to hover shaft power x time
    veh = build_vehicle(SHORT.platform)
    assert m["energy_kJ"] == pytest.approx(veh.shaft_power(veh.hover_speeds()) * 3.0 / 1e3, rel=0.1)


def test_fading_changes_channel_not_controller():
    sc = SHORT.with_updates({"perturbations.fading_k_db": 6.0, "sim.duration_s": 0.3})
    a, b = build(sc).closed_loop().run().log, build(SHORT.with_updates({"sim.duration_s": 0.3})).closed_loop().run().log
    np.testing.assert_allclose(a["relay.p_x"], b["relay.p_x"])  # the controller never sees the fading
    assert not np.allclose(a["sinr.source.relay"], b["sinr.source.relay"])


def test_cli_run_writes_outputs_and_compare(tmp_path):
    scen = tmp_path / "s.toml"
    scen.write_text(SHORT.with_updates({"sim.duration_s": 0.6}).to_toml())
    runner = CliRunner()
    for v in ("constrained", "unconstrained"):
        res = runner.invoke(app, ["run", str(scen), "--out", str(tmp_path / v), "--variant", v])
        assert res.exit_code == 0, res.output
    out = tmp_path / "constrained"
    for f in ("scenario.toml", "timeseries.parquet", "metrics.json", "trajectory_3d.png", "capacity.png",
              "constraints_relay.png", "tracking_relay.png", "trajectory.html"):
        assert (out / f).stat().st_size > 0, f
    df = pd.read_parquet(out / "timeseries.parquet")
    assert list(df.columns) == LOG_COLUMNS  # the relay's, the source's, the links', each jammer's true position last
    m = json.loads((out / "metrics.json").read_text())
    assert set(m["solve_ms"]) == {"mean", "p50", "p95", "p99", "max", "std"}
    res = runner.invoke(app, ["compare", str(tmp_path / "unconstrained"), str(out)])
    assert res.exit_code == 0 and "ratio B/A" in res.output and "c_min" in res.output
    res = runner.invoke(app, ["run", str(scen), "--out", str(tmp_path / "x"), "--variant", "bogus"])
    assert res.exit_code == 2


def test_control_rate_500hz_keeps_the_prediction_grid():
    sc = SHORT.with_updates({"sim.control_rate_hz": 500.0, "sim.duration_s": 0.2})
    parts = build(sc)
    loop = parts.closed_loop()
    # the OCP keeps its 15 ms grid (the horizon spans N ts = 0.45 s) and the plan is not shifted every 2 ms
    assert parts.relay("relay").controller.spec.ts == pytest.approx(0.015) and loop.relays[0].stepper.shift is False
    assert parts.relay("relay").controller.spec.horizon * parts.relay("relay").controller.spec.ts == pytest.approx(0.45)
    log = loop.run().log
    assert len(log["t"]) == 101 and log["t"][1] == pytest.approx(0.002)
    assert np.all(np.isfinite(log["capacity"]))
    p1 = np.column_stack([log["relay.p_x"], log["relay.p_y"], log["relay.p_z"]])
    assert np.linalg.norm(p1[-1] - p1[0]) < 0.05


def test_disturbances_are_seeded_and_leave_the_true_source_path_alone():
    base = SHORT.with_updates({"sim.duration_s": 0.5})
    noisy = base.with_updates({"perturbations.process_noise_v": 0.5, "perturbations.process_noise_w": 0.2,
                               "perturbations.csi_noise_m": 0.1})
    a, b, c = (build(s).closed_loop().run().log for s in (noisy, noisy, base))
    np.testing.assert_array_equal(a["relay.p_x"], b["relay.p_x"])  # same seed, same run
    assert not np.allclose(a["relay.p_x"], c["relay.p_x"])
    np.testing.assert_allclose(a["source.p_x"], c["source.p_x"])  # the true MRAV-2 path is untouched by CSI noise


@pytest.mark.parametrize("senses", [False, True])
def test_generator_jammer_power_before_and_after_localization(senses):
    sc = parse_scenario({"jammer": {"schedule": "on_off", "on_s": 5.0, "off_s": 5.0, "localization_delay_s": 2.0},
                         "controller": {"senses_jammer_state": senses}})
    loop = build(sc).closed_loop()
    pw = sc.jammer.power_w
    jam = loop.scene.jammers[0]
    assert jam.power_at(7.0) == 0.0 and jam.power_at(3.0) == pw  # OFF at 7 s, ON at 3 s
    planned = lambda t: known_jammers(loop.scene, t, loop.settings.senses_jammer_state)[1]  # what the loop plans with
    assert planned(1.0) == [0.0]  # not localized yet: BS-only planning
    assert planned(3.0) == [pw]
    assert planned(7.0) == [0.0 if senses else pw]


def test_logged_capacity_follows_the_antenna_options():
    """Isotropic BS and MRAV-2, dipoles scaled by D = 1.64: the log equals an independent
    recomputation with those patterns, and the controller's flight does not change."""
    from aerorelay.models.antenna import DipolePattern, IsotropicPattern

    sc = SHORT.with_updates({"sim.duration_s": 0.6, "antenna.bs_pattern": "isotropic", "antenna.source_pattern": "isotropic",
                             "antenna.directivity": 1.64})
    log = build(sc).closed_loop().run().log
    base = build(SHORT.with_updates({"sim.duration_s": 0.6})).closed_loop().run().log
    np.testing.assert_array_equal(log["relay.p_x"], base["relay.p_x"])
    p1 = np.column_stack([log["relay.p_x"], log["relay.p_y"], log["relay.p_z"]])
    p2 = np.column_stack([log["source.p_x"], log["source.p_y"], log["source.p_z"]])
    R1 = rotation_batch(np.column_stack([log["relay.phi"], log["relay.theta"], log["relay.psi"]]))
    R2 = rotation_batch(np.column_stack([log["source.phi"], log["source.theta"], log["source.psi"]]))
    pj, kw = np.array(SHORT.jammer.position), dict(tx_power=1.0, jam_power=1.0, noise_power=1.0)
    relay, iso = DipolePattern(1.64), IsotropicPattern(1.0)
    g21 = link_sinr(p2, R2, p1, R1, pj, pattern=iso, pattern_rx=relay, **kw)
    g10 = link_sinr(p1, R1, np.zeros(3), np.eye(3), pj, pattern=relay, pattern_rx=iso, **kw)
    np.testing.assert_allclose(log["capacity"], end_to_end_capacity(g21, g10), rtol=1e-9)
    assert log["capacity"].mean() > base["capacity"].mean()


def test_outage_durations_count_runs_of_consecutive_outage_steps():
    from aerorelay.sim.metrics import outage_durations

    o = np.array([0, 1, 1, 0, 0, 1, 1, 1, 1, 0, 1], bool)
    d = outage_durations(o, 0.5)
    assert d == {"outage_events": 3, "outage_duration_mean_s": pytest.approx((1.0 + 2.0 + 0.5) / 3),
                 "outage_duration_max_s": 2.0}
    assert outage_durations(np.zeros(5, bool), 0.1) == {"outage_events": 0, "outage_duration_mean_s": 0.0,
                                                        "outage_duration_max_s": 0.0}
