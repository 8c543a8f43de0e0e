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


def test_fly_against_the_sitl_vehicle(tmp_path):
    port = free_udp_port()
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    vehicle = subprocess.Popen([sys.executable, "-m", "aerorelay.cli", "sitl", "scenarios/nominal_tilted.toml",
                                "--listen", f"udpin:127.0.0.1:{port}", "--duration", "30"], env=env,
                               stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    try:
        assert vehicle.stdout is not None
        end = time.monotonic() + 60.0  # the vehicle's process starts (imports; slow on a loaded machine)
        while b"listening" not in vehicle.stdout.readline() and time.monotonic() < end:
            pass
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
