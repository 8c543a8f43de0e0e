"""aerorelay: communications-aware control of multirotor aerial relays under jamming.

Implements Silano et al., *Communications-Aware NMPC for Multi-Rotor Aerial Relay Networks
Under Jamming Interference*: a max-min trajectory generator plus a communications-aware NMPC
on a generically-tilted multirotor (GTMR) model, and goes beyond it (capacity bounds, a
capacity-seeking relay, radio scenes with any number of jammers). The public API is below;
``aerorelay.api`` documents it.
"""

from ._version import __version__
from .api import Result, bench, bound, controller, fly_lockstep, link_budget, plant_airframe, plant_airframes, reproduce, rotorpy_airframe, simulate
from .assembly import load_scenario, parse_scenario
from .assembly.parts import build, build_scene
from .config import Scenario, ScenarioError
from .control.relay_step import Command, SourceState, StaleSettings
from .flight.airframes import PointMass
from .flight.autopilot_loop import AutopilotLoop, Measured
from .models.antenna import CosinePattern, DipolePattern, IsotropicPattern, SinPowerPattern, TabulatedPattern
from .models.jammer import AlwaysOn, Jammer, PeriodicOnOff
from .models.radio import Antenna, LinkBudget, Node, NodePose, RadioScene, route_capacity
from .planning.base import PlannerContext, PlannerInput, register_planner
from .planning.trajectory_generator import Reference

__all__ = [
    "__version__", "AutopilotLoop", "Measured",
    "Command", "PointMass", "Result", "SourceState", "StaleSettings", "bench", "bound", "controller", "fly_lockstep", "link_budget",
    "plant_airframe", "plant_airframes",
    "reproduce", "rotorpy_airframe", "simulate", "CosinePattern", "DipolePattern", "IsotropicPattern", "SinPowerPattern",
    "TabulatedPattern", "AlwaysOn", "Jammer", "PeriodicOnOff", "Antenna", "LinkBudget", "Node", "NodePose",
    "RadioScene", "route_capacity", "PlannerContext", "PlannerInput", "register_planner", "Reference", "Scenario",
    "ScenarioError", "load_scenario", "parse_scenario", "build", "build_scene",
]
