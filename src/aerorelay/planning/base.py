"""One interface for every relay planner (the paper's generator, baselines A/B, new ones).

A planner is built from a scenario and MRAV-2's planned path by the factory registered under
its ``controller.planner`` name, and called once per control step with what the relay knows:

    planner.update(PlannerInput(t, dt, p1, p2, v2, a2, jammer_position, jammer_power)) -> Reference

Adding a planner: write the class and register its factory with ``@register_planner("name")``
(and add the name to ``controller.planner``'s choices in config.py).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from .trajectory_generator import Reference


@dataclass(frozen=True)
class PlannerInput:
    """What the relay knows at one control step (world frame, SI units).

    ``jammer_power`` is the power the planner should assume (0 before localization, see
    ``sim.closed_loop``), ``jammer_position`` the (possibly noisy) localized position.
    """

    t: float
    dt: float
    p1: np.ndarray
    p2: np.ndarray
    v2: np.ndarray
    a2: np.ndarray
    jammer_position: np.ndarray
    jammer_power: float


class Planner(Protocol):
    def update(self, inp: PlannerInput) -> Reference: ...


PlannerFactory = Callable[..., Planner]  # (scenario, source trajectory) -> Planner
_REGISTRY: dict[str, PlannerFactory] = {}


def register_planner(name: str) -> Callable[[PlannerFactory], PlannerFactory]:
    def deco(factory: PlannerFactory) -> PlannerFactory:
        if name in _REGISTRY:
            raise ValueError(f"planner {name!r} is registered twice")
        _REGISTRY[name] = factory
        return factory
    return deco


def build_planner(sc, source) -> Planner:
    """The planner ``sc.controller.planner`` for this scenario and MRAV-2 path."""
    from . import registry  # noqa: F401  (registers the built-in planners)

    name = sc.controller.planner
    try:
        factory = _REGISTRY[name]
    except KeyError:
        raise ValueError(f"controller.planner: unknown planner {name!r}; registered: {', '.join(sorted(_REGISTRY))}") from None
    return factory(sc, source)
