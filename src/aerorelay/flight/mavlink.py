"""MAVLink as PX4 speaks it: version 2 with the common message set (ODOMETRY and every message id
above 255 need version 2). pymavlink picks its wire protocol from the ``MAVLINK20`` environment
variable when a dialect is set: importing this module sets it (unless the process set it already)
and selects the common dialect for every connection pymavlink makes in this process."""

from __future__ import annotations

import os

from pymavlink import mavutil

os.environ.setdefault("MAVLINK20", "1")
mavutil.set_dialect("common")
MAV = mavutil.mavlink


def connect(url: str, *, system: int, component: int):
    """A MAVLink 2 connection on ``url`` (pymavlink's URL forms: ``udpin:HOST:PORT``, ``udpout:HOST:PORT``,
    ``tcp:HOST:PORT``, a serial device) sending as ``system`` / ``component``."""
    return mavutil.mavlink_connection(url, source_system=system, source_component=component, dialect="common")
