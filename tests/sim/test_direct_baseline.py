"""Issue 79, item 1: the direct-link baseline (``sim.baseline = "direct"``): per step the rate with no relay, each
source straight to its base station, equal to the single-hop formula written here (Friis, half-wave dipoles, kTB
with the noise figure, the jammer's interference); the run's C_min and mean over it in metrics.json; refused where
the flight's channel has terms the direct link's would not."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import aerorelay as ar
from aerorelay.config import ScenarioError

ROOT = Path(__file__).resolve().parents[2]
BOLTZMANN = 1.380649e-23  # J/K
LIGHT = 299_792_458.0  # m/s


def _zyx(phi: float, theta: float, psi: float) -> np.ndarray:
    """Body to world, Z-Y-X Euler angles: Rz(psi) Ry(theta) Rx(phi)."""
    cf, sf, ct, st, cp, sp = math.cos(phi), math.sin(phi), math.cos(theta), math.sin(theta), math.cos(psi), math.sin(psi)
    rz = np.array([[cp, -sp, 0.0], [sp, cp, 0.0], [0.0, 0.0, 1.0]])
    ry = np.array([[ct, 0.0, st], [0.0, 1.0, 0.0], [-st, 0.0, ct]])
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cf, -sf], [0.0, sf, cf]])
    return rz @ ry @ rx


def _dipole(g_bar: float, axis: np.ndarray, toward: np.ndarray) -> float:
    """A half-wave dipole's gain toward ``toward`` (any length): g_bar cos^2(pi/2 cos th) / sin^2 th."""
    c = float(axis @ toward) / float(np.linalg.norm(toward))
    return g_bar * math.cos(0.5 * math.pi * c) ** 2 / (1.0 - c * c)


def _friis(carrier_hz: float, d: float) -> float:
    lam = LIGHT / carrier_hz
    return (lam / (4.0 * math.pi * d)) ** 2


def _direct_rates(sc, log) -> np.ndarray:
    """The single-hop formula at every logged step: the inspector straight to the base station (Friis, the scenario's
    half-wave dipoles of gain 1, kTB with the noise figure, the isotropic jammer into the base station's dipole)."""
    ch, jam = sc.channel, sc.jammer_configs[0]
    p_tx = 10.0 ** ((ch.tx_power_dbm - 30.0) / 10.0)
    noise = BOLTZMANN * ch.temperature_k * ch.bandwidth_hz * 10.0 ** (ch.noise_figure_db / 10.0)
    p_bs, b_bs, p_j = np.zeros(3), np.array([0.0, 0.0, 1.0]), np.array(jam.position, float)
    out = []
    for k in range(len(log["t"])):
        p_s = np.array([log[f"inspector.{q}"][k] for q in ("p_x", "p_y", "p_z")])
        b_s = _zyx(*(log[f"inspector.{q}"][k] for q in ("phi", "theta", "psi")))[:, 2]
        d, dj = p_bs - p_s, p_bs - p_j
        signal = p_tx * _dipole(1.0, b_s, d) * _dipole(1.0, b_bs, -d) * _friis(ch.carrier_hz, float(np.linalg.norm(d)))
        interference = jam.power_w * _dipole(1.0, b_bs, -dj) * _friis(ch.carrier_hz, float(np.linalg.norm(dj)))
        out.append(ch.bandwidth_hz * math.log2(1.0 + signal / (noise + interference)))
    return np.array(out)


def test_the_direct_link_is_the_single_hop_formula_and_the_run_is_set_against_it():
    sc = ar.load_scenario(ROOT / "scenarios" / "long_inspection.toml",
                          set={"sim.duration_s": 0.6, "sim.baseline": "direct", "network.route": False})
    r = ar.simulate(sc)
    m, log = r.metrics, r.mission.log
    rates = _direct_rates(sc, log)
    assert m["c_min_direct"] == pytest.approx(rates.min(), rel=1e-9)
    assert m["c_mean_direct"] == pytest.approx(rates.mean(), rel=1e-9)
    assert m["c_min_over_direct"] == pytest.approx(m["c_min"] / rates.min(), rel=1e-9)
    assert m["c_mean_over_direct"] == pytest.approx(m["c_mean"] / rates.mean(), rel=1e-9)
    assert m["units"]["c_min_direct"] == "bit/s" and m["units"]["c_mean_over_direct"] == "1"


def test_without_the_setting_no_baseline_and_with_random_channel_terms_a_named_refusal():
    sc = ar.load_scenario(ROOT / "scenarios" / "nominal_tilted.toml", set={"sim.duration_s": 0.1})
    assert "c_min_direct" not in ar.simulate(sc).metrics
    with pytest.raises(ScenarioError, match=r"sim.baseline: 'direct' .*fading_k_db.*allowed here: 'none'"):
        ar.load_scenario(ROOT / "scenarios" / "nominal_tilted.toml",
                         set={"sim.baseline": "direct", "perturbations.fading_k_db": 6.0})
    with pytest.raises(ScenarioError, match=r"sim.baseline"):
        ar.load_scenario(ROOT / "scenarios" / "nominal_tilted.toml", set={"sim.baseline": "relayless"})


def test_a_scenario_with_no_relays_flies_the_direct_link():
    """Issue 79, item 1: ``relays = []`` with the route source -> base station is valid and flies (the number of relays
    is a dimension: 0 too): its rate at every step is the single-hop formula written above, to 1e-9, its bound is
    that rate (nothing to place: the bound's flyable path and upper path equal the flown rate at the bound's
    instants), its verdict complete, and the stepped controller (which commands relays) refuses it by name."""
    sc = ar.load_scenario(ROOT / "scenarios" / "long_inspection.toml",
                          set={"relays": [], "network.routes": [["inspector", "bs"]], "sim.duration_s": 3.0, "bound.dt_s": 0.6})
    assert sc.relay_list == [] and sc.shape.plans == "network"
    r = ar.simulate(sc, bound=True)
    m, log = r.metrics, r.mission.log
    rates = _direct_rates(sc, log)
    assert m["c_min"] == pytest.approx(rates.min(), rel=1e-9) and m["c_mean"] == pytest.approx(rates.mean(), rel=1e-9)
    assert m["exit_status"] == "complete" and m["relays"] == {}
    b = r.bound
    t = np.asarray(log["t"], float)
    at = np.searchsorted(t, b.t - 1e-9)  # the logged steps at the bound's instants (those the flight reached)
    flown = at < len(t)
    assert flown.sum() >= 5 and np.allclose(t[at[flown]], b.t[flown], atol=1e-9)
    np.testing.assert_allclose(b.flyable[flown], rates[at[flown]], rtol=1e-9)
    np.testing.assert_allclose(b.path_mean[flown], rates[at[flown]], rtol=1e-9)
    with pytest.raises(ScenarioError, match=r"relays: none: ar.controller"):
        ar.controller(sc)


def test_with_no_relays_the_controller_settings_are_refused_by_name():
    """No relay flies, so a controller setting changes nothing: refused by name (``config.applies``), as a planner
    object passed from Python."""
    with pytest.raises(ScenarioError, match=r"controller\.planner: applies only where the scenario has a relay"):
        ar.load_scenario(ROOT / "scenarios" / "long_inspection.toml",
                         set={"relays": [], "network.routes": None, "controller.planner": "capacity"})
    sc = ar.load_scenario(ROOT / "scenarios" / "long_inspection.toml",
                          set={"relays": [], "network.routes": None, "sim.duration_s": 0.1})
    assert sc.route_list == [["inspector", "bs"]]
    with pytest.raises(ScenarioError, match=r"relays: none: a planner passed from Python"):
        ar.simulate(sc, planner=object())
