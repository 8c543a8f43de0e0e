"""The in-repo MAVLink vehicle (``aerorelay sitl``) in its own process, for tests that fly it in real time."""

from __future__ import annotations

import os
import subprocess
import sys
import time


def sitl_vehicle(port: int, scenario: str = "scenarios/nominal_tilted.toml", *args: str) -> subprocess.Popen:
    """``aerorelay sitl SCENARIO`` listening on ``port`` (localhost), once it says so."""
    vehicle = subprocess.Popen([sys.executable, "-m", "aerorelay.cli", "sitl", scenario,
                                "--listen", f"udpin:127.0.0.1:{port}", "--duration", "30", *args],
                               env={**os.environ, "PYTHONUNBUFFERED": "1"}, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    assert vehicle.stdout is not None
    end = time.monotonic() + 60.0  # the vehicle's process starts (imports; slow on a loaded machine)
    while b"listening" not in vehicle.stdout.readline() and time.monotonic() < end:
        pass
    return vehicle
