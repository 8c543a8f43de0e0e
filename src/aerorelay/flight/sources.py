"""Where the relay's bridge learns where the source (the inspection drone, MRAV-2) is, each control
period: ``known(t, t_mission)`` returns a ``SourceState`` stamped on the mission's clock, or None
while nothing has arrived.

* ``MissionSource``: its mission file (the scenario's path), exact and always fresh.
* ``MavlinkSource``: a second MAVLink system (the inspection drone's autopilot on its own link):
  its LOCAL_POSITION_NED (NED on the wire, ENU inside) shifted by ``origin_enu`` (where its local
  frame's origin lies in the scenario's world, m; PX4 puts it where its estimator started), stamped
  with the bridge time it arrived. Its acceleration, which LOCAL_POSITION_NED does not carry, is the
  velocity's change between messages through a first-order filter (``accel_time_constant_s``). A
  source that stops reporting goes stale and the relays' controller holds (``control.network.Controller``).
"""

from __future__ import annotations

import math

import numpy as np

from ..control.relay_step import SourceState
from ..models.mission import SourceTrajectory
from .autopilot_loop import AccelerationFilter
from .frames import ned_to_enu
from .mavlink import MAV, connect, drain

GCS_HEARTBEAT_S = 1.0  # how often the bridge announces itself on the source's link once it is heard


class MissionSource:
    """The source on its mission file: where it is at the mission's time ``t_mission`` (s)."""

    def __init__(self, trajectory: SourceTrajectory):
        self.trajectory = trajectory

    def known(self, t: float, t_mission: float) -> SourceState | None:
        s = self.trajectory.state(t_mission)
        return SourceState(np.asarray(s.p, float), np.asarray(s.v, float), np.asarray(s.a, float), stamp=t_mission)


class MavlinkSource:
    """The source as a second MAVLink system on ``url`` (see the module); ``system``: its system id
    (None: any system that sends LOCAL_POSITION_NED on that link)."""

    def __init__(self, url: str, *, system: int | None = None, origin_enu=(0.0, 0.0, 0.0), accel_time_constant_s: float = 0.1):
        self.accel = AccelerationFilter(accel_time_constant_s)
        self.link = connect(url, system=255, component=191)
        self.system, self.origin = system, np.asarray(origin_enu, float)
        self.p: np.ndarray | None = None
        self.v = np.zeros(3)
        self.a = np.zeros(3)
        self.received_at = -math.inf
        self._announced_at = -math.inf

    def announce(self, t: float) -> None:
        """A GCS heartbeat (a source listening with ``udpin`` learns where to answer): every call until
        the source is heard, then once a second."""
        if self.p is None or t - self._announced_at >= GCS_HEARTBEAT_S:
            self.link.mav.heartbeat_send(MAV.MAV_TYPE_GCS, MAV.MAV_AUTOPILOT_INVALID, 0, 0, MAV.MAV_STATE_ACTIVE)
            self._announced_at = t

    def poll(self, t: float) -> None:
        """Read what arrived by bridge time ``t`` (s)."""
        for msg in drain(self.link, "LOCAL_POSITION_NED"):
            if self.system is not None and msg.get_srcSystem() != self.system:
                continue
            v = ned_to_enu([msg.vx, msg.vy, msg.vz])
            self.a = self.accel.update(t, v)
            self.p, self.v, self.received_at = self.origin + ned_to_enu([msg.x, msg.y, msg.z]), v, t

    def known(self, t: float, t_mission: float) -> SourceState | None:
        """The source's last report, stamped on the mission's clock; None before the first."""
        self.announce(t)
        self.poll(t)
        if self.p is None:
            return None
        return SourceState(self.p.copy(), self.v.copy(), self.a.copy(), stamp=t_mission - (t - self.received_at))
