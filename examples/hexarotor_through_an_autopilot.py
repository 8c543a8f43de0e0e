"""
The tilted hexarotor through an autopilot
=========================================

What the relay gives up when an autopilot flies it: the capacity-seeking relay on the paper's tilted
hexarotor, flown by its own rotor commands on aerorelay's plant (``ar.simulate``) and through the
MAVLink bridge to the same plant under a multirotor autopilot's cascade (``ar.plant_airframe``: thrust
along body z, as PX4 flies a multirotor), with position and with attitude setpoints::

    python examples/hexarotor_through_an_autopilot.py   # the 47 s mission, 3 flights, ~2 min; runs/example_autopilot/
"""

import os
from pathlib import Path

import aerorelay as ar

SCENARIOS = Path("scenarios") if Path("scenarios").is_dir() else Path("../scenarios")  # run from the repository or examples/

DURATION = float(os.environ.get("AERORELAY_EXAMPLE_DURATION", "47"))
OUT = Path(os.environ.get("AERORELAY_EXAMPLE_OUT", "runs/example_autopilot"))

sc = ar.load_scenario(SCENARIOS / "nominal_tilted.toml", set={"sim.duration_s": DURATION, "controller.planner": "capacity"})
flights = {"rotor commands (ar.simulate)": ar.simulate(sc)}
for setpoint in ("position", "attitude"):
    flights[f"autopilot, {setpoint}"] = ar.fly_lockstep(sc, ar.plant_airframe(sc), setpoint=setpoint)[0]
print(f"{'flown by':30} {'tracking m':>10} {'C_min':>9} {'mean C':>9} {'tilt max deg':>12} {'brake law':>9} {'unsafe':>6}")
for name, result in flights.items():
    m = result.metrics
    print(f"{name:30} {m['position_error_mean_m']:10.3f} {m['c_min'] * 1e3:9.4f} {m['c_mean'] * 1e3:9.4f} "
          f"{m['max_tilt_deg']:12.1f} {m['fallback_fraction']:9.3f} {m['unsafe']!s:>6}")
    result.save(OUT / name.replace(" ", "_").replace(",", "").replace("(", "").replace(")", "").replace(".", ""), figures=False)
print("capacities in 1e-3 bit/s/Hz (c_min, mean C);", f"run folders in {OUT}")
