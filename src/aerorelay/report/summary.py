"""Campaign summary: per-group metrics (Monte Carlo means), paper comparisons, qualitative claims.

Every number of the report comes from here and is written to ``summary.json``.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd

from ..experiments.campaign import run_dir
from ..experiments.study import RunSpec, Study

SCALAR_METRICS = (
    "c_min", "c_mean", "se_21_mean", "se_10_mean", "outage_fraction", "alignment_ok_fraction", "slack_active_fraction",
    "infeasible_fraction", "solve_ms.mean", "solve_ms.p99", "position_error_mean_m", "distance_m", "energy_kJ",
    "final_z_m", "max_tilt_deg", "taylor_rel_err_max",
)


def metric(m: dict, dotted: str):
    v = m
    for part in dotted.split("."):
        v = v[part]
    return v


def _load_metrics(out: Path, spec: RunSpec) -> dict | None:
    f = run_dir(out, spec) / "metrics.json"
    return json.loads(f.read_text()) if f.exists() else None


def _trajectory(out: Path, spec: RunSpec) -> np.ndarray:
    df = pd.read_parquet(run_dir(out, spec) / "timeseries.parquet", columns=["p1_x", "p1_y", "p1_z"])
    return df.to_numpy()


def summarize_study(study: Study, specs: list[RunSpec], out: Path) -> dict:
    """Group metrics (mean, std, n over seeds), paper comparisons and derived quantities of one study."""
    groups: dict[str, list[RunSpec]] = {}
    for s in specs:
        groups.setdefault(s.group, []).append(s)
    gsum: dict[str, dict] = {}
    missing: list[str] = []
    for g, runs in groups.items():
        ms: list[dict] = []
        for r in runs:
            m = _load_metrics(out, r)
            if m is not None:
                ms.append(m)
            else:
                missing.append(r.key)
        if not ms:
            continue
        entry: dict = {"n": len(ms), "runs": [r.key for r in runs]}
        for key in SCALAR_METRICS:
            vals = np.asarray([metric(m, key) for m in ms], dtype=float)
            entry[key] = float(vals.mean())
            if len(vals) > 1:
                entry[key + ".std"] = float(vals.std(ddof=1))
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


def _get(summary: dict, study: str, group: str, key: str):
    return summary.get(study, {}).get("groups", {}).get(group, {}).get(key)


def _claim(text: str, holds, evidence: str) -> dict:
    return {"claim": text, "holds": holds, "evidence": evidence}


def evaluate_claims(summary: dict) -> list[dict]:
    """The paper's qualitative claims, each judged on our numbers (None = not evaluated in this campaign)."""
    claims = []
    g = lambda *a: _get(summary, *a)

    c, u = g("nominal", "constrained", "c_min"), g("nominal", "unconstrained", "c_min")
    claims.append(_claim("constrained C_min >> unconstrained C_min (paper: ~94x)",
                         None if None in (c, u) else bool(c >= 10 * u),
                         "not run" if None in (c, u) else f"{c:.3g} vs {u:.3g} ({c / u:.3g}x)"))

    t, cp = g("platforms", "tilted_constrained", "c_min"), g("platforms", "coplanar_constrained", "c_min")
    claims.append(_claim("tilted beats coplanar (constrained C_min)", None if None in (t, cp) else bool(t > cp),
                         "not run" if None in (t, cp) else f"tilted {t:.3g} vs coplanar {cp:.3g}"))

    parts: list[str] = []
    ok: bool | None = True
    for plat, tol in (("tilted", 0.05), ("coplanar", 0.2)):
        # judged on the run whose controller senses the schedule when the study has it: without
        # sensing the trajectory equals the always-on one by construction
        run = f"{plat}_on_off_sensed" if g("on_off", f"{plat}_on_off_sensed", "c_min") is not None else f"{plat}_on_off"
        dev = g("on_off", run, "max_deviation_m")
        o_on, o_al = g("on_off", run, "outage_fraction"), g("on_off", f"{plat}_always_on", "outage_fraction")
        if None in (dev, o_on, o_al):
            ok = None
            break
        ok = ok and o_on <= o_al + 1e-12 and dev <= tol
        sensed = "schedule sensed" if run.endswith("_sensed") else "schedule not sensed"
        blind = g("on_off", f"{plat}_on_off", "max_deviation_m") if run.endswith("_sensed") else None
        also = "" if blind is None else f" (not sensed: {blind:.3g} m)"
        parts.append(f"{plat} ({sensed}): deviation {dev:.3g} m{also} (paper <= {tol} m), "
                     f"outage {o_on:.3g} vs always-on {o_al:.3g}")
    claims.append(_claim("ON-OFF jamming adds no outages and the trajectory stays close to always-on", ok,
                         "; ".join(parts) or "not run"))

    ks = ["6.0", "12.0", "18.0", "inf"]
    cons = [g("fading", f"fading_k_db={k},variant=constrained", "c_mean") for k in ks]
    unc = [g("fading", f"fading_k_db={k},variant=unconstrained", "c_mean") for k in ks]
    if None in cons + unc:
        claims.append(_claim("fading: constrained above unconstrained at every K, gap widening as K falls", None, "not run"))
    else:
        above = all(a > b for a, b in zip(cons, unc, strict=False))
        ratios = [a / b if b > 0 else math.inf for a, b in zip(cons, unc, strict=False)]
        widening = all(ratios[i] >= ratios[i + 1] for i in range(len(ratios) - 1))
        claims.append(_claim("fading: constrained above unconstrained at every K, gap widening as K falls",
                             bool(above and widening),
                             "mean C ratio constrained/unconstrained at K = 6, 12, 18, inf dB: " + ", ".join(f"{r:.3g}" for r in ratios)))

    a, b, o = (g("baselines", r, "c_min") for r in ("baseline_A", "baseline_B", "proposed"))
    claims.append(_claim("baselines A < B < ours in C_min", None if None in (a, b, o) else bool(a < b < o),
                         "not run" if None in (a, b, o) else f"A {a:.3g}, B {b:.3g}, ours {o:.3g}"))

    n0, t5 = g("robustness", "nominal", "c_min"), g("robustness", "tau_E_5s", "c_min")
    claims.append(_claim("tau_E up to 5 s costs <= ~15% of C_min", None if None in (n0, t5) else bool(t5 >= 0.85 * n0),
                         "not run" if None in (n0, t5) else f"C_min {t5:.3g} at 5 s vs {n0:.3g} nominal ({t5 / n0 - 1:+.1%})"))
    c10 = g("robustness", "csi_0.10m", "c_min")
    claims.append(_claim("CSI noise 0.10 m costs < 6% of C_min", None if None in (n0, c10) else bool(c10 > 0.94 * n0),
                         "not run" if None in (n0, c10) else f"C_min {c10:.3g} vs {n0:.3g} nominal ({c10 / n0 - 1:+.1%})"))
    return claims


def summarize(studies: list[Study], specs: list[RunSpec], out: Path, extra: dict | None = None) -> dict:
    """Summary of a campaign: every study's numbers plus the claims table."""
    per = {s.name: summarize_study(s, [r for r in specs if r.study == s.name], out) for s in studies}
    summary = {"studies": per, "claims": evaluate_claims(per)}
    summary.update(extra or {})
    return summary
