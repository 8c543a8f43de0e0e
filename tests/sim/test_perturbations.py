"""Channels beyond free space in the closed loop: physical link budget, log-distance path loss
with log-normal shadowing, Doppler fading; every random term logged, capacity recomputed from the
log alone with an independent per-link reference."""

import math
from pathlib import Path

import numpy as np
import pytest

from aerorelay.assembly import load_scenario, parse_scenario
from aerorelay.assembly.parts import build, build_scene
from aerorelay.config import ScenarioError
from aerorelay.models.geometry import rotation_batch
from aerorelay.models.propagation import rma_av_los_probability
from aerorelay.sim.perturbations import LinkPerturbations, PerturbationSettings
from tests.reference_channel import end_to_end_capacity, jammer_gain_sq, legitimate_gain_sq

BASE = parse_scenario({}).with_updates({"sim.duration_s": 2.0})
PHYSICAL = BASE.with_updates({
    "channel.units": "physical", "channel.carrier_hz": 2.4e9, "channel.bandwidth_hz": 20e6, "channel.tx_power_dbm": 20.0,
    "channel.noise_figure_db": 7.0, "jammer.power_dbm": 0.0,
    "channel.propagation.model": "log_distance", "channel.propagation.exponent": 2.7,
    "channel.propagation.reference_distance_m": 1.0, "channel.propagation.shadowing_std_db": 4.0,
    "channel.propagation.decorrelation_m": 5.0, "perturbations.fading_k_db": 6.0, "channel.fading.model": "doppler",
})


def test_physical_link_budget_is_dbm_and_kTB_plus_noise_figure():
    b = build_scene(PHYSICAL).budget
    assert b.tx_power == pytest.approx(0.1)  # 20 dBm
    # kT at 290 K = -173.98 dBm/Hz, + 10 log10(20 MHz) = 73.01 dB, + 7 dB noise figure = -93.96 dBm
    assert 10 * math.log10(b.noise_power * 1e3) == pytest.approx(-173.98 + 73.01 + 7.0, abs=0.01)
    assert b.bandwidth == 20e6
    scene = build_scene(PHYSICAL)
    assert scene.jammers[0].power == pytest.approx(1e-3)  # 0 dBm
    # log-distance with PL(1 m) = Friis at 1 m, 2.4 GHz (40.05 dB)
    assert scene.path_gain.loss_db(1.0) == pytest.approx(40.05, abs=0.01)
    assert scene.path_gain.loss_db(10.0) == pytest.approx(40.05 + 27.0, abs=0.01)


@pytest.fixture(scope="module")
def physical_run():
    return build(PHYSICAL).closed_loop().run()


def test_logged_capacity_is_recomputed_from_the_logged_poses_and_random_terms(physical_run):
    log = physical_run.log
    lam = 299_792_458.0 / 2.4e9
    K, n = (lam / (4 * math.pi)) ** 2, 2.7  # Friis at d0 = 1 m, then exponent 2.7
    p1 = np.column_stack([log["relay.p_x"], log["relay.p_y"], log["relay.p_z"]])
    p2 = np.column_stack([log["source.p_x"], log["source.p_y"], log["source.p_z"]])
    R1 = rotation_batch(np.column_stack([log["relay.phi"], log["relay.theta"], log["relay.psi"]]))
    R2 = rotation_batch(np.column_stack([log["source.phi"], log["source.theta"], log["source.psi"]]))
    pj, p0 = np.array(PHYSICAL.jammer_configs[0].position), np.zeros(3)

    def path(a, b):  # K d^-n instead of the reference's 1/d^2
        d = np.linalg.norm(np.asarray(b) - np.asarray(a), axis=-1)
        return K * d ** (2.0 - n)

    def rnd(link):
        return log[f"fade_amp_{link}"] ** 2 * 10 ** (log[f"shadow_db_{link}"] / 10)

    P_U, P_J = 0.1, 1e-3
    N = 1.380649e-23 * 290 * 20e6 * 10 ** 0.7
    h21 = legitimate_gain_sq(p2, R2, p1, R1) * path(p2, p1) * rnd("source_relay")
    f1 = jammer_gain_sq(pj, p1, R1) * path(pj, p1) * rnd("jammer_relay")
    h10 = legitimate_gain_sq(p1, R1, p0, np.eye(3)) * path(p1, p0) * rnd("relay_bs")
    f0 = jammer_gain_sq(pj, p0, np.eye(3)) * path(pj, p0) * rnd("jammer_bs")
    g21, g10 = h21 * P_U / (f1 * P_J + N), h10 * P_U / (f0 * P_J + N)
    np.testing.assert_allclose(log["sinr.source.relay"], g21, rtol=1e-9)
    np.testing.assert_allclose(log["sinr.relay.bs"], g10, rtol=1e-9)
    np.testing.assert_allclose(log["capacity"], end_to_end_capacity(g21, g10, 20e6), rtol=1e-9)  # bit/s


def test_random_terms_are_logged_correlated_and_deterministic_per_seed(physical_run):
    log = physical_run.log
    again = build(PHYSICAL).closed_loop().run().log
    for c in ("fade_amp_source_relay", "shadow_db_relay_bs", "capacity"):
        np.testing.assert_array_equal(log[c], again[c])
    other = build(PHYSICAL.with_updates({"seed": 1})).closed_loop().run().log
    assert not np.allclose(log["shadow_db_relay_bs"], other["shadow_db_relay_bs"])
    # a relay moving centimetres per step barely changes its shadowing (decorrelation 5 m) and
    # the Doppler fading evolves smoothly: consecutive steps strongly correlated, unlike i.i.d.
    s = log["shadow_db_relay_bs"]
    assert np.max(np.abs(np.diff(s))) < 0.5
    a = log["fade_amp_source_relay"]
    assert np.corrcoef(a[:-1], a[1:])[0, 1] > 0.9
    iid = build(PHYSICAL.with_updates({"channel.fading.model": "iid"})).closed_loop().run().log["fade_amp_source_relay"]
    assert abs(np.corrcoef(iid[:-1], iid[1:])[0, 1]) < 0.2


def test_default_runs_log_no_random_terms_and_the_controller_never_sees_them():
    plain = build(BASE.with_updates({"sim.duration_s": 0.3})).closed_loop().run().log
    assert not any(c.startswith(("fade_amp_", "shadow_db_")) for c in plain)
    noisy = build(BASE.with_updates({"sim.duration_s": 0.3, "channel.propagation.shadowing_std_db": 6.0})).closed_loop().run().log
    np.testing.assert_array_equal(plain["relay.p_x"], noisy["relay.p_x"])
    assert not np.allclose(plain["capacity"], noisy["capacity"])


def test_info_prints_the_link_budget_in_the_chosen_units():
    import aerorelay as ar

    lines = dict(ar.api.link_budget_lines(PHYSICAL))
    assert lines["noise power"] == "-94.0 dBm" and lines["transmit power"] == "20.0 dBm"
    g = ar.link_budget(PHYSICAL)
    assert lines["source -> relay: SINR"] == f"{10 * math.log10(g['gamma_21']):.1f} dB"
    assert lines["end-to-end capacity"].endswith("Mbit/s")
    # the paper's units: dBW, bit/s/Hz, and the same SINR as the model summary
    paper = dict(ar.api.link_budget_lines(BASE))
    assert paper["noise power"] == "0.0 dBW" and paper["end-to-end capacity"].endswith("bit/s/Hz")
    # received power - (interference + noise) = SINR, line by line
    rx = float(paper["relay -> bs: received power"].split()[0])
    assert rx - 0.0 == pytest.approx(10 * math.log10(ar.link_budget(BASE)["gamma_10"]), abs=0.3)


# ---------------------------------------------------------------- 3GPP TR 36.777 RMa-AV as the scene's channel
ROOT = Path(__file__).resolve().parents[2]
RMA = load_scenario(ROOT / "scenarios" / "rma_av.toml", set={"sim.duration_s": 2.0, "controller.planner": "capacity"})


def _tr36777_loss_db(d3, h, fc_ghz, los):
    """TR 36.777 Table B-2 RMa-AV, written out again here (independent of models/propagation.py)."""
    tail = 20 * np.log10(40 * np.pi * fc_ghz / 3)
    pl_los = np.maximum(23.9 - 1.8 * np.log10(h), 20.0) * np.log10(d3) + tail
    pl_nlos = np.maximum(pl_los, -12 + (35 - 5.3 * np.log10(h)) * np.log10(d3) + tail)
    return np.where(los, pl_los, pl_nlos)


def test_rma_av_logged_capacity_is_recomputed_from_the_logged_poses_los_states_and_shadowing():
    log = build(RMA).closed_loop().run().log
    scene = build_scene(RMA)
    p1 = np.column_stack([log["relay.p_x"], log["relay.p_y"], log["relay.p_z"]])
    p2 = np.column_stack([log["source.p_x"], log["source.p_y"], log["source.p_z"]])
    R1 = rotation_batch(np.column_stack([log["relay.phi"], log["relay.theta"], log["relay.psi"]]))
    R2 = rotation_batch(np.column_stack([log["source.phi"], log["source.theta"], log["source.psi"]]))
    pj, p0 = np.array(RMA.jammer_configs[0].position), np.zeros(3)

    def path(a, b, link):  # the logged state's loss and shadowing, times d^2 (the reference divides by it)
        a, b = np.broadcast_arrays(np.asarray(a, float), np.asarray(b, float))
        d3 = np.linalg.norm(b - a, axis=-1)
        h = np.maximum(a[..., 2], b[..., 2])
        loss = _tr36777_loss_db(d3, h, 2.4, log[f"los_{link}"] > 0.5)
        return d3**2 * 10 ** ((log[f"shadow_db_{link}"] - loss) / 10)

    P_U, P_J = 0.1, scene.jammers[0].power
    N = 1.380649e-23 * 290 * 20e6 * 10 ** 0.7
    h21 = legitimate_gain_sq(p2, R2, p1, R1) * path(p2, p1, "source_relay")
    f1 = jammer_gain_sq(pj, p1, R1) * path(pj, p1, "jammer_relay")
    h10 = legitimate_gain_sq(p1, R1, p0, np.eye(3)) * path(p1, p0, "relay_bs")
    f0 = jammer_gain_sq(pj, p0, np.eye(3)) * path(pj, p0, "jammer_bs")
    g21, g10 = h21 * P_U / (f1 * P_J + N), h10 * P_U / (f0 * P_J + N)
    np.testing.assert_allclose(log["sinr.source.relay"], g21, rtol=1e-9)
    np.testing.assert_allclose(log["sinr.relay.bs"], g10, rtol=1e-9)
    np.testing.assert_allclose(log["capacity"], end_to_end_capacity(g21, g10, 20e6), rtol=1e-9)
    # LoS within d1 = 18 m (h <= ~23 m): every link of this geometry; the LoS shadowing std 4.2 exp(-0.0046 h)
    assert all(np.all(log[f"los_{lk}"] == 1.0) for lk in ("source_relay", "relay_bs", "jammer_relay", "jammer_bs"))
    again = build(RMA).closed_loop().run().log
    np.testing.assert_array_equal(log["shadow_db_relay_bs"], again["shadow_db_relay_bs"])


def test_rma_av_los_states_are_drawn_with_the_los_probability():
    """Over 2000 seeds a 500 m link from the ground to 30 m is LoS with the standard's P_LoS there."""
    far = load_scenario(ROOT / "scenarios" / "rma_av.toml", set={"nodes.bs": [400.0, 300.0, 0.0]})
    scene = build_scene(far)
    p_los = float(rma_av_los_probability(500.0, 30.0))  # d2D 500 m, h 30 m
    assert 0.5 < p_los < 1.0
    pos = {"source": np.array([1.0, 1.0, 30.0]), "relay": np.array([0.0, 0.0, 30.0]), "bs": np.array([400.0, 300.0, 0.0])}
    vel = {k: np.zeros(3) for k in pos}
    los = [LinkPerturbations(scene, PerturbationSettings(decorrelation_m=37.0), period_s=0.015, seed=s).step(0.0, pos, vel)[1]
           ["los_relay_bs"] for s in range(2000)]
    assert np.mean(los) == pytest.approx(p_los, abs=3 * math.sqrt(p_los * (1 - p_los) / 2000))


@pytest.mark.parametrize("change, fragment", [
    ({"channel.units": "normalized"}, "channel.units = 'physical'"),
    ({"controller.workspace.min": [-7.0, -6.0, 0.5]}, "controller.workspace z spans 0.50"),
    ({"jammer.position": [-6.95, -5.79, 1.72]}, "jammer z spans 1.72"),
    ({"channel.propagation.shadowing_std_db": 4.0}, "rma_av draws the standard's shadowing"),
])
def test_rma_av_outside_its_validity_is_a_named_error(change, fragment):
    with pytest.raises(ScenarioError, match="rma_av|RMa-AV|physical") as err:
        RMA.with_updates(change)
    assert fragment in str(err.value)
