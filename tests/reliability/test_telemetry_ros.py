"""The ROS 2 node's odometry checked before it is flown (issue 45): the node is driven in-process
(its odometry set, ``tick`` called), so each bad message's handling is seen step by step. Before: a
zero quaternion killed the node in flight, NaN odometry was flown (466 NaN setpoints), odometry
stamped ahead of the clock defeated the stale check, unstamped odometry made it wait forever without a
word. Needs the optional ros extra (CI requires it: ``AERORELAY_REQUIRE_ROS=1``)."""

from __future__ import annotations

import math
import os

import numpy as np
import pytest

if os.environ.get("AERORELAY_REQUIRE_ROS") != "1":
    pytest.importorskip("rclpy", reason="the optional ros extra (pip install 'aerorelay[ros]') is not installed")

import rclpy  # noqa: E402
from nav_msgs.msg import Odometry  # noqa: E402

import aerorelay as ar  # noqa: E402
from aerorelay.assembly.parts import build_scene  # noqa: E402
from aerorelay.flight.ros_node import RelayNode  # noqa: E402


@pytest.fixture()
def node():
    sc = ar.load_scenario("scenarios/nominal_tilted.toml")
    rclpy.init(domain_id=int(os.environ.get("AERORELAY_TEST_ROS_DOMAIN", "201")))
    n = RelayNode(ar.controller(sc, autopilot=True), build_scene(sc), topics={"relay": "relay_t", "source": "source_t"})
    n.timer.cancel()  # the test ticks it
    yield sc, n
    n.destroy_node()
    rclpy.shutdown()


def _odom(n, p, q=(1.0, 0.0, 0.0, 0.0), stamp: float | None = None):
    m = Odometry()
    now = n.get_clock().now().nanoseconds * 1e-9 if stamp is None else stamp
    m.header.stamp.sec, m.header.stamp.nanosec = int(now), int(round((now - int(now)) * 1e9)) % 1_000_000_000
    m.pose.pose.position.x, m.pose.pose.position.y, m.pose.pose.position.z = (float(v) for v in p)
    m.pose.pose.orientation.w, m.pose.pose.orientation.x, m.pose.pose.orientation.y, m.pose.pose.orientation.z = q
    return m


def _tick(n, relay, source):
    n.odom["relay"], n.odom["source"] = relay, source
    k = len(n.commands)
    n.tick()
    return n.commands[-1]["relay"] if len(n.commands) > k else None


def test_bad_odometry_is_held_and_named_and_good_odometry_flies_again(node):
    sc, n = node
    p1, p2 = sc.nodes.relay, sc.mission.start
    assert _tick(n, _odom(n, p1), _odom(n, p2)).mode in ("nmpc", "fallback")
    cmd = _tick(n, _odom(n, p1, q=(0.0, 0.0, 0.0, 0.0)), _odom(n, p2))  # a zero quaternion
    assert cmd.mode == "hold" and "not finite (attitude" in cmd.rejected
    cmd = _tick(n, _odom(n, [math.nan, 0.0, 1.0]), _odom(n, p2))
    assert cmd.mode == "hold" and "not finite (position" in cmd.rejected
    ahead = n.get_clock().now().nanoseconds * 1e-9 + 5.0
    cmd = _tick(n, _odom(n, p1, stamp=ahead), _odom(n, p2))
    assert cmd.mode == "hold" and "ahead of the clock" in cmd.rejected
    assert all(np.all(np.isfinite(c.position_m)) for cmds in n.commands for c in cmds.values())
    assert len(n.rejected) == 3
    assert _tick(n, _odom(n, p1), _odom(n, p2)).mode in ("nmpc", "fallback")


def test_unstamped_odometry_is_never_fresh_and_the_node_says_so(node, caplog):
    sc, n = node
    said = []
    n.get_logger().warning = said.append  # rclpy's logger writes to stderr, not to logging
    assert _tick(n, _odom(n, sc.nodes.relay, stamp=0.0), _odom(n, sc.mission.start)) is None
    assert n.loop.waiting is not None and "old" in n.loop.waiting
    assert any("unstamped" in s and "/relay_t/odom" in s for s in said)
