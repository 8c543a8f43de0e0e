"""The only place that turns configuration (``aerorelay.config``) into parts: loading with the
physics checks (``load``, ``checks``), the vehicle (``vehicle``), everything a mission is made of
(``parts``)."""

from .checks import check_physics
from .load import load_scenario, parse_scenario, parse_sets, updated
from .parts import Parts, build, build_scene
from .vehicle import build_vehicle

__all__ = ["Parts", "build", "build_scene", "build_vehicle", "check_physics", "load_scenario", "parse_scenario",
           "parse_sets", "updated"]
