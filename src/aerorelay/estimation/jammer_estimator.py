"""Online jammer estimation: each jammer's position and power from measured interference-plus-noise power.

The paper hands the controller the jammer's true position ``tau_E`` after take-off (an oracle).
Here every receiver that measures (the relay; the base station when it reports) gives one
energy-detector reading per control step (``models/sensing.py``); ``aggregate_steps`` readings
are averaged into one measurement (the pose moves little in that time; the sample counts add).
The estimator knows each receiver's pose and antenna pattern, the noise power and the
deterministic path gain, and models each jammer as isotropic with unknown position ``p_j`` (m,
world) and EIRP ``P_j`` (W):

    y = N + sum_j s_j P_j g(p_j; receiver),   z = 10 log10 y + E[10 log10 X] + e

``g`` is the one channel implementation's ``link_gain`` (``models/radio.py``), ``s_j`` whether
jammer j radiates (a two-state Markov chain per jammer), ``e`` the detector's log noise plus
``model_error_db`` for what the model leaves out (fading, shadowing, a directional pattern): a
floor, scaled up by the residuals' own scale when they are larger (read robustly: ``residual_scale2``; the cuts,
weights and ON/OFF flags are in those scaled sigmas, so a fade is not read as a switch); plus, per
measurement, what the receiver's axis uncertainty (``axis_error_deg`` and the spread of the axes
averaged into it) makes of the jammers' share of the reading: near an antenna null a reading says
little about where the jammer is (the Gauss-Newton cost is that heteroscedastic likelihood).

Per jammer:

1. **A point-mass (grid) Bayes filter with the power profiled out**: for every cell of a grid over
   the search box, the weighted least-squares sums of the excess power ``e = y - N - others``
   against the cell's gain (relative errors, forgotten with ``forget_s``) give the best power
   ``P* = S_ge / S_gg`` and the log-likelihood ``S_ge^2 / (2 S_gg)``, updated recursively per
   measurement. Its posterior is the global picture: flat when the jammer is off or too weak, two
   modes when the relay's path leaves a mirror ambiguity.
2. **Gauss-Newton (Levenberg-Marquardt) on a sliding window** of the measurements (log domain,
   the same weights) over ``(p_j, ln P_j)`` of every jammer jointly, started from the grid's best
   cell whenever the current estimate sits outside the grid posterior's mass: the precise local
   estimate. It fits every row of the window (``window_rows`` can thin them).
3. With two or more jammers, **a joint search for pairs** (``pair_search.py``): every pair of the
   best grid cells scored at once, the powers profiled out; the best pair is polished beside the
   estimate and replaces it when it fits the window better (jammers found one after the other can
   settle in a wrong pair of modes that compensate each other).

The reported covariance is the inverse of the Gauss-Newton information plus a prior (uniform in
the search box, a wide log power: a direction the window says nothing about keeps the prior's
spread), plus the grid posterior's spread about the estimate for a rival mode: an estimate the
data do not pin down, or one with a rival mode, keeps a wide covariance instead of collapsing
onto a wrong point. Residuals correlated in time (a lasting fade) divide the information by an AR(1) process's
variance factor (``residual_inflation``). An estimate on the search box's face is not trusted (``at_edge``).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import NamedTuple

import numpy as np

from ..models.antenna import AntennaPattern, IsotropicPattern
from ..models.geometry import E3
from ..models.propagation import PathGain
from ..models.radio import link_gain
from ..models.sensing import KAPPA_DB, detector_log_mean_db, detector_log_std_db
from .pair_search import best_pair
from .window import MeasurementWindow, PendingReadings, cell_grid

log = logging.getLogger(__name__)
_ISOTROPIC = IsotropicPattern(1.0)
_MIN_DISTANCE_M = 0.3  # a candidate nearer a receiver than this has its gain capped (the gain's pole)
_FD_STEP_M = 1e-6  # forward-difference step of the gain's position derivative
_WINDOW_FORGET_SPANS = 2.0  # the window holds this many forget_s (weights down to exp(-2))
_ON_PRIOR_LOGODDS = 2.0  # prior log-odds that a jammer radiates at a measurement
_RESEED_EVERY = 4  # refinements between two checks of a found jammer against the grid's best rival
_RIVAL_MASS = 0.05  # grid mass away from the estimate below this is not checked as a rival mode
_DISAGREE_ODDS = 20.0  # the grid's mass about its best rival cell over its mass about the estimate above this: the
# grid and the window disagree, the rival mode counts in full
_FACE_MASS = 0.5  # the grid's mass within a cell of the faces an estimate sits on above this: the widen hint is said
_HUBER_SIGMAS = 3.0  # residuals beyond this many sigma count linearly (robust to readings across a switch)
_NP = 7  # parameters per jammer: position (3), log EIRP, velocity (3)
_FLAG_NEIGHBOURS = 1  # a row's ON flag sums the likelihood ratio over this many fitted rows each side
_SLOPE_STEP = 1e-4  # central-difference step in the cosine of the pattern's log-gain slope
_MAX_LOG_SLOPE = 1e3  # 1/rad: a slope cap (a pattern's exact null has an infinite log slope)
_LOG_POWER_PRIOR = 10.0  # std of ln EIRP in the covariance's prior (a factor e^10 either way)
_JOINT_EVERY = 8  # refinements between two joint searches for pairs of jammers
_JOINT_CELLS = 256  # the pair search scores pairs among this many best single cells
_JOINT_ROWS = 30  # window rows the pair search scores on (evenly thinned)
_EDGE_CELLS = 0.25  # an estimate this many grid cells from a side or the top of the search box is at its edge
_MIN_PAIRS = 8  # consecutive rows of one receiver below which the residuals' correlation is not estimated
_MAX_RHO = 0.98  # their lag-1 correlation's cap: a variance 99x the independent rows'
_JOINT_POLISH = 6  # Levenberg-Marquardt iterations on the best pair before it is compared with the estimate


@dataclass(frozen=True, kw_only=True)
class Receiver:
    """A measuring receiver: its antenna pattern (the axis comes with each reading), noise power (W),
    and whether it is fixed (a base station: one pose for every reading, its gains computed once)."""

    name: str
    pattern: AntennaPattern
    noise_w: float
    fixed: bool = False


@dataclass(frozen=True, kw_only=True)
class EstimatorSettings:
    """See ``[estimation]`` (``config/sections.py``): times s, distances m, powers dB."""

    search_min: np.ndarray
    search_max: np.ndarray
    n_samples: int = 100
    aggregate_steps: int = 10
    grid_m: float = 2.5
    forget_s: float = 20.0
    model_error_db: float = 0.2
    axis_error_deg: float = 1.0
    jammer_speed_m_s: float = 0.0  # > 0: each jammer moves at a constant velocity, this the prior std per axis (m/s)
    switch_prob: float = 0.02
    confident_std_m: float = 1.5
    confirm_s: float = 0.0  # an estimate is trusted once confident this long without a break (s)
    # measurements Gauss-Newton fits: every one in the window (None), or at most this many, evenly thinned
    # and each weighted for those it stands for. Thinned to 60, the fitted subset changed from fit to fit
    # and the estimate swung across its valley by up to 3.8 m per refinement (a moving jammer seen from
    # one spot); measured in docs/concepts/estimator.md
    window_rows: int | None = None
    min_rows: int = 8  # Gauss-Newton starts after this many measurements
    refine_every: int = 2  # one Gauss-Newton iteration per this many measurement rounds


class _LmStep(NamedTuple):
    """One Levenberg-Marquardt iteration's outcome (``JammerEstimator._lm_step``)."""

    theta: np.ndarray  # the new iterate
    lam: float  # the next damping
    H: np.ndarray  # the Gauss-Newton Hessian at the old iterate, over the fitted columns
    cols: np.ndarray  # those columns
    chi2: float  # the window's reduced chi-square at the old iterate
    cost: float  # the window cost of the old iterate (_window_cost's)
    inflation: float = 1.0  # the variance's factor for residuals correlated in time (``residual_inflation``)
    scale2: float = 1.0  # the residuals' squared scale in model sigmas (``residual_scale2``)


@dataclass(frozen=True)
class _Candidate:
    """A restart the joint pair search proposed: parameters (positions at ``t_ref``, s), the jammers
    it counts as found, its damping and the polishing iterations left."""

    theta: np.ndarray
    found: np.ndarray
    lam: float
    left: int
    t_ref: float


@dataclass(frozen=True)
class JammerEstimate:
    """The estimate at one instant, per jammer: ``positions`` ``(nJ, 3)`` m, ``powers`` ``(nJ,)`` W
    (EIRP), ``covariances`` ``(nJ, 3, 3)`` m^2 of the position, ``on_prob`` (that it radiates now),
    ``position_std`` (m: sqrt of each covariance's top eigenvalue), ``confident`` (``position_std``
    below ``confident_std_m`` and not ``at_edge``), ``at_edge`` (found within a quarter grid cell of a side or the top of
    the search box: the jammer may be outside it, and no spread the window gives covers that)."""

    positions: np.ndarray
    powers: np.ndarray
    covariances: np.ndarray
    on_prob: np.ndarray
    position_std: np.ndarray
    confident: np.ndarray
    at_edge: np.ndarray | None = None

    def position_std_max(self) -> np.ndarray:
        """Largest position standard deviation per jammer (m), computed once with the covariance."""
        return self.position_std

    def planner_view(self, senses_state: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(positions (nJ, 3) m, powers (nJ,) W, position std (nJ,) m)`` a planner plans with: a jammer
        enters with its estimated power once it is confident (0 before), and, when the controller senses
        the schedule, only while it is more likely ON than OFF."""
        powers = np.where(self.confident, self.powers, 0.0)
        if senses_state:
            powers = np.where(self.on_prob > 0.5, powers, 0.0)
        return self.positions.copy(), powers, self.position_std_max()


class JammerEstimator:
    """Estimates ``n_jammers`` jammers from the readings of ``receivers`` (see the module docstring).

    Per control step: ``add(t, receiver, position, axis, reading_w)`` for each reading, then
    ``update(t) -> JammerEstimate``."""

    def __init__(self, n_jammers: int, receivers: list[Receiver], path_gain: PathGain, settings: EstimatorSettings,
                 period_s: float):
        if n_jammers < 1:
            raise ValueError("the estimator needs >= 1 jammer to estimate")
        self.nj, self.receivers, self.path, self.s = n_jammers, receivers, path_gain, settings
        self._noise = np.array([r.noise_w for r in receivers], float)
        self.lo, self.hi = np.asarray(settings.search_min, float), np.asarray(settings.search_max, float)
        self._max_var = float(np.max(self.hi - self.lo)) ** 2  # no position is less known than "somewhere in the box"
        self.cells, sides = cell_grid(self.lo, self.hi, settings.grid_m)
        self.spacing = float(sides.max())
        row_s = settings.aggregate_steps * period_s
        self.forget = math.exp(-row_s / settings.forget_s)
        n_eff = settings.n_samples * settings.aggregate_steps
        self.log_mean = detector_log_mean_db(n_eff)
        self.sigma2 = detector_log_std_db(n_eff) ** 2 + settings.model_error_db**2  # dB^2
        self.rel2 = self.sigma2 / KAPPA_DB**2  # the same as a relative power error
        self.axis_var = math.radians(settings.axis_error_deg) ** 2
        self.gain_cap = float(path_gain.gain_from_d2(_MIN_DISTANCE_M**2)) * max(r.pattern.g_bar for r in receivers)
        span = _WINDOW_FORGET_SPANS * settings.forget_s / row_s
        self.window = MeasurementWindow(int(math.ceil(span * len(receivers))) + 2,
                                        len(self.cells) if n_jammers >= 2 else 0)  # cell gains: the pair search's
        self.s_ge = np.zeros((n_jammers, len(self.cells)))
        self.s_gg = np.zeros((n_jammers, len(self.cells)))
        # per jammer [position at t_ref (m), log EIRP, velocity (m/s)]; the velocity stays 0 for static jammers
        self.theta = np.tile(np.r_[0.5 * (self.lo + self.hi), -np.inf, np.zeros(3)], (n_jammers, 1))
        self.t_ref = 0.0
        self.moving = settings.jammer_speed_m_s > 0.0
        self._free = np.r_[np.ones(4, bool), np.full(3, self.moving)]  # the parameters Gauss-Newton fits
        self._vel_info = 1.0 / settings.jammer_speed_m_s**2 if self.moving else 0.0
        # the covariance's prior information per parameter: uniform in the box (12 / side^2), log EIRP
        # std _LOG_POWER_PRIOR; the velocity's prior is in the Gauss-Newton Hessian already
        self._prior_info = np.tile(np.r_[12.0 / (self.hi - self.lo) ** 2, 1.0 / _LOG_POWER_PRIOR**2, np.zeros(3)],
                                   n_jammers)
        self.started = np.zeros(n_jammers, bool)
        self.on_prob = np.full(n_jammers, 0.5)
        self.local_cov = np.tile(np.diag((self.hi - self.lo) ** 2 / 12.0), (n_jammers, 1, 1))
        self.lam = 1e-2
        self.chi2_scale = 1.0
        self.inflation = 1.0
        self.scale2 = 1.0
        self._fixed_cell_gains: dict[int, np.ndarray] = {}
        self._rounds = 0
        self._refines = 0
        self._grid_rows = np.zeros(n_jammers, int)  # measurements each jammer's grid has taken in
        self._rival = np.ones(n_jammers)  # likelihood ratio of the grid's rival mode to the estimate (<= 1)
        self._posterior: np.ndarray | None = None
        self._candidate: _Candidate | None = None  # the joint pair search's restart, being polished
        self.pending = [PendingReadings() for _ in receivers]
        self._edge_said = np.zeros(n_jammers, bool)
        self._confident_since = np.full(n_jammers, np.nan)  # when each estimate became confident (s; NaN: it is not)
        self._t = 0.0  # the last refinement's time (s)
        self._estimate = self._summarize()

    # --- the measurement model ------------------------------------------------------------
    def _gain(self, x: np.ndarray, receiver: int, position, axis) -> np.ndarray:
        """Power gain from jammer positions ``x`` ``(..., 3)`` (isotropic) to one receiver pose."""
        with np.errstate(divide="ignore", invalid="ignore"):  # a candidate on the receiver: capped below
            g = link_gain(x, E3, _ISOTROPIC, position, axis, self.receivers[receiver].pattern, self.path)
        return np.fmin(np.where(np.isnan(g), self.gain_cap, g), self.gain_cap)

    def _cell_gains(self, receiver: int, position, axis) -> np.ndarray:
        """Gains from every grid cell to a receiver pose (once for a fixed receiver)."""
        if not self.receivers[receiver].fixed:
            return self._gain(self.cells, receiver, position, axis)
        if receiver not in self._fixed_cell_gains:
            self._fixed_cell_gains[receiver] = self._gain(self.cells, receiver, position, axis)
        return self._fixed_cell_gains[receiver]

    def _row_gains(self, x: np.ndarray, idx: np.ndarray) -> np.ndarray:
        """``(K, M)`` gains from positions ``x`` (``(K, 3)``, or ``(K, M, 3)``: one per row) to the window rows ``idx``."""
        w = self.window
        x = x[:, None, :] if x.ndim == 2 else x
        if len(self.receivers) == 1:
            return self._gain(x, 0, w.rx[idx], w.ax[idx])
        out = np.empty((x.shape[0], idx.size))
        for i in range(len(self.receivers)):
            m = w.ri[idx] == i
            if not m.any():
                continue
            if self.receivers[i].fixed and x.shape[1] == 1:  # one pose, static jammers: one gain per position
                first = idx[m][0]
                out[:, m] = self._gain(x[:, 0, :], i, w.rx[first], w.ax[first])[:, None]
            else:
                out[:, m] = self._gain(x if x.shape[1] == 1 else x[:, m], i, w.rx[idx[m]], w.ax[idx[m]])
        return out

    def _positions_at(self, t: float) -> np.ndarray:
        """The estimated jammers' positions ``(nJ, 3)`` (m) at time ``t`` (s): constant velocity from ``t_ref``."""
        return self.theta[:, :3] + self.theta[:, 4:7] * (t - self.t_ref)

    def _row_positions(self, theta: np.ndarray, idx: np.ndarray, t_ref: float | None = None) -> np.ndarray:
        """Each jammer's position at each window row's time ``(nJ, M, 3)`` (m): ``theta``'s positions are
        at ``t_ref`` (default the estimate's), and move on at its constant velocity."""
        if not np.any(theta[:, 4:7]):  # static: one position for every row ``(nJ, 1, 3)``
            return theta[:, None, :3]
        return theta[:, None, :3] + theta[:, None, 4:7] * self._row_ages(idx, t_ref)[None, :, None]

    def _row_ages(self, idx: np.ndarray, t_ref: float | None = None) -> np.ndarray:
        """Each window row's time after ``t_ref`` (s; default the estimate's): how far a jammer has
        moved at its velocity between the estimate's positions and that row."""
        return self.window.t[idx] - (self.t_ref if t_ref is None else t_ref)

    @staticmethod
    def _powers(theta: np.ndarray, found: np.ndarray) -> np.ndarray:
        """Each jammer's EIRP (W) under ``theta``; 0 for those not ``found`` (``(nJ,)`` bool)."""
        return np.where(found, np.exp(np.where(found, theta[:, 3], 0.0)), 0.0)

    # --- per measurement --------------------------------------------------------------------
    def add(self, t: float, receiver: int, position, axis, reading_w: float) -> None:
        """One reading (W) of receiver ``receiver`` at ``position`` (m) with antenna ``axis`` (unit, world)."""
        if not (math.isfinite(reading_w) and reading_w > 0):
            raise ValueError(f"estimator: a reading must be a positive finite power (W), got {reading_w!r}")
        self.pending[receiver].add(position, axis, reading_w)

    def add_readings(self, t: float, readings: Sequence[tuple[np.ndarray, np.ndarray, float] | None]) -> JammerEstimate:
        """One control step's readings, receiver by receiver: ``(position m, antenna axis, reading W)``
        (None: that receiver read nothing), then ``update(t)``."""
        for i, r in enumerate(readings):
            if r is not None:
                self.add(t, i, *r)
        return self.update(t)

    def update(self, t: float) -> JammerEstimate:
        """Fold in every receiver's averaged measurement once ``aggregate_steps`` readings are in."""
        changed = False
        for i, r in enumerate(self.pending):
            if r.count >= self.s.aggregate_steps:
                norm = max(float(np.linalg.norm(r.axis)), 1e-12)
                jitter2 = max(0.0, 2.0 * (1.0 - norm / r.count))  # E[angle^2] of unit axes about their mean
                self._assimilate(t, i, r.position / r.count, r.axis / norm, r.power / r.count, jitter2)
                self.pending[i] = PendingReadings()
                changed = True
        if changed:
            self._rounds += 1
            if len(self.window) >= self.s.min_rows and self._rounds % self.s.refine_every == 0:
                self._refine(t)
                self._estimate = self._summarize()
            else:  # the position and its covariance change only when refined; the ON/OFF chain every round
                self._estimate = replace(self._estimate, on_prob=self.on_prob.copy())
        if self.moving:  # a moving jammer's estimate goes on along its velocity between two fits
            self._estimate = replace(self._estimate, positions=self._positions_at(t))
        return self._estimate

    def _assimilate(self, t: float, receiver: int, position: np.ndarray, axis: np.ndarray, y: float,
                    jitter2: float = 0.0) -> None:
        """One measurement ``y`` (W, averaged): each jammer's ON/OFF chain, then its grid sums."""
        noise = self.receivers[receiver].noise_w
        P = self._powers(self.theta, self.started)
        now = self._positions_at(t)
        g_est = np.array([float(self._gain(now[j], receiver, position, axis)) for j in range(self.nj)])
        on_now = self.on_prob > 0.5
        z = KAPPA_DB * math.log(y)
        g = self._cell_gains(receiver, position, axis)  # every cell's gain to this pose, shared by every jammer
        for j in range(self.nj):
            others = noise + float(np.sum(np.where(on_now, P * g_est, 0.0))) - (P[j] * g_est[j] if on_now[j] else 0.0)
            prior = self.on_prob[j] * (1.0 - self.s.switch_prob) + (1.0 - self.on_prob[j]) * self.s.switch_prob
            if self.started[j]:
                r_on = z - KAPPA_DB * math.log(others + P[j] * g_est[j]) - self.log_mean
                r_off = z - KAPPA_DB * math.log(others) - self.log_mean
                # log odds: both likelihoods underflow when the estimate explains neither state
                # in the window's scaled sigmas, as the fit's flags: a fade is not a switch
                logit = math.log(prior / (1.0 - prior)) + 0.5 * (r_off**2 - r_on**2) / (self.sigma2 * self.chi2_scale)
                self.on_prob[j] = 1.0 / (1.0 + math.exp(-min(max(logit, -700.0), 700.0)))
            else:
                self.on_prob[j] = prior
            if j > 0 and not self.started[j - 1]:
                continue  # jammers are found one after the other: each explains what the earlier ones leave
            wgt = (1.0 if not self.started[j] else self.on_prob[j]) / (y * y * self.rel2)
            self.s_ge[j] = self.forget * self.s_ge[j] + wgt * g * (y - others)
            self.s_gg[j] = self.forget * self.s_gg[j] + wgt * g * g
            self._grid_rows[j] += 1
        self.window.append(t, receiver, position, axis, y, jitter2, g)
        self._posterior = None

    def _grid_posterior(self, j: int) -> np.ndarray:
        """Posterior over the grid cells of jammer ``j`` (power profiled out), tempered by the window's
        reduced chi-square (residuals larger than the model say the model is optimistic)."""
        if self._posterior is None:
            ge, gg = self.s_ge, self.s_gg
            loglik = np.where((ge > 0) & (gg > 0), 0.5 * ge * ge / np.where(gg > 0, gg, 1.0), 0.0) / self.chi2_scale
            p = np.exp(loglik - loglik.max(axis=1, keepdims=True))
            self._posterior = p / p.sum(axis=1, keepdims=True)
        return self._posterior[j]

    # --- Gauss-Newton on the window ----------------------------------------------------------
    def _window_gains(self, theta: np.ndarray, idx: np.ndarray, jacobian: bool, t_ref: float | None = None):
        """``g`` ``(nJ, M)`` at ``theta``'s positions and, with ``jacobian``, ``dg/dp`` ``(nJ, 3, M)``."""
        x = self._row_positions(theta, idx, t_ref)
        if not jacobian:
            return self._row_gains(x, idx), None
        offsets = np.vstack([np.zeros(3), _FD_STEP_M * np.eye(3)])
        x4 = (x[:, None] + offsets[None, :, None, :]).reshape(-1, x.shape[1], 3)
        g4 = self._row_gains(x4, idx).reshape(self.nj, 4, -1)
        return g4[:, 0], (g4[:, 1:] - g4[:, :1]) / _FD_STEP_M

    def _on_flags(self, theta: np.ndarray, g: np.ndarray, idx: np.ndarray) -> np.ndarray:
        """Whether each jammer radiated at each fitted row ``(nJ, M)``: the likelihood ratio of ON vs OFF
        under ``theta`` (gains ``g``), summed over neighbouring rows, plus the prior log-odds for ON.
        Recomputed from the current estimate: a flag decided under an early, wrong estimate does not stick."""
        w = self.window
        contrib = np.exp(theta[:, 3])[:, None] * g
        noise = self._noise[w.ri[idx]]
        on = np.ones(contrib.shape, bool)
        kernel = np.ones(2 * _FLAG_NEIGHBOURS + 1)
        for j in range(self.nj):
            others = noise + (on * contrib).sum(axis=0) - contrib[j]
            r_on = w.z[idx] - KAPPA_DB * np.log(others + contrib[j]) - self.log_mean
            r_off = w.z[idx] - KAPPA_DB * np.log(others) - self.log_mean
            llr = np.convolve((r_off**2 - r_on**2) / (2.0 * self.sigma2 * self.chi2_scale), kernel, mode="same")
            on[j] = llr + _ON_PRIOR_LOGODDS > 0
        return on

    def _model(self, theta: np.ndarray, g: np.ndarray, dg, on: np.ndarray, idx: np.ndarray, t_ref: float | None = None):
        """``(z_hat (M,), J (M, 7 nJ) or None)``: the log readings ``theta`` predicts with gains ``g``
        (and ``dg``) and ON flags ``on`` on the rows ``idx``."""
        contrib = on * np.exp(theta[:, 3])[:, None] * g
        S = self._noise[self.window.ri[idx]] + contrib.sum(axis=0)
        z_hat = KAPPA_DB * np.log(S) + self.log_mean
        if dg is None:
            return z_hat, None
        J = np.empty((S.size, _NP * self.nj))
        dt = self._row_ages(idx, t_ref)[:, None]
        for j in range(self.nj):
            J[:, _NP * j:_NP * j + 3] = (KAPPA_DB * on[j] * math.exp(theta[j, 3]) / S * dg[j]).T
            J[:, _NP * j + 3] = KAPPA_DB * contrib[j] / S
            J[:, _NP * j + 4:_NP * j + 7] = J[:, _NP * j:_NP * j + 3] * dt  # the position at a row moves with the velocity
        return z_hat, J

    def _axis_log_slopes(self, x: np.ndarray, idx: np.ndarray) -> np.ndarray:
        """``|d ln G_rx / d angle|`` ``(nJ, M)`` (1/rad): how fast each receiver's antenna gain toward
        the positions ``x`` (``(nJ, 3)`` or ``(nJ, M, 3)``) changes as its axis turns, at the window rows ``idx``."""
        w = self.window
        d = w.rx[idx][None] - (x[:, None, :] if x.ndim == 2 else x)
        c = np.clip(-np.einsum("jmk,mk->jm", d, w.ax[idx]) / np.maximum(np.linalg.norm(d, axis=-1), 1e-9),
                    -1.0 + _SLOPE_STEP, 1.0 - _SLOPE_STEP)
        out = np.zeros(c.shape)
        for i, r in enumerate(self.receivers):
            m = w.ri[idx] == i
            cm = c[:, m]
            with np.errstate(divide="ignore"):
                lo, hi = np.log(r.pattern.gain_from_cos(cm - _SLOPE_STEP)), np.log(r.pattern.gain_from_cos(cm + _SLOPE_STEP))
            slope = np.where(np.isfinite(lo) & np.isfinite(hi), (hi - lo) / (2.0 * _SLOPE_STEP), _MAX_LOG_SLOPE)
            out[:, m] = np.minimum(np.abs(slope) * np.sqrt(1.0 - cm * cm), _MAX_LOG_SLOPE)
        return out

    def _row_variance(self, theta: np.ndarray, g: np.ndarray, on: np.ndarray, idx: np.ndarray,
                      found: np.ndarray, t_ref: float | None = None) -> np.ndarray:
        """Each row's log-reading variance (dB^2) under ``theta``: the detector's and the model error's,
        plus what the receiver's axis uncertainty (``axis_error_deg`` and the averaged axes' own spread)
        makes of the jammers' share of the reading. Near an antenna null the gain changes fastest with
        the axis: a reading there says little about where the jammer is, and is weighted so (without
        this, a relay that holds the jammer in its null pulled the estimate into a narrow wrong valley).
        ``found``: which jammers ``theta`` has found (``(nJ,)`` bool); the others contribute nothing."""
        contrib = on * self._powers(theta, found)[:, None] * g
        S = self._noise[self.window.ri[idx]] + contrib.sum(axis=0)
        slope = (contrib * self._axis_log_slopes(self._row_positions(theta, idx, t_ref), idx)).sum(axis=0) / S  # d ln S / d angle
        return self.sigma2 + (KAPPA_DB * slope) ** 2 * (self.axis_var + self.window.jitter2[idx])

    def information(self, theta: np.ndarray, on: np.ndarray, idx: np.ndarray, t_ref: float = 0.0) -> np.ndarray:
        """Fisher information ``(4 nJ, 4 nJ)`` the window rows ``idx`` carry about ``theta`` (each
        jammer's position, m, and log EIRP) with ON flags ``on`` ``(nJ, M)``, under the estimator's own
        measurement model (log readings, the rows' variances): ``J^T J / var``. For measuring a run
        against the Cramer-Rao bound (``sim/jammer_sensing.py``); the estimate does not use it. ``theta``
        ``(nJ, 4)``: static jammers; ``(nJ, 7)``: each also with a constant velocity (m/s), positions at
        ``t_ref`` (s): the information is then ``(7 nJ, 7 nJ)``."""
        static = theta.shape[1] == 4
        theta = np.hstack([theta, np.zeros((self.nj, 3))]) if static else theta
        g, dg = self._window_gains(theta, idx, True, t_ref)
        _, J = self._model(theta, g, dg, on, idx, t_ref)
        if static:
            J = J[:, np.tile(np.arange(_NP) < 4, self.nj)]
        var = self._row_variance(theta, g, on, idx, np.ones(self.nj, bool), t_ref)
        return J.T @ (J / var[:, None])

    def _huber(self, r: np.ndarray, base: np.ndarray, var: np.ndarray) -> tuple[float, np.ndarray]:
        """Robust negative log-likelihood of the window ``sum base (rho(r / sd) + ln var)`` (Huber at 3
        sigma: a reading averaged across a jammer's switch fits neither state) and the iteratively
        reweighted least-squares factors."""
        u = np.abs(r) / np.sqrt(var)
        rho = np.where(u <= _HUBER_SIGMAS, u * u, 2.0 * _HUBER_SIGMAS * u - _HUBER_SIGMAS**2)
        return float(np.sum(base * (rho + np.log(var)))), np.minimum(1.0, _HUBER_SIGMAS / np.maximum(u, 1e-300))

    def _mixed_rows(self, theta: np.ndarray, g: np.ndarray, on: np.ndarray, idx: np.ndarray, z_hat: np.ndarray,
                    var: np.ndarray, found: np.ndarray) -> np.ndarray:
        """Rows whose reading lies between what ``theta`` predicts and what it predicts with one found
        jammer's ON flag flipped, more than 3 sigma from both: that jammer switched within the row's
        average. Neither state fits such a row and it says nothing about where the jammer is: it is
        left out of the fit at a fixed cost (``_mixed_cost``), where Huber charged it linearly and
        made the true point look worse than a far, strong one at every switch. ``found``: which
        jammers ``theta`` has found (``(nJ,)`` bool)."""
        contrib = self._powers(theta, found)[:, None] * g
        S = np.exp((z_hat - self.log_mean) / KAPPA_DB)
        c = _HUBER_SIGMAS * np.sqrt(var)
        z = self.window.z[idx]
        mixed = np.zeros(idx.size, bool)
        for j in np.flatnonzero(found):
            z_flip = KAPPA_DB * np.log(np.maximum(S + np.where(on[j], -contrib[j], contrib[j]), 1e-300)) + self.log_mean
            mixed |= (z > np.minimum(z_hat, z_flip) + c) & (z < np.maximum(z_hat, z_flip) - c)
        return mixed

    def _mixed_cost(self, base: np.ndarray, var: np.ndarray, mixed: np.ndarray) -> float:
        """What a mixed row costs: as much as a reading 3 sigma off."""
        return float(np.sum(base[mixed] * (_HUBER_SIGMAS**2 + np.log(var[mixed]))))

    def _window_cost(self, theta: np.ndarray, idx: np.ndarray, base: np.ndarray, found: np.ndarray) -> float:
        """The window's robust cost of ``theta`` whose found jammers are ``found`` (``_lm_step``'s ``cost0``)."""
        g, _ = self._window_gains(theta, idx, jacobian=False)
        on = self._on_flags(theta, g, idx)
        z_hat, _ = self._model(theta, g, None, on, idx)
        var = self._row_variance(theta, g, on, idx, found) * self.scale2
        return self._scaled_cost(self.window.z[idx] - z_hat, var, theta, g, on, idx, z_hat, base, found)

    def _scaled_cost(self, r, var, theta, g, on, idx, z_hat, base, found) -> float:
        """The window's robust cost of residuals ``r`` under the variances ``var`` (the model's times the residuals'
        squared scale: candidates are compared in one scale, the last fit's, ``scale2``)."""
        mixed = self._mixed_rows(theta, g, on, idx, z_hat, var, found)
        return self._huber(r, base * ~mixed, var)[0] + self._mixed_cost(base, var, mixed) + self._velocity_cost(theta)

    def _reseed(self, idx: np.ndarray, base: np.ndarray) -> None:
        """Start Gauss-Newton at the grid's best cell at the first fit; afterwards, when the grid puts
        mass away from the estimate, compare the best such cell's window fit with the estimate's:
        restart there when it fits better, else keep it as a rival mode weighted by its likelihood
        ratio (``_rival``), which the reported covariance includes. A confident estimate is checked
        every ``_RESEED_EVERY`` refinements only (the grid moves slowly; the check costs two window fits)."""
        self._refines += 1
        for j in range(self.nj):
            if not self.started[j] and self._grid_rows[j] < self.s.min_rows:
                continue
            if self.started[j] and self._estimate.confident[j] and self._refines % _RESEED_EVERY:
                continue
            post = self._grid_posterior(j)
            far = np.linalg.norm(self.cells - self.theta[j, :3], axis=1) > 2.0 * self.spacing
            taken = np.zeros(len(self.cells), bool)  # cells another jammer's estimate already explains
            for k in range(self.nj):
                if k != j and self.started[k]:
                    taken |= np.linalg.norm(self.cells - self.theta[k, :3], axis=1) <= 2.0 * self.spacing
            if self.started[j] and post[far & ~taken].sum() < _RIVAL_MASS:
                # no rival mode: the reported covariance is the local one. (Weighing the little mass
                # left at 1, as before, made the std jump 0.07 -> 12 m for single steps at 20 dB,
                # whenever that mass dipped under the threshold below which it is not checked,
                # while a larger, checked mass was weighted by its tiny likelihood ratio.)
                self._rival[j] = 0.0
                continue
            allowed = (far if self.started[j] else np.ones(len(self.cells), bool)) & ~taken
            if not allowed.any():
                continue
            best = int(np.argmax(np.where(allowed, post, -1.0)))
            ge, gg = self.s_ge[j, best], self.s_gg[j, best]
            power = ge / gg if ge > 0 and gg > 0 else 1e-6 * float(self._noise.min())
            seed = self.theta.copy()
            seed[j] = np.r_[self.cells[best], math.log(power), np.zeros(3)]
            if self.started[j]:
                drop = (self._window_cost(seed, idx, base, self.started)
                        - self._window_cost(self.theta, idx, base, self.started))
                if drop >= 0.0:
                    # the window prefers the estimate; when the grid (every reading so far, another likelihood of the
                    # same data) puts many times more mass about its best rival cell than about the estimate, the two
                    # disagree about where the jammer is and the rival's spread counts in full: under Doppler fading
                    # the window settled on a mirror mode 11-29 m off and called it 0.5-1.4 m sure (NEES 250-434,000)
                    # while the grid held 24 to 1e10 times more mass elsewhere. (A grid merely diffuse, early on, is not
                    # another mode: the nominal's at 0.6-4.8 s had at most 3.3 times; its mass far away counted in full
                    # made that estimate 14-16 m unsure at 3.3 m off)
                    mode = np.linalg.norm(self.cells - self.cells[best], axis=1) <= 2.0 * self.spacing
                    held = float(post[mode].sum()) > _DISAGREE_ODDS * float(post[~far].sum())
                    self._rival[j] = 1.0 if held else math.exp(-0.5 * min(drop, 1400.0))
                    continue
            self.theta, self.lam = seed, 1e-2
            self.started[j] = True
            self._rival[j] = 1.0

    def _refine(self, t: float) -> None:
        """One Levenberg-Marquardt iteration on the window (log domain, weights exp(-age / forget_s))."""
        self._t = t
        idx, base = self._fit_rows(t, self.s.window_rows)
        self.theta[:, :3] = np.clip(self._positions_at(t), self.lo, self.hi)
        self.t_ref = t  # positions are now's; a row's is now's plus the velocity times its age
        self._reseed(idx, base)
        step = None
        if self.nj >= 2 and self._refines % _JOINT_EVERY == 0 and self._candidate is None:
            self._joint_search(*self._fit_rows(t, _JOINT_ROWS))  # its candidate is polished from the next refinement on
        else:
            step = self._advance_candidate(idx, base)
        if not self.started.any():
            return
        if step is None:
            step = self._lm_step(self.theta, self.lam, idx, base, self.started)
        self.theta, self.lam, H, cols, chi2 = step.theta, step.lam, step.H, step.cols, step.chi2
        if chi2 != self.chi2_scale:
            self._posterior = None
        self.chi2_scale, self.scale2 = chi2, step.scale2
        cov = np.full((_NP * self.nj, _NP * self.nj), 0.0)
        # with the prior (the search box, a wide log power): a direction the window says nothing about
        # keeps the prior's spread. (pinv(H) gave it zero variance: a jammer flagged OFF in every row of
        # the window, whose columns of J are zero, was reported at std 0 m, 6-16 m off, "confident".)
        # residuals correlated in time (a fade that changes slower than the readings come: Doppler fading at a relay
        # that hovers, shadowing) carry fewer independent readings than rows: the information shrinks by that much
        self.inflation = step.inflation
        cov[np.ix_(cols, cols)] = np.linalg.inv(H / (chi2 * self.inflation) + np.diag(self._prior_info[cols]))
        self.local_cov = np.array([_clip_eigenvalues(cov[_NP * j:_NP * j + 3, _NP * j:_NP * j + 3], self._max_var)
                                   for j in range(self.nj)])

    def _fit_rows(self, t: float, most: int | None) -> tuple[np.ndarray, np.ndarray]:
        """At most ``most`` window rows (evenly thinned; None: every row) and their weights at time ``t``
        (s): each stands for the rows thinned out, forgotten with ``exp(-age / forget_s)``."""
        idx = self.window.rows(len(self.window) if most is None else most)
        return idx, len(self.window) / idx.size * np.exp(-(t - self.window.t[idx]) / self.s.forget_s)

    def _lm_step(self, theta: np.ndarray, lam: float, idx: np.ndarray, base: np.ndarray, found: np.ndarray) -> _LmStep:
        """One Levenberg-Marquardt iteration from ``theta`` (the parameters of the jammers ``found``,
        ``(nJ,)`` bool) with damping ``lam`` (see ``_LmStep``)."""
        z = self.window.z[idx]
        g, dg = self._window_gains(theta, idx, jacobian=True)
        on = self._on_flags(theta, g, idx)
        z_hat, J = self._model(theta, g, dg, on, idx)
        free = np.outer(found, self._free).ravel()  # the found jammers' fitted parameters
        cols = np.flatnonzero(free)
        J = J[:, cols]
        r = z - z_hat
        var0 = self._row_variance(theta, g, on, idx, found)
        # the residuals' own scale (robust: 1.4826 x their median absolute size in model sigmas, at least 1): fading or
        # shadowing the model leaves out put readings many model sigmas off, and with the cuts at 3 model sigmas a
        # fade down read as a jammer switching within the row (left out of the fit) and Huber down-weighted the rest
        # alike: the fit kept the fades up and settled tens of metres off at a 2 m spread. The cuts are in the
        # scaled sigmas (Huber's proposal 2)
        scale2 = residual_scale2(r / np.sqrt(var0), base)
        var = var0 * scale2
        mixed = self._mixed_rows(theta, g, on, idx, z_hat, var, found)
        fixed_cost = self._mixed_cost(base, var, mixed)
        fit = base * ~mixed
        huber, robust = self._huber(r, fit, var)
        cost0 = huber + (self._velocity_cost(theta) + fixed_cost)
        # the window's cost in the last fit's scale, summed as _window_cost sums it (the same rows and variances when
        # the scale has not changed: those terms are reused, not computed again)
        window_cost = (huber + fixed_cost + self._velocity_cost(theta) if scale2 == self.scale2
                       else self._scaled_cost(r, var0 * self.scale2, theta, g, on, idx, z_hat, base, found))
        wr = fit / var * robust
        prior = np.where(np.tile(np.arange(_NP) >= 4, self.nj)[cols], self._vel_info, 0.0)  # the velocity's prior
        H = J.T @ (J * wr[:, None]) + np.diag(prior)
        full = np.zeros(_NP * self.nj)
        full[cols] = np.linalg.solve(H + lam * np.diag(np.diag(H) + 1e-9), J.T @ (wr * r) - prior * theta.ravel()[cols])
        trial = theta + full.reshape(self.nj, _NP)
        trial[:, :3] = np.clip(trial[:, :3], self.lo, self.hi)
        trial[:, 3] = np.where(found, np.clip(trial[:, 3], -60.0, 60.0), trial[:, 3])
        g_try, _ = self._window_gains(trial, idx, jacobian=False)
        z_try, _ = self._model(trial, g_try, None, on, idx)
        chi2 = scale2 * max(1.0, float(np.sum(wr * r * r) / max(np.sum(wr * var), 1e-12)))
        H = H * scale2  # H / chi2 is the information: the rows' weights brought back to the model's variance
        inflation = residual_inflation(r / np.sqrt(var), self.window.ri[idx], fit > 0)
        var_try = scale2 * self._row_variance(trial, g_try, on, idx, found)
        if self._huber(z - z_try, fit, var_try)[0] + self._velocity_cost(trial) + fixed_cost < cost0:
            return _LmStep(trial, max(lam / 3.0, 1e-6), H, cols, chi2, window_cost, inflation, scale2)
        return _LmStep(theta, min(lam * 5.0, 1e6), H, cols, chi2, window_cost, inflation, scale2)

    def _joint_search(self, idx: np.ndarray, base: np.ndarray) -> None:
        """Score every pair of grid cells for two jammers at once on the window (``pair_search.py``),
        the others held at their estimates; the best pair becomes a candidate that ``_advance_candidate``
        polishes beside the estimate and adopts once its window fit is the better one. Two jammers found
        one after the other can settle in a wrong pair of modes that compensate each other, which neither
        one-jammer check (``_reseed``) leaves: measured, 10-15 m off at a reported std below 1 m."""
        y = np.exp(self.window.z[idx] / KAPPA_DB)
        weights = base / (y * y * self.rel2)
        gains = self.window.cell_gains[idx].T  # (cells, rows), computed when each measurement came in
        g, _ = self._window_gains(self.theta, idx, jacobian=False)
        for j in range(self.nj):
            for k in range(j + 1, self.nj):
                held = self.started.copy()
                held[[j, k]] = False
                others = (self._powers(self.theta, held)[:, None] * g).sum(axis=0)
                pair = best_pair(gains, weights, y - self._noise[self.window.ri[idx]] - others, keep=_JOINT_CELLS)
                if pair.power_b <= 0.0 or self._pair_is_estimate(pair.a, pair.b, j, k):
                    continue  # one cell explains it (the one-jammer checks handle that), or nothing new
                seed = self.theta.copy()
                seed[j] = np.r_[self.cells[pair.a], math.log(pair.power_a), np.zeros(3)]
                seed[k] = np.r_[self.cells[pair.b], math.log(pair.power_b), np.zeros(3)]
                found = self.started.copy()
                found[[j, k]] = True
                self._candidate = _Candidate(seed, found, 1e-2, _JOINT_POLISH, self.t_ref)
                return  # one candidate at a time

    def _pair_is_estimate(self, a: int, b: int, j: int, k: int) -> bool:
        """Whether cells ``a, b`` are where jammers ``j, k`` are estimated (both found, each cell within
        two cells of one of them): the pair search then proposes nothing new."""
        if not (self.started[j] and self.started[k]):
            return False
        d = np.linalg.norm(self.cells[[a, b]][:, None, :] - self.theta[[j, k]][None, :, :3], axis=2)
        return bool(min(max(d[0, 0], d[1, 1]), max(d[0, 1], d[1, 0])) <= 2.0 * self.spacing)

    def _advance_candidate(self, idx: np.ndarray, base: np.ndarray) -> _LmStep | None:
        """One Levenberg-Marquardt iteration on the joint search's candidate (its positions moved on to
        now like the estimate's); adopt it as soon as its window fit beats the estimate's, drop it
        after ``_JOINT_POLISH`` iterations that did not (one iteration per refinement: no step pays
        for the whole polish). The estimate's own Levenberg-Marquardt step is taken here, its window
        cost being what the candidate is compared with; it is returned for ``_refine`` to use (None
        when no candidate lives or it was adopted: ``_refine`` then steps from the new estimate)."""
        c = self._candidate
        if c is None:
            return None
        step = self._lm_step(self.theta, self.lam, idx, base, self.started) if self.started.any() else None
        current = step.cost if step is not None else math.inf
        theta = c.theta.copy()
        theta[:, :3] = np.clip(theta[:, :3] + theta[:, 4:7] * (self.t_ref - c.t_ref), self.lo, self.hi)
        if self._window_cost(theta, idx, base, c.found) < current:  # adopted: its jammers are found
            self.theta, self.lam, self.started, self._candidate = theta, 1e-2, c.found.copy(), None
            self._rival[:] = 0.0
            return None
        polished = self._lm_step(theta, c.lam, idx, base, c.found)
        self._candidate = _Candidate(polished.theta, c.found, polished.lam, c.left - 1, self.t_ref) if c.left > 1 else None
        return step

    def _velocity_cost(self, theta: np.ndarray) -> float:
        """The velocities' prior, in the window cost's units: ``sum |v|^2 / jammer_speed^2``."""
        return float(self._vel_info * np.sum(theta[:, 4:7] ** 2))

    # --- the estimate --------------------------------------------------------------------------
    def _summarize(self) -> JammerEstimate:
        covs = []
        for j in range(self.nj):
            post = self._grid_posterior(j)
            d = self.cells - self.theta[j, :3]
            if self.started[j]:  # the local mode is the Gauss-Newton covariance; rival modes add their spread
                far = np.linalg.norm(d, axis=1) > 2.0 * self.spacing
                covs.append(self.local_cov[j] + self._rival[j] * (d[far].T @ (d[far] * post[far, None])))
            else:
                covs.append(d.T @ (d * post[:, None]))
        covs_a = np.array(covs)
        std = np.sqrt(np.maximum(np.linalg.eigvalsh(covs_a)[:, -1], 0.0))
        p = self.theta[:, :3]
        near = _EDGE_CELLS * self.spacing  # the fit clips to the box: an estimate the data pull outside sits on its face
        edge = self.started & (np.any(p[:, :2] - self.lo[:2] < near, axis=1)
                               | np.any(self.hi - p < near, axis=1))  # the floor is the ground: a jammer may sit on it
        for k in np.flatnonzero(edge & (std < self.s.confident_std_m) & ~self._edge_said):  # what would have been trusted
            if not self._grid_at_face(int(k), p[k], near):
                continue  # the grid holds the jammer inside: a fit that strayed onto the face, not a jammer beyond it
            self._edge_said[k] = True
            log.warning("jammer estimate %d at %s m, at the edge of the search box [%s, %s]: not trusted (the jammer may "
                        "be outside it); widen estimation.search_min_m / search_max_m", k, np.round(p[k], 1).tolist(),
                        self.lo.tolist(), self.hi.tolist())
        # trusted once confident for confirm_s without a break: a wrong mode both the grid and the window held for a
        # moment (a jammer outside the box, its image inside under Doppler fading: 0.3 s at 35 m, 1.46 m sure) is not
        confident = self.started & (std < self.s.confident_std_m) & ~edge
        self._confident_since = np.where(confident, np.fmin(self._confident_since, self._t), np.nan)
        trusted = confident & (self._t - np.nan_to_num(self._confident_since, nan=np.inf) >= self.s.confirm_s)
        return JammerEstimate(self.theta[:, :3].copy(), self._powers(self.theta, self.started), covs_a, self.on_prob.copy(), std,
                              trusted, edge)

    def _grid_at_face(self, j: int, p: np.ndarray, near: float) -> bool:
        """Whether jammer ``j``'s grid posterior (every reading so far) holds most of its mass within a cell of the
        faces the estimate ``p`` sits on (within ``near`` m; the floor excepted): a jammer beyond those faces pulls the
        grid onto them too, a fit that strayed onto a face while the grid holds the jammer inside does not."""
        at_lo = np.r_[p[:2] - self.lo[:2] < near, False]
        at_hi = self.hi - p < near
        c = self.cells
        on_face = (np.any(at_lo & (c - self.lo <= self.spacing), axis=1)
                   | np.any(at_hi & (self.hi - c <= self.spacing), axis=1))
        return float(self._grid_posterior(j)[on_face].sum()) > _FACE_MASS

    @property
    def estimate(self) -> JammerEstimate:
        return self._estimate


def residual_scale2(u: np.ndarray, used: np.ndarray) -> float:
    """The squared scale of standardized residuals ``u`` over the rows ``used`` (> 0): ``(1.4826 median |u|)^2``, the
    normal distribution's sigma read robustly, at least 1 (the model's own noise)."""
    a = np.abs(u[used > 0])
    return max(1.0, (1.4826 * float(np.median(a))) ** 2) if a.size else 1.0


def residual_inflation(e: np.ndarray, receiver: np.ndarray, used: np.ndarray) -> float:
    """How much a fit's variance grows when its standardized residuals ``e`` (time-ordered rows, each from
    ``receiver``; ``used`` the rows fitted) are correlated in time: an AR(1) process's ``(1 + rho) / (1 - rho)``, with
    ``rho`` the lag-1 correlation of each receiver's consecutive fitted rows, taken when it exceeds its 95% band under
    independence (``2 / sqrt(pairs)``: white residuals keep the factor 1) and capped at ``_MAX_RHO``."""
    a_parts, b_parts = [], []
    for rx in np.unique(receiver):
        mine = e[(receiver == rx) & used]
        a_parts.append(mine[:-1])
        b_parts.append(mine[1:])
    a, b = np.concatenate(a_parts), np.concatenate(b_parts)
    n = a.size
    if n < _MIN_PAIRS:
        return 1.0
    a, b = a - a.mean(), b - b.mean()
    den = 0.5 * float(a @ a + b @ b)
    rho = float(a @ b) / den if den > 0 else 0.0
    if rho <= 2.0 / math.sqrt(n):
        return 1.0
    rho = min(rho, _MAX_RHO)
    return (1.0 + rho) / (1.0 - rho)


def _clip_eigenvalues(cov: np.ndarray, most: float) -> np.ndarray:
    """The symmetric ``cov`` with its eigenvalues clipped to ``[0, most]``."""
    vals, vecs = np.linalg.eigh(0.5 * (cov + cov.T))
    return (vecs * np.clip(vals, 0.0, most)) @ vecs.T
