"""The relay controller stepped from outside (``ar.controller``): the same planner and NMPC a
mission flies, with the jammers as the relay was told them (the oracle after each one's ``tau_E``)
and, with ``[wind]``, its own external-force observer."""

from __future__ import annotations

import numpy as np

from ..config import Scenario, ScenarioError
from ..control.network import Controller, NetworkController
from ..control.nmpc import NmpcSettings
from ..control.readings import JammersFromReadings
from ..control.relay_step import StaleSettings
from ..models.radio import RadioScene
from ..sim.closed_loop import known_jammers
from .c_engine import install_c_engines
from .parts import build
from .vehicle import thrust_along_body_z


def oracle_jammers(scene: RadioScene, senses_state: bool):
    """``t -> (positions (nJ, 3) m, powers W, None)``: every jammer where it is, with the power the
    planner plans with (0 before its localization; the nominal power, or the radiated one when the
    controller senses the schedule), as ``ar.simulate`` gives them without CSI noise."""
    def view(t: float) -> tuple[np.ndarray, np.ndarray, None]:
        positions, powers = known_jammers(scene, t, senses_state)
        return positions, powers, None
    return view


def build_controller(sc: Scenario, *, nmpc_settings: NmpcSettings | None = None, stale: StaleSettings | None = None,
                     observer: bool = True, autopilot: bool = False) -> Controller:
    """The controller of any network stepped from outside (``ar.controller``): its planner and every relay's NMPC as
    ``ar.simulate`` flies them, the jammers as the network was told them, or estimated from the readings ``step`` is
    handed (``jammer.localization = "estimated"``: every relay's receiver, the base station's with
    ``estimation.use_bs``). Every relay gets ``stale`` (default: hold after 0.05 s, land after 3 s, on the world's
    ground) and, with ``[wind]`` and ``observer``, its own external-force observer (``observer=False``: none, for an
    autopilot's position loop); ``autopilot``: every relay's NMPC models the vehicle an autopilot flies
    (``thrust_along_body_z``). Spares (``standby``) are a simulation's: a named error here (the vehicles outside fly
    what they are told; launching and landing a spare is their operator's)."""
    if not sc.relay_list:
        raise ScenarioError("relays: none: ar.controller (aerorelay fly, the ROS 2 node) commands relays, and this scenario "
                            "has none (the direct link flies in ar.simulate / aerorelay run)")
    if sc.standby_names:
        i = next(i for i, r in enumerate(sc.relay_list) if r.standby)
        raise ScenarioError(f"relays[{i}].standby: spare relays take over in ar.simulate / aerorelay run; flying a fleet "
                            "from outside (ar.controller, aerorelay fly, ROS 2) does not launch them: leave the spare out")
    flown = thrust_along_body_z(sc) if autopilot else sc
    parts = build(flown, nmpc_settings=nmpc_settings, stale=stale or StaleSettings(ground_z_m=sc.world.ground_z_m),
                  observers=observer)
    control = NetworkController(scene=parts.scene, relays=parts.relays, planner=parts.planner, period_s=sc.control_period_s,
                                separation_m=parts.separation_m, replanner=parts.replanner, planner_name=parts.planner_name)
    install_c_engines(flown, control)  # relays flying their C library (controller.backend = "c"), freed with the controller
    senses = sc.controller.senses_jammer_state
    if parts.sensing is not None:  # estimated from the readings step() is handed, by every relay's receiver
        estimated = JammersFromReadings(parts.scene, parts.sensing.estimator, parts.sensing.receivers, senses)
        return Controller(control, estimated.view, estimated)
    return Controller(control, oracle_jammers(parts.scene, senses))
