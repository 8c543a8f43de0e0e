"""The jammers as the relay estimates them from its receivers' readings, handed to the step API
(``ctrl.step(..., readings={"relay": w, "bs": w})``) by whoever reads the radio: each reading is the
interference plus noise (W) a receiver measured over the last control period (the energy detector
``models/sensing.py`` models, ``meas_<receiver>_w`` in a simulated run's log), taken where the relay
was at its last step. They are folded into the scenario's estimator (``estimation/jammer_estimator.py``)
and the planner gets its confident estimates, as in ``ar.simulate`` (``sim/jammer_sensing.py``)."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ..estimation.jammer_estimator import JammerEstimator
from ..models.geometry import rotation_zyx
from ..models.radio import RadioScene
from ..models.state import ETA, P


class JammersFromReadings:
    """``add(t, relay_state, readings)`` folds one step's readings in; ``view(t)`` is what the planner
    plans with (positions, powers, std). ``receivers``: the estimator's receivers by node name."""

    def __init__(self, scene: RadioScene, estimator: JammerEstimator, receivers: list[str], senses_state: bool):
        self.scene, self.estimator, self.receivers, self.senses_state = scene, estimator, receivers, senses_state
        self.relay = scene.name_of("relay")

    def add(self, t: float, relay_state: np.ndarray | Mapping[str, np.ndarray], readings: Mapping[str, float]) -> None:
        """The readings (W, by receiver name) taken at ``t`` (s) with the relay at ``relay_state`` (a network's:
        every relay's state by name)."""
        states = relay_state if isinstance(relay_state, Mapping) else {self.relay: relay_state}
        unknown = sorted(set(readings) - set(self.receivers))
        if unknown:
            raise ValueError(f"step: readings from {unknown}; the scenario's receivers are {self.receivers} "
                             "(estimation.use_bs adds the base station)")
        rows: list[tuple[np.ndarray, np.ndarray, float] | None] = []
        for name in self.receivers:
            if name not in readings:
                rows.append(None)
                continue
            x = states.get(name)
            pose = self.scene.fixed_pose(name) if x is None else self.scene.pose(name, x[P], rotation_zyx(x[ETA]))
            rows.append((pose.position, pose.axis, float(readings[name])))
        self.estimator.add_readings(t, rows)

    def view(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return self.estimator.estimate.planner_view(self.senses_state)
