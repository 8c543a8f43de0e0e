"""The scenario as plain data (pydantic models): fields with units, ranges and descriptions, cheap
cross-field checks, error lines. Parts are made from it in ``aerorelay.assembly`` only."""

from .base import ScenarioError, Strict, Vec3, Waypoint, dbm_to_w
from .controller import CapacityPlannerConfig, ControllerConfig, FailsafeConfig, Weights, Workspace
from .mission import MissionConfig, flight_path
from .platform import PlatformConfig, Rotor
from .radio import AntennaConfig, ChannelConfig, ChannelFadingConfig, JammerConfig, NodesConfig, PropagationConfig
from .scenario import Scenario, validate_config
from .sections import BoundConfig, EstimationConfig, PerturbationConfig, SimConfig, WorldConfig

__all__ = [
    "AntennaConfig", "BoundConfig", "CapacityPlannerConfig", "ChannelConfig", "ChannelFadingConfig", "ControllerConfig",
    "EstimationConfig", "FailsafeConfig", "JammerConfig", "MissionConfig", "NodesConfig", "PerturbationConfig",
    "PlatformConfig", "PropagationConfig", "Rotor", "Scenario", "ScenarioError", "SimConfig", "Strict", "Vec3",
    "Waypoint", "Weights", "WorldConfig", "Workspace", "dbm_to_w", "flight_path", "validate_config",
]
