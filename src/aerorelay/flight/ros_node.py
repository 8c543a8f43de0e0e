"""A ROS 2 node for the relay (``aerorelay ros SCENARIO``; the optional extra ``aerorelay[ros]`` on the
``ros-rclpy`` wheels). ROS's frames are aerorelay's own (REP 103: world ENU, body FLU).

Subscribes ``/<relay>/odom`` and ``/<source>/odom`` (``nav_msgs/Odometry``: pose and twist, the twist
in the child (body) frame as REP 105 has it); every control period steps the controller
(``flight.stepper``) and publishes ``/<relay>/setpoint`` (``trajectory_msgs/MultiDOFJointTrajectory``,
one point: the position and attitude one period ahead, the velocity and body rates, the
acceleration) and ``/<relay>/link`` (``std_msgs/Float64MultiArray``: the end-to-end capacity and each
hop's SINR at the measured poses, the jammers as the relay was told them). Stale odometry holds, then
lands, as the step API does. The NMPC's state is ``flight.commanded``'s (the rotor speeds last
commanded, its own planned attitude for the autopilot's attitude loop); ``on_step`` gets every step
with the measured state (a ``sim.flight_record`` recorder: ``aerorelay ros --out``).
"""

from __future__ import annotations

import numpy as np
import rclpy
from geometry_msgs.msg import Transform, Twist
from nav_msgs.msg import Odometry
from rclpy.node import Node
from std_msgs.msg import Float64MultiArray
from trajectory_msgs.msg import MultiDOFJointTrajectory, MultiDOFJointTrajectoryPoint

from ..models.radio import RadioScene
from .commanded import CommandedState
from .frames import matrix_from_wxyz
from .mavlink_bridge import StepHook
from .stepper import Command, RelayStepper, SourceState


def _seconds(stamp) -> float:
    return float(stamp.sec) + 1e-9 * float(stamp.nanosec)


class RelayNode(Node):
    """The relay's controller as a ROS 2 node (see the module); ``relay`` / ``source`` name the topics."""

    def __init__(self, stepper: RelayStepper, scene: RadioScene, *, relay: str = "relay", source: str = "source",
                 on_step: StepHook | None = None):
        super().__init__(f"aerorelay_{relay}")
        self.stepper, self.scene, self.relay, self.source, self.on_step = stepper, scene, relay, source, on_step
        self.names = {role: scene.name_of(role) for role in ("relay", "source")}
        self.commanded = CommandedState(stepper.vehicle.hover_speeds())
        self.odom: dict[str, Odometry] = {}
        # depth 1: only the latest odometry matters (a backlog would hand the controller stale states)
        self.create_subscription(Odometry, f"/{relay}/odom", lambda m: self.odom.__setitem__("relay", m), 1)
        self.create_subscription(Odometry, f"/{source}/odom", lambda m: self.odom.__setitem__("source", m), 1)
        self.setpoints = self.create_publisher(MultiDOFJointTrajectory, f"/{relay}/setpoint", 10)
        self.link = self.create_publisher(Float64MultiArray, f"/{relay}/link", 10)
        self.t0: float | None = None
        self.commands: list[Command] = []
        self.timer = self.create_timer(stepper.period, self.tick)

    def _state(self, m: Odometry) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position (m), rotation body to world, world velocity (m/s) and body rates (rad/s) of an odometry."""
        p, q = m.pose.pose.position, m.pose.pose.orientation
        R = matrix_from_wxyz([q.w, q.x, q.y, q.z])
        v_body = np.array([m.twist.twist.linear.x, m.twist.twist.linear.y, m.twist.twist.linear.z])
        w = np.array([m.twist.twist.angular.x, m.twist.twist.angular.y, m.twist.twist.angular.z])
        return np.array([p.x, p.y, p.z]), R, np.concatenate([R @ v_body, w])

    def tick(self) -> None:
        now = self.get_clock().now().nanoseconds * 1e-9
        if "relay" not in self.odom or "source" not in self.odom:
            return
        if self.t0 is None:
            self.t0 = now
        t = now - self.t0
        stamp = _seconds(self.odom["relay"].header.stamp) - self.t0
        if not self.stepper.has_state and t - stamp > self.stepper.stale.hold_after_s:
            return  # nothing fresh yet and nothing to hold: wait for a fresh odometry
        p1, R1, vw1 = self._state(self.odom["relay"])
        p2, R2, vw2 = self._state(self.odom["source"])
        src = SourceState(p2, vw2[0:3], np.zeros(3), stamp=_seconds(self.odom["source"].header.stamp) - self.t0)
        measured = self.commanded.measured(p1, R1, vw1[0:3], vw1[3:6])
        cmd = self.stepper.step(t, self.commanded.for_nmpc(measured), src, state_stamp=stamp)
        self.commanded.commanded(cmd)
        self.commands.append(cmd)
        if self.on_step is not None:
            self.on_step(t, measured, cmd, src, t - stamp)
        self.setpoints.publish(self._trajectory(cmd))
        state = self.scene.evaluate(t, {self.names["relay"]: self.scene.pose(self.names["relay"], p1, R1),
                                        self.names["source"]: self.scene.pose(self.names["source"], p2, R2)})
        self.link.publish(Float64MultiArray(data=[float(state.capacity), *(float(g) for g in state.sinr)]))

    def _trajectory(self, cmd: Command) -> MultiDOFJointTrajectory:
        msg = MultiDOFJointTrajectory()
        msg.header.stamp = self.get_clock().now().to_msg()
        msg.header.frame_id = "map"
        msg.joint_names = [self.relay]
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
        pt.time_from_start.nanosec = int(self.stepper.period * 1e9)
        msg.points = [pt]
        return msg


def spin(stepper: RelayStepper, scene: RadioScene, duration_s: float | None = None, on_step: StepHook | None = None,
         **names: str) -> RelayNode:
    """Run the node until ``duration_s`` (None: until Ctrl-C); returns it (its ``commands``)."""
    rclpy.init()
    node = RelayNode(stepper, scene, on_step=on_step, **names)
    try:
        end = None if duration_s is None else node.get_clock().now().nanoseconds * 1e-9 + duration_s
        while rclpy.ok() and (end is None or node.get_clock().now().nanoseconds * 1e-9 < end):
            rclpy.spin_once(node, timeout_sec=0.001)  # one callback per call: called often, so none waits
    finally:
        node.destroy_node()
        rclpy.shutdown()
    return node
