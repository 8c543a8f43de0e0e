"""The C library's telemetry check (``ar_trust``, issue 77) against Python's (``control.relay_step.TelemetryCheck``):
the same faults (a 1 km position jump, a velocity jump, a stamp ahead of the clock or before the last trusted one, a
value not finite) get the same verdict, step by step, so the C offboard program holds where ``aerorelay fly`` holds
(it flew a 1 km telemetry jump, 300 of 400 periods on the brake law, with setpoints 39.9 km from the start)."""

from __future__ import annotations

import ctypes
from pathlib import Path

import numpy as np

import aerorelay as ar
from aerorelay.assembly.codegen import build_shared, write_tree
from aerorelay.control.relay_step import StaleSettings, TelemetryCheck

ROOT = Path(__file__).resolve().parents[2]
REASONS = {0: None, 2: "not finite", 3: "stamp", 4: "ahead", 5: "before the last trusted", 6: "position jumped",
           7: "velocity jumped"}


def test_ar_trust_gives_python_s_verdict_on_the_same_faults(tmp_path):
    sc = ar.load_scenario(ROOT / "scenarios" / "nominal_tilted.toml", set={"sim.duration_s": 0.1})
    lib = ctypes.CDLL(str(build_shared(write_tree(sc, tmp_path / "tree"))))
    dp = ctypes.POINTER(ctypes.c_double)
    lib.ar_create.restype = ctypes.c_void_p
    lib.ar_destroy.argtypes = [ctypes.c_void_p]
    lib.ar_trust.argtypes = [ctypes.c_void_p, ctypes.c_double, ctypes.c_double, dp, dp, ctypes.POINTER(ctypes.c_int)]
    lib.ar_trust.restype = ctypes.c_int
    c = lib.ar_create()
    veh = ar.build(sc).relays[0].vehicle
    py = TelemetryCheck(veh, StaleSettings())
    p, v = np.array([-6.95, 5.79, 1.72]), np.array([0.5, 0.0, 0.0])
    dt = 0.015
    cases = [(0.0, 0.0, p, v)]
    for k in range(1, 6):  # a vehicle flying straight at 0.5 m/s
        cases.append((k * dt, k * dt, p + v * k * dt, v))
    t = 5 * dt
    cases += [(t + dt, t + dt, p + [1000.0, 0.0, 0.0], v),            # a 1 km jump
              (t + dt, t + dt, p + v * (t + dt), v + [30.0, 0.0, 0.0]),  # a velocity jump
              (t + dt, t + dt + 0.2, p + v * (t + dt), v),          # stamped 0.2 s ahead of the clock
              (t + dt, t - 0.1, p + v * (t - 0.1), v),             # before the last trusted one
              (t + dt, t + dt, p + [np.nan, 0.0, 0.0], v),         # not finite
              (t + dt, t + dt, p + v * (t + dt), v),               # sound again
              (t + 40 * dt, t + 40 * dt, p + v * (t + 40 * dt) + [0.6, 0.0, 0.0], v)]  # within the reach of 0.6 s
    verdicts = []
    for now, stamp, pos, vel in cases:
        x = np.zeros(veh.nx)
        x[:3], x[6:9], x[12:] = pos, vel, veh.hover_speeds()
        why_py = py.problem(now, x, stamp, None)
        if why_py is None:
            py.trust(stamp, x)
        why = ctypes.c_int(-1)
        pc, vc = np.ascontiguousarray(pos, float), np.ascontiguousarray(vel, float)
        status = lib.ar_trust(c, now, stamp, pc.ctypes.data_as(dp), vc.ctypes.data_as(dp), ctypes.byref(why))
        verdicts.append((why_py is None, status == 0))
        assert (why_py is None) == (status == 0), (now, stamp, why_py, why.value)
        if why_py is not None:
            assert REASONS[why.value] in why_py, (why_py, why.value)
    lib.ar_destroy(c)
    assert [ok for ok, _ in verdicts] == [True] * 6 + [False] * 5 + [True, True]
