"""
RotorPy's quadrotor in the loop
===============================

The capacity-seeking relay's controller flying an independent simulator: RotorPy's Hummingbird
quadrotor (rigid body, first-order motors, parasitic and rotor drag, translational lift) behind the
in-repo MAVLink vehicle, driven through the offboard bridge in lockstep, against the same mission
on aerorelay's own plant; in still air and in the scenario's 5 m/s wind with Dryden gusts (the same
series in both simulators). ``scenarios/rotorpy_hummingbird.toml`` is RotorPy's vehicle in
aerorelay's units::

    pip install 'aerorelay[rotorpy]'
    python examples/rotorpy_in_the_loop.py      # the 47 s mission, 6 flights, ~4 min; runs/example_rotorpy/
"""

import os
from pathlib import Path

import aerorelay as ar

SCENARIOS = Path("scenarios") if Path("scenarios").is_dir() else Path("../scenarios")  # run from the repository or examples/

DURATION = float(os.environ.get("AERORELAY_EXAMPLE_DURATION", "47"))
OUT = Path(os.environ.get("AERORELAY_EXAMPLE_OUT", "runs/example_rotorpy"))
WINDS = {"still": None, "wind5": {"mean_m_s": [5.0, 0.0, 0.0], "gusts": True}}

print(f"{'air':6} {'plant':22} {'tracking m':>10} {'C_min':>9} {'mean C':>9} {'brake law':>9} {'unsafe':>6}")
for air, wind in WINDS.items():
    sc = ar.load_scenario(SCENARIOS / "rotorpy_hummingbird.toml",
                          set={"sim.duration_s": DURATION, **({"wind": wind} if wind else {})})
    flights = {"aerorelay plant": ar.simulate(sc)}
    for setpoint in ("position", "attitude"):
        flights[f"RotorPy, {setpoint}"] = ar.fly_lockstep(sc, ar.rotorpy_airframe(sc), setpoint=setpoint)[0]
    for plant, result in flights.items():
        m = result.metrics
        print(f"{air:6} {plant:22} {m['position_error_mean_m']:10.3f} {m['c_min'] * 1e3:9.4f} {m['c_mean'] * 1e3:9.4f} "
              f"{m['fallback_fraction']:9.3f} {m['unsafe']!s:>6}")
        result.save(OUT / f"{air}_{plant.replace(', ', '_').replace(' ', '_')}", figures=False)
print("capacities in 1e-3 bit/s/Hz (c_min, mean C);", f"run folders in {OUT}")
