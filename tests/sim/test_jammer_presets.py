"""The jammer presets: logged capacity equals an independent recomputation from the logged poses
(hand-written jammer positions, cosine gains and sums, the reference per-link channel), and the
jammers dominate the noise where the presets say so."""

import numpy as np
import pytest

import aerorelay as ar
from aerorelay.models.geometry import rotation_batch
from tests.reference_channel import DIPOLE, legitimate_gain_sq

PRESETS = ["two_jammers", "moving_jammer", "directional_jammer"]


def jammer_position(cfg, t):
    if cfg.waypoints is None:
        return np.tile(cfg.position, (len(t), 1))
    wp = np.array(cfg.waypoints)
    return np.column_stack([np.interp(t, wp[:, 0], wp[:, i]) for i in (1, 2, 3)])  # linear path


def jammer_gain_toward(cfg, pj, target_of_boresight, p_rx):
    """G_J toward the receiver: 1 for an isotropic jammer, the cosine pattern by hand otherwise."""
    if cfg.pattern == "isotropic":
        return np.ones(len(pj))
    bore = target_of_boresight - pj
    bore /= np.linalg.norm(bore, axis=1, keepdims=True)
    d = p_rx - pj
    c = np.sum(d * bore, axis=1) / np.linalg.norm(d, axis=1)
    return cfg.g_max * np.maximum(np.maximum(c, 0.0) ** cfg.exponent, cfg.back_lobe)


def received_interference(sc, t, p_rx, R_rx, nodes):
    total = np.zeros(len(t))
    for cfg in sc.jammer_configs:
        pj = jammer_position(cfg, t)
        d = pj - p_rx
        c = np.einsum("ki,ki->k", d, R_rx[:, :, 2]) / np.linalg.norm(d, axis=1)
        g_rx = DIPOLE.gain_from_cos(c)
        g_j = jammer_gain_toward(cfg, pj, nodes[cfg.point_at] if cfg.point_at else None, p_rx)
        total += cfg.power_w * g_j * g_rx / np.sum(d * d, axis=1)
    return total


@pytest.mark.parametrize("preset", PRESETS)
@pytest.mark.parametrize("planner", ["trajectory_generator", "capacity"])
def test_logged_capacity_equals_an_independent_recomputation(preset, planner):
    sc = ar.load_scenario(f"scenarios/{preset}.toml", set={"sim.duration_s": 3.0, "controller.planner": planner})
    df = ar.simulate(sc).timeseries
    t = df["t"].to_numpy()
    p1, p2 = (df[[f"{n}.p_x", f"{n}.p_y", f"{n}.p_z"]].to_numpy() for n in ("relay", "source"))
    R1, R2 = (rotation_batch(df[[f"{n}.phi", f"{n}.theta", f"{n}.psi"]].to_numpy()) for n in ("relay", "source"))
    p0, I = np.zeros((len(t), 3)), np.tile(np.eye(3), (len(t), 1, 1))
    nodes = {"bs": p0, "relay": p1, "source": p2}
    g21 = legitimate_gain_sq(p2, R2, p1, R1) / (received_interference(sc, t, p1, R1, nodes) + 1.0)
    g10 = legitimate_gain_sq(p1, R1, p0, I) / (received_interference(sc, t, p0, I, nodes) + 1.0)
    np.testing.assert_allclose(df["sinr.source.relay"], g21, rtol=1e-9)
    np.testing.assert_allclose(df["sinr.relay.bs"], g10, rtol=1e-9)
    a, b = np.log2(1 + g21), np.log2(1 + g10)
    np.testing.assert_allclose(df["capacity"], a * b / (a + b), rtol=1e-9)
    ws = sc.controller.workspace
    assert np.all(p1 >= np.array(ws.min) - 1e-3) and np.all(p1 <= np.array(ws.max) + 1e-3)


@pytest.mark.parametrize("preset,relay_db,bs_db", [("two_jammers", 0.0, 0.0), ("moving_jammer", 0.0, 0.0),
                                                   ("directional_jammer", None, 0.0)])
def test_jammers_dominate_the_noise_where_the_presets_say(preset, relay_db, bs_db):
    b = ar.link_budget(ar.load_scenario(f"scenarios/{preset}.toml"))
    assert b["inr_bs_db"] > bs_db
    if relay_db is not None:
        assert b["inr_relay_db"] > relay_db
    nominal = ar.link_budget(ar.load_scenario("scenarios/nominal_tilted.toml"))
    assert nominal["inr_bs_db"] < -15.0  # the paper's jammer adds ~1% to the noise


def test_bound_assumptions_are_written_from_the_scene():
    sc = ar.load_scenario("scenarios/directional_jammer.toml", set={"sim.duration_s": 1.0, "bound.dt_s": 0.5,
                                                                    "bound.grid_m": 2.0})
    text = ar.bound(sc).summary()["assumptions"]
    assert "jammer 'panel'" in text and "pointed at 'bs'" in text and "cosine" in text
    assert "base_station 'bs'" in text
