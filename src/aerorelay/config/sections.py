"""The smaller tables as data: ``[world]``, ``[sim]``, ``[perturbations]``, ``[bound]``, ``[estimation]`` and
``[verdict]``."""

from __future__ import annotations

import math
from typing import Literal

from pydantic import Field, model_validator

from .base import Strict, Vec3


class WorldConfig(Strict):
    """The world the vehicles fly in: the ground, and how far a mission may reach."""

    ground_z_m: float = Field(0.0, ge=-1000.0, le=10000.0, description="height of the ground, m (world z): the workspace, "
                              "every mission and every jammer stay at or above it; a vehicle below it makes the run unsafe")
    mission_max_distance_m: float = Field(1000.0, gt=0.0, le=100_000.0, description="how far from controller.workspace "
                                          "MRAV-2's path may reach, m: a sample farther away is refused as a damaged file")


class SimConfig(Strict):
    """Closed-loop simulation rates and length."""

    plant_rate_hz: float = Field(1000.0, gt=0.0, le=20000.0, description="RK4 rate of the simulated plant, Hz")
    control_rate_hz: float | None = Field(None, gt=0.0, le=500.0, description="default 1/Ts")
    duration_s: float | None = Field(None, gt=0.0, allow_inf_nan=False, description="default: the mission's length")
    max_minutes: float = Field(60.0, gt=0.0, le=10080.0, description="refuse, before any work, a flight estimated to "
                               "take longer here, min (its closed loop and its traced channel: experiments.budget)")
    baseline: Literal["none", "direct"] = Field("none", description="'direct': also the rate of the direct link (each "
                                                "source straight to its base station, no relay) at every step, on the "
                                                "deterministic channel with the true jammers; metrics.json's "
                                                "c_min_direct, c_mean_direct and the run's c_min_over_direct, "
                                                "c_mean_over_direct (sim/baseline.py)")


class PerturbationConfig(Strict):
    """Disturbances unknown to the controller (robustness studies)."""

    fading_k_db: float | None = Field(None, ge=0.0, allow_inf_nan=True, description="Rician K in dB; omit or inf for none")
    csi_noise_m: float = Field(0.0, ge=0.0, description="std of position noise on MRAV-2 and jammer")
    process_noise_v: float = Field(0.0, ge=0.0, description="translational acceleration noise std, m/s^2")
    process_noise_w: float = Field(0.0, ge=0.0, description="rotational acceleration noise std, rad/s^2")

    @property
    def stochastic(self) -> bool:
        """Whether the seed changes anything: fading with finite K, CSI or process noise."""
        fading = self.fading_k_db is not None and math.isfinite(self.fading_k_db)
        return fading or self.csi_noise_m > 0 or self.process_noise_v > 0 or self.process_noise_w > 0


class BoundConfig(Strict):
    """Resolution of the capacity bounds (``aerorelay bound``, planning/bound.py)."""

    max_speed_m_s: float = Field(1.0, gt=0.0, le=20.0, description="speed limit of the path bounds, m/s")
    grid_m: float | None = Field(None, ge=0.1, le=20.0, description="position grid spacing, m: the one relay's grid, a "
                                 "network's cubes (its cost grows with the square of the cells); default 0.5 m for one relay, "
                                 "2 m for a network (a ray-traced channel traces every cell: coarse, a few metres). "
                                 "bound.network_grid_m is its old spelling")
    dt_s: float | None = Field(None, ge=0.05, le=30.0, description="time grid spacing, s; default 0.5 s for one relay, 2 s "
                               "for a network. bound.network_dt_s is its old spelling")
    axis_step_deg: float = Field(5.0, ge=1.0, le=30.0, description="spacing of the relay antenna axes searched, deg")
    max_accel_m_s2: float = Field(4.0, gt=0.0, le=50.0, description="acceleration limit of the flyable paths (from rest "
                                  "at the start), m/s^2: the capacity planner's reference limit by default")
    max_minutes: float = Field(60.0, gt=0.0, le=10080.0, description="refuse, before any work, a bound estimated to take "
                               "longer than this on this machine (min; raise it to wait; a traced pre-flight route too); a "
                               "bound needing more than half of the machine's memory is always refused")
    branch_pairs: float = Field(1e6, ge=1e4, le=1e9, description="a network's branch and bound (its cubes split in eight "
                                "where they may hold the optimum): the pair terms one level may bound at most; more "
                                "tightens the bound for more time (10x with branch_levels = 10: the network study's "
                                "two relays at 120 m, its upper path bound 4.6% lower in 6.6x the time, "
                                "docs/results/networks.md)")
    branch_levels: int = Field(6, ge=0, le=20, description="a network's branch and bound: its levels at most (0: the "
                               "grid's cubes alone; every level's bound is certified)")
    global_seconds: float = Field(0.0, ge=0.0, le=86400.0, description="a network's static bound also solved to global "
                                  "optimality by SCIP at every instant, at most this long each (s; 0: not): the tighter "
                                  "of SCIP's certified dual bound and the cube bound is kept, SCIP's configuration too "
                                  "where it flies better (planning/network_bound_global.py)")
    global_gap: float = Field(1e-3, ge=1e-6, le=0.5, description="SCIP stops once its bound is this close to its best "
                              "configuration (relative)")


class EstimationConfig(Strict):
    """Online jammer estimation (``jammer.localization = "estimated"``): every control step the
    relay's receiver (and the base station's with ``use_bs``) reads its interference-plus-noise
    power with an energy detector; a grid filter plus sliding-window Gauss-Newton per jammer
    (``estimation/jammer_estimator.py``) estimates its position and power from the readings and the known poses."""

    use_bs: bool = Field(False, description="the base station's receiver measures too (its reports reach the relay)")
    n_samples: int = Field(100, ge=1, le=10_000_000, description="complex samples per energy reading (chi-square, 2n dof)")
    bias_db: float = Field(0.0, ge=-10.0, le=10.0, description="detector calibration bias, dB (unknown to the estimator)")
    aggregate_steps: int = Field(10, ge=1, le=1000, description="control steps' readings averaged into one measurement")
    grid_m: float = Field(2.5, ge=0.2, le=50.0, description="cell size of the grid filter over the search box, m")
    forget_s: float = Field(20.0, gt=0.0, le=1000.0, description="time constant of a measurement's weight exp(-age / forget_s), s "
                            "(shorter follows a moving jammer, longer averages more)")
    model_error_db: float = Field(0.2, ge=0.0, le=20.0, description="unmodelled error per measurement, dB std: a floor (the "
                                  "estimator scales it up by the residuals' reduced chi-square: fading, shadowing)")
    axis_error_deg: float = Field(1.0, ge=0.0, le=30.0, description="how well each receiver's antenna axis is known, deg "
                                  "std: near an antenna null a reading then says little about where the jammer is")
    jammer_speed_m_s: float = Field(0.0, ge=0.0, le=50.0, description="0: the jammers are static; > 0: each moves at a "
                                    "constant velocity the estimator fits, with this prior std per axis (m/s)")
    search_min_m: Vec3 | None = Field(None, description="search box corner, m world (default: the nodes' box +- 10 m, "
                                      "z >= 0, and the workspace; an estimate at its edge is not trusted)")
    search_max_m: Vec3 | None = Field(None, description="search box corner, m world")
    confident_std_m: float = Field(1.5, gt=0.0, le=100.0, description="the planner uses an estimate once its largest "
                                   "position std (m) is below this (before: plans without that jammer, as before tau_E)")
    confirm_s: float = Field(1.0, ge=0.0, le=60.0, description="an estimate is trusted once it has been confident (below "
                             "confident_std_m, off the search box's faces, the grid agreeing) this long without a break, s")

    @model_validator(mode="after")
    def _box(self):
        if (self.search_min_m is None) != (self.search_max_m is None):
            raise ValueError("give both search_min_m and search_max_m, or neither")
        if self.search_min_m is not None and any(a >= b for a, b in zip(self.search_min_m, self.search_max_m, strict=True)):
            raise ValueError(f"search_min_m {self.search_min_m} must be below search_max_m {self.search_max_m} on every axis")
        return self


REACH_MAX_TIMES = 300  # mission instants the alignment reachability check samples (1 s apart up to 299 s)
REACH_MAX_WORK = 6e7  # grid points x axes x instants it evaluates (~0.6 s on the project's VM; nominal: 2.5e7)
REACH_MAX_POINTS = 10_000  # relay positions it searches at most (1 m apart up to this, then coarser)


class VerdictConfig(Strict):
    """What a run must have done to read ``complete`` besides staying safe (``sim.exit_status``)."""

    fallback_fraction_max: float = Field(0.05, ge=0.0, le=1.0, description="a relay that flew more than this fraction "
                                         "of its steps on the brake law, or with failed QPs, ends the run 'fell_back' (exit "
                                         "4): its controller did not fly it (1: never)")
