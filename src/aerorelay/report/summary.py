"""Campaign summary: per-group metrics (Monte Carlo means), paper comparisons, qualitative claims.

Every number of the report comes from here and is written to ``summary.json``.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from ..experiments.campaign import is_finished, run_dir
from ..experiments.study import Claim, RunSpec, Study, combinations, parse_term
from ..store.run_folder import METRICS_FILE
from .explain import explain
from .folders import read_timeseries, vehicle_paths

SCALAR_METRICS = (
    "c_min", "c_mean",
    # the direct link (sim.baseline = "direct": no relay) and the run over it
    "c_min_direct", "c_mean_direct", "c_min_over_direct", "c_mean_over_direct",
    "se_21_mean", "se_10_mean", "outage_fraction", "outage_events", "outage_duration_mean_s",
    "outage_duration_max_s", "alignment_ok_fraction",
    "alignment_within_slack_fraction", "slack_active_fraction",
    "infeasible_fraction", "solve_ms.mean", "solve_ms.p99", "position_error_mean_m", "distance_m", "energy_kJ",
    "final_z_m", "max_tilt_deg", "taylor_rel_err_max", "fallback_fraction", "worst_relay_fallback_fraction",
    "worst_relay_infeasible_fraction", "motor_saturation_fraction",
    "rate_saturation_fraction", "min_altitude_m", "box_violation_max_m", "capacity_efficiency_mean",
    "capacity_efficiency_min", "bound.path_mean.mean", "bound.path_maxmin.min", "bound.path_mean.outage_fraction",
    "bound.path_maxmin.outage_fraction", "capacity_efficiency_mean_flyable", "capacity_efficiency_min_flyable",
    "bound.flyable_mean.mean", "bound.flyable_maxmin.min", "bound.flyable_mean.outage_fraction",
    "estimation_first_within_1m_s", "estimation_within_1m_after_10s", "estimation_err_mean_m", "estimation_err_final_m",
    "estimation_std_final_m", "estimator_ms.mean", "estimator_ms.p99", "estimation_crlb_first_1m_s", "estimation_crlb_10s_m",
    "estimation_within_1m_after_bound", "estimation_nees_final", "estimation_trusted_final",
    # networks (sim.metrics.compute_metrics): the network bound, the closest two vehicles, a relay lost in flight
    "capacity_efficiency_mean_achieved", "capacity_efficiency_min_achieved", "bound.static.mean", "bound.static.min",
    "bound.achieved.mean", "bound.flyable.mean", "bound.flyable.min", "bound.path_mean.min", "capacity_efficiency_mean_path",
    "separation_min_m", "fleet_solve_ms.mean",
    "fleet_solve_ms.p99", "c_mean_before_loss", "c_min_before_loss", "c_mean_after_loss", "c_min_after_loss", "capacity_efficiency_mean_before_loss",
    "capacity_efficiency_mean_after_loss", "capacity_efficiency_min_after_loss",
    # wind and obstacles (sim.metrics.air_metrics, safety_metrics)
    "wind_speed_mean_m_s", "drag_accel_mean_m_s2", "drag_accel_max_m_s2", "observer_error_mean_m_s2",
    "obstacle_clearance_min_m", "reference_kept_out_steps",
    # a ray-traced channel (sim.metrics.traced_metrics) and what a run took
    "delay_spread_mean_ns", "delay_spread_max_ns", "wall_s",
    # operations (sim.metrics.handover_metrics, spare_metrics)
    "handovers",
    "route_switches",
)


def metric(m: dict, dotted: str):
    v = m
    for part in dotted.split("."):
        v = v[part]
    return v


def has_metric(m: dict, dotted: str) -> bool:
    """Whether ``m`` holds the (dotted) metric as a number (a one-relay bound has no ``bound.static``)."""
    try:
        v = metric(m, dotted)
    except (KeyError, TypeError):
        return False
    return v is None or isinstance(v, int | float)


def _load_metrics(out: Path, spec: RunSpec) -> dict | None:
    """A run's metrics, or None unless the run is verified finished (``campaign.is_finished``):
    the report never reads a truncated, foreign or unsafe run."""
    if not is_finished(out, spec):
        return None
    return json.loads((run_dir(out, spec) / METRICS_FILE).read_text())


def _trajectory(out: Path, spec: RunSpec) -> np.ndarray:
    relays, _ = vehicle_paths(read_timeseries(run_dir(out, spec)))
    return next(iter(relays.values())).to_numpy()  # the (first) relay's path


QUANTILES = {"p05": 5, "p25": 25, "median": 50, "p75": 75, "p95": 95}  # the spread over seeds (summary.json)
KEPT_VALUES = ("c_min", "c_mean")  # whose per-seed values summary.json keeps (box plots)


def distribution(key: str, vals: np.ndarray) -> dict:
    """The spread of one metric over a group's seeds: ``<key>.p05`` ... ``<key>.p95`` (numpy's linear
    percentiles) and, for ``KEPT_VALUES``, every seed's value (``<key>.values``)."""
    finite = vals[np.isfinite(vals)]
    if not finite.size:
        return {}
    out: dict[str, float | list[float]] = {f"{key}.{name}": float(np.percentile(finite, q)) for name, q in QUANTILES.items()}
    if key in KEPT_VALUES:
        out[f"{key}.values"] = [float(v) for v in vals]
    return out


def summarize_study(study: Study, specs: list[RunSpec], out: Path) -> dict:
    """Group metrics (mean, std, n over seeds), paper comparisons and derived quantities of one study."""
    groups: dict[str, list[RunSpec]] = {}
    for s in specs:
        groups.setdefault(s.group, []).append(s)
    gsum: dict[str, dict] = {}
    missing: list[str] = []
    for g, runs in groups.items():
        ms: list[dict] = []
        fell_back: list[str] = []
        for r in runs:
            m = _load_metrics(out, r)
            if m is not None:
                ms.append(m)
                if m.get("fell_back"):  # flown safely, but a relay's controller did not fly it: the table marks it
                    fell_back.append(r.key)
            else:
                missing.append(r.key)
        if not ms:
            continue
        entry: dict = {"n": len(ms), "runs": [r.key for r in runs]}
        if fell_back:
            entry["fell_back_runs"] = fell_back
        for key in SCALAR_METRICS:
            if not all(has_metric(m, key) for m in ms):  # e.g. efficiency only where a bound was computed
                continue
            vals = np.asarray([metric(m, key) for m in ms], dtype=float)
            entry[key] = float(vals.mean())
            if len(vals) > 1:
                entry[key + ".std"] = float(vals.std(ddof=1))
                entry |= distribution(key, vals)
        gsum[g] = entry
    for a, b in study.compare_trajectories:
        if a in groups and b in groups and a in gsum and b in gsum:
            ta, tb = _trajectory(out, groups[a][0]), _trajectory(out, groups[b][0])
            n = min(len(ta), len(tb))
            gsum[a]["max_deviation_m"] = float(np.max(np.linalg.norm(ta[:n] - tb[:n], axis=1)))
    paper = []
    for p in study.paper:
        ours: float | None = gsum.get(p.run, {}).get(p.metric)
        ratio = (ours / p.value) if (ours is not None and p.value not in (0, 0.0)) else None
        paper.append({"run": p.run, "metric": p.metric, "paper": p.value, "ours": ours, "ratio": ratio, "note": p.note})
    return {"name": study.name, "title": study.title, "description": study.description, "groups": gsum,
            "paper": paper, "missing_runs": missing}


def _term_value(groups: dict, text: str) -> tuple[float | None, str]:
    """Value of ``metric@run`` or ``metric@run / metric@run`` from a study's group metrics."""
    vals = []
    for group, metric_name in parse_term(text):
        v = groups.get(group, {}).get(metric_name)
        if v is None:
            return None, f"{metric_name}@{group} not run"
        vals.append(float(v))
    if len(vals) == 2:
        return (vals[0] / vals[1] if vals[1] != 0 else math.inf), text
    return vals[0], text


_OPS = {"<": lambda a, b: a < b, "<=": lambda a, b: a <= b, ">": lambda a, b: a > b, ">=": lambda a, b: a >= b}


def evaluate_claim(claim: Claim, groups: dict) -> tuple[bool | None, str]:
    """``(holds, evidence)``: every condition with the numbers it compared; None if a run is missing."""
    verdicts, parts = [], []
    for c in claim.all:
        left, ltxt = _term_value(groups, c.left)
        right, rtxt = (c.value, f"{c.value:g}") if c.right is None else _term_value(groups, c.right)
        if left is None or right is None:
            return None, "not run: " + (ltxt if left is None else rtxt)
        bound = right * c.factor + c.tol
        ok = _OPS[c.op](left, bound)
        verdicts.append(ok)
        scale = f"{c.factor:g} x " if c.factor != 1.0 else ""
        plus = f" + {c.tol:g}" if c.tol else ""
        parts.append(f"{ltxt} = {left:.3g} {c.op} {scale}{rtxt}{'' if c.right is None else f' = {right:.3g}'}{plus}: "
                     f"{'yes' if ok else 'no'}")
    return all(verdicts), "; ".join(parts)


def evaluate_claims(studies: list[Study], per: dict, specs: list[RunSpec], out: Path) -> list[dict]:
    """The claims declared in the studies' ``[[claims]]``, each judged on our numbers; a claim that
    does not hold gets its measured causes (``why``), computed from the campaign's runs."""

    rows = []
    for st in studies:
        for claim in st.claims:
            holds, evidence = evaluate_claim(claim, per.get(st.name, {}).get("groups", {}))
            why = [explain(e, [s for s in specs if s.study == st.name], out) for e in claim.why] if holds is False else []
            rows.append({"study": st.name, "claim": claim.text, "holds": holds, "evidence": evidence, "why": why,
                         "contradiction": claim.contradiction})
    return rows


def rank_against_paper(study: Study, groups: dict) -> list[dict]:
    """The study's grid combinations sorted by RMS distance to the paper's numbers (``[ranking]``)."""
    if study.ranking is None:
        return []
    rows = []
    for label, pairs in combinations(study, study.ranking.pair_key).items():
        terms, errors = {}, []
        for t in study.ranking.terms:
            ours = groups.get(pairs.get(t.at, ""), {}).get(t.metric)
            if t.over is not None and ours is not None:
                den = groups.get(pairs.get(t.over, ""), {}).get(t.metric)
                ours = None if not den else ours / den
            name = f"{t.metric}@{t.at}" + (f"/{t.over}" if t.over else "")
            terms[name] = {"ours": ours, "paper": t.paper}
            if ours is None or (t.scale == "log" and ours <= 0):
                errors.append(math.inf if ours is not None else math.nan)
                continue
            errors.append(math.log10(ours / t.paper) if t.scale == "log" else
                          (ours - t.paper) / t.paper if t.scale == "rel" else ours - t.paper)
        finite = [e for e in errors if not math.isnan(e)]
        distance = math.sqrt(sum(e * e for e in finite) / len(finite)) if finite and len(finite) == len(errors) else None
        rows.append({"combination": label, "distance": distance, "terms": terms})
    return sorted(rows, key=lambda r: (r["distance"] is None, r["distance"] if r["distance"] is not None else 0.0))


def summarize(studies: list[Study], specs: list[RunSpec], out: Path, extra: dict | None = None) -> dict:
    """Summary of a campaign: every study's numbers plus the claims table."""

    per = {s.name: summarize_study(s, [r for r in specs if r.study == s.name], out) for s in studies}
    for s in studies:
        per[s.name]["ranking"] = rank_against_paper(s, per[s.name]["groups"])
        per[s.name]["why"] = [explain(e, [r for r in specs if r.study == s.name], out) for e in s.why]
    summary = {"studies": per, "claims": evaluate_claims(studies, per, specs, out)}
    summary.update(extra or {})
    return summary
