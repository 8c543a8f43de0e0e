"""Scenarios: the typed schema (pydantic), TOML files and overrides, and the composition root
(``build``) that turns a validated scenario into the parts the simulation is made of."""

from .load import load_scenario, parse_sets
from .schema import Scenario, ScenarioError, parse_scenario

__all__ = ["Scenario", "ScenarioError", "load_scenario", "parse_scenario", "parse_sets"]
