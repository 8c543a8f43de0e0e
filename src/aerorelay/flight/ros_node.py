"""The scenario's controller as one ROS 2 node, for any network (``aerorelay ros SCENARIO``; the optional extra
``aerorelay[ros]`` on the ``ros-rclpy`` wheels). ROS's frames are aerorelay's own (REP 103: world ENU, body FLU).

Each relay and source is under its own name as topic namespace (``aerorelay ros --relay NS --source NS`` renames
the one relay's and source's). Subscribes ``/<relay>/odom`` and ``/<source>/odom`` (``nav_msgs/Odometry``: pose and
twist, the twist in the child (body) frame as REP 105 has it); every control period steps the controller and
publishes ``/<relay>/setpoint`` per relay (``trajectory_msgs/MultiDOFJointTrajectory``, one point: the position and
attitude one period ahead, the velocity and body rates, the acceleration) and ``/network/link``
(``std_msgs/Float64MultiArray``: the network's rate, every route's rate, every hop's SINR at the measured poses in
the scenario's radio scene; its layout's one dimension is labelled with the entries' names, comma separated).

Stale odometry holds, then lands, as the step API does; odometry that cannot be trusted (non-finite, a quaternion
far from unit norm, stamped ahead of the clock or backwards, a jump no vehicle can make) is held as stale and logged
with why; unstamped odometry (``header.stamp`` zero) is never fresh, and the node says so. A relay whose odometry
stops holds, then lands and leaves the network (the others re-plan). The NMPC's state, the first step's gating and
the source's acceleration (from its velocity) are ``flight.autopilot_loop``'s, as for the MAVLink bridge;
``on_step`` gets every period flown with the measured states (a ``sim.flight_record`` recorder: ``aerorelay ros --out``).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import rclpy
from geometry_msgs.msg import Transform, Twist
from nav_msgs.msg import Odometry
from rclpy.node import Node
from std_msgs.msg import Float64MultiArray, MultiArrayDimension
from trajectory_msgs.msg import MultiDOFJointTrajectory, MultiDOFJointTrajectoryPoint

from ..control.network import Controller
from ..control.relay_step import Command
from ..models.radio import RadioScene
from .autopilot_loop import AutopilotLoop, Measured, StepHook, rotation_from_quaternion
from .names import check_ros_namespace

WARN_EVERY_S = 2.0  # how often the node repeats why it is not flying


def _seconds(stamp) -> float:
    return float(stamp.sec) + 1e-9 * float(stamp.nanosec)


def measured_from_odometry(m: Odometry, t0: float) -> Measured:
    """An odometry as aerorelay's measurement: position (m), rotation body to world, world velocity
    (m/s; REP 105's twist is in the body frame), body rates (rad/s), stamped on the node's clock (``t0``: its
    start, s; unstamped: never fresh)."""
    p, q = m.pose.pose.position, m.pose.pose.orientation
    R = rotation_from_quaternion([q.w, q.x, q.y, q.z])
    v_body = np.array([m.twist.twist.linear.x, m.twist.twist.linear.y, m.twist.twist.linear.z])
    w = np.array([m.twist.twist.angular.x, m.twist.twist.angular.y, m.twist.twist.angular.z])
    stamp = _seconds(m.header.stamp)
    return Measured(np.array([p.x, p.y, p.z]), R, R @ v_body, w, stamp - t0 if stamp > 0 else -float("inf"))


def trajectory_message(node: Node, cmd: Command, joint: str, period_s: float) -> MultiDOFJointTrajectory:
    """A command as one trajectory point one period ahead (position, attitude, velocity, body rates, acceleration)."""
    msg = MultiDOFJointTrajectory()
    msg.header.stamp = node.get_clock().now().to_msg()
    msg.header.frame_id = "map"
    msg.joint_names = [joint]
    pt = MultiDOFJointTrajectoryPoint()
    tf = Transform()
    tf.translation.x, tf.translation.y, tf.translation.z = (float(v) for v in cmd.position_m)
    w, qx, qy, qz = (float(v) for v in cmd.attitude_wxyz)
    tf.rotation.w, tf.rotation.x, tf.rotation.y, tf.rotation.z = w, qx, qy, qz
    vel, acc = Twist(), Twist()
    vel.linear.x, vel.linear.y, vel.linear.z = (float(v) for v in cmd.velocity_m_s)
    vel.angular.x, vel.angular.y, vel.angular.z = (float(v) for v in cmd.body_rates_rad_s)
    acc.linear.x, acc.linear.y, acc.linear.z = (float(v) for v in cmd.acceleration_m_s2)
    pt.transforms, pt.velocities, pt.accelerations = [tf], [vel], [acc]
    pt.time_from_start.nanosec = int(period_s * 1e9)
    msg.points = [pt]
    return msg


class RelayNode(Node):
    """The scenario's controller as one ROS 2 node for any network (see the module): each relay and source under its
    topic namespace (``topics``: scenario name -> namespace; default its name in the scenario)."""

    def __init__(self, controller: Controller, scene: RadioScene, *, on_step: StepHook | None = None,
                 topics: Mapping[str, str] | None = None):
        names = [*controller.relays, *controller.sources]
        unknown = sorted(set(topics or {}) - set(names))
        if unknown:
            raise ValueError(f"topics: no relay or source {unknown} in the scenario ({', '.join(names)})")
        self.topic = {n: check_ros_namespace((topics or {}).get(n, n), f"{n}'s topic namespace") for n in names}
        # named by its relays' vehicles, so that nodes of several networks run side by side
        super().__init__("aerorelay_" + "_".join(self.topic[r].replace("/", "_") for r in controller.relays))
        self.controller, self.scene = controller, scene
        self.relays, self.sources = list(controller.relays), list(controller.sources)
        self.loop = AutopilotLoop(controller, on_step=on_step)
        self.odom: dict[str, Odometry] = {}
        for name in names:  # depth 1: only the latest odometry matters (a backlog would hand the controller stale states)
            self.create_subscription(Odometry, f"/{self.topic[name]}/odom", lambda m, n=name: self.odom.__setitem__(n, m), 1)
        self.setpoints = {r: self.create_publisher(MultiDOFJointTrajectory, f"/{self.topic[r]}/setpoint", 10) for r in self.relays}
        self.link = self.create_publisher(Float64MultiArray, "/network/link", 10)
        self.t0: float | None = None
        self.commands: list[dict[str, Command]] = []
        self.rejected: list[tuple[float, str, str]] = []  # (time s, relay, why) of every relay step whose odometry was not trusted
        self._warned_at = -float("inf")
        self.timer = self.create_timer(controller.period, self.tick)

    def _warn(self, t: float, why: str) -> None:
        if t - self._warned_at >= WARN_EVERY_S:
            self.get_logger().warning(why)
            self._warned_at = t

    def link_labels(self, scene: RadioScene) -> list[str]:
        """The names of ``/network/link``'s entries: the rate, each route's (by its source), each hop's SINR."""
        return (["capacity", *(f"capacity.{r[0]}" for r in scene.all_routes)]
                + [f"sinr.{tx}.{rx}" for tx, rx in scene.hops])

    def tick(self) -> None:
        now = self.get_clock().now().nanoseconds * 1e-9
        if self.t0 is None:
            self.t0 = now
        t = now - self.t0
        measured = {n: measured_from_odometry(self.odom[n], self.t0) if n in self.odom else None for n in (*self.relays, *self.sources)}
        for n, m in measured.items():
            if m is not None and m.stamp == -float("inf"):
                self._warn(t, f"odometry on /{self.topic[n]}/odom is unstamped (header.stamp = 0): it is never fresh; stamp "
                              "it with the time it was measured")
        cmds = self.loop.tick(t, {r: measured[r] for r in self.relays}, {s: measured[s] for s in self.sources})
        if cmds is None:
            self._warn(t, f"not flying yet: {self.loop.waiting} (" + ", ".join(f"/{self.topic[n]}/odom" for n in measured) + ")")
            return
        for r, cmd in cmds.items():
            if cmd.rejected is not None and cmd.rejected != "no relay state":
                self.rejected.append((t, r, cmd.rejected))
        if self.loop.rejected:
            self._warn(t, "holding " + "; ".join(f"{n}: {why}" for n, why in self.loop.rejected.items()))
        self.commands.append(cmds)
        for r, cmd in cmds.items():
            self.setpoints[r].publish(trajectory_message(self, cmd, self.topic[r], self.controller.period))
        scene = self.controller.controller.scene  # the network flying now (a relay that left it is skipped)
        moving = {n: measured[n] for route in scene.all_routes for n in route[:-1]}
        known = {n: m for n, m in moving.items() if m is not None and np.all(np.isfinite(m.R)) and np.all(np.isfinite(m.p))}
        if len(known) == len(moving):
            state = scene.evaluate(t, {n: scene.pose(n, m.p, m.R) for n, m in known.items()})
            msg = Float64MultiArray(data=[float(state.capacity), *(float(c) for c in state.route_capacity),
                                          *(float(g) for g in state.sinr)])
            msg.layout.dim = [MultiArrayDimension(label=",".join(self.link_labels(scene)), size=len(msg.data), stride=1)]
            self.link.publish(msg)


def spin(controller: Controller, scene: RadioScene, duration_s: float | None = None, on_step: StepHook | None = None,
         topics: Mapping[str, str] | None = None) -> RelayNode:
    """Run the node until ``duration_s`` (None: until Ctrl-C); returns it (its ``commands``). ``topics``: a relay's or
    source's topic namespace by its name in the scenario (default: that name)."""
    rclpy.init()
    node = RelayNode(controller, scene, on_step=on_step, topics=topics)
    try:
        end = None if duration_s is None else node.get_clock().now().nanoseconds * 1e-9 + duration_s
        while rclpy.ok() and (end is None or node.get_clock().now().nanoseconds * 1e-9 < end):
            rclpy.spin_once(node, timeout_sec=0.001)  # one callback per call: called often, so none waits
    finally:
        node.destroy_node()
        rclpy.shutdown()
    return node
