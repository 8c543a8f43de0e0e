"""``controller.backend = "c"`` (issue 80, item 3): a relay flies its generated C library in ``ar.simulate`` and in the
stepped controller (``ar.controller``, which MAVLink and ROS 2 fly through); Python's controller is the reference. The
same engine source, flags and BLASFEO kernels: where the NMPC flies, the flight is Python's bit for bit; what reads the
controller during a flight reads the C library's (the plan the next step starts from: another relay's separation rows;
the fail-safe's counts: the verdict). Commands that compare the tree with Python's controller refuse it by name."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

import aerorelay as ar
from aerorelay import api
from aerorelay.config import ScenarioError

pytestmark = pytest.mark.skipif(shutil.which("make") is None or (shutil.which("gcc") or shutil.which("cc")) is None,
                                reason="needs make and a C compiler (the C library is built)")

CHAIN = "scenarios/chain_two_relays.toml"
TIMINGS = ("_ms", "wall_s")  # a step's compute time: the C library's is its own


def _float_columns(log) -> list[str]:
    return [c for c in log if np.asarray(log[c]).dtype.kind == "f" and not c.endswith(TIMINGS)]


def _flat(d: dict, pre: str = "") -> dict:
    out: dict = {}
    for k, v in d.items():
        out |= _flat(v, f"{pre}{k}.") if isinstance(v, dict) else {f"{pre}{k}": v}
    return out


def _same_metrics(a: dict, b: dict) -> list[str]:
    """The metrics that differ (compute times aside)."""
    fa, fb = _flat(a), _flat(b)
    timing = [k for k in fa if any(t in k for t in TIMINGS)]
    return [k for k in sorted(set(fa) | set(fb)) if k not in timing and not (
        fa.get(k) == fb.get(k) or (isinstance(fa.get(k), float) and isinstance(fb.get(k), float) and np.isnan(fa[k]) and np.isnan(fb[k])))]


def test_a_relay_on_its_c_library_flies_a_chain_as_python_bit_for_bit():
    """Relay r1 of the two-relay chain on its C library ([relays.controller] backend = "c", honoured per relay), r2 on
    Python: every logged number equal to the all-Python flight, bit for bit. r2's separation rows read r1's plan, so
    they read the C library's (``RelayStep.guess``): a stale or missing plan there would move r2."""
    base = ar.load_scenario(CHAIN, set={"sim.duration_s": 2.0})
    py = ar.simulate(base)
    c = ar.simulate(base.with_updates({"relays.0.controller.backend": "c"}))
    assert base.with_updates({"relays.0.controller.backend": "c"}).controller_of(1).backend == "python"
    a, b = py.mission.log, c.mission.log
    cols = _float_columns(a)
    assert "r1.p_x" in cols and "r2.p_x" in cols and len(cols) > 50
    for col in cols:
        np.testing.assert_array_equal(np.asarray(a[col], float), np.asarray(b[col], float), err_msg=col)
    assert _same_metrics(py.metrics, c.metrics) == []


def test_the_c_library_s_fail_safe_is_the_verdict_s():
    """Forced QP failures (the capacity planner's NMPC capped at 4 iterations): the brake law flies on the same steps,
    the fail-safe's episodes and the run's verdict (fell_back) are the C library's, and equal Python's; the flight within
    1e-6 relative of Python's (the brake law's allocation, SciPy's BVLS in Python and its C port, agree to 1e-9 per
    step: tests/control/test_codegen.py)."""
    base = ar.load_scenario("scenarios/nominal_tilted.toml", set={"sim.duration_s": 5.0, "controller.planner": "capacity",
                                                                  "controller.capacity.qp_iter_max": 4})
    py = ar.simulate(base)
    c = ar.simulate(base.with_updates({"controller.backend": "c"}))
    assert py.metrics["exit_status"] == c.metrics["exit_status"] == "fell_back"
    assert py.metrics["fallback_episodes"] == c.metrics["fallback_episodes"] >= 1
    a, b = py.mission.log, c.mission.log
    np.testing.assert_array_equal(np.asarray(a["relay.fallback"], float), np.asarray(b["relay.fallback"], float))
    for col in _float_columns(a):
        x, y = np.asarray(a[col], float), np.asarray(b[col], float)
        np.testing.assert_allclose(y, x, rtol=1e-6, atol=1e-9, err_msg=col)


def test_the_stepped_controller_flies_the_c_library_too():
    """``ar.controller`` (what ``aerorelay fly`` and the ROS 2 node step) with backend = "c": the same commands as
    Python's controller stepped on the same states."""
    sc = ar.load_scenario("scenarios/nominal_tilted.toml")
    ctrl_py = ar.controller(sc).one_relay()
    ctrl_c = ar.controller(sc.with_updates({"controller.backend": "c"})).one_relay()
    from aerorelay.assembly.parts import build

    parts = build(sc)
    x = parts.relay("relay").vehicle.hover_state(sc.nodes.relay)
    for k in range(5):
        m = parts.sources["source"].state(k * sc.control_period_s)
        s = ar.SourceState(m.p, m.v, m.a)
        a = ctrl_py.step(k * sc.control_period_s, x, s)
        b = ctrl_c.step(k * sc.control_period_s, x, s)
        np.testing.assert_array_equal(a.omega_dot_hz_s, b.omega_dot_hz_s)
        assert b.mode == "nmpc" and a.info.prep_ms > 0.0 and b.info.prep_ms == 0.0  # C: one timed call, ar_step


def test_commands_that_compare_with_python_refuse_it_by_name(tmp_path, monkeypatch):
    sc = ar.load_scenario("scenarios/nominal_tilted.toml", set={"controller.backend": "c"})
    with pytest.raises(ScenarioError, match=r"controller\.backend: 'c'.*aerorelay bench times Python's controller"):
        ar.bench(sc)
    with pytest.raises(ScenarioError, match=r"controller\.backend: 'c'.*codegen --record / --fly"):
        api.codegen(sc, tmp_path / "tree", fly=True)
    chain = ar.load_scenario(CHAIN, set={"relays.1.controller.backend": "c", "sim.duration_s": 0.1})
    monkeypatch.setattr(shutil, "which", lambda name: None)
    with pytest.raises(ScenarioError, match=r"relays\[1\]\.controller\.backend: 'c' builds each relay's C library with make"):
        ar.simulate(chain)
