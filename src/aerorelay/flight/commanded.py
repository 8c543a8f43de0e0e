"""The relay's state for its NMPC when an autopilot flies it (the MAVLink bridge, the ROS 2 node).

Position and velocity are measured. The rotor speeds, which autopilots do not report, are the ones
last commanded (hover at the start). The attitude and body rates are the autopilot's attitude loop's
business: the NMPC's own one-period-ahead attitude and rates stand in for them (a cascade: the NMPC
closes the position loop through its model, the autopilot the attitude loop). With
``measured_attitude`` the measured ones are used instead: beside rotor speeds that did not produce
them this is an inconsistent state (on RotorPy's quadrotor with attitude setpoints it took the
tracking error from 0.23 to 0.96 m over 10 s, docs/decisions.md). A run's log always has the
measured attitude (``measured``).
"""

from __future__ import annotations

import numpy as np

from ..control.relay_step import Command
from ..models.state import ETA, OMEGA
from .frames import euler_zyx, matrix_from_wxyz


class CommandedState:
    """``measured(p, R, v, w)`` (m, body to world, m/s world, rad/s body) builds the state
    ``(p, eta, v, omega, Omega)``, ``for_nmpc`` turns it into the NMPC's; ``commanded(cmd)`` after every step."""

    def __init__(self, hover_speeds: np.ndarray, *, measured_attitude: bool = False):
        self.hover = np.asarray(hover_speeds, float).copy()
        self.measured_attitude = measured_attitude
        self.forget()

    def forget(self) -> None:
        """Back to hover, no attitude planned (the autopilot flew the vehicle in between)."""
        self.speeds = self.hover.copy()
        self.plan = (np.zeros(3), np.zeros(3))  # the controller's last attitude (ZYX, rad) and body rates (rad/s)

    def measured(self, p, R, v, w) -> np.ndarray:
        """The state as measured (the rotor speeds last commanded)."""
        return np.concatenate([np.asarray(p, float), euler_zyx(R), np.asarray(v, float), np.asarray(w, float), self.speeds])

    def for_nmpc(self, measured: np.ndarray) -> np.ndarray:
        """The state the NMPC steps from (see the module), from the ``measured`` one."""
        x = measured.copy()
        if not self.measured_attitude:
            x[ETA], x[OMEGA] = self.plan
        return x

    def states(self, p, R, v, w) -> tuple[np.ndarray, np.ndarray]:
        """``(measured, x)``: the measured state and the NMPC's from it, a measured entry the NMPC's state does not
        use kept in it when it is not finite, so the telemetry check still sees it (a zero quaternion)."""
        measured = self.measured(p, R, v, w)
        x = self.for_nmpc(measured)
        bad = ~np.isfinite(measured)
        x[bad] = measured[bad]
        return measured, x

    def commanded(self, cmd: Command) -> None:
        """Keep what the step commanded (nothing on a hold or landing: the autopilot flies those)."""
        if cmd.rotor_speeds_hz is not None:
            self.speeds = cmd.rotor_speeds_hz
            self.plan = (euler_zyx(matrix_from_wxyz(cmd.attitude_wxyz)), cmd.body_rates_rad_s)
