"""Flight-safety supervisor: a safety envelope checked on the measured state, independent of the QP.

A solver can report success while the relay flips or leaves the world (e.g. an alignment
threshold mu = 0.99 the platform cannot meet). The envelope is the workspace box (plus a
tolerance), the ground and the obstacles (no tolerance), a body tilt limit, a speed limit, a body-rate limit and the motor speed bounds; a
state outside it hands the relay to the fail-safe brake law at once (``control/relay.py``),
whatever the QP status says; the NMPC takes over again only once the relay is at rest, and after
``max_handovers`` hand-overs not at all. The limits sit above what the nominal presets fly (tilt
<= 31 deg, speed <= 7.3 m/s, body rates <= 4.6 rad/s on the coplanar mission), so the supervisor
never triggers on them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..models.obstacles import Obstacle
from ..models.state import PITCH, ROLL, V, unpack
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
    ground_z_m: float = -math.inf  # the ground's height (m, world): below it is a violation, whatever the tolerance
    obstacles: tuple[Obstacle, ...] = ()  # the obstacles themselves (no margin): inside one is a violation
    _lo: list[float] = field(init=False, repr=False, compare=False, default_factory=list)
    _hi: list[float] = field(init=False, repr=False, compare=False, default_factory=list)
    _cos_max_tilt: float = field(init=False, repr=False, compare=False, default=1.0)

    def __post_init__(self):  # plain floats for the per-step check
        object.__setattr__(self, "_lo", [float(v) for v in self.workspace_min])
        object.__setattr__(self, "_hi", [float(v) for v in self.workspace_max])
        object.__setattr__(self, "_cos_max_tilt", math.cos(math.radians(self.max_tilt_deg)))

    @classmethod
    def for_vehicle(cls, vehicle: Multirotor, workspace_min, workspace_max, **limits) -> SafetyEnvelope:
        return cls(np.asarray(workspace_min, float), np.asarray(workspace_max, float), vehicle.omega_min, vehicle.omega_max,
                   **limits)

    def at_rest(self, x: np.ndarray) -> bool:
        """Slow and nearly level: where the NMPC may take over again after a hand-over."""
        x = np.asarray(x, float)
        tilt = np.degrees(np.arccos(np.clip(np.cos(x[ROLL]) * np.cos(x[PITCH]), -1.0, 1.0)))
        return bool(np.linalg.norm(x[V]) < self.rest_speed_m_s and tilt < self.rest_tilt_deg)

    def violations(self, x: np.ndarray) -> list[str]:
        """What the state ``(p, eta, v, omega, Omega)`` violates (empty: inside the envelope).
        Scalar arithmetic: this runs every control step (a few microseconds)."""
        vals = np.asarray(x, float).tolist()
        if not all(math.isfinite(a) for a in vals):
            return ["non-finite state"]
        out = []
        lo, hi = self._lo, self._hi
        pos, eta, vel, rates, speeds = unpack(vals)
        outside = max(max(lo[i] - pos[i], pos[i] - hi[i]) for i in range(3))
        if outside > self.box_tolerance_m:
            out.append(f"{outside:.2f} m outside the workspace")
        if pos[2] < self.ground_z_m:
            out.append(f"below the ground ({pos[2] - self.ground_z_m:.2f} m)")
        for i, o in enumerate(self.obstacles):
            depth = float(o.signed_distance(pos))
            if depth < 0:
                out.append(f"{-depth:.2f} m inside obstacle {i}")
        cos_tilt = math.cos(eta[0]) * math.cos(eta[1])  # roll, pitch
        if cos_tilt < self._cos_max_tilt:
            out.append(f"tilt {math.degrees(math.acos(max(-1.0, min(1.0, cos_tilt)))):.0f} deg > {self.max_tilt_deg:g}")
        speed = math.sqrt(vel[0] ** 2 + vel[1] ** 2 + vel[2] ** 2)
        if speed > self.max_speed_m_s:
            out.append(f"speed {speed:.1f} m/s > {self.max_speed_m_s:g}")
        rate = max(abs(rates[0]), abs(rates[1]), abs(rates[2]))
        if rate > self.max_body_rate_rad_s:
            out.append(f"body rate {rate:.1f} rad/s > {self.max_body_rate_rad_s:g}")
        if min(speeds) < 0.99 * self.omega_min or max(speeds) > 1.01 * self.omega_max:
            out.append(f"motor speeds [{min(speeds):.1f}, {max(speeds):.1f}] Hz outside [{self.omega_min:g}, {self.omega_max:g}]")
        return out

