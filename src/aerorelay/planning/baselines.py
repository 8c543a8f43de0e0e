"""Baseline relay planners of the paper's comparison (Sec. VIII-E).

- Baseline A (``controller.planner = "isotropic"``): a point-mass relay with isotropic antennas
  (``G = G_bar`` at every end) maximizing the end-to-end capacity: the trajectory generator with
  the isotropic surrogate (``mu = 1``), speed-bounded by the reference governor, tracked by the
  position-tracking NMPC without alignment terms (``controller.variant = "unconstrained"``).
- Baseline B (``controller.planner = "single_shot"``): ``SingleShotPlanner`` plans the relay's
  whole trajectory once, before take-off, from MRAV-2's mission plan, with the scene's antenna gains and
  each vehicle's antenna tilted with its acceleration (coplanar point masses), but with no jammer
  model, no actuator-rate limits and no replanning; the NMPC without alignment penalty tracks it.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np
from scipy.interpolate import CubicSpline

from ..models.geometry import E3
from ..models.radio import NodePose, RadioScene
from .trajectory_generator import Reference


@dataclass
class SingleShotPlan:
    t: np.ndarray  # knot times, s
    p: np.ndarray  # (K, 3) relay positions, m
    mean_capacity: float  # planner's own objective (no jammer), bit/s/Hz
    success: bool


class SingleShotPlanner:
    """Offline max-mean-capacity relay trajectory (baseline B), solved once by IPOPT.

    Knots every ``dt`` s; velocities and accelerations by finite differences; the relay's and
    MRAV-2's antenna axes along ``(a + g e3)/|a + g e3|``; the scene's antennas (their symbolic,
    NLP-smooth forms) and fixed nodes; no jammer. The relay speed between knots is bounded by
    ``max_speed`` (the same bound as the other planners) and a small acceleration penalty keeps
    the plan trackable.
    """

    def __init__(self, scene: RadioScene, *, dt: float = 0.5, max_speed: float = 0.5, gravity: float = 9.81,
                 accel_weight: float = 1e-4):
        self.scene = scene
        self.dt, self.max_speed, self.g, self.accel_weight = dt, max_speed, gravity, accel_weight

    def plan(self, source, p1_start, duration: float, workspace_min, workspace_max) -> SingleShotPlan:
        K = int(np.ceil(duration / self.dt)) + 1
        t = np.arange(K) * self.dt
        st = [source.state(tk) for tk in t]
        p2 = np.array([s.p for s in st])
        rho2 = np.array([s.a + self.g * E3 for s in st])
        rho2 /= np.linalg.norm(rho2, axis=1, keepdims=True)
        P = ca.MX.sym("p", 3, K)
        no_jammer = np.zeros(len(self.scene.jammers))
        src, relay = self.scene.name_of("source"), self.scene.name_of("relay")
        caps, g = [], []
        for k in range(K):
            a = (P[:, max(k - 1, 0)] - 2 * P[:, k] + P[:, min(k + 1, K - 1)]) / self.dt**2 if 0 < k < K - 1 else ca.DM.zeros(3)
            rho1 = (a + self.g * ca.DM(E3)) / ca.norm_2(a + self.g * ca.DM(E3))
            poses = {src: NodePose(ca.DM(p2[k]), ca.DM(rho2[k])), relay: NodePose(P[:, k], rho1)}
            caps.append(self.scene.evaluate(float(t[k]), poses, jammer_powers=no_jammer).capacity)  # eq. 5-9
            if k + 1 < K:
                g.append(ca.sumsqr(P[:, k + 1] - P[:, k]))
        acc = sum(ca.sumsqr(P[:, k - 1] - 2 * P[:, k] + P[:, k + 1]) for k in range(1, K - 1)) / self.dt**4
        mean_c = sum(caps) / K
        nlp = {"x": ca.vec(P), "f": -mean_c * 1e3 + self.accel_weight * acc, "g": ca.vertcat(*g)}
        solver = ca.nlpsol("single_shot", "ipopt", nlp, {"ipopt.print_level": 0, "ipopt.sb": "yes", "print_time": False,
                                                           "ipopt.max_iter": 500, "ipopt.tol": 1e-6})
        lo = np.tile(np.asarray(workspace_min, float)[:, None], (1, K))
        hi = np.tile(np.asarray(workspace_max, float)[:, None], (1, K))
        lo[:, 0] = hi[:, 0] = p1_start
        guess = np.tile(np.asarray(p1_start, float)[:, None], (1, K))
        sol = solver(x0=ca.vec(ca.DM(guess)), lbx=ca.vec(ca.DM(lo)), ubx=ca.vec(ca.DM(hi)),
                     lbg=0.0, ubg=(self.max_speed * self.dt) ** 2)
        p = np.array(sol["x"]).reshape(K, 3)  # column-major vec of a 3 x K matrix
        value = float(ca.Function("c", [ca.vec(P)], [mean_c])(sol["x"]))
        return SingleShotPlan(t, p, value, bool(solver.stats()["success"]))


class PlannedReference:
    """Feeds a precomputed plan to the NMPC: position, velocity and acceleration from a cubic spline."""

    def __init__(self, plan: SingleShotPlan, max_ref_accel: float = 2.0):
        self.plan = plan
        self.spline = CubicSpline(plan.t, plan.p, axis=0, bc_type="clamped")
        self.max_ref_accel = max_ref_accel

    def update(self, t: float) -> Reference:
        tt = float(np.clip(t, self.plan.t[0], self.plan.t[-1]))
        p = self.spline(tt)
        v = self.spline(tt, 1)
        a = self.spline(tt, 2)
        n = np.linalg.norm(a)
        if n > self.max_ref_accel:
            a = a * self.max_ref_accel / n
        return Reference(p_opt=p.copy(), p_ref=p.copy(), v_ref=v, a_ref=a)
