"""``[wind]``: the air every relay flies in. A mean wind (constant in space and time) plus, when
``gusts``, Dryden turbulence (MIL-F-8785C low-altitude form, ``models/wind.py``) with its
intensities and scale lengths from the mean wind's horizontal speed (taken as the wind at 6 m) and
the altitude. It acts on each relay through its platform's drag (``[platform] drag_area_m2``).
No ``[wind]`` table: still air, every number as without this feature."""

from __future__ import annotations

import math

from pydantic import Field, field_validator

from .base import Strict, Vec3

AIR_DENSITY_KG_M3 = 1.225  # ISA sea level, 15 deg C
MAX_WIND_M_S = 40.0  # the mean wind's largest speed (as gust_w20_m_s's)


class WindConfig(Strict):
    """Wind and gusts, and the NMPC's disturbance observer that compensates them."""

    mean_m_s: Vec3 = Field(default_factory=lambda: [0.0, 0.0, 0.0], description="mean wind velocity, m/s (world ENU: "
                           "the direction the air moves toward)")
    gusts: bool = Field(False, description="add Dryden turbulence (seeded by the scenario's seed)")
    gust_w20_m_s: float | None = Field(None, ge=0.0, le=40.0, description="the wind speed at 6 m (20 ft) that sets the "
                                       "gusts' intensities, m/s; default: the mean wind's horizontal speed")
    altitude_m: float | None = Field(None, ge=0.0, le=1000.0, description="the altitude above the ground the Dryden "
                                     "scale lengths use, m (clamped to 3-305 m); default: the first relay's start height")
    air_density_kg_m3: float = Field(AIR_DENSITY_KG_M3, gt=0.0, le=2.0, description="rho of the drag force "
                                     "0.5 rho C_d A |v_air| v_air, kg/m^3 (default ISA sea level)")
    observer: bool = Field(True, description="each relay's NMPC compensates an estimate of the external acceleration "
                           "(an external-force observer on its measured velocity; off: the NMPC flies as in still air)")
    observer_time_constant_s: float = Field(0.3, gt=0.0, le=10.0, description="how fast the estimate follows the "
                                            "measured disturbance, s (first order)")

    @field_validator("mean_m_s")
    @classmethod
    def _a_wind_a_relay_flies_in(cls, v):
        speed = math.hypot(*v)
        if not speed <= MAX_WIND_M_S:
            raise ValueError(f"|v| = {speed:.4g} m/s; allowed 0-{MAX_WIND_M_S:g} m/s (no multirotor relay flies in more)")
        return v

    @property
    def w20_m_s(self) -> float:
        """The wind speed at 6 m setting the gusts (m/s)."""
        return self.gust_w20_m_s if self.gust_w20_m_s is not None else math.hypot(self.mean_m_s[0], self.mean_m_s[1])
