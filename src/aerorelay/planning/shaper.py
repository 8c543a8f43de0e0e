"""One reference shaper for every capacity-seeking planner, one relay or a fleet's every relay.

A planner picks a goal (position, m, world) and an antenna-axis goal (unit, world); the shaper turns
them into a reference the NMPC can fly (``trajectory_generator.Reference``'s ``p_ref``, ``v_ref``,
``a_ref``, ``axis``):

- the velocity points at the goal at most ``speed_m_s``, slow enough to stop on it at
  ``brake_accel_m_s2`` (``v <= sqrt(2 a d)``), changing by at most ``max_accel_m_s2 * dt`` per step,
  landing on the goal in the step that would pass it;
- the acceleration feed-forward is the velocity's change low-passed (time constant ``accel_tau_s``)
  and bounded by ``max_accel_m_s2``;
- the axis turns toward its goal along the great circle at most ``axis_rate_deg_s``; a tilted
  platform holds it relative to the thrust its acceleration needs (``geometry.align_with_thrust``);
- a level-only platform (``tilt_limit`` 0) moves only by tilting, its thrust direction read from
  ``a_ref``: the acceleration a critically damped PD law at ``tracking_freq_rad_s`` asks toward the
  reference is added (bounded like the reference's own).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..models.geometry import E3, align_with_thrust, clip_norm


@dataclass(frozen=True, kw_only=True)
class ShaperSettings:
    """Speed (m/s), accelerations (m/s^2), the acceleration filter's time constant (s), the axis
    turn rate (deg/s), the level-only tracking frequency (rad/s), the platform's hover tilt limit
    (rad; 0: level-only) and gravity (m/s^2)."""

    speed_m_s: float = 1.0
    max_accel_m_s2: float = 4.0
    brake_accel_m_s2: float = 1.5
    accel_tau_s: float = 0.3
    axis_rate_deg_s: float = 30.0
    tracking_freq_rad_s: float = 1.0
    tilt_limit: float = 0.0
    gravity: float = 9.81


class ReferenceShaper:
    """The reference of one relay (see the module docstring): its state ``p_ref`` (m), ``v_ref``
    (m/s), ``a_ref`` (m/s^2), ``axis`` (unit), world frame."""

    def __init__(self, settings: ShaperSettings):
        self.settings = settings
        self.speed, self.max_accel = settings.speed_m_s, settings.max_accel_m_s2
        self.brake_accel = min(settings.brake_accel_m_s2, settings.max_accel_m_s2)
        self.axis_rate = np.radians(settings.axis_rate_deg_s)
        self.p_ref: np.ndarray | None = None
        self.v_ref, self.a_ref = np.zeros(3), np.zeros(3)
        self.axis = E3.copy()

    def velocity_toward(self, d_vec: np.ndarray, dt: float) -> np.ndarray:
        """Reference velocity (m/s, world) toward a goal ``d_vec`` (m) away: at most ``speed``, slow
        enough to stop on it at ``brake_accel`` (v <= sqrt(2 a d)), changing by <= ``max_accel dt``
        per step (a reference that jumps from 3 m/s to rest overshoots by metres; one that brakes
        at 4 m/s^2 left a tilted relay holding its antenna 0.9 m past it, motors at their bounds)."""
        d = float(np.linalg.norm(d_vec))
        if d < 1e-9:
            v_des = np.zeros(3)
        else:
            v_des = d_vec / d * min(self.speed, np.sqrt(2.0 * self.brake_accel * d))
        dv = v_des - self.v_ref
        n = float(np.linalg.norm(dv))
        if n > self.max_accel * dt:
            dv *= self.max_accel * dt / n
        v = self.v_ref + dv
        if float(np.linalg.norm(v)) * dt >= d:  # would pass the goal within the step: land on it
            return d_vec / dt
        return v

    def advance(self, goal: np.ndarray, dt: float) -> np.ndarray:
        """One step toward ``goal`` (m): ``p_ref`` and ``v_ref`` moved, ``a_ref`` the velocity's change
        low-passed (``accel_tau_s``) and bounded; returns the step's ``v_ref`` (m/s)."""
        assert self.p_ref is not None  # start() first
        v_ref = self.velocity_toward(goal - self.p_ref, dt)
        self.p_ref = self.p_ref + v_ref * dt
        alpha = min(1.0, dt / self.settings.accel_tau_s)
        a_raw = (v_ref - self.v_ref) / dt
        self.a_ref = (1 - alpha) * self.a_ref + alpha * a_raw
        n = float(np.linalg.norm(self.a_ref))
        if n > self.max_accel:
            self.a_ref *= self.max_accel / n
        self.v_ref = v_ref
        return v_ref

    def turn_axis(self, axis_goal: np.ndarray, dt: float) -> None:
        """Rotate the axis reference toward ``axis_goal`` at <= ``axis_rate`` (great-circle step)."""
        c = float(np.clip(self.axis @ axis_goal, -1.0, 1.0))
        ang = np.arccos(c)
        if ang < 1e-9:
            return
        frac = min(1.0, self.axis_rate * dt / ang)
        v = (1 - frac) * self.axis + frac * axis_goal
        self.axis = v / np.linalg.norm(v)

    def held_axis(self, axis_now: np.ndarray) -> np.ndarray | None:
        """The body-z reference of a tilted platform: ``axis_now`` held relative to the thrust ``a_ref``
        needs; None for a level-only platform (its thrust direction follows ``a_ref``)."""
        return align_with_thrust(axis_now, self.a_ref, self.settings.gravity) if self.settings.tilt_limit > 0 else None

    def with_tracking(self, p1: np.ndarray, v1: np.ndarray | None, a_ref: np.ndarray) -> np.ndarray:
        """A level-only platform moves only by tilting, and its thrust-direction reference comes
        from ``a_ref``: a reference at rest asks it to stay level, and the NMPC's thrust-direction
        weight then holds the relay off a reference it has drifted from (0.66 m for 7 s at the
        coplanar corner). The tracking acceleration a PD law would ask (critically damped,
        ``tracking_freq`` rad/s) toward the reference from the measured ``p1`` (m), ``v1`` (m/s; None:
        ``a_ref`` as it is) is added, bounded like the reference's own."""
        if v1 is None:
            return a_ref.copy()
        assert self.p_ref is not None
        w = self.settings.tracking_freq_rad_s
        return clip_norm(a_ref + w**2 * (self.p_ref - np.asarray(p1, float)) + 2.0 * w * (self.v_ref - np.asarray(v1, float)),
                         self.max_accel)

    def acceleration(self, p1: np.ndarray, v1: np.ndarray | None, axis: np.ndarray | None) -> np.ndarray:
        """The reference's acceleration feed-forward (m/s^2): ``a_ref`` for a tilted platform holding ``axis``,
        with the tracking law's for a level-only one (``axis`` None)."""
        return self.a_ref.copy() if axis is not None else self.with_tracking(p1, v1, self.a_ref)
