"""Long relay chains generated from their geometry, for measuring how a network holds as it grows (``aerorelay bench
--chain``, the networks-at-scale tests): ``K`` relays evenly spaced on the line from the base station to an
inspection drone ``length_m`` out along ``heading_deg``, the drone flying the last ``approach_m`` of the line out at
its end (3 m to the line's side), two jammers beside the way at a third and two thirds of it, physical units.

Only the geometry is generated: every other setting (platform, controller, channel, verdict...) comes from the base
scenario file, so a chain flies what the file says of a relay (``long_chain``)."""

from __future__ import annotations

import math
import tomllib
from pathlib import Path
from typing import Any

from ..assembly.load import apply_updates, parse_scenario
from ..config import Scenario, ScenarioError

CHAIN_REPLACES = ("nodes", "mission", "jammer", "jammers", "relays", "sources", "base_stations", "network", "obstacles",
                  "buildings")  # the base file's tables a generated chain writes anew


def long_chain_data(relays: int, length_m: float = 250.0, *, heading_deg: float = 45.0, duration_s: float = 15.0,
                    approach_m: float = 30.0, jammer_power_w: float = 0.08, jammer_side_m: float = 20.0,
                    relay_z_m: float = 8.0, separation_m: float = 2.0) -> dict[str, Any]:
    """The generated tables of a chain of ``relays`` relays (see the module): ``relays`` ``r1`` (farthest out) to
    ``rK`` on ``[[relays]]``, the drone ``inspector`` on ``[[sources]]``, ``[[jammers]]``, the workspace and
    ``[network]``. Distances in m, the heading in degrees from x toward y, times in s."""
    if not 1 <= relays <= 16:
        raise ScenarioError(f"chain: relays must be 1..16 (the scenario's limit), got {relays}")
    if not (length_m > approach_m + 5.0 and length_m <= 5000.0):
        raise ScenarioError(f"chain: length_m must be in ({approach_m + 5.0:g}, 5000] m (beyond the approach), got {length_m:g}")
    if length_m / (relays + 1) < 2.0 * separation_m:
        raise ScenarioError(f"chain: {relays} relays over {length_m:g} m are closer than twice the separation "
                            f"({separation_m:g} m)")
    h = math.radians(heading_deg)
    u, n = (math.cos(h), math.sin(h)), (-math.sin(h), math.cos(h))

    def at(s: float, side: float, z: float) -> list[float]:
        return [round(s * u[0] + side * n[0], 3), round(s * u[1] + side * n[1], 3), z]

    start = at(length_m - approach_m, 3.0, 10.0)
    out: dict[str, Any] = {
        "sources": [{"name": "inspector", "mission": {"waypoints": [[0.0, *start], [duration_s, *at(length_m, 3.0, 12.0)]]}}],
        "jammers": [{"name": f"j{i}", "position": at(f * length_m, -jammer_side_m, 2.0), "power_w": jammer_power_w}
                    for i, f in ((1, 1 / 3), (2, 2 / 3))],
        "network": {"min_separation_m": separation_m},
    }
    # r1 farthest out (every route runs source -> r1 -> ... -> bs), evenly spaced toward the drone's start, alternately
    # a metre to either side of the line
    def on_line(f: float, side: float) -> list[float]:  # a fraction f of the way to the drone's start, a side offset
        return [round(f * start[0] + side * n[0], 3), round(f * start[1] + side * n[1], 3), relay_z_m]

    out["relays"] = [{"name": f"r{i}", "start": on_line((relays + 1 - i) / (relays + 1), (-1.0) ** i)}
                     for i in range(1, relays + 1)]
    corners = [[0.0, 0.0], at(length_m, 0.0, 0.0)[:2]] + [j["position"][:2] for j in out["jammers"]]
    lo = [min(c[i] for c in corners) - 10.0 for i in range(2)]
    hi = [max(c[i] for c in corners) + 10.0 for i in range(2)]
    out["controller"] = {"workspace": {"min": [round(lo[0], 3), round(lo[1], 3), 0.5], "max": [round(hi[0], 3), round(hi[1], 3), 25.0]}}
    out["sim"] = {"duration_s": duration_s}
    return out


def long_chain(base: str | Path, relays: int, length_m: float = 250.0, *, updates: dict | None = None,
               **geometry) -> Scenario:
    """The base scenario file with its network replaced by a generated chain (``long_chain_data``; ``geometry``
    its keywords), then ``updates`` (dotted keys, as ``--set``), validated as any scenario. Its name says the chain."""
    path = Path(base)
    try:
        data = tomllib.loads(path.read_text())
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise ScenarioError(f"{path}: cannot read the chain's base scenario ({exc})") from None
    for key in CHAIN_REPLACES:
        data.pop(key, None)
    gen = long_chain_data(relays, length_m, **geometry)
    controller = data.setdefault("controller", {})
    controller["workspace"] = gen.pop("controller")["workspace"]
    data.setdefault("channel", {})["units"] = "physical"
    data.setdefault("sim", {}).update(gen.pop("sim"))
    data |= gen
    data["name"] = f"chain_K{relays}_{length_m:g}m"
    data["description"] = f"{relays} relays over {length_m:g} m (generated from {path.name}: experiments.chains)"
    apply_updates(data, updates or {})  # as --set: before validation, refused where it changes nothing
    return parse_scenario(data)
