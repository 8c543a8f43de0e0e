"""
The step API as a three-line loop
=================================

The controller stepped from outside over your own plant (here aerorelay's, so the numbers match
``ar.simulate``): ``cmd = ctrl.step(t, state, source)``, ``state = plant(state, cmd)``. The same for a
chain of relays: states and commands by relay name, the relays' plans exchanged inside the controller.
"""

import os
from pathlib import Path

import numpy as np

import aerorelay as ar
from aerorelay.models.geometry import rotation_zyx
from aerorelay.models.state import ETA, P  # the state by name: x = [p, eta, v, omega, Omega]
from aerorelay.sim.closed_loop import plant_step_function

SCENARIOS = Path("scenarios") if Path("scenarios").is_dir() else Path("../scenarios")  # run from the repository or examples/
DURATION = min(float(os.environ.get("AERORELAY_EXAMPLE_DURATION", "5")), 5.0)

# one relay and one source: ar.controller(sc).one_relay() takes its state and returns its command (the explicit adapter)
sc = ar.load_scenario(SCENARIOS / "nominal_tilted.toml", set={"sim.duration_s": DURATION})
ctrl, vehicle, mission = ar.controller(sc).one_relay(), ar.api.vehicle(sc), ar.build(sc).sources["source"]
plant = plant_step_function(vehicle, sc.sim.plant_rate_hz, sc.control_period_s)
scene = ar.build_scene(sc)
x, rates = vehicle.hover_state(sc.nodes.relay), []
for k in range(int(DURATION / sc.control_period_s) + 1):
    t, s = k * sc.control_period_s, mission.state(k * sc.control_period_s)
    cmd = ctrl.step(t, x, ar.SourceState(s.p, s.v, s.a))                       # 1. the controller
    poses = {"relay": scene.pose("relay", x[P], rotation_zyx(x[ETA])),
             "source": scene.pose("source", s.p, rotation_zyx(s.attitude()))}
    rates.append(float(scene.evaluate(t, poses).capacity))                      # 2. the link at the flown poses
    x = np.asarray(plant(x, cmd.omega_dot_hz_s, np.zeros(6))).ravel()          # 3. your plant
print(f"one relay stepped {len(rates)} periods: C_min {min(rates):.4e}, mean C {np.mean(rates):.4e}")

# any network (one relay too): the controller itself, states and commands by relay name
sc = ar.load_scenario(SCENARIOS / "chain_two_relays.toml", set={"sim.duration_s": DURATION})
ctrl, parts = ar.controller(sc), ar.build(sc)
x = {r.name: r.vehicle.hover_state(r.start) for r in parts.relays}
for k in range(int(DURATION / sc.control_period_s) + 1):
    t = k * sc.control_period_s
    sources = {n: ar.SourceState(s.p, s.v, s.a) for n, path in parts.sources.items() for s in [path.state(t)]}
    cmds = ctrl.step(t, x, sources)
    x = {r.name: np.asarray(r.plant(x[r.name], cmds[r.name].omega_dot_hz_s, np.zeros(6))).ravel() for r in parts.relays}
print("chain stepped: relays end at " + ", ".join(f"{n} {np.round(xs[P], 2).tolist()}" for n, xs in x.items()))
