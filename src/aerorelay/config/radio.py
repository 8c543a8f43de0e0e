"""The radio tables as data: ``[antenna]``, ``[channel]`` (with ``[channel.propagation]`` and
``[channel.fading]``), ``[nodes]`` and each ``[[jammers]]`` table. The patterns, path gains and
jammers are built from them in ``assembly.parts``."""

from __future__ import annotations

import math
from typing import Literal

from pydantic import Field, field_validator, model_validator

from .base import NAME_PATTERN, Strict, Vec3, Waypoint, check_waypoint_times, dbm_to_w, nonzero_direction, on_the_earth
from .mission import FILE_KINDS, flight_path, readable_file

LOOP_CLOSURE_M = 0.01  # a repeating jammer path's last waypoint within this of its first (m)
OUTAGE_SPECTRAL_EFFICIENCY = 1e-3  # bit/s/Hz: the paper's outage threshold (B = 1); times the bandwidth in physical units


# ITU-R P.2040-3 Table 3's materials as Sionna RT names them (models.generated_scene.ITU_MATERIALS)
ItuMaterial = Literal["concrete", "brick", "plasterboard", "wood", "glass", "ceiling_board", "chipboard", "plywood",
                      "marble", "floorboard", "metal", "very_dry_ground", "medium_dry_ground", "wet_ground"]

class NodeAntennaConfig(Strict):
    """One vehicle's own antenna (``[[relays]] antenna = {...}``, ``[[sources]] antenna = {...}``), its
    axis along the vehicle's body z: a half-wave dipole, sin(theta)^exponent, isotropic, or cosine (a
    patch or panel: ``G = g_bar max(max(cos psi, 0)^exponent, back_lobe)``, boresight body z). Default:
    ``[antenna]``'s."""

    pattern: Literal["dipole", "sin_power", "isotropic", "cosine"] = Field(description="the pattern about body z")
    g_bar: float = Field(1.0, gt=0.0, le=1e4, description="peak gain (linear): broadside for dipole and sin_power, "
                         "boresight for cosine, everywhere for isotropic")
    exponent: float = Field(2.0, ge=0.0, le=100.0, description="n of sin^n, or of the cosine pattern's cos^n")
    back_lobe: float = Field(0.01, ge=0.0, le=1.0, description="cosine: the gain floor relative to g_bar")
    axis: Vec3 | None = Field(None, description="the antenna's axis (a cosine antenna's boresight) in the vehicle's body "
                              "frame (x forward, y left, z up): [0, 0, 1] up (unset: up) or [0, 0, -1] down, e.g. a patch "
                              "under the vehicle facing the ground. A mount off body z would point where the yaw takes it, "
                              "which no planner plans: refused")

    @field_validator("axis")
    @classmethod
    def _up_or_down(cls, v):
        if v is None:
            return v
        n = math.hypot(*v)
        if not math.isfinite(n) or n < 1e-9 or math.hypot(v[0], v[1]) > 1e-9 * n:
            raise ValueError(f"must be along the body z axis: [0, 0, 1] (up) or [0, 0, -1] (down), got {v}")
        return [0.0, 0.0, math.copysign(1.0, v[2])]

    @property
    def down(self) -> bool:
        """Whether its axis points down the body z axis (its gain toward a direction is the upward one's toward the
        direction mirrored through the body's xy plane: ``models.antenna.FlippedPattern``)."""
        return self.axis is not None and self.axis[2] < 0.0

    @property
    def doughnut(self) -> bool:
        """Whether its gain has a null along its axis and a peak across it (what the paper's misalignment terms assume)."""
        return self.pattern in ("dipole", "sin_power")


class AntennaConfig(Strict):
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

    _nonzero_axis = field_validator("bs_axis")(lambda v: nonzero_direction(v, "the base station's antenna axis"))

    @model_validator(mode="before")
    @classmethod
    def _gain_in_dbi(cls, data):
        """``g_bar_dbi`` given: ``g_bar`` is ``10^(g_bar_dbi / 10)`` (or must already agree with it)."""
        if not isinstance(data, dict) or data.get("g_bar_dbi") is None:
            return data
        try:
            linear = 10.0 ** (float(data["g_bar_dbi"]) / 10.0)
            given = float(data["g_bar"]) if "g_bar" in data else None
        except (TypeError, ValueError, OverflowError):
            return data  # the fields' own checks name the bad value
        if given is not None and not math.isclose(given, linear, rel_tol=1e-9):
            raise ValueError(f"antenna.g_bar ({given:g}) and antenna.g_bar_dbi ({float(data['g_bar_dbi']):g} dBi = "
                             f"{linear:.6g}) disagree: give one of them")
        return {**data, "g_bar": linear}

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


BOLTZMANN_J_K = 1.380649e-23


class PropagationConfig(Strict):
    """Large-scale propagation (``models/propagation.py``). ``free_space``: the paper's ``1/d^2``
    (Friis with the wavelength in physical units); ``log_distance``: ``PL(d0) + 10 n log10(d/d0)``;
    ``rma_av``: 3GPP TR 36.777 RMa-AV (physical units, every aerial end above 10 m: controllers plan
    with the gain expected over the LoS state, the plant draws the state and the standard's
    shadowing). Log-normal shadowing (dB, zero mean, a random field over each link's geometry
    correlated ``exp(-Delta d / decorrelation_m)``) perturbs the plant's channel and the bound, not
    what the controllers plan with. ``ray_traced``: the plant's true channel traced with Sionna RT
    in ``scene`` (the optional ``rt`` extra; ``models/raytrace.py``, ``sim/traced.py``): every link's paths
    weighed by each end's antenna at its attitude, traced every ``trace_period_s`` and carried to the
    ends' positions in between; planners, NMPC and bound plan with free space (physical units only)."""

    model: Literal["free_space", "log_distance", "rma_av", "ray_traced"] = Field(
        "free_space", description="the path-gain model (see the table's text)")
    scene: str | None = Field(None, min_length=1, description="ray_traced: a Sionna RT scene by name (simple_street_canyon, "
                              "munich, etoile, floor_wall, ...; 'empty': free space), a Mitsuba XML file, named "
                              "relative to the scenario file, or 'obstacles': a scene generated from the scenario's "
                              "obstacles ([[obstacles]], [buildings]) and a flat ground")
    building_material: ItuMaterial = Field("concrete", description="scene = 'obstacles': the ITU-R P.2040 material of "
                                           "every obstacle without its own material")
    wall_thickness_m: float = Field(0.2, gt=0.0, le=5.0, description="scene = 'obstacles': the obstacles' walls' "
                                    "thickness, m (each surface a slab: reflection and transmission by ITU-R P.2040)")
    ground_material: ItuMaterial | Literal["none"] = Field("medium_dry_ground", description="scene = 'obstacles': the "
                                                           "ground's material at world.ground_z_m (a half space), or "
                                                           "'none' (no ground: without obstacles, free space)")
    origin_m: Vec3 = Field(default_factory=lambda: [0.0, 0.0, 0.0], description="ray_traced: where the scenario's origin "
                                                 "sits in the scene, m (scene coordinates)")
    yaw_deg: float = Field(0.0, ge=-360.0, le=360.0, description="ray_traced: the scenario's frame turned about z in "
                           "the scene, deg (counter-clockwise)")
    max_depth: int = Field(3, ge=0, le=8, description="ray_traced: most interactions per path")
    rays_per_source: int = Field(1_000_000, ge=1_000, le=100_000_000, description="ray_traced: rays shot from each "
                                 "transmitter to find the paths (Sionna RT's samples_per_src; each found path is then "
                                 "exact): fewer trace faster and may miss weak paths (docs/concepts/ray-tracing.md)")
    reflection: bool = Field(True, description="ray_traced: specular reflections")
    diffraction: bool = Field(False, description="ray_traced: diffraction on edges")
    scattering: bool = Field(False, description="ray_traced: diffuse reflection")
    refraction: bool = Field(False, description="ray_traced: refraction through objects")
    paths_sum: Literal["coherent", "power"] = Field("power", description="ray_traced: coherent: the paths added with "
                                                    "their phases (narrowband); power: their powers added (wideband)")
    trace_period_s: float = Field(0.25, gt=0.0, le=10.0, description="ray_traced: seconds between traces (the links "
                                  "carried to the ends' positions in between); the control period or less: every step")
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
        if self.model == "ray_traced" and self.scene is None:
            raise ValueError("channel.propagation.scene: model = 'ray_traced' needs a scene (a Sionna RT scene's name "
                             "such as 'simple_street_canyon', 'empty', or a Mitsuba XML file)")
        if self.scene == "obstacles" and (any(v != 0 for v in self.origin_m) or self.yaw_deg != 0):
            raise ValueError("channel.propagation.origin_m / yaw_deg: the scene generated from the obstacles is in the "
                             "scenario's own frame; leave them at 0")
        if self.model == "ray_traced" and self.shadowing_std_db > 0:
            raise ValueError("channel.propagation.shadowing_std_db: the ray-traced channel's large-scale terms come "
                             "from the scene; leave it at 0")
        if self.model == "rma_av" and self.shadowing_std_db > 0:
            raise ValueError("channel.propagation.shadowing_std_db: rma_av draws the standard's shadowing "
                             "(TR 36.777 Table B-3: LoS 4.2 exp(-0.0046 h) dB, NLoS 6 dB); leave it at 0")
        return self


class ChannelFadingConfig(Strict):
    """Small-scale fading model for ``perturbations.fading_k_db``: ``iid`` (the paper's robustness
    runs: an independent Rician draw per control step) or ``doppler`` (Rician whose diffuse part
    is a Gauss-Markov process with the correlation ``J0(2 pi f_D tau)`` at the control period,
    ``f_D`` from each link's relative speed and ``channel.carrier_hz``)."""

    model: Literal["iid", "doppler"] = Field("iid", description="iid: a Rician draw per step; doppler: time-correlated")


class ChannelConfig(Strict):
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


class NodesConfig(Strict):
    """Fixed and initial node positions (m, world). MRAV-2 starts at the mission's first point."""

    bs: Vec3 = Field(default_factory=lambda: [0.0, 0.0, 0.0], description="the base station's position p0, m (world)")
    relay: Vec3 = Field(default_factory=lambda: [-6.95, 5.79, 1.72], description="the relay's start p1(0), m (world), "
                        "hovering; inside controller.workspace")


JAMMER_TRACK_KINDS = {f: kind for f, kind in FILE_KINDS.items() if kind != "ulog"}  # a jammer's track: CSV, .plan, GPX


def jammer_track(field: str, file: str, origin=None):
    """A jammer's track file (``field`` one of ``JAMMER_TRACK_KINDS``) read as a path (m, local ENU)."""
    kind = JAMMER_TRACK_KINDS[field]
    return flight_path(kind, file, origin=None if kind == "csv" or origin is None else tuple(float(v) for v in origin))


class JammerConfig(Strict):
    """A jammer: fixed at ``position``, moving along timed ``waypoints`` or circling (``path = "circle"``); isotropic
    (the paper's) or ``cosine``: ``G(psi) = g_max max(max(cos psi, 0)^exponent, back_lobe)``,
    ``psi`` off boresight, pointed at a node (``point_at``, tracking it) or along ``boresight``."""

    name: str = Field("jammer", min_length=1, max_length=32, pattern=NAME_PATTERN,
                      description="names the jammer in logs and reports (its log columns: jam_<name>_x, est_<name>_x, ...)")
    position: Vec3 = Field(default_factory=lambda: [-6.95, -5.79, 1.72], description="m, world (the start when moving)")
    waypoints: list[Waypoint] | None = Field(None, min_length=2, description="timed path [[t_s, x, y, z], ...]")
    path: Literal["linear", "minimum_jerk", "circle"] = Field("linear", description="how the jammer moves between "
                                                               "waypoints, or circle: around center_m at radius_m, one lap "
                                                               "every period_s (from due east of the center)")
    center_m: Vec3 | None = Field(None, description="circle: the center, m (world; the circle is horizontal at its height)")
    radius_m: float | None = Field(None, gt=0.0, le=10_000.0, description="circle: the radius, m")
    period_s: float | None = Field(None, gt=0.0, le=1e6, description="circle: the time of one lap, s")
    clockwise: bool = Field(False, description="circle: seen from above, clockwise (default counter-clockwise)")
    trajectory_csv: str | None = Field(None, description="the jammer's track as a CSV with columns t,px,py,pz[,vx,vy,vz,ax,ay,az] "
                                       "(s, m local ENU; a truck along a road), named relative to the scenario file")
    trajectory_plan: str | None = Field(None, description="the jammer's track as a QGroundControl .plan (WGS84), in the local "
                                        "frame at geo_origin (default [geo] origin, else the plan's home)")
    trajectory_gpx: str | None = Field(None, description="the jammer's track as a GPX track (timed points, WGS84), in the local "
                                       "frame at geo_origin (default [geo] origin, else its first point)")
    geo_origin: Vec3 | None = Field(None, description="the local frame's origin for the jammer's .plan / GPX track: "
                                    "[lat_deg, lon_deg, alt_m] (WGS84)")
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
    point_at: str | None = Field(None, min_length=1, description="cosine pattern: the node it tracks (bs, relay, source, "
                                 "or a name of [[relays]] / [[sources]])")
    boresight: Vec3 | None = Field(None, description="cosine pattern: fixed boresight direction, world")

    @property
    def peak_power_w(self) -> float:
        """``power_w``, or ``power_dbm`` in W when given."""
        return dbm_to_w(self.power_dbm) if self.power_dbm is not None else self.power_w

    @model_validator(mode="before")
    @classmethod
    def _starts_at_first_waypoint(cls, data):
        """A moving jammer's ``position`` is its first waypoint's, its circle's start or its track's first point
        (given, it must be that)."""
        files = [f for f in JAMMER_TRACK_KINDS if isinstance(data, dict) and data.get(f)]
        if len(files) == 1:
            try:
                start = [float(v) for v in jammer_track(files[0], data[files[0]], data.get("geo_origin")).state(0.0).p]
            except (OSError, ValueError, TypeError):
                return data  # the file's own check names the problem
            if "position" in data:
                try:
                    given = [float(v) for v in data["position"]]
                except (TypeError, ValueError):
                    return data
                if math.dist(given, start) > 1e-6:
                    raise ValueError(f"position {given} is not {files[0]}'s start {start}: omit position for a jammer on a track")
            return {**data, "position": start}
        if isinstance(data, dict) and data.get("path") == "circle":
            try:
                c, r = [float(v) for v in data["center_m"]], float(data["radius_m"])
            except (TypeError, ValueError, KeyError):
                return data  # the circle's own checks name the problem
            start = [c[0] + r, c[1], c[2]]
            if "position" in data and [float(v) for v in data["position"]] != start:
                raise ValueError(f"position {data['position']} is not the circle's start {start} (due east of center_m): "
                                 "omit position for a circling jammer")
            return {**data, "position": start}
        if not isinstance(data, dict) or not data.get("waypoints"):
            return data
        try:
            start = [float(v) for v in data["waypoints"][0][1:]]
        except (TypeError, ValueError, IndexError, KeyError):
            return data  # the waypoints' own checks name the problem
        if "position" in data:
            try:
                given = [float(v) for v in data["position"]]
            except (TypeError, ValueError):
                return data
            if given != start:
                raise ValueError(f"position {given} differs from waypoints[0] {start}: omit position for a moving jammer")
        return {**data, "position": start}

    _geo_origin_on_the_earth = field_validator("geo_origin")(lambda v: v if v is None else on_the_earth(v))

    @model_validator(mode="after")
    def _readable_track(self):
        given = [f for f in JAMMER_TRACK_KINDS if getattr(self, f) is not None]
        if len(given) > 1:
            raise ValueError(f"give one of {', '.join(JAMMER_TRACK_KINDS)}, not {' and '.join(given)}")
        if given and (self.waypoints is not None or self.path == "circle" or self.repeat):
            raise ValueError(f"{given[0]} is the jammer's path: not with waypoints, path = \"circle\" or repeat")
        if self.geo_origin is not None and not any(getattr(self, f) for f in ("trajectory_plan", "trajectory_gpx")):
            raise ValueError("geo_origin applies to trajectory_plan / trajectory_gpx only")
        for field in given:
            f = getattr(self, field)
            readable_file(field, f, lambda field=field, f=f: jammer_track(field, f, self.geo_origin))
        return self

    @property
    def track_field(self) -> str | None:
        """The field of the jammer's track file (``trajectory_csv`` / ``_plan`` / ``_gpx``), if any."""
        return next((f for f in JAMMER_TRACK_KINDS if getattr(self, f) is not None), None)

    def track(self):
        """The jammer's track read from its file (``models.mission`` path, m, local ENU), None without one."""
        field = self.track_field
        return None if field is None else jammer_track(field, getattr(self, field), self.geo_origin)

    @model_validator(mode="after")
    def _path_and_pointing(self):
        if self.power_dbm is not None and self.inr_db_at_relay_start is not None:
            raise ValueError("give power_dbm or inr_db_at_relay_start, not both")
        if self.waypoints is not None:
            check_waypoint_times(self.waypoints, first_zero=False)
            start = list(self.waypoints[0][1:])
            end = self.waypoints[-1][1:]
            if self.repeat and math.dist(start, end) > LOOP_CLOSURE_M:
                raise ValueError(f"repeat = true flies the waypoints as a loop: the last one {end} must be at the first "
                                 f"one's position {start} (within {LOOP_CLOSURE_M} m)")
        elif self.repeat:
            raise ValueError("repeat = true needs waypoints (a fixed jammer has nothing to repeat)")
        circle = [f for f in ("center_m", "radius_m", "period_s") if getattr(self, f) is not None]
        if self.path == "circle":
            if self.waypoints is not None:
                raise ValueError("path = \"circle\" takes center_m, radius_m and period_s, not waypoints")
            missing = [f for f in ("center_m", "radius_m", "period_s") if getattr(self, f) is None]
            if missing:
                raise ValueError(f"path = \"circle\" needs {', '.join(missing)}")
        elif circle:
            raise ValueError(f"{', '.join(circle)} apply to path = \"circle\" only")
        if self.pattern == "cosine" and (self.point_at is None) == (self.boresight is None):
            raise ValueError("pattern = 'cosine': a cosine jammer needs exactly one of point_at (a node) and boresight (a direction)")
        if self.pattern == "isotropic" and (self.point_at is not None or self.boresight is not None):
            raise ValueError("point_at / boresight apply to pattern = \"cosine\" only")
        if self.boresight is not None:
            nonzero_direction(self.boresight, "boresight")
        return self

