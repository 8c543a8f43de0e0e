"""``[platform]`` -> the vehicle model (``models.vehicle.Multirotor``)."""

from __future__ import annotations

import functools
from typing import Any

import numpy as np

from ..config import PlatformConfig, Scenario
from ..models.vehicle import Multirotor, star_multirotor


def build_vehicle(cfg: PlatformConfig) -> Multirotor:
    """The vehicle model described by ``[platform]`` (a star layout, or the custom ``rotors``)."""
    params: dict[str, Any] = dict(
        mass=cfg.mass_kg,
        inertia=np.diag(cfg.inertia_kgm2),
        gravity=cfg.gravity_m_s2,
        c_xi=cfg.c_xi,
        c_tau=cfg.c_tau,
        omega_min=cfg.omega_min_hz,
        omega_max=cfg.omega_max_hz,
        omega_dot_min=cfg.omega_dot_min_hz_s,
        omega_dot_max=cfg.omega_dot_max_hz_s,
    )
    if cfg.rotors is None:
        return star_multirotor(cfg.rotor_count, cfg.tilt_deg, cfg.arm_length_m, **params)
    axes = np.array([r.axis for r in cfg.rotors], float)
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    return Multirotor(
        positions=np.array([r.position for r in cfg.rotors], float),
        axes=axes,
        spins=np.array([r.spin for r in cfg.rotors], float),
        **params,
    )


@functools.lru_cache(maxsize=8)
def _cached_vehicle(platform_json: str) -> Multirotor:
    return build_vehicle(PlatformConfig.model_validate_json(platform_json))


def shared_vehicle(cfg: PlatformConfig) -> Multirotor:
    """The platform's vehicle, built once per platform for the load checks (its hover-tilt limits
    are LPs, cached on it). Read-only: a mission builds its own with ``build_vehicle``."""
    return _cached_vehicle(cfg.model_dump_json())


def thrust_along_body_z(sc: Scenario) -> Scenario:
    """``sc`` with its relays' rotors turned to push along body z (a star layout untilted, a custom
    layout's axes set to body z; positions and spins kept; a network's relays' own platforms too): the
    vehicle an autopilot flies, whose thrust stays along body z, so the NMPC plans only what the
    autopilot can fly."""
    updates: dict = {}
    if sc.platform.rotors is not None or sc.platform.tilt_deg != 0:
        updates["platform"] = _untilted(sc.platform)
    if sc.relays is not None and any(r.platform is not None for r in sc.relays):  # a relay's own platform, likewise
        updates["relays"] = [r.model_dump() | ({} if r.platform is None else {"platform": _untilted(sc.platform_of(i))})
                             for i, r in enumerate(sc.relays)]
    return sc.with_updates(updates) if updates else sc


def _untilted(p) -> dict:
    """A platform table with its rotors pushing along body z."""
    table = p.model_dump()
    if p.rotors is not None:
        table["rotors"] = [r | {"axis": [0.0, 0.0, 1.0]} for r in table["rotors"]]
    else:
        table["tilt_deg"] = 0.0
    return table
