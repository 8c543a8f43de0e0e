"""The unit of every metric in ``metrics.json`` (its ``units`` table) and how values print with SI
prefixes. Capacities are in the scenario's capacity unit: bit/s/Hz (normalized, the paper's B = 1)
or bit/s (physical)."""

from __future__ import annotations

import math

DIMENSIONLESS = "1"
# metric-name endings and the unit they carry (longest ending first)
SUFFIX_UNITS = (("_m_s2", "m/s^2"), ("_m_s", "m/s"), ("_hz_s", "Hz/s"), ("_fraction", DIMENSIONLESS), ("_ms", "ms"), ("_kJ", "kJ"), ("_deg", "deg"),
                ("_hz", "Hz"), ("_m", "m"), ("_ns", "ns"), ("_s", "s"))
CAPACITY_METRICS = ("c_min", "c_mean", "outage_threshold", "c_min_before_loss", "c_mean_before_loss", "c_min_after_loss",
                    "c_mean_after_loss", "c_min_after_takeover", "c_mean_before_takeover", "c_mean_after_takeover",
                    "c_min_direct", "c_mean_direct")
SPECTRAL = "bit/s/Hz"
COUNTS = ("steps", "safety_violations", "fallback_episodes", "separation_unguarded_steps", "outage_events", "reference_clipped_steps",
          "reference_held_steps", "reference_kept_out_steps", "telemetry_rejected_periods", "handovers", "route_switches")
NOT_QUANTITIES = ("unsafe", "unsafe_reason", "controller", "units", "unit_system", "null_reasons", "optional_outputs_failed",
                  "aborted", "reference_first", "planner_name", "bound", "losses", "telemetry_rejected_reason", "metrics_failed",
                  "exit_status", "exit_sentence", "exit_statuses", "injected", "lost_in_flight", "took_over_from",
                  "standby_only", "flew", "estimation_trusted_final", "fell_back", "fell_back_reason")


def metric_unit(key: str, capacity_unit: str) -> str | None:
    """The unit of metric ``key`` (top-level name in metrics.json; None: not a quantity)."""
    if key in NOT_QUANTITIES:
        return None
    if key in CAPACITY_METRICS:
        return capacity_unit
    if key.startswith("se_"):
        return SPECTRAL
    if (key.startswith(("capacity_efficiency", "efficiency_", "estimation_within")) or key in COUNTS or key.endswith("_over_direct")
            or key.endswith("_rel_err_max") or key == "estimation_nees_final"):
        return DIMENSIONLESS
    for suffix, unit in SUFFIX_UNITS:
        if key.endswith(suffix):
            return unit
    return None


GROUPS = ("routes", "relays")  # a run's metrics per route (by source) and per relay
HOP_TABLES = {"se_mean": SPECTRAL, "delay_spread_ns": "ns", "paths_mean": DIMENSIONLESS}  # per hop, by "<tx>-><rx>"


def metric_units(metrics: dict, capacity_unit: str) -> dict[str, str]:
    """``{metric: unit}`` for every quantity in ``metrics`` (dicts of statistics such as ``solve_ms`` take
    the unit of their name): the network's at the top, each route's and each relay's as
    ``routes.<source>.<metric>`` and ``relays.<name>.<metric>``. Raises KeyError naming a metric without
    a unit, so a new metric cannot be written without one."""
    out = _units({k: v for k, v in metrics.items() if k not in GROUPS and k not in HOP_TABLES}, capacity_unit)
    out |= {k: unit for k, unit in HOP_TABLES.items() if k in metrics}
    for group in GROUPS:
        for node, node_metrics in metrics.get(group, {}).items():
            out |= {f"{group}.{node}.{k}": u for k, u in _units(node_metrics, capacity_unit).items()}
    return out


def _units(metrics: dict, capacity_unit: str) -> dict[str, str]:
    out = {}
    for key in metrics:
        unit = metric_unit(key, capacity_unit)
        if unit is None and key not in NOT_QUANTITIES:
            raise KeyError(f"metric {key!r} has no unit: add it to sim/units.py")
        if unit is not None:
            out[key] = unit
    return out


_PREFIXES = ((1e12, "T"), (1e9, "G"), (1e6, "M"), (1e3, "k"), (1.0, ""), (1e-3, "m"), (1e-6, "u"), (1e-9, "n"))
PREFIXABLE = ("bit/s", "W", "Hz", "m", "s")


def si(value: float | None, unit: str, digits: int = 4) -> str:
    """``value`` with an SI prefix on ``unit`` where that reads better (bit/s, W, Hz, m, s:
    ``3.1e5 bit/s`` -> ``310 kbit/s``); other units (bit/s/Hz, deg, dimensionless) in plain
    ``g`` format. None prints as ``-``."""
    if value is None:
        return "-"
    if not math.isfinite(value):
        return f"{value} {unit}".strip()
    if unit not in PREFIXABLE or value == 0.0:
        return f"{value:.{digits}g}" + ("" if unit in ("", DIMENSIONLESS) else f" {unit}")
    for scale, prefix in _PREFIXES:
        if abs(value) >= scale:
            return f"{value / scale:.{digits}g} {prefix}{unit}"
    scale, prefix = _PREFIXES[-1]
    return f"{value / scale:.{digits}g} {prefix}{unit}"


def _number_like(v) -> bool:
    """A metric's value as written: a number, null, a flag, or a table / list of them (text allowed inside)."""
    if v is None or isinstance(v, bool | int | float):
        return True
    if isinstance(v, dict):
        return all(_number_like(x) or isinstance(x, str) for x in v.values())
    if isinstance(v, list):
        return all(_number_like(x) or isinstance(x, str | list | dict) for x in v)
    return False


def metric_value_problem(metrics: dict) -> str | None:
    """The first metric in ``metrics`` whose value is not a number (a hand-edited or damaged
    metrics.json), as ``"key = value"``; None when every quantity is one."""
    for key, v in metrics.items():
        if key in NOT_QUANTITIES or key.endswith("_reason") or key.endswith("_first"):
            continue
        if not _number_like(v):
            return f"{key} = {v!r}"
    return None
