"""``[platform]`` -> the vehicle model (``models.vehicle.Multirotor``)."""

from __future__ import annotations

import functools
from typing import Any

import numpy as np

from ..config import PlatformConfig
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
