"""The world's parts from ``[wind]`` and ``[[obstacles]]``: each obstacle's shape (grown by its
margin for the planners and the NMPC; bare for the supervisor and the safety verdict), and the air
(the wind series, each relay's plant with its platform's drag, its observer)."""

from __future__ import annotations

import functools
from collections.abc import Mapping

import numpy as np

from ..config import PlatformConfig, Scenario
from ..estimation.disturbance import ExternalAccelerationObserver
from ..models.drag import drag_coefficients
from ..models.generated_scene import GROUND_THICKNESS_M, solid, write_scene
from ..models.obstacles import Obstacle, obstacle_model
from ..models.raytrace import RayTracer, TraceSettings, scene_digest, sionna_rt
from ..models.vehicle import Multirotor
from ..sim.air import Air, AirborneRelay, HeldWind, WindSeries, WindSettings
from ..sim.blockage import Blockage
from ..sim.closed_loop import plant_step_function
from ..sim.traced import TracedChannel
from ..store.cache import cache_dir


def obstacles(sc: Scenario, margin: bool = True) -> tuple[Obstacle, ...]:
    """Every obstacle's shape, grown by its margin (``margin=False``: the obstacle itself)."""
    return tuple(obstacle_model(o, margin) for o in sc.obstacle_list)


def blockage(sc: Scenario) -> Blockage:
    """The plant's radio blockage by the obstacles that block radio (``nlos_loss_db`` > 0; none: inactive)."""
    return Blockage(obstacles(sc, margin=False), [o.nlos_loss_db for o in sc.obstacle_list])


GROUND_REACH_M = 200.0  # the generated ground reaches this far past every node and obstacle (m)


def generated_scene_file(sc: Scenario) -> str:
    """The Mitsuba XML file of the scene generated from ``sc``'s obstacles and ground (``scene = "obstacles"``,
    ``models.generated_scene``), written into the cache folder once per content."""
    prop = sc.channel.propagation
    solids = [solid(str(o.name), obstacle_model(o, margin=False), o.material or prop.building_material,
                    prop.wall_thickness_m) for o in sc.obstacle_list]
    ground = None if prop.ground_material == "none" else (prop.ground_material, GROUND_THICKNESS_M)
    ws = sc.controller.workspace
    xy = [ws.min[:2], ws.max[:2], *(b.position[:2] for b in sc.base_station_list), *(r.start[:2] for r in sc.relay_list),
          *(j.position[:2] for j in sc.jammer_configs), *(c[:2] for s in solids for c in s.footprint)]
    lo, hi = np.min(xy, axis=0) - GROUND_REACH_M, np.max(xy, axis=0) + GROUND_REACH_M
    return str(write_scene(cache_dir() / "scenes", solids, ground, lo, hi, sc.world.ground_z_m))


def trace_settings(sc: Scenario) -> TraceSettings:
    """What the plant's ray tracer traces (``[channel.propagation]``, model ``ray_traced``; the scene ``"obstacles"``:
    the one generated from the scenario's obstacles, ``generated_scene_file``)."""
    prop = sc.channel.propagation
    assert prop.scene is not None
    scene = generated_scene_file(sc) if prop.scene == "obstacles" else prop.scene
    return TraceSettings(scene, sc.channel.carrier_hz, origin_m=(prop.origin_m[0], prop.origin_m[1], prop.origin_m[2]), yaw_deg=prop.yaw_deg,
                         max_depth=prop.max_depth, rays_per_source=prop.rays_per_source, reflection=prop.reflection, scattering=prop.scattering,
                         diffraction=prop.diffraction, refraction=prop.refraction)


@functools.lru_cache(maxsize=4)
def shared_tracer(settings: TraceSettings) -> RayTracer:
    """One loaded ray tracer per trace settings in this process: the plant's, the scoring planners' (rebuilt after
    a relay is lost or taken over) and the bounds' share its scene (loaded once) and its traces in memory. Its
    ``calls`` count every Sionna call any of them made."""
    return RayTracer(settings)


def traced_coherent(sc: Scenario) -> bool:
    """Whether a ray-traced channel's paths are summed with their phases (``paths_sum = "coherent"``), else in power."""
    return sc.channel.propagation.paths_sum == "coherent"


def traced_channel(sc: Scenario) -> TracedChannel | None:
    """The plant's ray-traced channel (``model = "ray_traced"``; None otherwise)."""
    prop = sc.channel.propagation
    if prop.model != "ray_traced":
        return None
    return TracedChannel(shared_tracer(trace_settings(sc)), trace_period_s=max(prop.trace_period_s, sc.control_period_s),
                         coherent=traced_coherent(sc))


def map_tracer(sc: Scenario) -> RayTracer | None:
    """A ray tracer of the scene's map (``model = "ray_traced"``; None otherwise): what the one relay's bound and a
    traced pre-flight route trace their cells with."""
    return shared_tracer(trace_settings(sc)) if sc.channel.propagation.model == "ray_traced" else None


def scene_key(sc: Scenario) -> dict:
    """A traced scene's files in a cache key (``models.raytrace.scene_digest``: a scene's meshes edited, its bound is
    computed again); empty without a ray-traced channel."""
    prop = sc.channel.propagation
    if prop.model != "ray_traced" or prop.scene is None:
        return {}
    return {"scene_digest": scene_digest(sionna_rt(), trace_settings(sc).scene)}


def scoring_tracer(sc: Scenario) -> RayTracer | None:
    """The ray tracer the capacity planners score candidates with (``controller.capacity.scoring = "traced"``, the
    one relay's and a fleet's; None otherwise)."""
    return shared_tracer(trace_settings(sc)) if sc.controller.capacity.scoring == "traced" else None


def wind_settings(sc: Scenario) -> WindSettings:
    """The wind of ``[wind]`` (its altitude: the first relay's start height over the ground by default)."""
    w = sc.wind
    assert w is not None
    altitude = w.altitude_m if w.altitude_m is not None else sc.relay_list[0].start[2] - sc.world.ground_z_m
    return WindSettings(mean=(w.mean_m_s[0], w.mean_m_s[1], w.mean_m_s[2]), gusts=w.gusts, w20_m_s=w.w20_m_s,
                        altitude_m=float(altitude))


def observer(sc: Scenario, vehicle: Multirotor) -> ExternalAccelerationObserver | None:
    """A relay's external-force observer on its own model (``[wind] observer``); None without it."""
    w = sc.wind
    if w is None or not w.observer:
        return None
    period = sc.control_period_s
    return ExternalAccelerationObserver(plant_step_function(vehicle, sc.sim.plant_rate_hz, period), period,
                                        w.observer_time_constant_s)


def air(sc: Scenario, relays: Mapping[str, tuple[Multirotor, PlatformConfig]]) -> Air | None:
    """The air every relay of ``relays`` (name: its vehicle and platform) flies in; None without ``[wind]``."""
    w = sc.wind
    if w is None:
        return None
    period, rate = sc.control_period_s, sc.sim.plant_rate_hz
    flying = {}
    for name, (vehicle, platform) in relays.items():
        drag = drag_coefficients(platform.drag_area_m2, w.air_density_kg_m3)
        flying[name] = AirborneRelay(plant=plant_step_function(vehicle, rate, period, drag=drag), drag=np.asarray(drag),
                                     mass=vehicle.mass, observer=observer(sc, vehicle))
    return Air(WindSeries(wind_settings(sc), period, sc.seed), flying)


def wind_field(sc: Scenario) -> HeldWind | None:
    """``[wind]`` as a wind field for a simulator outside aerorelay (RotorPy behind ``aerorelay sitl``):
    the same mean, gusts and seed as ``ar.simulate``'s air; None without ``[wind]``."""
    if sc.wind is None:
        return None
    return HeldWind(WindSeries(wind_settings(sc), sc.control_period_s, sc.seed), sc.control_period_s)


def bound_key_data(sc: Scenario, data: dict) -> dict:
    """A bound's cache-key data without what cannot change a bound (the platforms' drag: the bounds
    fly no wind), with the obstacles when there are any (a scenario without keeps its key)."""
    for platform in [data.get("platform"), *(r.get("platform") for r in data.get("relays") or [])]:
        if isinstance(platform, dict):
            platform.pop("drag_area_m2", None)
    if sc.obstacles:
        data["obstacles"] = [o.model_dump() for o in sc.obstacle_list]
    return data
