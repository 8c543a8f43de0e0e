"""The campaign report: one self-contained HTML file (figures embedded as base64 PNG)."""

from __future__ import annotations

import base64
import html
import io
import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
import plotly.graph_objects as go  # noqa: E402
from plotly.offline import get_plotlyjs  # noqa: E402

from ..experiments.campaign import RunStatus, first_run_per_group, run_dir  # noqa: E402
from ..experiments.study import RunSpec, Study, groups_of_run, scenario_of  # noqa: E402
from ..store.run_folder import BOUND_PARQUET, TIMESERIES_FILE
from .figures import PAPER_LABELS, jammer_traces  # noqa: E402
from .folders import read_timeseries, vehicle_paths
from .sweeps import box_figure, sweep_figures  # noqa: E402

# the runs table shows these first; the rest of TABLE_METRICS opens on demand (<details>)
MAIN_METRICS = ("c_min", "c_mean", "outage_fraction", "outage_duration_mean_s", "outage_duration_max_s")
TABLE_METRICS = ("c_min", "c_mean", "outage_fraction", "alignment_ok_fraction", "alignment_within_slack_fraction",
                 "slack_active_fraction", "infeasible_fraction", "energy_kJ", "distance_m", "final_z_m", "solve_ms.mean",
                 "solve_ms.p99", "motor_saturation_fraction", "rate_saturation_fraction")
# column headers with units, breakable so that tables fit the page
HEADERS = {"c_min": "C_min (bit/s/Hz)", "c_mean": "mean C (bit/s/Hz)", "outage_fraction": "outage fraction",
           "outage_duration_mean_s": "outage duration, mean (s)", "outage_duration_max_s": "longest outage (s)",
           "alignment_ok_fraction": "alignment >= mu", "alignment_within_slack_fraction": "alignment >= mu - 0.02",
           "slack_active_fraction": "slack active", "infeasible_fraction": "QP failures", "energy_kJ": "energy (kJ)",
           "distance_m": "distance (m)", "final_z_m": "final z (m)", "solve_ms.mean": "step mean (ms)",
           "solve_ms.p99": "step p99 (ms)", "max_deviation_m": "max deviation (m)",
           "capacity_efficiency_mean": "efficiency, mean C", "capacity_efficiency_min": "efficiency, C_min",
           "capacity_efficiency_mean_flyable": "mean C / flyable path's", "capacity_efficiency_min_flyable": "C_min / flyable path's",
           "capacity_efficiency_mean_path": "mean C / upper path bound's",
           "c_min_over_direct": "C_min / direct link's", "c_mean_over_direct": "mean C / direct link's",
           "fallback_fraction": "fail-safe steps", "worst_relay_fallback_fraction": "worst relay: brake law",
           "worst_relay_infeasible_fraction": "worst relay: QP failures", "motor_saturation_fraction": "a motor at a speed bound",
           "rate_saturation_fraction": "a motor at a rate bound",
           "estimation_first_within_1m_s": "jammer estimate first within 1 m (s)",
           "estimation_crlb_first_1m_s": "Cramer-Rao bound first <= 1 m (s)", "estimation_crlb_10s_m": "Cramer-Rao bound at 10 s (m)",
           "estimation_within_1m_after_bound": "estimate within 1 m once the bound is",
           "estimation_within_1m_after_10s": "estimate within 1 m after 10 s", "estimator_ms.mean": "estimator (ms/step)"}
MAX_CURVES = 8

CSS = """
body{font-family:system-ui,sans-serif;max-width:1100px;margin:2em auto;padding:0 1em;color:#222}
table{border-collapse:collapse;margin:1em 0;font-size:13px}td,th{border:1px solid #ccc;padding:3px 7px;text-align:right}
th{background:#f3f3f3}td:first-child,th:first-child{text-align:left}.yes{color:#176a1f;font-weight:600}
.no{color:#b00020;font-weight:600}.na{color:#777}img{max-width:100%;border:1px solid #eee;margin:4px 0}
.warn{background:#fff4e0;border-left:4px solid #f0a000;padding:6px 10px}code{background:#f5f5f5;padding:0 3px}
.wide{overflow-x:auto;max-width:100%}th{white-space:normal;vertical-align:bottom}
td{overflow-wrap:anywhere}td.text{text-align:left}details{margin:.5em 0}summary{cursor:pointer;color:#345}
"""


def _png(fig, alt: str = "figure") -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100, bbox_inches="tight")
    plt.close(fig)
    return f'<img alt="{html.escape(alt)}" src="data:image/png;base64,{base64.b64encode(buf.getvalue()).decode()}">'


def _fmt(v) -> str:
    if v is None:
        return "—"
    if isinstance(v, float):
        if math.isinf(v) or math.isnan(v):
            return str(v)
        return f"{v:.3g}"
    return html.escape(str(v))


def _capacity_figure(study: Study, specs: list[RunSpec], out: Path) -> str | None:
    """Seed 0 of each run, 1 s means; one panel per capacity unit (bit/s/Hz, bit/s) the study uses."""
    firsts = first_run_per_group(specs, out)
    if not firsts:
        return None
    by_unit: dict[str, list[tuple[str, RunSpec]]] = {}
    for g, s in firsts.items():
        by_unit.setdefault(scenario_of(s).channel.capacity_unit, []).append((g, s))
    fig, axes = plt.subplots(len(by_unit), 1, figsize=(9, 3.8 * len(by_unit)), squeeze=False)
    for ax, (unit, runs) in zip(axes[:, 0], sorted(by_unit.items(), reverse=True), strict=True):
        for g, s in runs[:MAX_CURVES]:
            df = pd.read_parquet(run_dir(out, s) / TIMESERIES_FILE, columns=["t", "capacity"])
            c = np.maximum(df["capacity"].to_numpy(), 1e-9)
            window = max(1, int(round(1.0 / max(float(np.median(np.diff(df["t"]))), 1e-9))))  # 1 s moving mean: fading noise off
            smooth = pd.Series(c).rolling(window, center=True, min_periods=1).mean().to_numpy()
            ax.semilogy(df["t"], smooth, lw=1.4, label=g)
        _outage_lines(ax, [s for _, s in runs])
        ax.set_xlabel("t (s)")
        ax.set_ylabel(f"end-to-end C, 1 s mean ({unit})")
        ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0)
    axes[0, 0].set_title(f"{study.title}: capacity over time of each run's first seed (1 s means; the spread over seeds "
                         "is the box plot's)", fontsize=9, wrap=True)
    fig.tight_layout()
    return _png(fig)


def _bound_figures(study: Study, specs: list[RunSpec], out: Path) -> list[str]:
    """One figure per ``bound_figures`` entry: the runs' capacity and the bounds of their scenario."""
    firsts = first_run_per_group(specs, out)
    figs = []
    for groups in study.bound_figures:
        runs = [firsts[g] for g in groups if g in firsts]
        if not runs or not (run_dir(out, runs[0]) / BOUND_PARQUET).exists():
            continue
        bound = pd.read_parquet(run_dir(out, runs[0]) / BOUND_PARQUET)
        fig, ax = plt.subplots(figsize=(8, 3.4))
        ax.semilogy(bound["t"], bound["path_mean"], color="0.3", lw=2, alpha=0.5, label="bound: best path (mean), <= v_max")
        ax.semilogy(bound["t"], bound["static"], color="0.5", ls=":", lw=1, label="bound: best pose per instant")
        for s in runs:
            df = pd.read_parquet(run_dir(out, s) / TIMESERIES_FILE, columns=["t", "capacity"])
            ax.semilogy(df["t"], np.maximum(df["capacity"], 1e-9), lw=1.2, label=s.group)
        _outage_lines(ax, runs)
        ax.set_xlabel("t (s)")
        ax.set_ylabel(f"end-to-end C ({capacity_unit(runs)}, log scale)")
        title = " vs ".join(groups) + " vs the bound"
        ax.set_title(title, fontsize=9)
        ax.legend(fontsize=7)
        figs.append(_png(fig, alt=title))
    return figs


def _estimation_figures(study: Study, specs: list[RunSpec], out: Path) -> list[str]:
    """Per ``estimation_figures`` pair: the estimated run's position error per jammer over time with
    the estimate's 2-sigma band (twice its largest position std) and the Cramer-Rao bound of its
    path (dashed, where defined), and both runs' capacity."""
    firsts = first_run_per_group(specs, out)
    figs = []
    for est, oracle in study.estimation_figures:
        if est not in firsts:
            continue
        df = pd.read_parquet(run_dir(out, firsts[est]) / TIMESERIES_FILE)
        names = [c[4:-6] for c in df.columns if c.startswith("est_") and c.endswith("_err_m")]
        fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 3.4))
        for i, n in enumerate(names):
            ax1.fill_between(df["t"], 0.0, 2.0 * df[f"est_{n}_std_m"], color=f"C{i}", alpha=0.2, lw=0,
                             label=f"{n}: 2 sigma")
            ax1.plot(df["t"], df[f"est_{n}_err_m"], color=f"C{i}", lw=1.2, label=f"{n}: error")
            if f"est_{n}_crlb_m" in df and np.isfinite(df[f"est_{n}_crlb_m"].iloc[-1]):
                ax1.plot(df["t"], df[f"est_{n}_crlb_m"], color=f"C{i}", ls="--", lw=0.9, label=f"{n}: Cramer-Rao bound")
        ax1.axhline(1.0, color="k", ls=":", lw=0.8, label="1 m")
        ax1.set_yscale("log")
        ax1.set_ylim(0.01, 100.0)
        ax1.set_xlabel("t (s)")
        ax1.set_ylabel("jammer position error (m)")
        ax1.set_title(f"{est}: estimate vs truth", fontsize=9)
        ax1.legend(fontsize=7)
        for g in (est, oracle):
            if g in firsts:
                c = pd.read_parquet(run_dir(out, firsts[g]) / TIMESERIES_FILE, columns=["t", "capacity"])
                ax2.semilogy(c["t"], np.maximum(c["capacity"], 1e-9), lw=1.1, label=g)
        ax2.set_xlabel("t (s)")
        ax2.set_ylabel(f"end-to-end C ({capacity_unit(specs)})")
        ax2.set_title("capacity: estimated vs oracle jammer", fontsize=9)
        ax2.legend(fontsize=7)
        fig.tight_layout()
        figs.append(_png(fig, alt=f"{est} estimation error and capacity vs {oracle}"))
    return figs


def _tradeoff_figures(study: Study, study_sum: dict) -> list[str]:
    """One figure per ``[[tradeoffs]]``: per run id a line through its grid groups' (x, y) means,
    its bound (if declared) dashed in the same colour."""
    groups, figs = study_sum["groups"], []
    for tr in study.tradeoffs:
        fig, axes = plt.subplots(1, len(tr.y), figsize=(4.6 * len(tr.y), 3.6), squeeze=False)
        for j, (ax, key) in enumerate(zip(axes[0], tr.y, strict=True)):
            bound_key = tr.bounds[j] if tr.bounds else None
            for i, run in enumerate(study.runs):
                pts = [(groups[g][tr.x], groups[g][key], g) for g in groups_of_run(study, run.id)
                       if g in groups and tr.x in groups[g] and key in groups[g]]
                if not pts:
                    continue
                pts.sort()
                color = f"C{i % 10}"
                ax.plot([p[0] for p in pts], [p[1] for p in pts], "o-", color=color, ms=4, label=run.id)
                bvals = [groups[g][bound_key] for _, _, g in pts if bound_key and bound_key in groups[g]]
                if bvals:
                    ax.axhline(float(np.mean(bvals)), color=color, ls="--", lw=0.9, alpha=0.7)
            ax.set_xlabel(HEADERS.get(tr.x, tr.x))
            ax.set_ylabel(HEADERS.get(key, key))
            ax.grid(alpha=0.3)
            ax.set_title(f"{key} vs {tr.x}" + (f" (dashed: {bound_key})" if bound_key else ""), fontsize=8)
        axes[0][-1].legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0)
        if tr.title:
            fig.suptitle(tr.title, fontsize=9)
        fig.tight_layout()
        figs.append(_png(fig, alt=tr.title or "trade-off"))
    return figs


def _bars_figure(study_sum: dict) -> str | None:
    groups = study_sum["groups"]
    if not groups:
        return None
    names = list(groups)
    fig, axes = plt.subplots(1, 2, figsize=(9, 3.4))
    for ax, key in zip(axes, ("c_min", "c_mean"), strict=False):
        vals = [groups[g][key] for g in names]
        errs = [groups[g].get(key + ".std", 0.0) for g in names]
        ax.errorbar(range(len(names)), np.maximum(vals, 1e-9), yerr=errs, fmt="o", color="#4a78b0", label="ours")
        for p in study_sum["paper"]:
            if p["metric"] == key and p["run"] in names:
                ax.plot(names.index(p["run"]), p["paper"], "r*", ms=10, label="paper")
        ax.set_yscale("log")
        ax.set_ylabel(f"{HEADERS[key]}, log scale")
        ax.set_xticks(range(len(names)))
        ax.set_xticklabels([n if len(n) <= 28 else n[:26] + "..." for n in names], rotation=60, ha="right", fontsize=6)
        ax.set_xlabel("run")
        ax.grid(axis="y", which="major", alpha=0.3)
        ax.set_title(key + " (ours: dots with spread over seeds, paper: red stars)", fontsize=9)
    fig.tight_layout()
    return _png(fig)


def _trajectory_3d(study: Study, specs: list[RunSpec], out: Path) -> str | None:
    """Interactive 3D view (plotly) of the relay paths of a small study, with MRAV-2, BS and jammer."""

    firsts = first_run_per_group(specs, out)
    if not firsts or len(firsts) > 6 or study.seeds > 1:
        return None
    traces = []
    for i, (g, s) in enumerate(firsts.items()):
        relays, sources = vehicle_paths(read_timeseries(run_dir(out, s)))  # one relay's log or a fleet's
        for name, p in relays.items():
            label = f"{name}: {g}"
            traces.append(go.Scatter3d(x=p.iloc[:, 0], y=p.iloc[:, 1], z=p.iloc[:, 2], mode="lines", name=label, line=dict(width=5)))
        for name, p in sources.items() if i == 0 else ():
            traces.append(go.Scatter3d(x=p.iloc[:, 0], y=p.iloc[:, 1], z=p.iloc[:, 2], mode="lines",
                                       name=PAPER_LABELS.get(name, f"source {name}"),
                                       line=dict(color="#7b3fa0", width=4, dash="dash")))
    sc = scenario_of(next(iter(firsts.values())))
    traces += [go.Scatter3d(x=[b.position[0]], y=[b.position[1]], z=[b.position[2]], mode="markers",
                            name="BS" if len(sc.base_station_list) == 1 else f"BS {b.name}", marker=dict(color="black", size=5))
               for b in sc.base_station_list]
    traces.extend(jammer_traces(sc, np.arange(0.0, sc.duration_s + 1e-9, 0.5)))
    fig = go.Figure(traces)
    fig.update_layout(height=520, scene=dict(aspectmode="data", xaxis_title="x (m)", yaxis_title="y (m)", zaxis_title="z (m)"),
                      margin=dict(l=0, r=0, t=30, b=0),
                      title=dict(text="trajectories (drag to rotate)", font=dict(size=12)))
    return fig.to_html(full_html=False, include_plotlyjs=False)


def _breakable(text: str) -> str:
    """Escaped text that may wrap after commas and underscores (long run names)."""
    return html.escape(text).replace(",", ",<wbr>").replace("_", "_<wbr>")


def _ranking_table(ranking: list[dict]) -> str:
    """Combinations sorted by distance to the paper, the closest first and named."""
    names = list(ranking[0]["terms"])
    rows = []
    for i, r in enumerate(ranking, 1):
        cells = [f"{_fmt(r['terms'][n]['ours'])} <span class='na'>({_fmt(r['terms'][n]['paper'])})</span>" for n in names]
        rows.append([str(i), _breakable(r["combination"]), _fmt(r["distance"]), *cells])
    best = ranking[0]
    intro = (f"<h3>Which assumptions come closest to the paper's numbers</h3><p>Distance: root mean square over the "
             f"terms below of log10(ours / paper) for capacities and their ratio, (ours - paper) for fractions, "
             f"(ours - paper) / paper for lengths. Closest: <b>{html.escape(best['combination'])}</b> "
             f"(distance {_fmt(best['distance'])}). Each cell: ours (paper).</p>")
    return intro + _table(["rank", "assumptions", "distance", *[n.replace("@", " @ ").replace("/", " / ") for n in names]], rows)


def _is_number(cell) -> bool:
    try:
        float(str(cell).replace("%", "").replace("x", "", 1))
        return True
    except ValueError:
        return str(cell) in ("-", "", "inf", "nan")


def _table(headers, rows) -> str:
    """Numbers right-aligned, text (claims, evidence, notes) left-aligned."""
    head = "".join(f"<th>{html.escape(h)}</th>" for h in headers)
    body = "".join("<tr>" + "".join(f"<td>{c}</td>" if _is_number(c) else f"<td class='text'>{c}</td>" for c in r) + "</tr>"
                   for r in rows)
    return f"<div class='wide'><table><tr>{head}</tr>{body}</table></div>"


def _outage_lines(ax, specs: list[RunSpec]) -> None:
    """The runs' outage thresholds (each scenario's ``channel.outage_threshold``, in its unit)."""
    for thr, unit in sorted({(sc.channel.outage, sc.channel.capacity_unit) for sc in map(scenario_of, specs)}):
        ax.axhline(thr, color="r", ls="--", lw=0.8, label=f"outage threshold ({thr:g} {unit})")


def capacity_unit(specs: list[RunSpec]) -> str:
    """The unit of the runs' capacities: bit/s/Hz, bit/s, or both named when a study mixes them."""
    units = sorted({scenario_of(s).channel.capacity_unit for s in specs}, reverse=True)
    return units[0] if len(units) == 1 else "bit/s/Hz; physical-unit runs bit/s"


def _headers(cols, unit: str) -> list[str]:
    """Column headers, capacities in ``unit``."""
    return [HEADERS.get(c, c).replace("(bit/s/Hz)", f"({unit})") for c in cols]


def _study_section(study: Study, study_sum: dict, specs: list[RunSpec], out: Path, manifest: dict) -> str:
    parts = [f'<h2 id="{study.name}">{html.escape(study.title)}</h2>', f"<p>{html.escape(study.description)}</p>"]
    if study_sum["paper"]:
        rows = [[html.escape(p["metric"]), html.escape(p["run"]), _fmt(p["ours"]), _fmt(p["paper"]),
                 _fmt(p["ratio"]), html.escape(p["note"])] for p in study_sum["paper"]]
        parts.append("<h3>Ours beside the paper</h3>" + _table(["metric", "run", "ours", "paper", "ours / paper", "note"], rows))
    groups = study_sum["groups"]
    if groups:
        extra = [k for k in ("c_min_over_direct", "c_mean_over_direct", "max_deviation_m", "capacity_efficiency_mean",
                             "capacity_efficiency_min",
                             "capacity_efficiency_mean_flyable", "capacity_efficiency_min_flyable",
                             "capacity_efficiency_mean_path",
                             "estimation_first_within_1m_s", "estimation_crlb_first_1m_s", "estimation_within_1m_after_10s",
                             "estimation_within_1m_after_bound",
                             "estimator_ms.mean")
                 if any(k in g for g in groups.values())]
        main = list(MAIN_METRICS) + extra
        # the worst relay's shares: one column for one relay and a network alike (a relay's own share of a network's run
        # is not at the top level)
        shares = {"infeasible_fraction": "worst_relay_infeasible_fraction"}
        more = [shares.get(c, c) for c in (*TABLE_METRICS, "worst_relay_fallback_fraction") if c not in main]
        unit = capacity_unit(specs)
        for cols, title in ((main, "<h3>Runs (means over seeds)</h3>"), (more, None)):
            rows = [[_breakable(g) + (f' <span class="warn" title="{len(v["fell_back_runs"])} run(s) fell back">(fell back)'
                                      '</span>' if v.get("fell_back_runs") else ""), str(v["n"])]
                    + [_fmt(v.get(c)) for c in cols] for g, v in groups.items()]
            table = _table(["run", "n"] + _headers(cols, unit), rows)
            parts.append(title + table if title else f"<details><summary>more columns: {', '.join(HEADERS.get(c, c) for c in cols)}"
                                                      f"</summary>{table}</details>")
    if study_sum.get("ranking"):
        parts.append(_ranking_table(study_sum["ranking"]))
    for fig in (*sweep_figures(study, study_sum, capacity_unit(specs), _png), box_figure(study, study_sum, capacity_unit(specs), _png),
                *_tradeoff_figures(study, study_sum),
                *_bound_figures(study, specs, out),
                *_estimation_figures(study, specs, out), _capacity_figure(study, specs, out),
                _bars_figure(study_sum),
                _trajectory_3d(study, specs, out)):
        if fig:
            parts.append(fig)
    failed = [r for r in manifest.values() if r.get("study") == study.name and r.get("status") == RunStatus.FAILED]
    if failed or study_sum["missing_runs"]:
        items = "".join(f"<li><code>{html.escape(r['key'])}</code>: {html.escape(r.get('error', ''))}</li>" for r in failed)
        parts.append(f'<div class="warn">{len(study_sum["missing_runs"])} run(s) without results.<ul>{items}</ul></div>')
    fell = [r for r in manifest.values() if r.get("study") == study.name and r.get("status") == RunStatus.FELL_BACK]
    if fell:
        items = "".join(f"<li><code>{html.escape(r['key'])}</code>: {html.escape(r.get('error', ''))}</li>" for r in fell)
        parts.append(f'<div class="warn">{len(fell)} run(s) fell back: a relay flew more than '
                     f'verdict.fallback_fraction_max of its steps on the brake law or with failed QPs; their numbers are '
                     f'what the fail-safe flew, not the controller.<ul>{items}</ul></div>')
    unsafe = [r for r in manifest.values() if r.get("study") == study.name and r.get("status") == RunStatus.UNSAFE]
    if unsafe:
        items = "".join(f"<li><code>{html.escape(r['key'])}</code>: {html.escape(r.get('error', ''))}</li>" for r in unsafe)
        parts.append(f'<div class="warn">{len(unsafe)} unsafe run(s): the relay left its world whatever the QPs '
                     f'reported; their numbers are not used.<ul>{items}</ul></div>')
    return "\n".join(parts)


def _why_section(summary: dict, studies: list[Study]) -> str:
    """Why our numbers differ: each claim that does not hold with its measured causes, the paper's
    self-contradictions with both numbers, and the studies' own measured causes."""
    items = []
    for c in summary["claims"]:
        if c["holds"] is False or c.get("contradiction"):
            causes = "".join(f"<li>{html.escape(w)}</li>" for w in c.get("why", []))
            if c.get("contradiction"):
                causes += f"<li><b>The paper contradicts itself:</b> {html.escape(c['contradiction'])}</li>"
            state = "does not hold" if c["holds"] is False else "holds"
            items.append(f"<li><b>{html.escape(c['claim'])}</b> ({state})<ul>{causes or '<li>no cause declared</li>'}</ul></li>")
    for s in studies:
        for w in summary["studies"][s.name].get("why", []):
            items.append(f"<li><b>{html.escape(s.title)}</b>: {html.escape(w)}</li>")
    if not items:
        return ""
    return "<h2>Why our numbers differ</h2><ul>" + "".join(items) + "</ul>"


def render_report(summary: dict, studies: list[Study], specs: list[RunSpec], out: Path, manifest: dict) -> str:
    """The whole report as an HTML string."""
    claims_rows = []
    for c in summary["claims"]:
        verdict = {True: '<span class="yes">holds</span>', False: '<span class="no">does not hold</span>',
                   None: '<span class="na">not evaluated</span>'}[c["holds"]]
        if c.get("contradiction"):
            verdict += '<br><span class="na">(the paper contradicts itself here)</span>'
        claims_rows.append([html.escape(c["claim"]), verdict, html.escape(c["evidence"])])
    meta = summary.get("campaign", {})
    paper_like = any(st.paper for st in studies)
    title = "reproduction of the paper's experiments" if paper_like else "; ".join(st.title or st.name for st in studies)
    partial = meta.get("runs_finished") is not None and meta.get("runs_finished") < meta.get("runs_total", 0)
    note = (f"<div class='warn'>Partial report: {meta.get('runs_finished')} of {meta.get('runs_total')} runs finished; "
            f"studies with missing runs say so. Run the same <code>aerorelay reproduce</code> command to resume.</div>"
            if partial else "")
    head = (f"<h1>aerorelay: {html.escape(title)}</h1>{note}"
            f"<p>aerorelay {html.escape(str(meta.get('version', '')))}, {html.escape(str(meta.get('date', '')))}; "
            f"{meta.get('runs_total', 0)} runs ({meta.get('runs_failed', 0)} failed), "
            f"{'quick mode (fewer seeds, shorter missions where the study allows)' if meta.get('quick') else 'full campaign'}; "
            f"this invocation ran {meta.get('runs_ran', 0)} runs and skipped {meta.get('runs_skipped', 0)} finished ones "
            f"in {meta.get('wall_s') or 0:.0f} s wall; the runs' own wall times add up to {meta.get('runs_compute_s') or 0:.0f} s. "
            f"Controller: {html.escape(str(meta.get('controller', 'not recorded')))}. "
            f"Normalized capacities (B = 1). Solve times measured "
            f"with runs in parallel on the same cores: use <code>aerorelay bench</code> for isolated timing.</p>")
    toc = "<p>" + " · ".join(f'<a href="#{s.name}">{html.escape(s.name)}</a>' for s in studies) + "</p>"
    body = [head, toc]
    if claims_rows:
        heading = "The paper's claims on our numbers" if any(st.paper for st in studies) else "Claims on our numbers"
        body += [f"<h2>{heading}</h2>", _table(["claim", "verdict", "evidence"], claims_rows), _why_section(summary, studies)]
    for s in studies:
        body.append(_study_section(s, summary["studies"][s.name], [r for r in specs if r.study == s.name], out, manifest))

    return (f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>aerorelay report</title>"
            f"<style>{CSS}</style><script>{get_plotlyjs()}</script></head><body>{''.join(body)}</body></html>")
