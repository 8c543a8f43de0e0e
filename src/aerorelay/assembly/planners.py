"""Which planner a scenario names and the NMPC its references need: one registry (``planning.base.PLANNERS``) for
one relay and networks; a planner declares what its references carry (``planning.base.REFERENCES``), and the NMPC's
cost terms follow that declaration, never the planner's name."""

from __future__ import annotations

from ..config import Scenario
from ..planning import registry as _builtins  # noqa: F401  (the built-in planners registered)
from ..planning.base import PlannerEntry, planner_entry


def planner_of(sc: Scenario) -> PlannerEntry:
    """The planner ``sc`` names (``Scenario.planner``); ValueError naming ``controller.planner`` when none is registered
    under that name."""
    return planner_entry(sc.planner)


def tracking(sc: Scenario) -> bool:
    """Whether the tracking NMPC flies the planner's references (positions, and an antenna-axis reference when they
    carry one), with ``[controller.capacity]``'s position weights and QP limits; else the paper's NMPC."""
    return planner_of(sc).tracking


def comms_aware(sc: Scenario) -> bool:
    """Whether the relay's NMPC carries the paper's comms-aware terms (misalignment cost, alignment constraint): its
    planner's references are positions the NMPC aligns itself (``references = "alignment"``) and
    ``controller.variant = "constrained"`` (``sc``: a relay's view, its own controller)."""
    return sc.controller.variant == "constrained" and not tracking(sc)
