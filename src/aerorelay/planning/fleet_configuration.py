"""A fleet's configuration at one instant on the true network rate: its rate, each relay's best
holdable axis, and positions and axes refined jointly (the network bound's ``achieved``); and a flyable
fleet path over a mission (``flyable_fleet_path``: the network bound's lower path bound and the fleet
planner's pre-flight route).

A configuration is every relay's position ``(K, 3)`` (m, world) and antenna axis ``(K, 3)`` (unit,
world), relays in ``relays`` order; the other nodes' poses come in ``poses`` (name -> ``NodePose``).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from scipy.optimize import minimize

from ..models.axes import axis_cone, tilted_axes
from ..models.geometry import rotation_zyx
from ..models.mission import SourceTrajectory
from ..models.obstacles import inside_any
from ..models.radio import NodePose, RadioScene
from .feasible_path import FleetPath, best_feasible_fleet_path, fleet_thrust_directions, speed_limited


class FleetConfigurations:
    """Configurations of ``relays`` in ``scene`` inside the box ``[lo, hi]`` (m), each relay's axis within
    its hover tilt limit (``tilt_limits``, rad; cones every ``axis_step_rad``), every relay at least
    ``separation_m`` (m) from the other nodes and from each other and outside ``obstacles``; the jammers at
    ``jammer_positions`` (m, ``(nJ, 3)``) radiating ``jammer_powers`` (W, ``(nJ,)``; None: the scene's own)."""

    def __init__(self, scene: RadioScene, relays: Sequence[str], lo, hi, tilt_limits: Mapping[str, float],
                 axis_step_rad: float, separation_m: float = 0.0, obstacles: tuple = (), jammer_positions=None,
                 jammer_powers=None):
        self.scene, self.relays = scene, list(relays)
        self.lo, self.hi = np.asarray(lo, float), np.asarray(hi, float)
        self.tilt_limits = dict(tilt_limits)
        self.cones = {r: axis_cone(self.tilt_limits[r], axis_step_rad) for r in self.relays}
        self.separation_m, self.obstacles = separation_m, obstacles
        self.jammer_positions, self.jammer_powers = jammer_positions, jammer_powers

    def rate(self, t: float, positions: np.ndarray, axes: np.ndarray, poses) -> float:
        """The true network rate with the relays at ``positions`` ``(K, 3)`` with antenna ``axes`` ``(K, 3)``."""
        relay_poses = {r: NodePose(positions[k], axes[k]) for k, r in enumerate(self.relays)}
        with np.errstate(divide="ignore", invalid="ignore"):
            rate = self.scene.evaluate(t, {**poses, **relay_poses}, jammer_positions=self.jammer_positions,
                                       jammer_powers=self.jammer_powers).capacity
            return float(np.nan_to_num(rate, nan=0.0))

    def best_axes(self, t: float, P: np.ndarray, poses, thrust: np.ndarray | None = None) -> np.ndarray:
        """Each relay's best axis of its cone for the relays at ``P`` ``(K, 3)`` on the true rate, one
        relay at a time, twice round (``(K, 3)``, unit, world); with ``thrust`` ``(K, 3)`` (unit: where each
        relay's body z must lean to fly its path) only the axes within its tilt limit of it (the nearest
        where none is)."""
        choices = []
        for k, r in enumerate(self.relays):
            cone = self.cones[r]
            if thrust is not None:
                cos = cone @ thrust[k]
                held = cos >= np.cos(self.tilt_limits[r]) - 1e-12
                cone = cone[held] if held.any() else cone[[int(np.argmax(cos))]]
            choices.append(cone)
        return coordinate_best_axes(choices, lambda batch: [self.rate(t, P, A, poses) for A in batch])[0]

    def refine(self, t: float, start: np.ndarray, poses) -> tuple[float, np.ndarray, np.ndarray]:
        """The relays from ``start`` ``(K, 3)`` (m) refined on the true rate: each relay's best cone axis there
        (one at a time), then every position and (tilt, azimuth) jointly inside the box and tilt limits
        (L-BFGS-B; SLSQP with the separation from every node in ``poses`` and between relays). Returns the
        rate, positions and axes; the start's when the solve ends worse, outside the separation or in an
        obstacle."""
        if not self.relays:  # the direct link: nothing to place, the rate is the fixed nodes'
            none = np.zeros((0, 3))
            return self.rate(t, none, none, poses), none, none
        P = np.clip(np.asarray(start, float), self.lo, self.hi)  # a cell may reach past the box: its centre brought in
        A = self.best_axes(t, P, poses)
        limits = [self.tilt_limits[r] for r in self.relays]
        tilt0 = np.arccos(np.clip(A[:, 2], -1, 1))
        az0 = np.arctan2(A[:, 1], A[:, 0])
        x0 = np.concatenate([P.ravel(), tilt0, az0])
        K = len(self.relays)

        def unpack(x):
            return x[: 3 * K].reshape(K, 3), tilted_axes(x[3 * K : 4 * K], x[4 * K :])

        scale = 1.0 / self.scene.budget.bandwidth  # in bit/s/Hz: unscaled (Mbit/s as bit/s) SLSQP stopped on
        # "Inequality constraints incompatible" at the start (18.41 against 17.68 Mbit/s, network study K = 2, 120 m)

        def neg(x):
            return -self.rate(t, *unpack(x), poses) * scale

        bounds = [(lo, hi) for _ in range(K) for lo, hi in zip(self.lo, self.hi, strict=True)]
        bounds += [(0.0, lim) for lim in limits] + [(None, None)] * K
        sep = self.separation_m
        if sep <= 0:
            res = minimize(neg, x0, method="L-BFGS-B", bounds=bounds, options={"maxiter": 80})
        else:  # every relay the separation from the fixed nodes and from every other relay (m^2 margins >= 0)
            fixed = np.array([p.position for p in poses.values()])

            def margins(x):
                P = x[: 3 * K].reshape(K, 3)
                out = [(np.sum((P[:, None, :] - fixed[None, :, :]) ** 2, axis=-1) - sep**2).ravel()]
                out += [[np.sum((P[i] - P[j]) ** 2) - sep**2 for i in range(K) for j in range(i + 1, K)]]
                return np.concatenate(out)
            res = minimize(neg, x0, method="SLSQP", bounds=bounds, constraints=[{"type": "ineq", "fun": margins}],
                           options={"maxiter": 80})
            if np.min(margins(res.x)) < -1e-6:
                res.fun = np.inf  # ended outside the separation: keep the start
        better = -res.fun >= -neg(x0) and not np.any(inside_any(self.obstacles, unpack(res.x)[0]))
        P, A = unpack(res.x if better else x0)
        return self.rate(t, P, A, poses), P, A


def coordinate_best_axes(choices: Sequence[np.ndarray], score) -> tuple[np.ndarray, float]:
    """Each relay's best axis among its ``choices[k]`` ``(n_k, 3)`` (unit, world), one relay at a time from vertical
    with the others held, twice round; ``score(axes (n, K, 3))`` rates a batch of the fleet's axes ``(n,)``. The axes
    ``(K, 3)`` and the last choice's score (the rate at those axes)."""
    A = np.tile([0.0, 0.0, 1.0], (len(choices), 1))
    best = -np.inf
    for _ in range(2):
        for k, cone in enumerate(choices):
            batch = np.repeat(A[None], len(cone), axis=0)
            batch[:, k] = cone
            scores = np.asarray(score(batch), float)
            j = int(np.argmax(scores))
            A[k], best = cone[j], float(scores[j])
    return A, best


def mission_poses(scene: RadioScene, sources: Mapping[str, SourceTrajectory], t: float, gravity: float) -> dict[str, NodePose]:
    """Every source at its pose on its mission at ``t`` (s; its antenna along its thrust), the fixed nodes as placed."""
    poses = {n.name: scene.fixed_pose(n.name) for n in scene.nodes if n.position is not None}
    for name, path in sources.items():
        s = path.state(t)
        poses[name] = scene.pose(name, s.p, rotation_zyx(s.attitude(gravity)))
    return poses


def flyable_fleet_path(configs: FleetConfigurations, times: np.ndarray, targets: np.ndarray, starts: np.ndarray,
                       poses: Sequence[Mapping[str, NodePose]], *, speed_m_s: float, accel_m_s2: float | None, gravity: float,
                       max_iter: int = 300) -> FleetPath:
    """A flyable path of ``configs``' relays over ``times`` (s): each relay from its start (``starts`` ``(K, 3)``, m,
    at rest) chasing ``targets`` ``(T, K, 3)`` at most ``speed_m_s`` and changing its move by at most
    ``accel_m_s2 dt^2`` per sample (``feasible_path.speed_limited``) with its best axis it can hold while leaning
    for that path (``best_axes``), then every relay's positions and axes optimized together on the network's rate
    as ``configs`` sees it (its jammers), the other nodes at ``poses[i]`` (``feasible_path.best_feasible_fleet_path``:
    the speed and acceleration limits, each axis within its tilt limit of its thrust, ``configs.separation_m``
    from every node after the start)."""
    lo, hi, relays = configs.lo, configs.hi, configs.relays
    dt = float(times[1] - times[0]) if len(times) > 1 else 1.0
    dv = None if accel_m_s2 is None else accel_m_s2 * dt**2
    P = np.stack([np.clip(speed_limited(targets[:, k], np.clip(starts[k], lo, hi), speed_m_s * dt, dv), lo, hi)
                  for k in range(len(relays))], axis=1)
    thrust = fleet_thrust_directions(P, dt, gravity)
    A0 = np.stack([configs.best_axes(float(t), P[i], poses[i], thrust[i]) for i, t in enumerate(times)])
    angles = np.stack([np.arccos(np.clip(A0[..., 2], -1.0, 1.0)), np.arctan2(A0[..., 1], A0[..., 0])], axis=-1)
    fixed = np.stack([np.array([p.position for p in pz.values()]) for pz in poses])

    def capacity(t: float, positions: list, axes: list):
        i = int(np.argmin(np.abs(times - t)))
        relay_poses = {r: NodePose(positions[k], axes[k]) for k, r in enumerate(relays)}
        return configs.scene.evaluate(t, {**poses[i], **relay_poses}, jammer_positions=configs.jammer_positions,
                                      jammer_powers=configs.jammer_powers).capacity

    return best_feasible_fleet_path(capacity, times, P, lo, hi, speed_m_s, [configs.tilt_limits[r] for r in relays], gravity,
                                    "mean", max_iter=max_iter, max_accel=accel_m_s2, a0=angles,
                                    separation_m=configs.separation_m, fixed=fixed)
