"""One run's report, for any network: ``aerorelay report RUN_DIR`` writes ``RUN_DIR/report.html``, one self-contained
file (figures embedded) with the run's scenario, its key metrics with their units, its safety
verdict, what is null and why, and its figures (capacity over the bound, alignment and slack,
tracking, the 3D path), drawn from the run folder's own files."""

from __future__ import annotations

import html
from pathlib import Path

import pandas as pd

from ..sim.log_schema import relays_in
from ..sim.units import DIMENSIONLESS, metric_units, si
from ..store.run_folder import BOUND_PARQUET
from .figures import fig_capacity, fig_constraints, fig_paths, fig_tracking, fig_trajectory_3d, run_title
from .folders import read_metrics, read_scenario, read_timeseries
from .html import CSS, _png

RUN_REPORT = "report.html"
RUN_METRICS = ("c_min", "c_mean", "outage_fraction", "outage_duration_max_s", "capacity_efficiency_min",
               "capacity_efficiency_mean", "alignment_ok_fraction", "slack_active_fraction", "position_error_mean_m",
               "distance_m", "energy_kJ", "final_z_m", "max_tilt_deg", "min_altitude_m", "infeasible_fraction",
               "fallback_fraction", "motor_saturation_fraction", "solve_ms", "feedback_ms", "steps", "sim_s", "wall_s")


def _value(m: dict, key: str, units: dict) -> str:
    v = m.get(key)
    unit = units.get(key, "")
    if isinstance(v, dict):  # statistics of a timing: mean / p99 / max
        return " / ".join(si(v.get(s), unit) for s in ("mean", "p99", "max") if s in v) + " (mean / p99 / max)"
    if v is None:
        why = (m.get("null_reasons") or {}).get(key)
        return f"- ({html.escape(why)})" if why else "-"
    if isinstance(v, bool | str):
        return html.escape(str(v))
    if isinstance(v, list):  # a range or a list of names
        return ", ".join(_value({"v": x}, "v", {"v": unit}) for x in v)
    return si(float(v), unit) if unit != DIMENSIONLESS else f"{float(v):.4g}"


def render_run_report(run: Path) -> str:
    """The HTML of one run folder's report, for any network (read from its scenario.toml, metrics.json,
    timeseries.parquet and bound.parquet when there): the key metrics with their units, a network's
    routes' and relays' metrics, the safety verdict, what is null and why, the figures."""
    run = Path(run)
    sc, m, df = read_scenario(run), read_metrics(run), read_timeseries(run)
    bound = pd.read_parquet(run / BOUND_PARQUET) if (run / BOUND_PARQUET).is_file() else None
    units = m.get("units") or metric_units(m, sc.channel.capacity_unit)  # a folder written before units
    relays = relays_in(df.columns)

    def value(key: str) -> str:
        node: object = m
        for part in key.split("."):
            node = node.get(part) if isinstance(node, dict) else None
        return _value({"v": node, "null_reasons": m.get("null_reasons")}, "v", {"v": units.get(key, "")})

    keys = [k for k in (*RUN_METRICS, "separation_min_m", "fleet_solve_ms") if k in m]
    keys += [k for k in units if k.startswith(("routes.", "relays."))]  # every route's and relay's rows, one relay's too
    rows = "".join(f"<tr><td>{html.escape(k)}</td><td>{value(k)}</td></tr>" for k in keys)
    verdict = (f'<p class="no">unsafe: {html.escape(str(m.get("unsafe_reason", "")))}</p>' if m.get("unsafe")
               else '<p class="yes">safe: every relay stayed in its workspace, above the ground, upright, and no two '
                    'vehicles came closer than network.min_separation_m</p>')
    if m.get("fell_back"):  # safe, but not what its controller flew
        verdict += f'<p class="no">fell back: {html.escape(str(m.get("fell_back_reason", "")))}</p>'
    keys += [k for k in ("worst_relay_fallback_fraction", "worst_relay_infeasible_fraction") if k in m]
    missing = m.get("optional_outputs_failed") or {}
    warn = "".join(f'<p class="warn">{html.escape(k)} not written: {html.escape(v)}</p>' for k, v in missing.items())
    figs = [_png(fig_capacity(df, sc, bound), "capacity"), _png(fig_paths(df, sc), "paths")]
    for r in relays:
        figs += [_png(fig_constraints(df, sc, r), f"{r}: alignment and slack"), _png(fig_tracking(df, sc, r), f"{r}: tracking")]
    figs.append(_png(fig_trajectory_3d(df, sc), "3D path"))
    routes = "; ".join(" -> ".join(r) for r in sc.route_list)
    title = html.escape(run_title(sc))
    return (f"<!doctype html><html><head><meta charset='utf-8'><title>{title}</title><style>{CSS}</style></head><body>"
            f"<h1>{title}</h1><p>{html.escape(sc.description)}</p><p>routes: {html.escape(routes)}</p>{verdict}{warn}"
            f"<p>capacities in {html.escape(sc.channel.capacity_unit)} ({html.escape(sc.channel.units)} units); a network's "
            f"rate is every source's (each hop its own slot); outage below {si(sc.channel.outage, sc.channel.capacity_unit)}</p>"
            f"<table><tr><th>metric</th><th>value</th></tr>{rows}</table>"
            + "".join(figs) + f"<details><summary>scenario.toml</summary><pre>{html.escape(sc.to_toml())}</pre></details>"
            "</body></html>")
