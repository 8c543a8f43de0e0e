"""The checks a scenario needs physics or its mission file's content for, run once per load as
their own step after the data is valid (``config``): the platform hovers with its margin and can
hold its attitude, the workspace, the mission and the jammers stay above the ground, the mission
stays near the workspace, ``controller.mu`` is reachable, RMa-AV's geometry holds. Each raises
ScenarioError with the line ``config`` would show for the field it names."""

from __future__ import annotations

import functools
import math

import numpy as np

from ..config import MissionConfig, PlatformConfig, Scenario, ScenarioError
from ..config.errors import error_line
from ..config.scenario import after_validation
from ..models.axes import axis_cone
from ..models.channel import reachable_mutual_alignment
from ..models.mission import check_flies, source_trajectory
from ..models.obstacles import obstacle_model, segment_clearance
from ..models.propagation import RMA_AV_MAX_D2D_M, RMA_AV_MAX_HEIGHT_M, RMA_AV_MIN_HEIGHT_M
from ..models.vehicle import HoverInfeasibleError
from ..planning.bound_cost import TRACE_S_PER_RAY_RECEIVER, grid_cells
from .planners import comms_aware
from .vehicle import shared_vehicle

REACH_MAX_TIMES = 300  # mission instants the alignment reachability check samples (1 s apart up to 299 s)
REACH_MAX_WORK = 6e7  # grid points x axes x instants it evaluates (~0.6 s on the project's VM; nominal: 2.5e7)
REACH_MAX_POINTS = 10_000  # relay positions it searches at most (1 m apart up to this, then coarser)


def check_physics(sc: Scenario) -> Scenario:
    """Every physics check of ``sc`` (see the module); returns ``sc``. Remembered per scenario
    content, so a scenario validated again (``simulate``, ``build``) is not checked twice."""
    key = sc.model_dump_json()
    if key in _PASSED:
        return sc
    # the path's distance before the ground: a waypoint 111 km away is below the local ground by the earth's curvature
    for loc, check in (("scenario", _hovers), ("scenario", _mission_near_workspace), ("scenario", _above_ground),
                       ("scenario", _missions_fly),
                       ("scenario", _mu_reachable), ("scenario", _rma_av_geometry), ("scenario", _ray_traced_physics),
                       ("scenario", _missions_clear_obstacles), ("scenario", _batteries_last)):
        try:
            check(sc)
        except ValueError as exc:
            raise ScenarioError(error_line(loc, str(exc))) from None
    if len(_PASSED) >= 256:
        _PASSED.clear()
    _PASSED.add(key)
    return sc


_PASSED: set[str] = set()  # scenarios (their JSON) that passed every check
after_validation(check_physics)  # Scenario.with_updates runs them too


def _hovers(sc: Scenario) -> None:
    """The rotor layout produces thrust plus three independent moments, and hovers with every motor
    ``min_hover_margin`` below ``omega_max_hz``."""
    for field, p in _platforms(sc):
        try:
            _hovers_with_margin(p)
        except ValueError as exc:
            raise ValueError(f"{field}: {exc}") from None


def _batteries_last(sc: Scenario) -> None:
    """No relay is sent up on a battery that is sure to run empty in flight. At hover power (rotors' shaft power plus
    the avionics; flying draws more in this model, so these are the least it can need): with ``go_home`` the usable
    energy above its reserve covers landing from its start (``d = 0``, its height down to the workspace floor at
    ``land_speed_m_s``), else it turns home at once and lands on its reserve or on nothing; without ``go_home`` the
    usable energy covers
    the mission (a spare waits on the ground: it is not checked for the mission). What flying draws beyond hover is
    caught in flight: a relay whose state of charge goes below 0 makes the run unsafe (``sim.metrics.flew_empty``)."""
    for i, r in enumerate(sc.relay_list):
        p = sc.platform_of(i)
        bat = p.battery
        if bat is None:
            continue
        field = f"relays[{i}].platform.battery" if sc.relays is not None and r.platform is not None else "platform.battery"
        veh = shared_vehicle(p)
        draw_w = float(veh.shaft_power(veh.hover_speeds())) + bat.avionics_w
        usable_j = bat.capacity_wh * 3600.0 * bat.usable_fraction
        hover_s = usable_j / draw_w
        if bat.go_home:
            height = max(float(r.start[2]) - float(sc.controller_of(i).workspace.min[2]), 0.0)
            land_s = height / bat.land_speed_m_s
            above = usable_j * (1.0 - bat.reserve_fraction)
            if above < land_s * draw_w:
                raise ValueError(f"{field}.capacity_wh: {bat.capacity_wh:g} Wh ({usable_j:.0f} J usable, {above:.0f} J above "
                                 f"its reserve) cannot bring relay {r.name!r} home from its start with its reserve kept: "
                                 f"{height:.1f} m down at {bat.land_speed_m_s:g} m/s takes {land_s:.1f} s at {draw_w:.0f} W "
                                 f"hovering ({land_s * draw_w:.0f} J); use more than "
                                 f"{land_s * draw_w / (1.0 - bat.reserve_fraction) / 3600.0 / bat.usable_fraction:.3g} Wh")
        elif not r.standby and hover_s < sc.duration_s:
            raise ValueError(f"{field}.go_home: false, and {bat.capacity_wh:g} Wh ({usable_j:.0f} J usable) lasts "
                             f"{hover_s:.1f} s even hovering ({draw_w:.0f} W), shorter than the {sc.duration_s:g} s mission: "
                             f"relay {r.name!r} would fly on an empty battery; set go_home = true (it flies home in time), "
                             f"capacity_wh >= {draw_w * sc.duration_s / 3600.0 / bat.usable_fraction:.3g}, or a shorter "
                             "sim.duration_s")


def _platforms(sc: Scenario) -> list[tuple[str, PlatformConfig]]:
    """``[platform]`` and every relay's own platform, with its field."""
    out = [("platform", sc.platform)]
    for i, r in enumerate(sc.relays or []):
        if r.platform is not None:
            out.append((f"relays[{i}].platform", sc.platform_of(i)))
    return out


def _hovers_with_margin(p: PlatformConfig) -> None:
    veh = shared_vehicle(p)
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
    limit = (1.0 - p.min_hover_margin) * p.omega_max_hz
    if float(np.max(hover)) > limit + 1e-9:
        raise ValueError(f"hover needs {np.max(hover):.2f} Hz, above {limit:.2f} Hz = (1 - min_hover_margin "
                         f"{p.min_hover_margin:g}) x omega_max_hz: no thrust left to brake or recover; raise "
                         "omega_max_hz or state a smaller min_hover_margin")


def _box_distance(p: np.ndarray, lo, hi) -> np.ndarray:
    """Distance (m) of points ``(n, 3)`` from the box ``[lo, hi]`` (0 inside)."""
    out = np.maximum(np.maximum(np.asarray(lo, float) - p, p - np.asarray(hi, float)), 0.0)
    return np.linalg.norm(out, axis=1)


def _above_ground(sc: Scenario) -> None:
    """The workspace, the nodes, MRAV-2's path (every waypoint, or every sample of its file) and
    every jammer (its position and waypoints) at or above ``world.ground_z_m``. Minimum-jerk and
    straight segments never pass below both their ends, so the waypoints decide."""
    g = sc.world.ground_z_m
    where = "the ground" if g == 0.0 else f"the ground (world.ground_z_m = {g:g} m)"
    ws = sc.controller.workspace
    if ws.min[2] < g:
        raise ValueError(f"controller.workspace.min: z = {ws.min[2]:g} m is below {where}; the relay must stay above it")
    for i, b in enumerate(sc.base_station_list):
        if b.position[2] < g:
            field = "nodes.bs" if sc.base_stations is None else f"base_stations[{i}].position"
            raise ValueError(f"{field}: z = {b.position[2]:g} m is below {where}")
    for field, m in _missions(sc):
        if m.flown_file is None:
            low = [w for w in m.waypoints if w[3] < g]
            if low:
                raise ValueError(f"{field}.waypoints: MRAV-2's path goes below ground (z < {g:g}) at {low[0]}")
            continue
        z = _flight_columns(field, m)["pz"]
        k = int(np.argmin(z))
        if z[k] < g:
            key = m.flown_field
            fix = "; shift it with ulog_offset_m" if m.trajectory_ulog else ""
            raise ValueError(f"{field}.{key}: MRAV-2's path goes below ground (z = {z[k]:.2f} m at sample {k + 1}{fix})"
                             if g == 0.0 else f"{field}.{key}: MRAV-2's path goes below {where} (z = {z[k]:.2f} m at "
                             f"sample {k + 1}{fix})")
    for i, j in enumerate(sc.jammer_configs):
        zs = [j.position[2]] + [w[3] for w in (j.waypoints or [])]
        if min(zs) < g:
            raise ValueError(f"{sc.jammer_field(i)}: its path goes below {where} (z = {min(zs):g} m)")

MISSION_SAMPLE_S = 0.1  # the obstacle check samples every mission this often (a source at 10 m/s moves 1 m)
MISSION_SAMPLES_MAX = 100_000  # at most this many samples per mission (a longer one is sampled more coarsely)


def _missions_clear_obstacles(sc: Scenario) -> None:
    """No source's path enters an obstacle (the obstacle itself: a source may inspect it closely):
    the path sampled every ``MISSION_SAMPLE_S`` until it ends (after its last point it holds there) or the
    flight does, at most ``MISSION_SAMPLES_MAX`` samples, and each straight segment between two samples
    checked exactly (``models.obstacles.segment_clearance``: a thin wall between samples is found). The
    path between samples is taken straight: a source turning at 1 g leaves it by a*dt^2/8 = 1.2 cm."""
    if not sc.obstacles:
        return
    shapes = [obstacle_model(o, margin=False) for o in sc.obstacle_list]
    for field, m in _missions(sc):
        path = source_trajectory(m)
        end = min(sc.duration_s, path.duration)
        n = int(min(MISSION_SAMPLES_MAX, np.ceil(end / MISSION_SAMPLE_S))) + 1
        times = np.linspace(0.0, end, max(n, 2))
        p = np.array([path.state(float(t)).p for t in times])
        for o, shape in zip(sc.obstacle_list, shapes, strict=True):
            d = segment_clearance(shape, p[:-1], p[1:])
            if d.min() < 0:
                k = int(np.argmin(d))
                raise ValueError(f"{field}: the source's path goes through obstacle {o.name!r} ({-d[k]:.2f} m deep between "
                                 f"t = {times[k]:.2f} and {times[k + 1]:.2f} s, near {np.round(p[k], 2).tolist()}): move the "
                                 "path or the obstacle")


def _mission_near_workspace(sc: Scenario) -> None:
    """MRAV-2's path within ``world.mission_max_distance_m`` of the relay's workspace: a sample
    farther away (a ULog sample at 3e38 m, a CSV at 1e300 m) is a damaged or foreign file."""
    ws, most = sc.controller.workspace, sc.world.mission_max_distance_m
    for field, m in _missions(sc):
        if m.flown_file is None:
            pts, what = np.array([w[1:] for w in m.waypoints], float), field + ".waypoints[{k}]"
        else:
            c = _flight_columns(field, m)
            pts = np.column_stack([c["px"], c["py"], c["pz"]])
            what = f"{field}.{m.flown_field} sample {{k1}}"
        d = _box_distance(pts, ws.min, ws.max)
        k = int(np.argmax(d))
        if d[k] > most:
            raise ValueError(f"{what.format(k=k, k1=k + 1)}: MRAV-2 at {np.array2string(pts[k], precision=4)} is "
                             f"{d[k]:.4g} m from controller.workspace; its path must stay within "
                             f"world.mission_max_distance_m = {most:g} m")


def _missions_fly(sc: Scenario) -> None:
    """Every mission file's path is a mission: longer than 0 s and no faster than a multirotor flies
    (``models.mission.check_flies``; after ``_mission_near_workspace``, which names a sample far away by its row)."""
    for field, m in _missions(sc):
        if m.flown_file is None:
            continue
        try:
            check_flies(m.flight())
        except ValueError as exc:
            raise ValueError(f"{field}.{m.flown_field}: {exc}") from None


def _flight_columns(field: str, m: MissionConfig) -> dict:
    """The columns of a mission's flight file (a file gone since the table was read is named)."""
    flight = m.flight()
    if flight is None:
        raise ValueError(f"{field}: {m.flown_file}: no such file")
    return flight.cols


def _missions(sc: Scenario) -> list[tuple[str, MissionConfig]]:
    """Every source's mission with its field: ``mission``, or ``sources[i].mission``."""
    if sc.sources is None:
        return [("mission", sc.mission)]
    return [(f"sources[{i}].mission", s.mission) for i, s in enumerate(sc.sources)]

def _ray_traced_physics(sc: Scenario) -> None:
    """A ray-traced channel gives physical path gains (m, Hz): physical units; its blockage comes from the
    scene's geometry, not from obstacles' fixed losses. Traced scoring needs a traced channel."""
    traced_scoring = [f for f, c in (("controller", sc.controller), *((f"relays[{i}].controller", sc.controller_of(i))
                                                                      for i in range(len(sc.relay_list))))
                      if c.capacity.scoring == "traced"]
    if traced_scoring and sc.channel.propagation.model != "ray_traced":
        raise ValueError(f"{traced_scoring[0]}.capacity.scoring: 'traced' scores candidates on the ray-traced channel: "
                         "set channel.propagation.model = 'ray_traced' (and its scene)")
    fleet = sc.shape.plans == "network"  # a network's candidates are scored by one fleet planner
    if traced_scoring and fleet and sc.controller.capacity.scoring != "traced":
        raise ValueError(f"{traced_scoring[0]}.capacity.scoring: a network's candidates are scored by its fleet planner: "
                         "set controller.capacity.scoring = 'traced' (with controller.planner = 'capacity')")
    if traced_scoring and fleet and sc.planner != "capacity":
        raise ValueError(f"controller.capacity.scoring: 'traced' scores the capacity-seeking planners' candidates; "
                         f"controller.planner = {sc.planner!r} scores none: set controller.planner = 'capacity'")
    if traced_scoring and sc.has_route_choice:
        raise ValueError(f"{traced_scoring[0]}.capacity.scoring: 'traced' scores a fixed route; a route to 'any' of "
                         "several base stations, or one that may skip relays (network.route_selection), scores on free "
                         "space so far")
    if traced_scoring and not fleet:
        _traced_route_fits(sc)
    if sc.channel.propagation.model != "ray_traced":
        return
    if not sc.channel.physical:
        raise ValueError("channel.propagation.model = 'ray_traced' traces physical path gains at a carrier in Hz: "
                         "set channel.units = 'physical'")
    for i, o in enumerate(sc.obstacle_list):
        if o.nlos_loss_db > 0:
            raise ValueError(f"obstacles[{i}].nlos_loss_db: with a ray-traced channel the scene's geometry blocks "
                             "radio; leave it at 0 (the obstacle still keeps the relays out)")


def _traced_route_fits(sc: Scenario) -> None:
    """The one relay's pre-flight route on the traced map (``scoring = "traced"``) traces every cell of its grid at each
    of its instants before take-off: refused, naming ``route_grid_m``, when that is estimated longer than
    ``bound.max_minutes`` (``planning.bound_cost``'s tracing rate)."""
    cap = sc.controller.capacity
    ws = sc.controller.workspace
    lo, hi = np.asarray(ws.min, float) + cap.margin_m, np.asarray(ws.max, float) - cap.margin_m
    dt = max(sc.route_dt_s, cap.route_grid_m / cap.speed_m_s)
    cells, instants = grid_cells(lo, hi, cap.route_grid_m), int(sc.duration_s / dt) + 2
    minutes = cells * instants * sc.channel.propagation.rays_per_source * TRACE_S_PER_RAY_RECEIVER / 60.0
    if minutes > sc.bound.max_minutes:
        raise ValueError(f"controller.capacity.route_grid_m: the pre-flight route on the traced map traces {cells:,} cells "
                         f"at {instants} instants, ~{minutes:.3g} min here, more than bound.max_minutes = "
                         f"{sc.bound.max_minutes:g}: a coarser route_grid_m or route_dt_s, fewer "
                         "channel.propagation.rays_per_source, a smaller workspace, or a larger bound.max_minutes")


def _rma_av_geometry(sc: Scenario) -> None:
    """RMa-AV (TR 36.777 Annex B) holds for aerial heights in (10, 300] m and physical units:
    every link's higher end (the relay's workspace, MRAV-2's path, every jammer) must be there."""
    if sc.channel.propagation.model != "rma_av":
        return
    if not sc.channel.physical:
        raise ValueError("channel.propagation.model = 'rma_av' gives losses in dB at a carrier in Hz: "
                         "set channel.units = 'physical'")
    lo, hi = RMA_AV_MIN_HEIGHT_M, RMA_AV_MAX_HEIGHT_M
    ws = sc.controller.workspace
    heights = {"controller.workspace z": (ws.min[2], ws.max[2])}
    for field, m in _missions(sc):
        path = source_trajectory(m)
        z2 = [path.state(t).p[2] for t in np.linspace(0.0, path.duration, 200)]
        heights["MRAV-2's path z" if field == "mission" else f"{field} z"] = (min(z2), max(z2))
    for i, j in enumerate(sc.jammer_configs):
        zj = [j.position[2]] + [w[3] for w in (j.waypoints or [])]
        heights[f"{sc.jammer_field(i)} z"] = (min(zj), max(zj))
    for what, (zmin, zmax) in heights.items():
        if zmin <= lo or zmax > hi:
            raise ValueError(f"channel.propagation.model = 'rma_av' holds for aerial heights in ({lo:g}, {hi:g}] m "
                             f"(TR 36.777 Table B-2): {what} spans {zmin:.2f}-{zmax:.2f} m")
    span = math.dist(ws.min[:2], ws.max[:2]) + max(math.dist(b.position[:2], p[:2]) for p in (ws.min, ws.max)
                                                   for b in sc.base_station_list)
    if span > RMA_AV_MAX_D2D_M:
        raise ValueError(f"channel.propagation.model = 'rma_av' holds for 2D distances <= {RMA_AV_MAX_D2D_M:g} m")

def _mu_reachable(sc: Scenario) -> None:
    """``controller.mu`` no higher than the mutual alignment the relay can reach while holding a
    hover, somewhere in its workspace, at every second of the mission. Above it the alignment
    slack dominates the NMPC's cost all mission long and the NMPC trades the vehicle's stability
    for alignment (measured on the nominal missions, supervisor on: mu = 0.9 flips the tilted
    hexarotor (109 deg) and sends it 3.8 m out of the box, mu = 0.7 the coplanar one 12.5 m;
    mu = 0.7 tilted and 0.5 coplanar, just above their reach, fly inside it)."""
    if not sc.has_two_hops:  # a relay of a chain aligns with its route neighbours, not with the base station and MRAV-2
        return
    view = sc.relay_view(0)
    c, platform, mission = view.controller, view.platform, sc.source_list[0].mission
    if c.mu <= 0.0 or not comms_aware(view):
        return
    reach, times, tilt = _reachable_alignment(platform.model_dump_json(), mission.model_dump_json(),
                                              tuple(c.workspace.min), tuple(c.workspace.max), tuple(sc.first_station.position),
                                              sc.duration_s)
    k = int(np.argmin(reach))
    limit = math.floor(reach[k] * 100.0) / 100.0
    if c.mu > limit:
        raise ValueError(
            f"controller.mu = {c.mu:g} is above {reach[k]:.3f}, the largest mutual alignment the relay can reach "
            f"while holding a hover (tilt <= {tilt:.1f} deg) anywhere in "
            f"controller.workspace at t = {times[k]:.0f} s of the mission: the alignment slack would dominate the "
            f"NMPC's cost and trade the vehicle's stability for alignment; use mu in (0, {limit:.2f}]")


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
    veh = shared_vehicle(PlatformConfig.model_validate_json(platform_json))
    lo, hi = np.array(ws_min, float), np.array(ws_max, float)
    path = source_trajectory(MissionConfig.model_validate_json(mission_json))
    end = min(duration_s, path.duration)  # MRAV-2 holds its last state after its path
    times = np.linspace(0.0, end, min(int(np.ceil(end)) + 1, REACH_MAX_TIMES))
    axes = axis_cone(veh.hover_tilt_limit, np.radians(3.0))
    grid = reach_grid(lo, hi, min(REACH_MAX_POINTS, max(8, int(REACH_MAX_WORK / (len(axes) * len(times))))))
    p2 = np.array([path.state(t).p for t in times])
    return reachable_mutual_alignment(grid, axes, bs, p2), times, math.degrees(veh.hover_tilt_limit)
