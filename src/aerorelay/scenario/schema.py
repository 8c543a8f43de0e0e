"""Typed scenario configuration (pydantic) loaded from TOML presets in ``scenarios/``.

Every field carries its unit in its name or docstring. Unknown fields are rejected. Defaults are
the paper's Table I values and the working spec's resolved choices (docs/concepts/spec.md), so an empty ``[section]`` is valid.
"""

from __future__ import annotations

import difflib
import functools
import math
import re
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, create_model, field_validator, model_validator

from ..control.terms import COST_TERMS
from ..models.antenna import CosinePattern, DipolePattern, IsotropicPattern, NodePatterns, SinPowerPattern
from ..models.axes import axis_cone
from ..models.channel import reachable_mutual_alignment
from ..models.mission import CsvPath, MinimumJerkPath, UlogPath, source_trajectory
from ..models.propagation import RMA_AV_MAX_D2D_M, RMA_AV_MAX_HEIGHT_M, RMA_AV_MIN_HEIGHT_M
from ..models.vehicle import HEXAROTOR_ARM_LENGTH_M, HoverInfeasibleError, Multirotor, star_multirotor
from .tomltext import compact_toml

Vec3 = Annotated[list[float], Field(min_length=3, max_length=3)]
MIN_NODE_SEPARATION_M = 0.1
LOOP_CLOSURE_M = 0.01  # a repeating jammer path's last waypoint within this of its first (m)
OUTAGE_SPECTRAL_EFFICIENCY = 1e-3  # bit/s/Hz: the paper's outage threshold (B = 1); times the bandwidth in physical units
MIN_MOTOR_RATE_HZ_S = 20.0  # slower motors cannot follow a braking manoeuvre (|omega_dot| bounds below this are rejected)
MIN_PREDICTION_S = 0.3  # horizon x Ts: shorter predictions cannot plan a stop inside the workspace
MAX_TS_S = 0.05  # one RK4 step per Ts: longer periods do not resolve the attitude dynamics


def _nonzero_direction(v: list[float], what: str) -> list[float]:
    if math.hypot(*v) < 1e-9:
        raise ValueError(f"{what} must be a non-zero direction")
    return v


class ScenarioError(ValueError):
    """A scenario failed validation; ``str()`` lists one line per bad field."""


class _Strict(BaseModel):
    # no inf / NaN anywhere unless a field says so (fading K = inf means "no fading")
    model_config = ConfigDict(extra="forbid", validate_assignment=True, allow_inf_nan=False)


class Rotor(_Strict):
    """One rotor of a custom GTMR layout (body frame)."""

    position: Vec3 = Field(description="the rotor's position p_m_i, m (body frame)")
    axis: Vec3 = Field(description="the rotor's thrust axis z_P_i (body frame; normalized, not zero)")
    spin: Literal[-1, 1] = Field(description="s_i: the sign of the rotor's drag moment about its axis")

    _nonzero = field_validator("axis")(lambda v: _nonzero_direction(v, "a rotor's thrust axis"))


class PlatformConfig(_Strict):
    """Relay vehicle (MRAV-1). Hexarotor by default; ``rotors`` overrides the layout."""

    rotor_count: int = Field(6, ge=3, le=16, description="rotors of the star layout (arms evenly spaced)")
    tilt_deg: float = Field(20.0, ge=0.0, le=60.0, description="alternating tilt of each rotor about its arm, deg")
    arm_length_m: float = Field(HEXAROTOR_ARM_LENGTH_M, gt=0.0, le=5.0, description="star layout: distance of every rotor "
                                "from the centre of mass, m")
    rotors: list[Rotor] | None = Field(None, min_length=4, description="custom layout; overrides tilt/arm")
    mass_kg: float = Field(2.57, gt=0.0, description="m, kg (Table I)")
    inertia_kgm2: Vec3 = Field(default_factory=lambda: [0.11, 0.11, 0.19], description="diagonal of J, kg m^2")
    gravity_m_s2: float = Field(9.81, gt=0.0, description="g, m/s^2")
    c_xi: float = Field(1.18e-3, gt=0.0, description="thrust coefficient, N/Hz^2")
    c_tau: float = Field(2.5e-5, ge=0.0, description="drag-moment coefficient, N m/Hz^2")
    omega_min_hz: float = Field(16.0, ge=0.0, description="lowest motor speed Omega, Hz (rev/s; thrust c_xi Omega^2)")
    omega_max_hz: float = Field(100.0, gt=0.0, description="highest motor speed Omega, Hz")
    omega_dot_min_hz_s: float = Field(-300.0, le=-MIN_MOTOR_RATE_HZ_S, description="most negative motor acceleration, Hz/s")
    omega_dot_max_hz_s: float = Field(400.0, ge=MIN_MOTOR_RATE_HZ_S, description="largest motor acceleration, Hz/s")
    min_hover_margin: float = Field(0.2, ge=0.0, lt=1.0, description="fraction of omega_max_hz every motor keeps "
                                    "above its hover speed (thrust headroom to brake and recover)")

    @field_validator("inertia_kgm2")
    @classmethod
    def _positive_inertia(cls, v):
        if min(v) <= 0:
            raise ValueError(f"every principal inertia must be > 0 kg m^2, got {v}")
        return v

    @model_validator(mode="after")
    def _bounds_and_hover(self):
        if self.omega_min_hz >= self.omega_max_hz:
            raise ValueError(
                f"omega_min_hz ({self.omega_min_hz}) must be < omega_max_hz ({self.omega_max_hz})"
            )
        veh = self.vehicle()
        F, M = veh.allocation()
        if np.linalg.matrix_rank(np.vstack([F, M]), tol=1e-9 * max(1.0, float(np.abs(F).max()))) < 4 or \
                np.linalg.matrix_rank(M, tol=1e-12) < 3:
            raise ValueError("the rotor layout's allocation cannot produce thrust plus three independent moments "
                             f"(rank [F; M] = {np.linalg.matrix_rank(np.vstack([F, M]))}, rank M = {np.linalg.matrix_rank(M)}): "
                             "the vehicle cannot hold its attitude")
        try:
            hover = veh.hover_speeds()
        except HoverInfeasibleError as exc:
            raise ValueError(str(exc)) from None
        limit = (1.0 - self.min_hover_margin) * self.omega_max_hz
        if float(np.max(hover)) > limit + 1e-9:
            raise ValueError(f"hover needs {np.max(hover):.2f} Hz, above {limit:.2f} Hz = (1 - min_hover_margin "
                             f"{self.min_hover_margin:g}) x omega_max_hz: no thrust left to brake or recover; raise "
                             "omega_max_hz or state a smaller min_hover_margin")
        return self

    def vehicle(self) -> Multirotor:
        """Build the vehicle model described by this configuration."""
        params: dict[str, Any] = dict(
            mass=self.mass_kg,
            inertia=np.diag(self.inertia_kgm2),
            gravity=self.gravity_m_s2,
            c_xi=self.c_xi,
            c_tau=self.c_tau,
            omega_min=self.omega_min_hz,
            omega_max=self.omega_max_hz,
            omega_dot_min=self.omega_dot_min_hz_s,
            omega_dot_max=self.omega_dot_max_hz_s,
        )
        if self.rotors is None:
            return star_multirotor(self.rotor_count, self.tilt_deg, self.arm_length_m, **params)
        axes = np.array([r.axis for r in self.rotors], float)
        axes /= np.linalg.norm(axes, axis=1, keepdims=True)
        return Multirotor(
            positions=np.array([r.position for r in self.rotors], float),
            axes=axes,
            spins=np.array([r.spin for r in self.rotors], float),
            **params,
        )


class AntennaConfig(_Strict):
    """Antenna pattern shared by every node (dipole along body z by default)."""

    pattern: Literal["dipole", "sin_power"] = Field("dipole", description="the vehicles' antenna pattern: half-wave "
                                                    "dipole (App. A) or sin(theta)^exponent")
    exponent: float = Field(2.0, gt=0.0, description="n of the sin^n pattern")
    g_bar: float = Field(1.0, gt=0.0, description="peak (broadside) gain")
    g_bar_dbi: float | None = Field(None, ge=-30.0, le=30.0, description="the peak gain in dBi (link budgets): sets "
                                    "g_bar = 10^(g_bar_dbi / 10); given with g_bar, the two must agree")
    bs_pattern: Literal["dipole", "isotropic", "cosine"] = Field(
        "dipole", description="the base station's antenna: a vertical dipole (of `pattern`), isotropic (gain g_bar) or "
        "cosine: a sector antenna G = bs_g_max max(max(cos psi, 0)^bs_exponent, bs_back_lobe), psi off its boresight, "
        "pointed by bs_tilt_deg and bs_azimuth_deg")
    bs_g_max: float = Field(4.0, gt=0.0, le=1e4, description="cosine base station: peak gain (linear; 4 = 6 dBi)")
    bs_exponent: float = Field(2.0, ge=0.0, le=100.0, description="cosine base station: n of max(cos psi, 0)^n")
    bs_back_lobe: float = Field(0.01, ge=0.0, le=1.0, description="cosine base station: gain floor relative to bs_g_max")
    bs_tilt_deg: float = Field(10.0, ge=-90.0, le=90.0, description="cosine base station: boresight below the horizon, "
                               "deg (down-tilt; negative points it up)")
    bs_azimuth_deg: float = Field(0.0, ge=-360.0, le=360.0, description="cosine base station: boresight azimuth, deg "
                                  "(from world x toward world y)")
    source_pattern: Literal["dipole", "isotropic"] = Field(
        "dipole", description="MRAV-2's antenna: a dipole (of `pattern`) along its body z, or isotropic (gain g_bar)")
    directivity: float = Field(1.0, gt=0.0, le=10.0,
                               description="multiplies every dipole's normalized gain (the paper's D = 1.64 informational)")
    bs_axis: Vec3 = Field(default_factory=lambda: [0.0, 0.0, 1.0], description="the base station's antenna axis, world")

    _nonzero_axis = field_validator("bs_axis")(lambda v: _nonzero_direction(v, "the base station's antenna axis"))

    @model_validator(mode="after")
    def _gain_in_dbi(self):
        if self.g_bar_dbi is None:
            return self
        linear = 10.0 ** (self.g_bar_dbi / 10.0)
        if "g_bar" in self.model_fields_set and not math.isclose(self.g_bar, linear, rel_tol=1e-9):
            raise ValueError(f"antenna.g_bar ({self.g_bar:g}) and antenna.g_bar_dbi ({self.g_bar_dbi:g} dBi = "
                             f"{linear:.6g}) disagree: give one of them")
        object.__setattr__(self, "g_bar", linear)
        return self

    @model_validator(mode="after")
    def _one_bs_direction(self):
        if self.bs_pattern == "cosine" and self.bs_axis != [0.0, 0.0, 1.0]:
            raise ValueError("bs_axis: a cosine base station is pointed by bs_tilt_deg and bs_azimuth_deg; "
                             "leave bs_axis at its default")
        return self

    def bs_antenna_axis(self) -> list[float]:
        """The base station's antenna axis (world; the scene normalizes it): ``bs_axis``, or a cosine
        antenna's boresight from its down-tilt and azimuth."""
        if self.bs_pattern != "cosine":
            return list(self.bs_axis)
        tilt, az = math.radians(self.bs_tilt_deg), math.radians(self.bs_azimuth_deg)
        return [math.cos(tilt) * math.cos(az), math.cos(tilt) * math.sin(az), -math.sin(tilt)]

    def build(self):
        """The relay's pattern (a dipole scaled by the directivity)."""
        g = self.g_bar * self.directivity
        if self.pattern == "dipole":
            return DipolePattern(g)
        return SinPowerPattern(self.exponent, g)

    def patterns(self) -> NodePatterns:
        """Every node's pattern; the trajectory generator's surrogate does not use them (eq. 12-13)."""
        dipole = self.build()
        bs = {"dipole": dipole, "isotropic": IsotropicPattern(self.g_bar),
              "cosine": CosinePattern(self.bs_g_max, self.bs_exponent, self.bs_back_lobe)}[self.bs_pattern]
        return NodePatterns(relay=dipole, source=dipole if self.source_pattern == "dipole" else IsotropicPattern(self.g_bar),
                            bs=bs)


BOLTZMANN_J_K = 1.380649e-23


class PropagationConfig(_Strict):
    """Large-scale propagation (``models/propagation.py``). ``free_space``: the paper's ``1/d^2``
    (Friis with the wavelength in physical units); ``log_distance``: ``PL(d0) + 10 n log10(d/d0)``;
    ``rma_av``: 3GPP TR 36.777 RMa-AV (physical units, every aerial end above 10 m: controllers plan
    with the gain expected over the LoS state, the plant draws the state and the standard's
    shadowing). Log-normal shadowing (dB, zero mean, a random field over each link's geometry
    correlated ``exp(-Delta d / decorrelation_m)``) perturbs the plant's channel and the bound, not
    what the controllers plan with."""

    model: Literal["free_space", "log_distance", "rma_av"] = Field("free_space", description="the path-gain model "
                                                                   "(see the table's text)")
    exponent: float = Field(2.0, ge=1.0, le=6.0, description="log_distance: path-loss exponent n")
    reference_distance_m: float = Field(1.0, gt=0.0, le=1000.0, description="log_distance: d0, m")
    reference_loss_db: float | None = Field(None, ge=-100.0, le=200.0, description="log_distance: PL(d0), dB "
                                            "(default: free space at d0: Friis in physical units, 0 dB normalized)")
    shadowing_std_db: float = Field(0.0, ge=0.0, le=20.0, description="log-normal shadowing std, dB (0: none)")
    decorrelation_m: float = Field(10.0, gt=0.0, le=1000.0, description="shadowing decorrelation distance, m")

    @property
    def random(self) -> bool:
        """Whether the large-scale channel has a realization drawn per seed (shadowing, LoS states)."""
        return self.shadowing_std_db > 0 or self.model == "rma_av"

    @model_validator(mode="after")
    def _rma_av_shadowing_is_the_standards(self):
        if self.model == "rma_av" and self.shadowing_std_db > 0:
            raise ValueError("channel.propagation.shadowing_std_db: rma_av draws the standard's shadowing "
                             "(TR 36.777 Table B-3: LoS 4.2 exp(-0.0046 h) dB, NLoS 6 dB); leave it at 0")
        return self


class ChannelFadingConfig(_Strict):
    """Small-scale fading model for ``perturbations.fading_k_db``: ``iid`` (the paper's robustness
    runs: an independent Rician draw per control step) or ``doppler`` (Rician whose diffuse part
    is a Gauss-Markov process with the correlation ``J0(2 pi f_D tau)`` at the control period,
    ``f_D`` from each link's relative speed and ``channel.carrier_hz``)."""

    model: Literal["iid", "doppler"] = Field("iid", description="iid: a Rician draw per step; doppler: time-correlated")


class ChannelConfig(_Strict):
    """Link budget. ``units = "normalized"``: the paper's (Table I; B = 1, powers in W, C in
    bit/s/Hz). ``units = "physical"``: carrier (Hz), bandwidth (Hz), transmit power (dBm), noise
    ``k T B`` plus a noise figure (dB), Friis free space with the wavelength; C in bit/s."""

    units: Literal["normalized", "physical"] = Field("normalized", description="normalized: the paper's (B = 1, W, "
                                                     "bit/s/Hz); physical: Hz, dBm, kTB noise, bit/s")
    bandwidth: float = Field(1.0, gt=0.0, description="B, normalized (units = normalized)")
    tx_power_w: float = Field(1.0, gt=0.0, description="P_U (units = normalized)")
    noise_power_w: float = Field(1.0, gt=0.0, description="sigma^2 (units = normalized)")
    carrier_hz: float = Field(2.4e9, ge=1e8, le=1e11, description="carrier frequency, Hz (physical units, Doppler fading)")
    bandwidth_hz: float = Field(20e6, ge=1e3, le=1e10, description="bandwidth, Hz (units = physical)")
    tx_power_dbm: float = Field(20.0, ge=-30.0, le=60.0, description="transmit power of MRAV-2 and the relay, dBm (physical)")
    noise_figure_db: float = Field(7.0, ge=0.0, le=30.0, description="receiver noise figure, dB (physical)")
    temperature_k: float = Field(290.0, gt=0.0, le=1000.0, description="noise temperature, K (physical)")
    outage_threshold: float | None = Field(None, gt=0.0, description="outage when the end-to-end C is below this, in the "
                                           "capacity's unit (bit/s/Hz normalized, bit/s physical); default: "
                                           "OUTAGE_SPECTRAL_EFFICIENCY = 1e-3 bit/s/Hz (the paper's), times bandwidth_hz "
                                           "in physical units (20 kbit/s at 20 MHz)")
    propagation: PropagationConfig = Field(default_factory=PropagationConfig)
    fading: ChannelFadingConfig = Field(default_factory=ChannelFadingConfig)

    @property
    def physical(self) -> bool:
        return self.units == "physical"

    @property
    def outage(self) -> float:
        """The outage threshold in the capacity's unit: ``outage_threshold``, or the paper's 1e-3
        bit/s/Hz (normalized) and the same spectral efficiency times the bandwidth (physical, bit/s)."""
        if self.outage_threshold is not None:
            return self.outage_threshold
        return OUTAGE_SPECTRAL_EFFICIENCY * (self.bandwidth_hz if self.physical else 1.0)

    @property
    def capacity_unit(self) -> str:
        """What capacities are in: bit/s/Hz (the paper's normalized B = 1) or bit/s (physical)."""
        return "bit/s" if self.physical else "bit/s/Hz"

    def link_budget_values(self) -> tuple[float, float, float]:
        """``(P_U W, noise W, B)``: the normalized fields, or ``10^((dBm - 30)/10)``, ``k T B
        10^(NF/10)`` and ``B`` in Hz."""
        if not self.physical:
            return self.tx_power_w, self.noise_power_w, self.bandwidth
        noise = BOLTZMANN_J_K * self.temperature_k * self.bandwidth_hz * 10.0 ** (self.noise_figure_db / 10.0)
        return dbm_to_w(self.tx_power_dbm), noise, self.bandwidth_hz


def dbm_to_w(dbm: float) -> float:
    """``10^((dBm - 30)/10)`` W."""
    return 10.0 ** ((dbm - 30.0) / 10.0)


class NodesConfig(_Strict):
    """Fixed and initial node positions (m, world). MRAV-2 starts at the mission's first point."""

    bs: Vec3 = Field(default_factory=lambda: [0.0, 0.0, 0.0], description="the base station's position p0, m (world)")
    relay: Vec3 = Field(default_factory=lambda: [-6.95, 5.79, 1.72], description="the relay's start p1(0), m (world), "
                        "hovering; inside controller.workspace")


Waypoint = Annotated[list[float], Field(min_length=4, max_length=4)]


def _check_waypoint_times(wps: list[list[float]], first_zero: bool) -> None:
    t = [w[0] for w in wps]
    if first_zero and t[0] != 0.0:
        raise ValueError(f"the first waypoint time must be 0 s, got {t[0]}")
    if t[0] < 0.0:
        raise ValueError(f"waypoint times must be >= 0 s, got {t[0]}")
    if any(b <= a for a, b in zip(t, t[1:], strict=False)):
        raise ValueError(f"waypoint times must be strictly increasing, got {t}")


class JammerConfig(_Strict):
    """A ground jammer: fixed at ``position`` or moving along timed ``waypoints``; isotropic
    (the paper's) or ``cosine``: ``G(psi) = g_max max(max(cos psi, 0)^exponent, back_lobe)``,
    ``psi`` off boresight, pointed at a node (``point_at``, tracking it) or along ``boresight``."""

    name: str = Field("jammer", min_length=1, description="names the jammer in logs and reports")
    position: Vec3 = Field(default_factory=lambda: [-6.95, -5.79, 1.72], description="m, world (the start when moving)")
    waypoints: list[Waypoint] | None = Field(None, min_length=2, description="timed path [[t_s, x, y, z], ...]")
    path: Literal["linear", "minimum_jerk"] = Field("linear", description="how the jammer moves between waypoints")
    repeat: bool = Field(False, description="fly the waypoints again and again (a loop: the last waypoint at the first "
                         "one's position); false: hold the last one")
    power_w: float = Field(1.0, ge=0.0, description="peak radiated power P_J, W (the paper's 1 W adds ~1% to its 1 W "
                           "noise: set a jammer where it matters)")
    power_dbm: float | None = Field(None, ge=-30.0, le=90.0, description="peak power in dBm (replaces power_w)")
    schedule: Literal["always_on", "on_off"] = Field("always_on", description="always_on, or on_off: on_s ON then "
                                                     "off_s OFF, repeating (OFF: P_J = 0)")
    on_s: float = Field(5.0, gt=0.0, description="on_off schedule: ON time, s")
    off_s: float = Field(5.0, gt=0.0, description="on_off schedule: OFF time, s")
    localization_delay_s: float = Field(2.0, ge=0.0, description="tau_E")
    localization: Literal["oracle", "estimated"] = Field(
        "oracle", description="oracle: the true position after tau_E (the paper's); estimated: the relay estimates it "
        "from its received interference power ([estimation], estimation/jammer_estimator.py)")
    inr_db_at_relay_start: float | None = Field(
        None, ge=-40.0, le=40.0, description="set the peak power so that this jammer's interference-to-noise ratio at "
        "the relay's start (hovering, its antenna gain included) is this many dB (replaces power_w / power_dbm)")
    pattern: Literal["isotropic", "cosine"] = Field("isotropic", description="the jammer's antenna: isotropic (the "
                                                    "paper's) or cosine (g_max, exponent, back_lobe, pointed)")
    g_max: float = Field(1.0, gt=0.0, le=1e4, description="cosine pattern: peak gain (linear)")
    exponent: float = Field(0.0, ge=0.0, le=100.0, description="cosine pattern: n of max(cos psi, 0)^n")
    back_lobe: float = Field(0.0, ge=0.0, le=1.0, description="cosine pattern: gain floor relative to g_max")
    point_at: Literal["bs", "relay", "source"] | None = Field(None, description="cosine pattern: the node it tracks")
    boresight: Vec3 | None = Field(None, description="cosine pattern: fixed boresight direction, world")

    @property
    def peak_power_w(self) -> float:
        """``power_w``, or ``power_dbm`` in W when given."""
        return dbm_to_w(self.power_dbm) if self.power_dbm is not None else self.power_w

    @model_validator(mode="after")
    def _path_and_pointing(self):
        if self.power_dbm is not None and self.inr_db_at_relay_start is not None:
            raise ValueError("give power_dbm or inr_db_at_relay_start, not both")
        if self.waypoints is not None:
            _check_waypoint_times(self.waypoints, first_zero=False)
            start = list(self.waypoints[0][1:])
            if "position" in self.model_fields_set and self.position != start:
                raise ValueError(f"position {self.position} differs from waypoints[0] {start}: omit position for a moving jammer")
            object.__setattr__(self, "position", start)
            end = self.waypoints[-1][1:]
            if self.repeat and math.dist(start, end) > LOOP_CLOSURE_M:
                raise ValueError(f"repeat = true flies the waypoints as a loop: the last one {end} must be at the first "
                                 f"one's position {start} (within {LOOP_CLOSURE_M} m)")
        elif self.repeat:
            raise ValueError("repeat = true needs waypoints (a fixed jammer has nothing to repeat)")
        if self.pattern == "cosine" and (self.point_at is None) == (self.boresight is None):
            raise ValueError("a cosine jammer needs exactly one of point_at (a node) and boresight (a direction)")
        if self.pattern == "isotropic" and (self.point_at is not None or self.boresight is not None):
            raise ValueError("point_at / boresight apply to pattern = \"cosine\" only")
        if self.boresight is not None:
            _nonzero_direction(self.boresight, "boresight")
        return self


def _weights_model() -> type[BaseModel]:
    """``[controller.weights]``: one field per cost term of ``control/terms.py`` (and
    ``<name>_terminal`` for a term with its own terminal weight). Each is the diagonal entry
    ``q`` of a term ``q * r^2`` (docs/concepts/weights-that-fly.md)."""
    fields: dict = {}
    for t in COST_TERMS:
        low = {"gt": 0.0} if t.strictly_positive else {"ge": 0.0}
        fields[t.name] = (float, Field(t.default, description=t.doc, **low))  # type: ignore[call-overload]
        if t.own_terminal:
            fields[f"{t.name}_terminal"] = (float, Field(float(t.terminal), ge=0.0, description=f"terminal: {t.doc}"))  # type: ignore[arg-type]
    return create_model("Weights", __base__=_Strict, __doc__=_weights_model.__doc__, **fields)


Weights = _weights_model()


class FailsafeConfig(_Strict):
    """When the brake law takes over from the NMPC, and when the NMPC takes over again."""

    failures_to_fallback: int = Field(3, ge=1, le=1000, description="consecutive QP failures before the hand-over")
    successes_to_resume: int = Field(5, ge=1, le=1000, description="consecutive QP successes before the NMPC resumes")
    workspace_margin_m: float = Field(0.5, ge=0.0, le=5.0, description="the brake law's hold point keeps this far inside the workspace")
    supervisor: bool = Field(True, description="the flight-safety supervisor: outside its envelope the brake law flies at once")
    box_tolerance_m: float = Field(0.05, ge=0.0, le=2.0, description="envelope: how far past the workspace box, m")
    max_tilt_deg: float = Field(45.0, gt=0.0, le=89.0, description="envelope: body tilt, deg")
    max_speed_m_s: float = Field(10.0, gt=0.0, le=50.0, description="envelope: speed, m/s")
    max_body_rate_rad_s: float = Field(6.0, gt=0.0, le=50.0, description="envelope: body rates, rad/s")
    max_safety_handovers: int = Field(1, ge=1, le=1000, description="after this many envelope hand-overs the brake law "
                                      "keeps the relay for the rest of the mission")


class Workspace(_Strict):
    """Axis-aligned box (m, world) the relay must stay in (NMPC position bounds)."""

    min: Vec3 = Field(default_factory=lambda: [-7.0, -6.0, 0.5], description="the box's lower corner, m (world; z at or "
                      "above world.ground_z_m)")
    max: Vec3 = Field(default_factory=lambda: [7.0, 6.0, 19.0], description="the box's upper corner, m (world)")

    @model_validator(mode="after")
    def _ordered(self):
        for i, ax in enumerate("xyz"):
            if self.min[i] >= self.max[i]:
                raise ValueError(f"workspace {ax}: min ({self.min[i]}) must be < max ({self.max[i]})")
        return self

    def contains(self, p) -> bool:
        return all(self.min[i] <= p[i] <= self.max[i] for i in range(3))


class CapacityPlannerConfig(_Strict):
    """The capacity-seeking planner (``controller.planner = "capacity"``). Its NMPC tracks the
    planner's position and antenna-axis references: the paper's comms-aware terms (misalignment
    cost, mutual-alignment constraint) are dropped whatever ``controller.variant`` says, and the
    position weights below replace ``weights.position`` / ``weights.position_terminal``."""

    speed_m_s: float = Field(1.0, gt=0.0, le=5.0, description="reference speed limit, m/s")
    max_accel_m_s2: float = Field(4.0, gt=0.0, le=8.0, description="reference acceleration limit, m/s^2")
    brake_accel_m_s2: float = Field(1.5, gt=0.0, le=8.0, description="the reference slows down early enough to stop on "
                                    "its target at this deceleration, m/s^2 (at most max_accel_m_s2; 4: the tilted relay at "
                                    "3 m/s overshot its braking reference by 0.9 m, motors at their bounds: docs/results/controller-speed.md)")
    margin_m: float = Field(0.05, ge=0.0, le=2.0, description="the reference keeps this far inside the workspace box, m")
    leash_m: float = Field(1.0, gt=0.0, le=20.0, description="the target stays this close to the pre-flight route, m")
    route_grid_m: float = Field(1.0, ge=0.1, le=3.0, description="grid of the pre-flight route, m (0.5 m: 9-11 s before "
                                "take-off, 1 m: 0.3-0.6 s on this VM, capacity within 0.01 of the bound either way)")
    lookahead_s: float | None = Field(None, ge=0.0, le=10.0, description="MRAV-2 is predicted this far ahead for the "
                                      "target, s (default: 1 s up to 1 m/s, 1 m / speed_m_s above: a faster relay lags less)")
    axis_rate_deg_s: float = Field(30.0, gt=0.0, le=720.0, description="the antenna-axis reference turns at most this fast, deg/s")
    axis_step_deg: float = Field(5.0, ge=1.0, le=30.0, description="spacing of the antenna axes the planner scores "
                                 "(tilt rings and azimuths), deg")
    tilt_fraction: float = Field(0.85, gt=0.0, le=1.0, description="the antenna axes the planner may ask for tilt at most "
                                 "this fraction of the platform's hover tilt limit toward their azimuth (1: up to the limit, "
                                 "where a motor saturates; the bound allows the full limit)")
    tracking_freq_rad_s: float = Field(1.0, gt=0.0, le=5.0, description="a level-only platform's thrust-direction reference "
                                       "adds the acceleration a critically damped PD law of this frequency asks to close its "
                                       "tracking error (1.5: the same link, a motor at a bound 5x as often)")
    boundary_axes: bool = Field(True, description="besides the tilt rings every axis_step_deg, the axes at the tilt limit "
                                "(times tilt_fraction) toward each azimuth: the strongest holdable tilts, which the rings miss "
                                "by up to axis_step_deg")
    yaw_rate_deg_s: float = Field(0.0, ge=0.0, le=90.0, description="the platform may yaw (its reference at most this "
                                  "fast, deg/s, in 10 deg steps within +-60 deg) to bring its strongest tilt azimuth under "
                                  "the antenna axis it wants (0: zero yaw)")
    excursion_m: float = Field(0.0, ge=0.0, le=10.0, description="while an estimated jammer's position std is above "
                               "excursion_std_m, the target circles at this radius (m) to make the jammer observable (0: off)")
    excursion_std_m: float = Field(1.0, gt=0.0, le=100.0, description="the excursion stops once every estimated jammer's "
                                   "largest position std is below this, m")
    excursion_max_loss: float = Field(0.05, ge=0.0, le=1.0, description="the excursion pauses while the best capacity at "
                                      "its circling point is more than this fraction below the target's (1: never pauses)")
    position_weight: float = Field(5.0, ge=0.0, description="replaces weights.position, m^-2")
    position_weight_terminal: float = Field(50.0, ge=0.0, description="replaces weights.position_terminal, m^-2")
    scoring: Literal["joint", "decoupled"] = Field("joint", description="joint: every candidate position with every "
                                                   "holdable axis (27 x K poses); decoupled: the positions at the current "
                                                   "axis goal, then every axis at the best one (27 + K: docs/results/controller-speed.md)")
    replan_every: int = Field(4, ge=1, le=50, description="control steps between two replans (all candidates scored in "
                              "one compiled call): 1 spreads the planner over every step, so no step carries it alone "
                              "(docs/results/controller-speed.md)")
    qp_iter_max: int = Field(50, ge=1, le=100, description="the tracking NMPC's QP interior-point iteration cap (5 "
                             "trims the step-time tail on the presets; an iterate that fails qp_accept_tol continues from "
                             "itself for up to 50 more: docs/results/controller-speed.md)")
    qp_accept_tol: float = Field(0.0, ge=0.0, le=1e-2, description="a QP the cap stopped is flown when its primal "
                                 "residuals (dynamics, every inequality) are <= this, else it is a QP failure (0: never)")

    @property
    def lookahead(self) -> float:
        """MRAV-2's prediction horizon for the target, s (``lookahead_s``, or 1 s up to 1 m/s and
        1 m / ``speed_m_s`` above: measured on the nominal tilted mission at 3 m/s, mean C 0.796 /
        0.818 / 0.835 of the path bound at 1 / 0.5 / 0 s; at 1 m/s 0.842 / 0.832 at 1 / 0.5 s)."""
        return self.lookahead_s if self.lookahead_s is not None else min(1.0, 1.0 / self.speed_m_s)


class ControllerConfig(_Strict):
    """Trajectory generator + communications-aware NMPC."""

    variant: Literal["constrained", "unconstrained"] = Field("constrained", description="constrained: the paper's "
                                                             "comms-aware NMPC (misalignment cost, alignment constraint); "
                                                             "unconstrained: the same NMPC without them")
    planner: Literal["trajectory_generator", "isotropic", "single_shot", "capacity"] = Field(
        "trajectory_generator",
        description="the paper's generator; baseline A (isotropic surrogate); baseline B (single-shot plan); "
        "capacity: the capacity-seeking planner (planning/capacity_planner.py)",
    )

    ts_s: float = Field(0.015, gt=0.0, le=MAX_TS_S, description="NMPC sampling period Ts (one RK4 step per period)")
    horizon: int = Field(30, ge=1, le=200, description="N shooting intervals")
    mu: float = Field(0.2, ge=0.0, le=1.0, description="minimum mutual alignment")
    q_slack: float = Field(1e4, gt=0.0, description="q_pi")
    governor_speed_m_s: float = Field(0.5, gt=0.0, description="max speed of the reference governor")
    hessian_eig_floor: float = Field(1e-3, gt=0.0, description="min eigenvalue of H11 after regularization")
    exact_input_rate: bool = Field(
        True, description="input-rate cost through an augmented state (exact) or the previous plan (faster)"
    )
    senses_jammer_state: bool = Field(
        False, description="after localization, the generator plans with P_J = 0 while the jammer is OFF "
        "(it senses the schedule); otherwise it plans with the nominal power throughout"
    )
    weights: Weights = Field(default_factory=Weights)  # type: ignore[valid-type]
    workspace: Workspace = Field(default_factory=Workspace)
    failsafe: FailsafeConfig = Field(default_factory=FailsafeConfig)
    capacity: CapacityPlannerConfig = Field(default_factory=CapacityPlannerConfig)

    @model_validator(mode="after")
    def _surrogate_defined(self):
        if self.mu <= 0.0 and self.planner == "trajectory_generator":
            raise ValueError("mu = 0 makes the trajectory generator's surrogate link H_bar = sqrt(mu) G_bar / d vanish "
                             "(its inverse capacity is infinite); use mu > 0 with controller.planner = 'trajectory_generator'")
        return self

    @model_validator(mode="after")
    def _prediction_long_enough(self):
        if self.horizon * self.ts_s < MIN_PREDICTION_S - 1e-12:
            raise ValueError(f"horizon x ts_s = {self.horizon} x {self.ts_s:g} s = {self.horizon * self.ts_s:.3g} s: the NMPC "
                             f"must predict >= {MIN_PREDICTION_S} s to plan a stop inside the workspace (horizon >= "
                             f"{math.ceil(MIN_PREDICTION_S / self.ts_s - 1e-9)} at this ts_s)")
        return self

    @property
    def comms_aware(self) -> bool:
        """Whether the NMPC carries the paper's comms-aware terms (constrained variant, and not
        the capacity planner, whose antenna-axis reference replaces them)."""
        return self.variant == "constrained" and self.planner != "capacity"


@functools.lru_cache(maxsize=16)
def _flight_file_path(kind: str, file: str, stamp: tuple, yaw_deg: float, offset: tuple):
    """A CSV or ULog path, cached by file, modification stamp and frame (read-only objects)."""
    return UlogPath(file, yaw_deg=yaw_deg, offset=list(offset)) if kind == "ulog" else CsvPath(file)


def flight_path(kind: str, file: str, yaw_deg: float = 0.0, offset=(0.0, 0.0, 0.0)):
    """A mission file's path (``kind`` ``csv`` or ``ulog``), read once per content: every check of a
    load and the path itself share it. ValueError names a file that cannot be read."""
    st = Path(file).stat()
    return _flight_file_path(kind, file, (st.st_mtime_ns, st.st_size), float(yaw_deg), tuple(offset))


class MissionConfig(_Strict):
    """MRAV-2 path: minimum-jerk segments through timed waypoints ``[t_s, x, y, z]`` or a CSV."""

    waypoints: list[Waypoint] = Field(
        default_factory=lambda: [
            [0.0, -3.04, 5.79, 1.72],
            [12.0, -1.5, 4.29, 9.0],
            [17.0, -1.5, 4.29, 9.0],
            [28.0, -3.0, 4.29, 16.5],
            [38.0, 0.0, 4.29, 16.5],
            [47.0, -1.5, 4.29, 17.5],
        ],
        min_length=2,
        description="MRAV-2's timed path [[t_s, x, y, z], ...] (s, m world), minimum-jerk segments, first time 0",
    )
    trajectory_csv: str | None = Field(None, description="CSV with columns t,px,py,pz,vx,vy,vz,ax,ay,az (or t,px,py,pz)")
    trajectory_ulog: str | None = Field(None, description="PX4 flight log (ULog): vehicle_local_position, NED")
    ulog_yaw_deg: float = Field(0.0, ge=-360.0, le=360.0, description="turns the ULog's east-north frame about z, deg")
    ulog_offset_m: Vec3 = Field(default_factory=lambda: [0.0, 0.0, 0.0], description="shifts the ULog's path, m (world)")

    @field_validator("waypoints")
    @classmethod
    def _increasing_times(cls, wps):
        _check_waypoint_times(wps, first_zero=True)
        return wps

    @field_validator("trajectory_csv")
    @classmethod
    def _readable_csv(cls, v):
        if v is None:
            return v
        if not Path(v).is_file():
            raise ValueError(f"no such file {v}")
        flight_path("csv", v)  # finite numbers, >= 2 rows, increasing time, every column (ValueError names the problem)
        return v

    @model_validator(mode="after")
    def _readable_ulog(self):
        if self.trajectory_ulog is None:
            return self
        if self.trajectory_csv is not None:
            raise ValueError("give one of trajectory_csv and trajectory_ulog, not both")
        if not Path(self.trajectory_ulog).is_file():
            raise ValueError(f"trajectory_ulog: no such file {self.trajectory_ulog}")
        try:
            flight_path("ulog", self.trajectory_ulog, self.ulog_yaw_deg, self.ulog_offset_m)
        except ValueError as exc:
            raise ValueError(f"trajectory_ulog: {exc}") from None
        return self

    @property
    def flown_file(self) -> str | None:
        """The mission file that flies (ULog or CSV), if any."""
        return self.trajectory_ulog or self.trajectory_csv

    def path(self):
        """MRAV-2's path object (``models.mission``); a flight file is read once per content stamp
        (the checks of a load ask for it several times)."""
        f = self.flown_file
        if f and Path(f).is_file():
            if self.trajectory_ulog:
                return flight_path("ulog", f, self.ulog_yaw_deg, self.ulog_offset_m)
            return flight_path("csv", f)
        if self.trajectory_ulog:
            return UlogPath(self.trajectory_ulog, yaw_deg=self.ulog_yaw_deg, offset=self.ulog_offset_m)
        return CsvPath(self.trajectory_csv) if self.trajectory_csv else MinimumJerkPath(self.waypoints)

    @property
    def duration_s(self) -> float:
        """Mission length (s): the last waypoint's time, or the flight file's last time."""
        f = self.flown_file
        return self.path().duration if f and Path(f).is_file() else self.waypoints[-1][0]

    @property
    def start(self) -> list[float]:
        """MRAV-2's initial position (m)."""
        f = self.flown_file
        if f and Path(f).is_file():
            return [float(v) for v in self.path().state(0.0).p]
        return list(self.waypoints[0][1:])


class WorldConfig(_Strict):
    """The world the vehicles fly in: the ground, and how far a mission may reach."""

    ground_z_m: float = Field(0.0, ge=-1000.0, le=10000.0, description="height of the ground, m (world z): the workspace, "
                              "every mission and every jammer stay at or above it; a vehicle below it makes the run unsafe")
    mission_max_distance_m: float = Field(1000.0, gt=0.0, le=100_000.0, description="how far from controller.workspace "
                                          "MRAV-2's path may reach, m: a sample farther away is refused as a damaged file")


def _box_distance(p: np.ndarray, lo, hi) -> np.ndarray:
    """Distance (m) of points ``(n, 3)`` from the box ``[lo, hi]`` (0 inside)."""
    out = np.maximum(np.maximum(np.asarray(lo, float) - p, p - np.asarray(hi, float)), 0.0)
    return np.linalg.norm(out, axis=1)


class SimConfig(_Strict):
    """Closed-loop simulation rates and length."""

    plant_rate_hz: float = Field(1000.0, gt=0.0, le=20000.0, description="RK4 rate of the simulated plant, Hz")
    control_rate_hz: float | None = Field(None, gt=0.0, le=500.0, description="default 1/Ts")
    duration_s: float | None = Field(None, gt=0.0, allow_inf_nan=False, description="default: the mission's length")


class PerturbationConfig(_Strict):
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


class BoundConfig(_Strict):
    """Resolution of the capacity bounds (``aerorelay bound``, planning/bound.py)."""

    max_speed_m_s: float = Field(1.0, gt=0.0, le=20.0, description="speed limit of the path bounds, m/s")
    grid_m: float = Field(0.5, ge=0.1, le=3.0, description="position grid spacing, m")
    dt_s: float = Field(0.5, ge=0.05, le=5.0, description="time grid spacing, s")
    axis_step_deg: float = Field(5.0, ge=1.0, le=30.0, description="spacing of the relay antenna axes searched, deg")
    max_accel_m_s2: float = Field(4.0, gt=0.0, le=50.0, description="acceleration limit of the flyable paths (from rest "
                                  "at the start), m/s^2: the capacity planner's reference limit by default")


class EstimationConfig(_Strict):
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
    search_min_m: Vec3 | None = Field(None, description="search box corner, m world (default: the nodes' box +- 10 m, z >= 0)")
    search_max_m: Vec3 | None = Field(None, description="search box corner, m world")
    confident_std_m: float = Field(1.5, gt=0.0, le=100.0, description="the planner uses an estimate once its largest "
                                   "position std (m) is below this (before: plans without that jammer, as before tau_E)")

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


def reach_grid(lo: np.ndarray, hi: np.ndarray, max_points: int) -> np.ndarray:
    """Relay positions over the box ``[lo, hi]`` (m): 1 m apart, or evenly coarser until at most
    ``max_points``; ``(P, 3)``."""
    spacing = 1.0
    while True:
        counts = [int(np.ceil((hi[i] - lo[i]) / spacing)) + 1 for i in range(3)]
        if math.prod(counts) <= max_points:
            break
        spacing *= 1.1
    return np.stack(np.meshgrid(*[np.linspace(lo[i], hi[i], counts[i]) for i in range(3)], indexing="ij"), -1).reshape(-1, 3)


@functools.lru_cache(maxsize=8)
def _platform_vehicle(platform_json: str) -> Multirotor:
    """The platform's vehicle, built once per platform (its hover-tilt limits are LPs, cached on it)."""
    return PlatformConfig.model_validate_json(platform_json).vehicle()


@functools.lru_cache(maxsize=64)
def _reachable_alignment(platform_json: str, mission_json: str, ws_min: tuple, ws_max: tuple, bs: tuple,
                         duration_s: float) -> tuple[np.ndarray, np.ndarray, float]:
    """Per second of the mission: the largest mutual alignment the relay reaches in hover anywhere in
    the workspace (1 m grid, hover-holdable axes every 3 deg); the times (s); the hover tilt limit
    (deg). Bounded whatever the scenario: at most ``REACH_MAX_TIMES`` instants (evenly spaced over a
    longer mission) and ``REACH_MAX_WORK`` evaluations (a coarser grid over a large workspace), so
    the check is exact on the presets and a lower estimate of the reach on huge scenarios. A grid
    point on the base station or MRAV-2 (no link direction) is skipped. Cached: every load of the
    same scenario asks the same."""
    veh = _platform_vehicle(platform_json)
    lo, hi = np.array(ws_min, float), np.array(ws_max, float)
    path = source_trajectory(MissionConfig.model_validate_json(mission_json))
    end = min(duration_s, path.duration)  # MRAV-2 holds its last state after its path
    times = np.linspace(0.0, end, min(int(np.ceil(end)) + 1, REACH_MAX_TIMES))
    axes = axis_cone(veh.hover_tilt_limit, np.radians(3.0))
    grid = reach_grid(lo, hi, min(REACH_MAX_POINTS, max(8, int(REACH_MAX_WORK / (len(axes) * len(times))))))
    p2 = np.array([path.state(t).p for t in times])
    return reachable_mutual_alignment(grid, axes, bs, p2), times, math.degrees(veh.hover_tilt_limit)


class Scenario(_Strict):
    """A complete, validated relay scenario."""

    name: str = Field("scenario", description="names the scenario in outputs and reports")
    description: str = Field("", description="free text, shown in reports")
    seed: int = Field(0, ge=0, description="seeds every random element (noise, fading, shadowing, the energy detector)")
    platform: PlatformConfig = Field(default_factory=PlatformConfig)
    antenna: AntennaConfig = Field(default_factory=AntennaConfig)
    channel: ChannelConfig = Field(default_factory=ChannelConfig)
    nodes: NodesConfig = Field(default_factory=NodesConfig)
    jammer: JammerConfig | None = Field(None, description="one jammer (the paper's); or [[jammers]] for any number")
    jammers: list[JammerConfig] | None = Field(None, max_length=32, description="any number of jammers (array of tables)")
    controller: ControllerConfig = Field(default_factory=ControllerConfig)
    mission: MissionConfig = Field(default_factory=MissionConfig)
    sim: SimConfig = Field(default_factory=SimConfig)
    perturbations: PerturbationConfig = Field(default_factory=PerturbationConfig)
    bound: BoundConfig = Field(default_factory=BoundConfig)
    estimation: EstimationConfig = Field(default_factory=EstimationConfig)
    world: WorldConfig = Field(default_factory=WorldConfig)

    @model_validator(mode="before")
    @classmethod
    def _one_jammer_table(cls, data):
        if isinstance(data, dict):
            if data.get("jammer") is not None and data.get("jammers") is not None:
                raise ValueError("give either [jammer] (one jammer) or [[jammers]] (any number), not both")
            if data.get("jammer") is None and data.get("jammers") is None:
                data = {**data, "jammer": {}}
        return data

    @property
    def jammer_configs(self) -> list[JammerConfig]:
        """Every jammer of the scenario, in order ([jammer] or [[jammers]])."""
        return list(self.jammers) if self.jammers is not None else [self.jammer] if self.jammer is not None else []

    def jammer_field(self, i: int) -> str:
        return "jammer" if self.jammers is None else f"jammers[{i}]"

    @model_validator(mode="after")
    def _consistent(self):
        if self.jammers is not None:
            for i, j in enumerate(self.jammers):  # several unnamed jammers are numbered
                if "name" not in j.model_fields_set and len(self.jammers) > 1:
                    object.__setattr__(j, "name", f"jammer{i + 1}")
            names = [j.name for j in self.jammers]
            dup = sorted({n for n in names if names.count(n) > 1})
            if dup:
                raise ValueError(f"jammers: names must be unique, {dup} used more than once")
        pts = {
            "nodes.bs": self.nodes.bs,
            "nodes.relay": self.nodes.relay,
            **{f"{self.jammer_field(i)}.position": j.position for i, j in enumerate(self.jammer_configs)},
            "mission.waypoints[0]": self.mission.start,
        }
        names = list(pts)
        for i, a in enumerate(names):
            for b in names[i + 1 :]:
                d = math.dist(pts[a], pts[b])
                if d < MIN_NODE_SEPARATION_M:
                    raise ValueError(
                        f"{a} and {b} coincide ({d:.3g} m apart); nodes must be >= {MIN_NODE_SEPARATION_M} m apart"
                    )
        modes = {j.localization for j in self.jammer_configs}
        if len(modes) > 1:
            raise ValueError("jammer.localization: every jammer must use the same mode (oracle or estimated)")
        ws = self.controller.workspace
        if not ws.contains(self.nodes.relay):
            raise ValueError(f"nodes.relay {self.nodes.relay} must lie inside controller.workspace [{ws.min}, {ws.max}]")
        steps = self.sim.plant_rate_hz * self.control_period_s
        if abs(steps - round(steps)) > 1e-6 or round(steps) < 1:
            raise ValueError(
                f"the control period ({self.control_period_s} s) must be a whole number of plant steps "
                f"(sim.plant_rate_hz = {self.sim.plant_rate_hz})"
            )
        self._above_ground()
        self._mission_near_workspace()
        self._mu_reachable()
        self._rma_av_geometry()
        return self

    def _above_ground(self):
        """The workspace, the nodes, MRAV-2's path (every waypoint, or every sample of its file) and
        every jammer (its position and waypoints) at or above ``world.ground_z_m``. Minimum-jerk and
        straight segments never pass below both their ends, so the waypoints decide."""
        g = self.world.ground_z_m
        where = "the ground" if g == 0.0 else f"the ground (world.ground_z_m = {g:g} m)"
        ws = self.controller.workspace
        if ws.min[2] < g:
            raise ValueError(f"controller.workspace.min: z = {ws.min[2]:g} m is below {where}; the relay must stay above it")
        if self.nodes.bs[2] < g:
            raise ValueError(f"nodes.bs: z = {self.nodes.bs[2]:g} m is below {where}")
        m = self.mission
        if m.flown_file is None:
            low = [w for w in m.waypoints if w[3] < g]
            if low:
                raise ValueError(f"mission.waypoints: MRAV-2's path goes below ground (z < {g:g}) at {low[0]}")
        else:
            z = m.path().cols["pz"]
            k = int(np.argmin(z))
            if z[k] < g:
                key = "trajectory_ulog" if m.trajectory_ulog else "trajectory_csv"
                fix = "; shift it with ulog_offset_m" if m.trajectory_ulog else ""
                raise ValueError(f"mission.{key}: MRAV-2's path goes below ground (z = {z[k]:.2f} m at sample {k + 1}{fix})"
                                 if g == 0.0 else f"mission.{key}: MRAV-2's path goes below {where} (z = {z[k]:.2f} m at "
                                 f"sample {k + 1}{fix})")
        for i, j in enumerate(self.jammer_configs):
            zs = [j.position[2]] + [w[3] for w in (j.waypoints or [])]
            if min(zs) < g:
                raise ValueError(f"{self.jammer_field(i)}: its path goes below {where} (z = {min(zs):g} m)")

    def _mission_near_workspace(self):
        """MRAV-2's path within ``world.mission_max_distance_m`` of the relay's workspace: a sample
        farther away (a ULog sample at 3e38 m, a CSV at 1e300 m) is a damaged or foreign file."""
        m, ws, most = self.mission, self.controller.workspace, self.world.mission_max_distance_m
        if m.flown_file is None:
            pts, what = np.array([w[1:] for w in m.waypoints], float), "mission.waypoints[{k}]"
        else:
            c = m.path().cols
            pts = np.column_stack([c["px"], c["py"], c["pz"]])
            what = f"mission.{'trajectory_ulog' if m.trajectory_ulog else 'trajectory_csv'} sample {{k1}}"
        d = _box_distance(pts, ws.min, ws.max)
        k = int(np.argmax(d))
        if d[k] > most:
            raise ValueError(f"{what.format(k=k, k1=k + 1)}: MRAV-2 at {np.array2string(pts[k], precision=4)} is {d[k]:.4g} m "
                             f"from controller.workspace; its path must stay within world.mission_max_distance_m = {most:g} m")

    def _rma_av_geometry(self):
        """RMa-AV (TR 36.777 Annex B) holds for aerial heights in (10, 300] m and physical units:
        every link's higher end (the relay's workspace, MRAV-2's path, every jammer) must be there."""
        if self.channel.propagation.model != "rma_av":
            return
        if not self.channel.physical:
            raise ValueError("channel.propagation.model = 'rma_av' gives losses in dB at a carrier in Hz: "
                             "set channel.units = 'physical'")
        lo, hi = RMA_AV_MIN_HEIGHT_M, RMA_AV_MAX_HEIGHT_M
        ws = self.controller.workspace
        heights = {"controller.workspace z": (ws.min[2], ws.max[2])}
        path = source_trajectory(self.mission)
        z2 = [path.state(t).p[2] for t in np.linspace(0.0, path.duration, 200)]
        heights["MRAV-2's path z"] = (min(z2), max(z2))
        for i, j in enumerate(self.jammer_configs):
            zj = [j.position[2]] + [w[3] for w in (j.waypoints or [])]
            heights[f"{self.jammer_field(i)} z"] = (min(zj), max(zj))
        for what, (zmin, zmax) in heights.items():
            if zmin <= lo or zmax > hi:
                raise ValueError(f"channel.propagation.model = 'rma_av' holds for aerial heights in ({lo:g}, {hi:g}] m "
                                 f"(TR 36.777 Table B-2): {what} spans {zmin:.2f}-{zmax:.2f} m")
        span = math.dist(ws.min[:2], ws.max[:2]) + max(math.dist(self.nodes.bs[:2], p[:2]) for p in (ws.min, ws.max))
        if span > RMA_AV_MAX_D2D_M:
            raise ValueError(f"channel.propagation.model = 'rma_av' holds for 2D distances <= {RMA_AV_MAX_D2D_M:g} m")

    def _mu_reachable(self):
        """``controller.mu`` no higher than the mutual alignment the relay can reach while holding a
        hover, somewhere in its workspace, at every second of the mission. Above it the alignment
        slack dominates the NMPC's cost all mission long and the NMPC trades the vehicle's stability
        for alignment (measured on the nominal missions, supervisor on: mu = 0.9 flips the tilted
        hexarotor (109 deg) and sends it 3.8 m out of the box, mu = 0.7 the coplanar one 12.5 m;
        mu = 0.7 tilted and 0.5 coplanar, just above their reach, fly inside it)."""
        c = self.controller
        if not c.comms_aware or c.mu <= 0.0:
            return
        reach, times, tilt = _reachable_alignment(self.platform.model_dump_json(), self.mission.model_dump_json(),
                                                  tuple(c.workspace.min), tuple(c.workspace.max), tuple(self.nodes.bs),
                                                  self.duration_s)
        k = int(np.argmin(reach))
        limit = math.floor(reach[k] * 100.0) / 100.0
        if c.mu > limit:
            raise ValueError(
                f"controller.mu = {c.mu:g} is above {reach[k]:.3f}, the largest mutual alignment the relay can reach "
                f"while holding a hover (tilt <= {tilt:.1f} deg) anywhere in "
                f"controller.workspace at t = {times[k]:.0f} s of the mission: the alignment slack would dominate the "
                f"NMPC's cost and trade the vehicle's stability for alignment; use mu in (0, {limit:.2f}]")

    @property
    def stochastic(self) -> bool:
        """Whether the seed changes anything: the perturbations', log-normal shadowing, or the
        energy detector's noise when the relay estimates its jammers."""
        return self.perturbations.stochastic or self.channel.propagation.random or self.estimates_jammers

    @property
    def estimates_jammers(self) -> bool:
        """Whether the relay estimates the jammers online instead of being told (``localization``)."""
        return any(j.localization == "estimated" for j in self.jammer_configs)

    @property
    def control_period_s(self) -> float:
        rate = self.sim.control_rate_hz
        return self.controller.ts_s if rate is None else 1.0 / rate

    @property
    def duration_s(self) -> float:
        return self.sim.duration_s if self.sim.duration_s is not None else self.mission.duration_s

    def to_toml(self, mission_file: str | None = None) -> str:
        """The resolved scenario as TOML text (every default spelled out), arrays on one line, with
        only the mission source that flies (no waypoints beside a CSV); ``mission_file`` replaces
        the CSV's path (a run folder holds its own copy)."""
        data = self.model_dump(exclude_none=True)
        m = data["mission"]
        if self.mission.flown_file:
            m.pop("waypoints", None)
            if mission_file is not None:
                m["trajectory_ulog" if self.mission.trajectory_ulog else "trajectory_csv"] = mission_file
        if not self.mission.trajectory_ulog:
            m.pop("ulog_yaw_deg", None)
            m.pop("ulog_offset_m", None)
        return compact_toml(data)

    def with_updates(self, updates: dict) -> Scenario:
        """A new validated scenario with dotted-key updates, e.g. ``{"controller.variant": "unconstrained"}``."""
        data = self.model_dump(exclude_none=True)
        if self.mission.flown_file and "mission.waypoints" in updates:  # waypoints given: they fly, not the file
            data["mission"].pop("trajectory_csv", None)
            data["mission"].pop("trajectory_ulog", None)
        for key, value in updates.items():
            node: Any = data
            *parents, leaf = key.split(".")
            try:
                for p in parents:
                    node = node[int(p)] if isinstance(node, list) else node.setdefault(p, {})
                if isinstance(node, list):
                    node[int(leaf)] = value
                elif not isinstance(node, dict):
                    raise TypeError
                else:
                    node[leaf] = value
            except (TypeError, ValueError, IndexError, AttributeError):
                raise ScenarioError(f"{key}: not a field of the scenario (a table or list index is missing or out of range)") from None
        return parse_scenario(data)


_BOUND_ERRORS = {"greater_than", "greater_than_equal", "less_than", "less_than_equal"}


def _submodel(ann) -> type[BaseModel] | None:
    """The pydantic model inside an annotation (``X``, ``X | None``, ``list[X]``, ``list[X] | None``)."""
    if isinstance(ann, type) and issubclass(ann, BaseModel):
        return ann
    for arg in getattr(ann, "__args__", ()):
        found = _submodel(arg)
        if found is not None:
            return found
    return None


def _allowed_range(loc: tuple) -> str:
    """Human-readable allowed range of the numeric field at ``loc`` (e.g. ``[0, 1]``, ``(0, inf)``)."""
    model: type[BaseModel] | None = Scenario
    info = None
    for part in loc:
        if isinstance(part, int):  # an index into a list of tables
            continue
        if not isinstance(part, str) or model is None or part not in model.model_fields:
            return ""
        info = model.model_fields[part]
        model = _submodel(info.annotation)
    lo, hi, lo_open, hi_open = "-inf", "inf", True, True
    for m in info.metadata if info else []:
        for attr, is_lo, is_open in (("gt", 1, 1), ("ge", 1, 0), ("lt", 0, 1), ("le", 0, 0)):
            v = getattr(m, attr, None)
            if v is not None:
                if is_lo:
                    lo, lo_open = f"{v:g}", bool(is_open)
                else:
                    hi, hi_open = f"{v:g}", bool(is_open)
    return f"{'(' if lo_open else '['}{lo}, {hi}{')' if hi_open else ']'}"


def _did_you_mean(loc: tuple) -> str:
    """'; did you mean X?' for an unknown field close to one of its table's fields."""
    model: type[BaseModel] | None = Scenario
    for part in loc[:-1]:
        if isinstance(part, int):
            continue
        if model is None or not isinstance(part, str) or part not in model.model_fields:
            return ""
        model = _submodel(model.model_fields[part].annotation)
    if model is None:
        return ""
    close = difflib.get_close_matches(str(loc[-1]), list(model.model_fields), n=1, cutoff=0.6)
    return f"; did you mean {close[0]!r}?" if close else ""


def _format_errors(err: ValidationError) -> str:
    lines = []
    for e in err.errors():
        loc = ".".join(str(p) for p in e["loc"]) or "scenario"
        msg = e["msg"].removeprefix("Value error, ")
        got = e.get("input")
        shown = "" if isinstance(got, dict) or e["type"] == "missing" else f" (got {got!r})"
        if e["type"] == "extra_forbidden":
            msg, shown = "unknown field" + _did_you_mean(tuple(e["loc"])), ""
        elif e["type"] in _BOUND_ERRORS:
            msg = f"must be in {_allowed_range(tuple(e['loc']))}"
        elif e["type"] == "finite_number":
            rng = _allowed_range(tuple(e["loc"]))
            msg = f"must be a finite number{' in ' + rng if rng else ''}"
        if loc == "scenario" and _FIELD_PREFIX.match(msg):  # a cross-field check that names its field first
            loc, msg = msg.split(": ", 1)
        lines.append(f"{loc}: {msg}{shown}")
    return "\n".join(lines)


_FIELD_PREFIX = re.compile(r"^(jammers?|mission|controller|nodes|world)(\[\d+\])?(\.[a-z_]+)*: ")


def parse_scenario(data: dict) -> Scenario:
    """Validate a scenario from a plain dict; raises ScenarioError with one line per problem."""
    try:
        return Scenario.model_validate(data)
    except ValidationError as exc:
        raise ScenarioError(_format_errors(exc)) from None
