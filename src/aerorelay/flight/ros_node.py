"""A ROS 2 node for the relay (``aerorelay ros SCENARIO``; the optional extra ``aerorelay[ros]`` on the
``ros-rclpy`` wheels). ROS's frames are aerorelay's own (REP 103: world ENU, body FLU).

Subscribes ``/<relay>/odom`` and ``/<source>/odom`` (``nav_msgs/Odometry``: pose and twist, the twist
in the child (body) frame as REP 105 has it); every control period steps the controller
(``flight.stepper``) and publishes ``/<relay>/setpoint`` (``trajectory_msgs/MultiDOFJointTrajectory``,
one point: the position and attitude one period ahead, the velocity and body rates, the
acceleration) and ``/<relay>/link`` (``std_msgs/Float64MultiArray``: the end-to-end capacity and each
hop's SINR at the measured poses in the scenario's radio scene). Stale odometry holds, then lands,
as the step API does; odometry that cannot be trusted (non-finite, a quaternion far from unit norm,
stamped ahead of the clock or backwards, a jump no vehicle can make) is held as stale and logged with
why; unstamped odometry (``header.stamp`` zero) is never fresh, and the node says so. The NMPC's
state, the first step's gating, the telemetry check and the source's acceleration (from its
velocity) are ``flight.autopilot_loop``'s, as for the MAVLink bridge; ``on_step`` gets every step
with the measured state (a ``sim.flight_record`` recorder: ``aerorelay ros --out``).

A network (``FleetNode``, ``aerorelay ros`` on a scenario with ``[[relays]]``) is one node for the fleet: each
relay under its own name as namespace (``/<relay>/odom`` in, ``/<relay>/setpoint`` out), each source's
``/<source>/odom``, and ``/network/link`` (``std_msgs/Float64MultiArray``: the network's rate, every route's rate,
every hop's SINR at the measured poses; its layout's one dimension is labelled with the entries' names, comma
separated). The gating, staleness and telemetry check per relay are ``flight.autopilot_loop.FleetLoop``'s: a
relay whose odometry stops holds, then lands and leaves the network (the others re-plan).
"""

from __future__ import annotations

import numpy as np
import rclpy
from geometry_msgs.msg import Transform, Twist
from nav_msgs.msg import Odometry
from rclpy.node import Node
from std_msgs.msg import Float64MultiArray, MultiArrayDimension
from trajectory_msgs.msg import MultiDOFJointTrajectory, MultiDOFJointTrajectoryPoint

from ..models.radio import RadioScene
from .autopilot_loop import AccelerationFilter, AutopilotLoop, FleetLoop, FleetStepHook, Measured, StepHook, rotation_from_quaternion
from .names import check_ros_namespace
from .network_controller import NetworkStepper
from .stepper import Command, RelayStepper, SourceState

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
    """The relay's controller as a ROS 2 node (see the module); ``relay`` / ``source`` name the topics."""

    def __init__(self, stepper: RelayStepper, scene: RadioScene, *, relay: str = "relay", source: str = "source",
                 on_step: StepHook | None = None):
        relay, source = check_ros_namespace(relay, "--relay"), check_ros_namespace(source, "--source")
        super().__init__(f"aerorelay_{relay.replace('/', '_')}")
        self.stepper, self.scene, self.relay, self.source = stepper, scene, relay, source
        self.names = {role: scene.name_of(role) for role in ("relay", "source")}
        self.loop = AutopilotLoop(stepper, on_step=on_step)
        self.source_accel = AccelerationFilter()
        self.odom: dict[str, Odometry] = {}
        # depth 1: only the latest odometry matters (a backlog would hand the controller stale states)
        self.create_subscription(Odometry, f"/{relay}/odom", lambda m: self.odom.__setitem__("relay", m), 1)
        self.create_subscription(Odometry, f"/{source}/odom", lambda m: self.odom.__setitem__("source", m), 1)
        self.setpoints = self.create_publisher(MultiDOFJointTrajectory, f"/{relay}/setpoint", 10)
        self.link = self.create_publisher(Float64MultiArray, f"/{relay}/link", 10)
        self.t0: float | None = None
        self.commands: list[Command] = []
        self.rejected: list[tuple[float, str]] = []  # (time s, why) of every step whose odometry was not trusted
        self._warned_at = -float("inf")
        self.timer = self.create_timer(stepper.period, self.tick)

    def _state(self, m: Odometry, t0: float) -> Measured:
        return measured_from_odometry(m, t0)

    def _warn(self, t: float, why: str) -> None:
        if t - self._warned_at >= WARN_EVERY_S:
            self.get_logger().warning(why)
            self._warned_at = t

    def tick(self) -> None:
        now = self.get_clock().now().nanoseconds * 1e-9
        if self.t0 is None:
            self.t0 = now
        t = now - self.t0
        relay = self._state(self.odom["relay"], self.t0) if "relay" in self.odom else None
        src_m = self._state(self.odom["source"], self.t0) if "source" in self.odom else None
        for m, topic in ((relay, self.relay), (src_m, self.source)):
            if m is not None and m.stamp == -float("inf"):
                self._warn(t, f"odometry on /{topic}/odom is unstamped (header.stamp = 0): it is never fresh; stamp it "
                              "with the time it was measured")
        src = None
        if src_m is not None:
            src = SourceState(src_m.p, src_m.v, self.source_accel.update(src_m.stamp, src_m.v), stamp=src_m.stamp)
        cmd = self.loop.tick(t, relay, src)
        if cmd is None:
            self._warn(t, f"not flying yet: {self.loop.waiting} (/{self.relay}/odom, /{self.source}/odom)")
            return
        if cmd.rejected is not None:
            self.rejected.append((t, cmd.rejected))
            self._warn(t, f"odometry not trusted, holding: {cmd.rejected}")
        self.commands.append(cmd)
        self.setpoints.publish(self._trajectory(cmd))
        if relay is not None and src_m is not None and cmd.rejected is None and np.all(np.isfinite(src_m.R)):
            state = self.scene.evaluate(t, {self.names["relay"]: self.scene.pose(self.names["relay"], relay.p, relay.R),
                                            self.names["source"]: self.scene.pose(self.names["source"], src_m.p, src_m.R)})
            self.link.publish(Float64MultiArray(data=[float(state.capacity), *(float(g) for g in state.sinr)]))

    def _trajectory(self, cmd: Command) -> MultiDOFJointTrajectory:
        return trajectory_message(self, cmd, self.relay, self.stepper.period)


class FleetNode(Node):
    """A network's controller as one ROS 2 node (see the module): every relay's and source's name is its namespace."""

    def __init__(self, stepper: NetworkStepper, scene: RadioScene, *, on_step: FleetStepHook | None = None):
        super().__init__("aerorelay_fleet")
        self.stepper, self.scene = stepper, scene
        self.relays = [check_ros_namespace(n, "relay name") for n in stepper.relays]
        self.sources = [check_ros_namespace(n, "source name") for n in stepper.controller.sources]
        self.loop = FleetLoop(stepper, on_step=on_step)
        self.odom: dict[str, Odometry] = {}
        for name in (*self.relays, *self.sources):  # depth 1: only the latest odometry matters
            self.create_subscription(Odometry, f"/{name}/odom", lambda m, n=name: self.odom.__setitem__(n, m), 1)
        self.setpoints = {r: self.create_publisher(MultiDOFJointTrajectory, f"/{r}/setpoint", 10) for r in self.relays}
        self.link = self.create_publisher(Float64MultiArray, "/network/link", 10)
        self.t0: float | None = None
        self.commands: list[dict[str, Command]] = []
        self._warned_at = -float("inf")
        self.timer = self.create_timer(stepper.period, self.tick)

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
                self._warn(t, f"odometry on /{n}/odom is unstamped (header.stamp = 0): it is never fresh; stamp it with the "
                              "time it was measured")
        cmds = self.loop.tick(t, {r: measured[r] for r in self.relays}, {s: measured[s] for s in self.sources})
        if cmds is None:
            self._warn(t, f"not flying yet: {self.loop.waiting}")
            return
        if self.loop.rejected:
            self._warn(t, "holding " + "; ".join(f"{n}: {why}" for n, why in self.loop.rejected.items()))
        self.commands.append(cmds)
        for r, cmd in cmds.items():
            self.setpoints[r].publish(trajectory_message(self, cmd, r, self.stepper.period))
        scene = self.stepper.controller.scene  # the network flying now (a relay that left it is skipped)
        moving = {n: measured[n] for route in scene.all_routes for n in route[:-1]}
        known = {n: m for n, m in moving.items() if m is not None and np.all(np.isfinite(m.R))}
        if len(known) == len(moving):
            state = scene.evaluate(t, {n: scene.pose(n, m.p, m.R) for n, m in known.items()})
            msg = Float64MultiArray(data=[float(state.capacity), *(float(c) for c in state.route_capacity),
                                          *(float(g) for g in state.sinr)])
            msg.layout.dim = [MultiArrayDimension(label=",".join(self.link_labels(scene)), size=len(msg.data), stride=1)]
            self.link.publish(msg)


def spin(stepper: RelayStepper | NetworkStepper, scene: RadioScene, duration_s: float | None = None,
         on_step: StepHook | FleetStepHook | None = None, **names: str) -> RelayNode | FleetNode:
    """Run the node until ``duration_s`` (None: until Ctrl-C); returns it (its ``commands``). A ``NetworkStepper``
    runs a ``FleetNode`` (its names are the scenario's; ``names`` are for one relay)."""
    rclpy.init()
    node: RelayNode | FleetNode
    if isinstance(stepper, NetworkStepper):
        if names:
            raise ValueError(f"a fleet's topics are its relays' and sources' names; {', '.join(names)} are for one relay")
        node = FleetNode(stepper, scene, on_step=on_step)  # type: ignore[arg-type]
    else:
        node = RelayNode(stepper, scene, on_step=on_step, **names)  # type: ignore[arg-type]
    try:
        end = None if duration_s is None else node.get_clock().now().nanoseconds * 1e-9 + duration_s
        while rclpy.ok() and (end is None or node.get_clock().now().nanoseconds * 1e-9 < end):
            rclpy.spin_once(node, timeout_sec=0.001)  # one callback per call: called often, so none waits
    finally:
        node.destroy_node()
        rclpy.shutdown()
    return node
