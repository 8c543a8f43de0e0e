"""``aerorelay sitl`` and ``aerorelay fly`` end to end in real time: the vehicle in its own process,
the bridge arming it and flying the controller in OFFBOARD for a few seconds, its run folder written."""

from __future__ import annotations

import os
import subprocess
import sys
import time

import pandas as pd
from typer.testing import CliRunner

from aerorelay.cli import app
from aerorelay.experiments.flight import free_udp_port
from tests.sitl import sitl_vehicle


def test_fly_against_the_sitl_vehicle(tmp_path):
    port = free_udp_port()
    vehicle = sitl_vehicle(port)
    try:
        result = CliRunner().invoke(app, ["fly", "scenarios/nominal_tilted.toml", "--mavlink", f"udpout:127.0.0.1:{port}",
                                          "--arm", "--duration", "6", "--out", str(tmp_path)])
        assert result.exit_code == 0, result.output
        assert {"timeseries.parquet", "metrics.json", "run.mcap", "flight.parquet"} <= {p.name for p in tmp_path.iterdir()}
        df = pd.read_parquet(tmp_path / "flight.parquet")
        # real time on a shared 2-core machine: the count of periods flown varies, the sequence does not
        assert (df["mode"] == "stream").any() and (df["mode"] == "nmpc").sum() >= 20, df["mode"].value_counts()
        assert df["armed"].iloc[-1]
        assert "control periods flown" in result.output
    finally:
        vehicle.kill()
        vehicle.wait()


def test_sitl_names_an_unknown_airframe():
    result = CliRunner().invoke(app, ["sitl", "scenarios/nominal_tilted.toml", "--airframe", "px4"])
    assert result.exit_code != 0 and "--airframe must be pointmass, plant or rotorpy" in result.output


def test_fly_refuses_an_output_folder_it_did_not_write_before_contacting_a_vehicle(tmp_path):
    (tmp_path / "notes.txt").write_text("mine")
    result = CliRunner().invoke(app, ["fly", "scenarios/nominal_tilted.toml", "--mavlink", "udpout:127.0.0.1:9",
                                      "--out", str(tmp_path)])
    assert result.exit_code != 0 and "nothing was written" in result.output
    assert (tmp_path / "notes.txt").read_text() == "mine"


def test_fly_names_a_bad_source_origin_before_contacting_a_vehicle():
    result = CliRunner().invoke(app, ["fly", "scenarios/nominal_tilted.toml", "--mavlink", "udpout:127.0.0.1:9",
                                      "--source-mavlink", "udpout:127.0.0.1:10", "--source-origin", "1,2"])
    assert result.exit_code != 0 and "--source-origin must be three finite numbers" in result.output


def test_fly_a_chain_of_two_relays_against_two_sitl_vehicles(tmp_path):
    """A network: one ``aerorelay sitl --relay`` process per relay (each its own port and system id), one
    ``aerorelay fly --mavlink NAME=URL`` per relay; both flown in OFFBOARD by the fleet's controller, the run
    folder recording both relays."""
    ports = {"r1": free_udp_port(), "r2": free_udp_port()}
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    chain = "scenarios/chain_two_relays.toml"
    vehicles = [subprocess.Popen([sys.executable, "-m", "aerorelay.cli", "sitl", chain, "--relay", r, "--listen",
                                  f"udpin:127.0.0.1:{p}", "--duration", "40"], env=env, stdout=subprocess.PIPE,
                                 stderr=subprocess.STDOUT) for r, p in ports.items()]
    try:
        for v in vehicles:
            assert v.stdout is not None
            end = time.monotonic() + 60.0
            while b"listening" not in v.stdout.readline() and time.monotonic() < end:
                pass
        args = ["fly", chain, "--arm", "--duration", "5", "--out", str(tmp_path)]
        for r, p in ports.items():
            args += ["--mavlink", f"{r}=udpout:127.0.0.1:{p}"]
        result = CliRunner().invoke(app, args)
        assert result.exit_code == 0, result.output
        df = pd.read_parquet(tmp_path / "flight.parquet")
        for r in ports:
            mine = df[df["relay"] == r]
            assert (mine["mode"] == "stream").any() and (mine["mode"] == "nmpc").sum() >= 20, mine["mode"].value_counts()
            assert mine["armed"].iloc[-1]
        ts = pd.read_parquet(tmp_path / "timeseries.parquet")
        assert ts[["r1.p_x", "r2.p_x", "sinr.r1.r2"]].notna().all().all()
        assert "control periods flown per relay (r1:" in result.output
    finally:
        for v in vehicles:
            v.kill()
            v.wait()


def test_fly_names_a_network_without_a_vehicle_for_every_relay():
    chain = "scenarios/chain_two_relays.toml"
    result = CliRunner().invoke(app, ["fly", chain, "--mavlink", "r1=udpout:127.0.0.1:9"])
    assert result.exit_code != 0 and "no vehicle for the relays ['r2']" in result.output
    result = CliRunner().invoke(app, ["fly", chain, "--mavlink", "udpout:127.0.0.1:9"])
    assert result.exit_code != 0 and "one NAME=URL per relay" in result.output
    result = CliRunner().invoke(app, ["sitl", chain, "--relay", "r9"])
    assert result.exit_code != 0 and "the scenario's relays are r1, r2" in result.output


def test_a_flight_whose_source_never_answers_is_not_reported_flown(tmp_path):
    """Issue 61 (left from the third battery): ``fly --source-mavlink`` with no source answering exited 0."""
    port, silent = free_udp_port(), free_udp_port()
    vehicle = sitl_vehicle(port)
    try:
        result = CliRunner().invoke(app, ["fly", "scenarios/nominal_tilted.toml", "--mavlink", f"udpout:127.0.0.1:{port}",
                                          "--source-mavlink", f"udpout:127.0.0.1:{silent}", "--arm", "--duration", "3",
                                          "--out", str(tmp_path)])
        assert result.exit_code == 2, result.output
        assert "nothing was flown: the mission never started" in result.output and "source" in result.output
    finally:
        vehicle.kill()
        vehicle.wait()
