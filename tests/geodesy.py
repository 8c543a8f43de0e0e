"""Local east-north-up metres of WGS84 points written out for the tests: pyproj's geodetic-to-ECEF transform (EPSG:4979
to EPSG:4978, a different pipeline from the program's topocentric one) and the ENU rotation of the standard formula,
so the program's frame is checked against this, not against itself."""

from __future__ import annotations

import math

import numpy as np
from pyproj import Transformer


def enu_by_hand(origin, lat, lon, alt) -> np.ndarray:
    """``(n, 3)`` ENU (m) at ``origin`` ``(lat_deg, lon_deg, alt_m)`` of the points ``lat``, ``lon`` (deg), ``alt`` (m)."""
    to_ecef = Transformer.from_crs("EPSG:4979", "EPSG:4978", always_xy=True)
    x, y, z = to_ecef.transform(np.atleast_1d(lon), np.atleast_1d(lat), np.atleast_1d(alt))
    x0, y0, z0 = to_ecef.transform(origin[1], origin[0], origin[2])
    phi, lam = math.radians(origin[0]), math.radians(origin[1])
    d = np.vstack([np.asarray(x) - x0, np.asarray(y) - y0, np.asarray(z) - z0])
    R = np.array([[-math.sin(lam), math.cos(lam), 0.0],
                  [-math.sin(phi) * math.cos(lam), -math.sin(phi) * math.sin(lam), math.cos(phi)],
                  [math.cos(phi) * math.cos(lam), math.cos(phi) * math.sin(lam), math.sin(phi)]])
    return (R @ d).T
