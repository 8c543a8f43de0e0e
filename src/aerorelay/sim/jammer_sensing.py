"""The relay's view of the jammers when it is not told (``jammer.localization = "estimated"``).

Each control step the relay's receiver (and the base station's, when it reports) reads its true
interference plus noise (``ChannelState.interference`` of the hop it receives, with every fading
and shadowing term of the plant) through an energy detector (``models/sensing.py``); the
estimator (``estimation/jammer_estimator.py``) folds the readings in; the planner gets the
estimate: a jammer enters the plan once its estimate is confident (before that the planner plans
without it, as before ``tau_E`` with the oracle), with its estimated power (0 while it is
estimated OFF, when the controller senses the schedule). Log columns: ``meas_<receiver>_w``,
``estimator_ms`` and per jammer (the estimate matched to it: estimates carry no names, so each step
they are assigned to the true jammers by least total distance) ``est_<name>_x/_y/_z`` (m), ``_power_w``, ``_on_prob``,
``_std_m`` (largest position std), ``_err_m`` (distance to the true position), the position
covariance ``_cov_xx ... _cov_yz`` (m^2) and ``_crlb_m``: the Cramer-Rao bound of the position
(largest std, m) from every measurement so far, at the true jammers, under the estimator's
measurement model with the search box as a prior: what the relay's path made knowable, which no
unbiased estimator beats (static jammers, or jammers on linear paths with their velocity unknown;
NaN for a directional jammer or a curved path, which that model does not hold).
"""

from __future__ import annotations

import time

import numpy as np
from scipy.optimize import linear_sum_assignment

from ..estimation.jammer_estimator import JammerEstimate, JammerEstimator
from ..models.antenna import IsotropicPattern
from ..models.radio import ChannelState, NodePose, RadioScene
from ..models.sensing import EnergyDetector
from ..models.streams import stream
from .log_schema import COV_ENTRIES


class JammerSensing:
    """Readings, estimator and log values; ``receivers``: node names that measure (the relay first)."""

    def __init__(self, scene: RadioScene, estimator: JammerEstimator, receivers: list[str], *, n_samples: int,
                 bias_db: float, seed: int):
        self.scene, self.estimator, self.receivers = scene, estimator, receivers
        rx_of_hop = {rx: k for k, (_, rx) in enumerate(scene.hops)}
        missing = [r for r in receivers if r not in rx_of_hop]
        if missing:
            raise ValueError(f"estimation: {missing} receive no hop of the route {list(scene.route)}: nothing to measure")
        self.hop_of = [rx_of_hop[r] for r in receivers]
        self.detector = EnergyDetector(n_samples, bias_db, seed=stream(seed, "detector"))
        self.noise = scene.budget.noise_power
        self.names = [j.name for j in scene.jammers]
        self.columns = [f"meas_{r}_w" for r in receivers] + ["estimator_ms"] + [
            f"est_{n}_{q}" for n in self.names
            for q in ("x", "y", "z", "power_w", "on_prob", "std_m", "trusted", "err_m", "crlb_m", *(f"cov_{c}" for c, _, _ in COV_ENTRIES))]
        self.last_ms = 0.0
        self.crlb = InformationMeter(estimator, scene)

    @property
    def estimate(self) -> JammerEstimate:
        return self.estimator.estimate

    def step(self, t: float, channel: ChannelState, poses: dict[str, NodePose]) -> dict[str, float]:
        """Read every receiver, update the estimator (timed), and the row's log values."""
        values: dict[str, float] = {}
        readings = []
        for r, hop in zip(self.receivers, self.hop_of, strict=True):
            y = float(self.detector.measure(float(channel.interference[hop]) + self.noise))
            readings.append(y)
            values[f"meas_{r}_w"] = y
        t0 = time.perf_counter()
        e = self.estimator.add_readings(t, [(poses[r].position, poses[r].axis, y) for r, y in zip(self.receivers, readings, strict=True)])
        self.last_ms = (time.perf_counter() - t0) * 1e3
        values["estimator_ms"] = self.last_ms
        crlb = self.crlb.update(t)
        std = e.position_std_max()
        match, err = match_estimates(np.array([j.position_at(t) for j in self.scene.jammers]), e.positions)
        for i, (n, k) in enumerate(zip(self.names, match, strict=True)):
            p = e.positions[k]
            values.update({f"est_{n}_x": p[0], f"est_{n}_y": p[1], f"est_{n}_z": p[2], f"est_{n}_power_w": e.powers[k],
                           f"est_{n}_on_prob": e.on_prob[k], f"est_{n}_std_m": std[k], f"est_{n}_trusted": float(e.confident[k]),
                           f"est_{n}_err_m": err[i], f"est_{n}_crlb_m": crlb[i]})
            for c, a, b in COV_ENTRIES:
                values[f"est_{n}_cov_{c}"] = e.covariances[k, a, b]
        return values


def match_estimates(truth: np.ndarray, estimates: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Which estimate ``(nJ, 3)`` belongs to which true jammer ``(nJ, 3)`` (m): the assignment of least
    total distance (the estimator does not know which jammer is which). ``(match, error)``: true jammer
    ``i`` gets estimate ``match[i]`` at distance ``error[i]`` (m)."""
    dist = np.linalg.norm(estimates[None, :, :] - truth[:, None, :], axis=-1)
    rows, match = linear_sum_assignment(dist)
    return match, dist[rows, match]


class InformationMeter:
    """The Cramer-Rao bound of the jammers' positions from the estimator's measurements so far: their
    Fisher information at the true jammers (``JammerEstimator.information``, each measurement once,
    nothing forgotten) plus the search box as a prior (uniform: variance side^2 / 12 per axis; log
    EIRP std 10; velocity std 10 m/s). Defined for isotropic jammers with power that are static, or
    all move at a constant velocity (a linear path: then position at t = 0, log EIRP and velocity
    are the unknowns, and the bound is the position's at the time asked); NaN otherwise."""

    def __init__(self, estimator: JammerEstimator, scene):
        self.estimator, self.jammers = estimator, scene.jammers
        nj = len(self.jammers)
        velocities = [_constant_velocity(j) for j in self.jammers]
        self.moving = any(j.path is not None for j in self.jammers)
        self.defined = all(isinstance(j.pattern, IsotropicPattern) and j.power > 0 for j in self.jammers) and all(
            v is not None for v in velocities)
        self.n = 7 if self.moving else 4  # parameters per jammer
        box = 12.0 / (estimator.hi - estimator.lo) ** 2
        self.info = np.diag(np.tile(np.r_[box, 1e-2, np.full(3, 1e-2)][:self.n], nj))
        self.seen = 0
        if self.defined:
            self.theta = np.array([np.r_[j.position_at(0.0), np.log(j.power * j.pattern.g_bar), v][:self.n]
                                   for j, v in zip(self.jammers, velocities, strict=True)])
        self.bound = self._position_bound(0.0) if self.defined else np.full(nj, np.nan)

    def _position_bound(self, t: float) -> np.ndarray:
        cov = np.linalg.inv(self.info)
        at_t = np.hstack([np.eye(3), np.zeros((3, 1)), t * np.eye(3)])[:, :self.n]  # position at t from the unknowns
        n = self.n
        return np.array([np.sqrt(np.linalg.eigvalsh(at_t @ cov[n * k:n * k + n, n * k:n * k + n] @ at_t.T)[-1])
                         for k in range(len(self.jammers))])

    def update(self, t: float) -> np.ndarray:
        """Fold in the measurements assimilated since the last call; the bound per jammer (m) at ``t`` (s)."""
        w = self.estimator.window
        new = min(w.appended - self.seen, len(w))
        self.seen = w.appended
        if not self.defined:
            return self.bound
        if new > 0:
            idx = np.arange(w.hi - new, w.hi)
            on = np.array([[bool(j.schedule.is_on(ti)) for ti in w.t[idx]] for j in self.jammers])
            self.info = self.info + self.estimator.information(self.theta, on, idx, 0.0)
        if new > 0 or self.moving:
            self.bound = self._position_bound(t)
        return self.bound


def _constant_velocity(jammer) -> np.ndarray | None:
    """A jammer's velocity (m/s): zero when static, its constant velocity on a linear path, None when it varies."""
    if jammer.path is None:
        return np.zeros(3)
    times = np.linspace(0.0, jammer.path.duration, 7)[1:-1]
    v = np.array([jammer.path.state(t).v for t in times])
    return v[0] if np.allclose(v, v[0], atol=1e-9) else None
