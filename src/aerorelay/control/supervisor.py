"""Flight-safety supervisor: a safety envelope checked on the measured state, independent of the QP.

A solver can report success while the relay flips or leaves the world (e.g. an alignment
threshold mu = 0.99 the platform cannot meet). The envelope is the workspace box (plus a
tolerance), a body tilt limit, a speed limit, a body-rate limit and the motor speed bounds; a
state outside it hands the relay to the fail-safe brake law at once (``control/relay.py``),
whatever the QP status says; the NMPC takes over again only once the relay is at rest, and after
``max_handovers`` hand-overs not at all. The limits sit above what the nominal presets fly (tilt
<= 31 deg, speed <= 7.3 m/s, body rates <= 4.6 rad/s on the coplanar mission), so the supervisor
never triggers on them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..models.vehicle import Multirotor


@dataclass(frozen=True)
class SafetyEnvelope:
    """Limits on the relay's state: workspace box (m, world) + ``box_tolerance_m``, body tilt
    (deg), speed (m/s), body rates (rad/s), motor speeds within the vehicle's bounds +- 1%."""

    workspace_min: np.ndarray
    workspace_max: np.ndarray
    omega_min: float
    omega_max: float
    box_tolerance_m: float = 0.05
    max_tilt_deg: float = 45.0
    max_speed_m_s: float = 10.0
    max_body_rate_rad_s: float = 6.0
    rest_speed_m_s: float = 1.0  # after a hand-over the NMPC resumes only from rest: slower than this
    rest_tilt_deg: float = 20.0  # and tilted less than this
    max_handovers: int = 1  # then the brake law keeps the relay for the rest of the mission

    @classmethod
    def for_vehicle(cls, vehicle: Multirotor, workspace_min, workspace_max, **limits) -> SafetyEnvelope:
        return cls(np.asarray(workspace_min, float), np.asarray(workspace_max, float), vehicle.omega_min, vehicle.omega_max,
                   **limits)

    def at_rest(self, x: np.ndarray) -> bool:
        """Slow and nearly level: where the NMPC may take over again after a hand-over."""
        x = np.asarray(x, float)
        tilt = np.degrees(np.arccos(np.clip(np.cos(x[3]) * np.cos(x[4]), -1.0, 1.0)))
        return bool(np.linalg.norm(x[6:9]) < self.rest_speed_m_s and tilt < self.rest_tilt_deg)

    def violations(self, x: np.ndarray) -> list[str]:
        """What the state ``(p, eta, v, omega, Omega)`` violates (empty: inside the envelope)."""
        x = np.asarray(x, float)
        if not np.all(np.isfinite(x)):
            return ["non-finite state"]
        out = []
        p, eta, v, w, speeds = x[0:3], x[3:6], x[6:9], x[9:12], x[12:]
        outside = float(np.max(np.r_[self.workspace_min - p, p - self.workspace_max]))
        if outside > self.box_tolerance_m:
            out.append(f"{outside:.2f} m outside the workspace")

        tilt = np.degrees(np.arccos(np.clip(np.cos(eta[0]) * np.cos(eta[1]), -1.0, 1.0)))
        if tilt > self.max_tilt_deg:
            out.append(f"tilt {tilt:.0f} deg > {self.max_tilt_deg:g}")
        if np.linalg.norm(v) > self.max_speed_m_s:
            out.append(f"speed {np.linalg.norm(v):.1f} m/s > {self.max_speed_m_s:g}")
        if np.max(np.abs(w)) > self.max_body_rate_rad_s:
            out.append(f"body rate {np.max(np.abs(w)):.1f} rad/s > {self.max_body_rate_rad_s:g}")
        if speeds.min() < 0.99 * self.omega_min or speeds.max() > 1.01 * self.omega_max:
            out.append(f"motor speeds [{speeds.min():.1f}, {speeds.max():.1f}] Hz outside [{self.omega_min:g}, {self.omega_max:g}]")
        return out
