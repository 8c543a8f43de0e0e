"""The ROS 2 fleet node (``aerorelay ros`` on a network) against a second process over localhost, in its own
ROS domain: this test publishes both relays' and the inspector's odometry, receives each relay's setpoints
and the network's link state, checks the link against the chain's rate written out here from the paper's
channel in physical units (Friis, dipoles, the jammer), then silences one relay: it holds, lands and leaves
the network, the other re-plans alone, and the run folder names the relay and when. Needs the optional ros
extra (CI requires it: ``AERORELAY_REQUIRE_ROS=1``)."""

from __future__ import annotations

import json
import math
import os
import random
import signal
import subprocess
import sys
import time

import numpy as np
import pandas as pd
import pytest

if os.environ.get("AERORELAY_REQUIRE_ROS") != "1":
    pytest.importorskip("rclpy", reason="the optional ros extra (pip install 'aerorelay[ros]') is not installed")

import aerorelay as ar  # noqa: E402
from aerorelay.assembly.parts import build_scene  # noqa: E402
from tests.flight.ros_messages import odometry  # noqa: E402
from tests.reference_channel import jammer_gain_sq, legitimate_gain_sq  # noqa: E402

SCENARIO = "scenarios/chain_two_relays.toml"


def chain_rate(sc, positions):
    """The chain inspector -> r1 -> r2 -> bs at ``positions`` (level attitudes): each hop's SINR with Friis'
    ``(lambda / 4 pi)^2``, vertical dipoles, the isotropic jammer, ``kTB`` noise and 7 dB noise figure; the route's
    rate ``B / sum_hops 1 / log2(1 + SINR)`` (eq. 9 over three hops)."""
    lam = 299_792_458.0 / 2.4e9
    k = (lam / (4 * math.pi)) ** 2
    P_U, P_J = 0.1, build_scene(sc).jammers[0].power
    N = 1.380649e-23 * 290 * 20e6 * 10 ** 0.7
    pj, eye = np.array(sc.jammer_configs[0].position), np.eye(3)
    sinrs = []
    for tx, rx in (("inspector", "r1"), ("r1", "r2"), ("r2", "bs")):
        h = k * legitimate_gain_sq(positions[tx], eye, positions[rx], eye)
        f = k * jammer_gain_sq(pj, positions[rx], eye)
        sinrs.append(float(h * P_U / (f * P_J + N)))
    return 20e6 / sum(1.0 / math.log2(1.0 + g) for g in sinrs), sinrs


def test_the_fleet_node_flies_both_relays_and_one_that_goes_silent_leaves_the_network(tmp_path):
    import rclpy
    from nav_msgs.msg import Odometry
    from rclpy.node import Node
    from std_msgs.msg import Float64MultiArray
    from trajectory_msgs.msg import MultiDOFJointTrajectory

    sc = ar.load_scenario(SCENARIO)
    held = {"r1": np.array(sc.relay_list[0].start), "r2": np.array(sc.relay_list[1].start),
            "inspector": np.array(sc.source_list[0].mission.start), "bs": np.array(sc.nodes.bs)}
    domain = str(random.randint(1, 200))
    env = {**os.environ, "ROS_DOMAIN_ID": domain, "PYTHONUNBUFFERED": "1"}
    out = tmp_path / "fleet_run"
    node_proc = subprocess.Popen([sys.executable, "-m", "aerorelay.cli", "ros", SCENARIO, "--duration", "300", "--out", str(out)],
                                 env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    os.environ["ROS_DOMAIN_ID"] = domain
    rclpy.init()
    probe = Node("aerorelay_test_fleet_probe")
    setpoints = {"r1": [], "r2": []}
    links = []
    for r in setpoints:
        probe.create_subscription(MultiDOFJointTrajectory, f"/{r}/setpoint", setpoints[r].append, 10)
    probe.create_subscription(Float64MultiArray, "/network/link", links.append, 10)
    pubs = {n: probe.create_publisher(Odometry, f"/{n}/odom", 10) for n in ("r1", "r2", "inspector")}

    def publish_until(done, silent=(), within=240.0):
        end = time.monotonic() + within
        while time.monotonic() < end and not done():
            for n, pub in pubs.items():
                if n not in silent:
                    pub.publish(odometry(probe, held[n]))
            rclpy.spin_once(probe, timeout_sec=0.01)
        return done()

    try:
        flying = publish_until(lambda: min(len(v) for v in setpoints.values()) >= 30 and len(links) >= 30)
        assert flying, node_proc.stdout.read1().decode() if node_proc.poll() is not None else "no setpoints"
        for r, msgs in setpoints.items():  # one period ahead of a relay held at its start, under its own name
            pt = msgs[-1].points[0].transforms[0].translation
            assert np.linalg.norm(np.array([pt.x, pt.y, pt.z]) - held[r]) < 0.5 and msgs[-1].joint_names == [r]
        rate, sinrs = chain_rate(sc, held)
        labels = links[-1].layout.dim[0].label.split(",")
        assert labels == ["capacity", "capacity.inspector", "sinr.inspector.r1", "sinr.r1.r2", "sinr.r2.bs"]
        np.testing.assert_allclose(links[-1].data, [rate, rate, *sinrs], rtol=1e-9)
        # r2 goes silent: it holds, then (after land_after_s = 3 s) lands and leaves the network; r1 re-plans alone
        silent_from = len(setpoints["r2"])
        assert publish_until(lambda: "sinr.r1.bs" in links[-1].layout.dim[0].label.split(","), silent=("r2",), within=30.0)
        n_links = len(links)
        publish_until(lambda: len(links) >= n_links + 40, silent=("r2",), within=30.0)
        landing = [m.points[0].transforms[0].translation.z for m in setpoints["r2"][silent_from:]]
        assert landing[-1] < held["r2"][2] - 0.1  # r2's setpoints descend (0.5 m/s)
        rate_r1 = links[-1].data[0]
        assert rate_r1 > 0 and links[-1].layout.dim[0].label.split(",") == ["capacity", "capacity.inspector",
                                                                            "sinr.inspector.r1", "sinr.r1.bs"]
    finally:
        probe.destroy_node()
        rclpy.shutdown()
        node_proc.send_signal(signal.SIGINT)
        try:
            node_proc.wait(timeout=120)
        except subprocess.TimeoutExpired:
            node_proc.kill()
            node_proc.wait()
    metrics = json.loads((out / "metrics.json").read_text())
    assert [e["relay"] for e in metrics["lost_in_flight"]] == ["r2"] and metrics["relays"]["r2"]["lost_at_s"] > 3.0
    df = pd.read_parquet(out / "timeseries.parquet")
    assert np.allclose(df[["r1.p_x", "r1.p_y", "r1.p_z"]].to_numpy(), held["r1"], atol=1e-6)
    assert df["r2.p_x"].isna().any() and df["sinr.r1.bs"].notna().any()  # rows after r2 left: gone, and the new hop
