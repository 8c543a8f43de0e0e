"""A Foxglove layout for one run's ``run.mcap``, generated from the run's own columns (any network),
so every panel names a series the file has: the 3D scene, the capacity (the network's and each
route's), every hop's SINR and every relay's mutual alignment, the relays' motor speeds and solve
times. Written as ``foxglove_layout.json`` into a run folder beside ``run.mcap``."""

from __future__ import annotations

import json
from collections.abc import Iterable
from pathlib import Path

LAYOUT_FILE = "foxglove_layout.json"
MAX_PATHS = 12  # series per panel


def _plot(title: str, columns: list[str]) -> dict:
    return {"title": title, "showLegend": True,
            "paths": [{"value": f"/timeseries.{c}", "enabled": True, "timestampMethod": "receiveTime"} for c in columns[:MAX_PATHS]]}


def layout_for(columns: Iterable[str], capacity_unit: str) -> dict:
    """The layout for a run whose ``/timeseries`` has ``columns`` (see the module)."""
    cols = list(columns)
    capacity = [c for c in cols if c == "capacity" or c.startswith("capacity.")]
    alignment = [c for c in cols if c.endswith(".mutual_alignment")]
    sinr = [c for c in cols if c.startswith("sinr.")] + alignment
    motors = [c for c in cols if ".Omega_" in c] + [c for c in cols if c.endswith("solve_ms")]
    return {
        "configById": {
            "3D!relay": {"followTf": "world", "scene": {"transforms": {"showLabel": True}},
                         "topics": {"/scene": {"visible": True}, "/scene/static": {"visible": True}, "/tf": {"visible": True}},
                         "cameraState": {"distance": 40, "perspective": True, "phi": 55, "thetaOffset": 45,
                                         "targetOffset": [0, 0, 8]}},
            "Plot!capacity": _plot(f"capacity ({capacity_unit})", capacity),
            "Plot!sinr": _plot("SINR per hop" + (" and mutual alignment" if alignment else ""), sinr),
            "Plot!motors": _plot("motor speeds (Hz) and solve time (ms)", motors),
        },
        "globalVariables": {}, "userNodes": {},
        "layout": {"direction": "row", "first": "3D!relay",
                   "second": {"direction": "column", "first": "Plot!capacity",
                              "second": {"direction": "column", "first": "Plot!sinr", "second": "Plot!motors"}},
                   "splitPercentage": 55},
    }


def write_layout(columns: Iterable[str], capacity_unit: str, path: Path) -> Path:
    """``layout_for`` as JSON at ``path``."""
    Path(path).write_text(json.dumps(layout_for(columns, capacity_unit), indent=1))
    return Path(path)
