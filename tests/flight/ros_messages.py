"""Messages the ROS 2 tests publish (needs rclpy: imported by tests that have it)."""

from __future__ import annotations


def odometry(node, p):
    """``nav_msgs/Odometry`` of a vehicle held level at ``p`` (m, map frame), stamped now on ``node``'s clock."""
    from nav_msgs.msg import Odometry

    m = Odometry()
    m.header.stamp = node.get_clock().now().to_msg()
    m.header.frame_id, m.child_frame_id = "map", "base_link"
    m.pose.pose.position.x, m.pose.pose.position.y, m.pose.pose.position.z = (float(v) for v in p)
    m.pose.pose.orientation.w = 1.0
    return m
