"""Random scenario perturbations (weights, bounds, horizon, mu) through a short flight: each is
rejected at validation, or stays inside the safety envelope, or is reported unsafe. Never silently
otherwise: a relay found outside its box in the log is always reported unsafe."""

from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import aerorelay as ar
from aerorelay.config import ScenarioError

NOMINAL = Path(__file__).resolve().parents[2] / "scenarios" / "nominal_tilted.toml"
BASE = ar.load_scenario(NOMINAL, set={"sim.duration_s": 2.0})

perturbation = st.fixed_dictionaries({
    "controller.mu": st.floats(0.0, 1.0),
    "controller.horizon": st.sampled_from([1, 20, 30, 30]),  # few sizes: each new one compiles an engine
    "controller.weights.position": st.floats(0.0, 1e3),
    "controller.weights.misalignment": st.floats(0.0, 1e3),
    "controller.weights.input_rate": st.floats(0.0, 1.0),
    "platform.omega_max_hz": st.floats(70.0, 120.0),
    "platform.omega_dot_max_hz_s": st.floats(10.0, 600.0),
    "nodes.relay": st.tuples(st.floats(-6.9, 6.9), st.floats(-5.9, 5.9), st.floats(0.6, 18.9)).map(list),
})


@settings(max_examples=16, deadline=None, suppress_health_check=[HealthCheck.too_slow], derandomize=True)
@given(perturbation)
def test_rejected_or_safe_or_reported_unsafe(updates):
    try:
        sc = BASE.with_updates(updates)
    except ScenarioError:
        return  # rejected at validation, with a named error
    r = ar.simulate(sc)
    m, df = r.metrics, r.timeseries
    p1 = df[["relay.p_x", "relay.p_y", "relay.p_z"]].to_numpy()
    ws = sc.controller.workspace
    outside = max(float(np.max(np.array(ws.min) - p1)), float(np.max(p1 - np.array(ws.max))), 0.0)
    tilt = np.degrees(np.arccos(np.clip(np.cos(df["relay.phi"]) * np.cos(df["relay.theta"]), -1, 1))).max()
    left_its_world = outside > sc.controller.failsafe.box_tolerance_m or tilt > 90.0
    assert m["unsafe"] == left_its_world, (updates, m["unsafe_reason"], outside, tilt)
    if not m["unsafe"]:
        assert m["safety_violations"] == 0 or df["relay.fallback"][df["relay.safety_violation"]].all()  # every violation handed over
