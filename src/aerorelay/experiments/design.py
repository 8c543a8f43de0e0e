"""``aerorelay design``: how many relays a mission needs, under which schedule, against the direct link.

For each relay count ``K`` asked and each schedule (``network.schedule``), the scenario is flown by ``K``
capacity-seeking relays that the tool places (``placed_relays``: evenly on the line from the base station toward the
source's farthest point, above its start; the capacity planner's pre-flight route and its in-flight search then move
them), with the capacity bound (the one relay's exact bound, a network's certified bound:
its upper bound and its flyable path) and the direct-link baseline (``sim.baseline = "direct"``: the rate with no
relay, ``K = 0``). The runs are a campaign (``experiments.campaign``: on dask, resumable, parallel on a cluster),
their results ``design.json`` (per ``K`` and schedule: the bound, the flyable path, the flight, their times),
``design.png`` (the flown rate against ``K`` per schedule with each bound's band, the direct link at ``K = 0``) and the
recommended design as a scenario file (``recommended.toml``: the best flown of those tried; the direct link when no
relay beats it)."""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from ..config import Scenario, ScenarioError  # noqa: E402
from ..models.mission import source_trajectory  # noqa: E402
from ..models.radio import SCHEDULES  # noqa: E402
from ..store.outputs import write_atomic  # noqa: E402
from .campaign import RunStatus, load_manifest, run_dir  # noqa: E402
from .study import RunSpec, _updated  # noqa: E402

DESIGN_FILE = "design.json"
DESIGN_FIGURE = "design.png"
RECOMMENDED_FILE = "recommended.toml"
STUDY = "design"
START_CLEARANCE_M = 0.5  # the relays start this much more than the separation apart, and this far inside the workspace
MAX_RELAYS = 16  # [[relays]]' limit
BY = ("c_mean", "c_min")  # what "best flown" means


@dataclass(frozen=True)
class DesignRun:
    """One design point: ``relays`` capacity-seeking relays under ``schedule``, flown as ``spec``."""

    relays: int
    schedule: str
    spec: RunSpec


def parse_relays(text: str) -> list[int]:
    """``--relays``: ``"1-3"``, ``"2"`` or ``"1,2,4"`` -> the relay counts (1..16); a ValueError naming the form."""
    try:
        counts: set[int] = set()
        for part in text.split(","):
            lo, _, hi = part.strip().partition("-")
            a, b = int(lo), int(hi or lo)
            counts |= set(range(a, b + 1))
    except ValueError:
        counts = set()
    if not counts or min(counts) < 1 or max(counts) > MAX_RELAYS:
        raise ValueError(f"--relays: {text!r}: relay counts from 1 to {MAX_RELAYS} as 'A-B', 'K' or 'A,B,C' (0 relays, the "
                         "direct link, is in every design: sim.baseline = 'direct')")
    return sorted(counts)


def placed_relays(sc: Scenario, k: int) -> list[dict]:
    """``k`` relays on the line from the (first) base station toward the first source's farthest point of its mission
    (horizontally; the x axis where it stays above the base station), evenly over that line (``r1`` farthest out) and
    ``separation + START_CLEARANCE_M`` apart at least, that much above the source's start altitude (so no relay starts
    on the source), kept ``START_CLEARANCE_M`` inside the workspace."""
    bs = np.asarray(sc.first_station.position, float)
    path = source_trajectory(sc.source_list[0].mission)
    src = np.asarray(sc.source_list[0].mission.start, float)
    far = max((np.asarray(path.state(t).p, float) for t in np.linspace(0.0, sc.duration_s, 200)),
              key=lambda p: float(np.hypot(*(p[:2] - bs[:2]))))
    d = far[:2] - bs[:2]
    length = float(np.hypot(*d))
    u = d / length if length > 1e-9 else np.array([1.0, 0.0])
    gap = sc.separation_m + START_CLEARANCE_M
    spacing = max(length / (k + 1), gap)
    ws = sc.controller.workspace
    lo, hi = np.asarray(ws.min, float) + START_CLEARANCE_M, np.asarray(ws.max, float) - START_CLEARANCE_M
    out = []
    for i in range(k):  # r1 farthest out, as a route [source, r1, ..., rK, bs] runs
        along = spacing * (k - i)
        p = np.clip(np.array([bs[0] + along * u[0], bs[1] + along * u[1], src[2] + gap]), lo, hi)
        out.append({"name": f"r{i + 1}", "start": [round(float(v), 3) for v in p]})
    return out


def design_runs(sc: Scenario, counts: Sequence[int], schedules: Sequence[str], *, bound: bool = True) -> list[DesignRun]:
    """Every design point's run (validated before any work: a count whose relays the scenario cannot hold is a
    ScenarioError naming it)."""
    bad = [s for s in schedules if s not in SCHEDULES]
    if bad or not schedules:
        raise ValueError(f"--schedule: {bad or schedules!r}: each one of {', '.join(SCHEDULES)}")
    runs = []
    for k in counts:
        for schedule in schedules:
            updates: dict = {"relays": placed_relays(sc, k), "network.routes": None, "controller.planner": "capacity",
                             "network.schedule": schedule, "sim.baseline": "direct", "name": f"{STUDY}/K{k}[{schedule}]"}
            if sc.relays is None:  # a file naming its one relay as nodes.relay: the design names its own
                updates["nodes.relay"] = None
            try:
                flown = _updated(sc, updates, f"design, {k} relays, schedule {schedule!r}")
            except ValueError as exc:
                raise ScenarioError(str(exc)) from None
            runs.append(DesignRun(k, schedule, RunSpec(STUDY, f"K{k}[schedule={schedule}]", 0, flown.to_toml(), bound)))
    return runs


def _point(out: Path, run: DesignRun, status: str | None) -> dict:
    """One design point's numbers from its run folder (``status`` the campaign's record)."""
    row: dict = {"relays": run.relays, "schedule": run.schedule, "run": str(run_dir(out, run.spec).relative_to(out)),
                 "status": status}
    path = run_dir(out, run.spec) / "metrics.json"
    if status != RunStatus.DONE or not path.is_file():
        return row
    m = json.loads(path.read_text())
    b = m.get("bound") or {}
    row["flown"] = {k: m.get(k) for k in ("c_mean", "c_min", "exit_status", "unsafe", "wall_s")}
    row["direct"] = {"c_mean": m.get("c_mean_direct"), "c_min": m.get("c_min_direct")}
    upper = b.get("path_mean") or b.get("static") or {}
    row["bound"] = {"upper_mean": upper.get("mean"), "upper": "path_mean" if "path_mean" in b else "static",
                    "static_mean": (b.get("static") or {}).get("mean"),
                    "flyable_mean": (b.get("flyable") or b.get("flyable_mean") or {}).get("mean"),
                    "schedule_factor": (b.get("resolution") or {}).get("schedule_factor", 1.0)}
    row["within_bound"] = (None if row["bound"]["upper_mean"] is None or m.get("c_mean") is None else
                           bool(m["c_mean"] <= row["bound"]["upper_mean"] * (1 + 1e-9)))
    return row


def summarize(out: Path, runs: Sequence[DesignRun], by: str = "c_mean") -> dict:
    """``design.json``: every design point, the direct link, and the recommendation (the best flown by ``by`` among
    the safe, complete runs; the direct link when none beats it)."""
    if by not in BY:
        raise ValueError(f"--by: {by!r}: one of {', '.join(BY)}")
    records = load_manifest(out)
    points = [_point(out, r, (records.get(r.spec.key) or {}).get("status")) for r in runs]
    flown = [p for p in points if "flown" in p and p["flown"].get("exit_status") == "complete" and p["flown"].get(by) is not None]
    direct = next((p["direct"] for p in points if p.get("direct", {}).get(by) is not None), None)
    best = max(flown, key=lambda p: p["flown"][by], default=None)
    if best is not None and direct is not None and direct[by] >= best["flown"][by]:
        recommended: dict = {"relays": 0, "schedule": None, by: direct[by], "why": "no relay count tried beats the direct link"}
    elif best is not None:
        recommended = {"relays": best["relays"], "schedule": best["schedule"], by: best["flown"][by], "run": best["run"],
                       "why": f"the best flown {by} of those tried"}
    else:
        recommended = {"relays": None, "why": "no design point flew to its end safely"}
    return {"by": by, "points": points, "direct": direct, "recommended": recommended,
            "missing": [p["run"] for p in points if "flown" not in p]}


def write_outputs(out: Path, runs: Sequence[DesignRun], summary: dict, capacity_unit: str) -> None:
    """``design.json``, ``design.png`` and, where the recommendation is a relay design, ``recommended.toml``."""
    write_atomic(out / DESIGN_FILE, json.dumps(summary, indent=2, default=float) + "\n")
    rec = summary["recommended"]
    chosen = next((r for r in runs if r.relays == rec.get("relays") and r.schedule == rec.get("schedule")), None)
    if chosen is not None:
        write_atomic(out / RECOMMENDED_FILE, f"# aerorelay design: {rec['why']} ({summary['by']} "
                     f"{rec[summary['by']]:.6g} {capacity_unit})\n" + chosen.spec.scenario_toml)
    fig, ax = plt.subplots(figsize=(6, 4))
    by = summary["by"]
    for i, schedule in enumerate(dict.fromkeys(r.schedule for r in runs)):
        pts = sorted((p for p in summary["points"] if p["schedule"] == schedule and "flown" in p), key=lambda p: p["relays"])
        if not pts:
            continue
        k = [p["relays"] for p in pts]
        ax.plot(k, [p["flown"][by] for p in pts], "o-", color=f"C{i}", label=f"flown, {schedule}")
        upper = [p["bound"]["upper_mean"] if p["bound"]["upper_mean"] is not None else math.nan for p in pts]
        lower = [p["bound"]["flyable_mean"] if p["bound"]["flyable_mean"] is not None else math.nan for p in pts]
        if by == "c_mean" and not all(math.isnan(v) for v in upper):
            ax.fill_between(k, lower, upper, color=f"C{i}", alpha=0.15, label=f"bound: flyable .. upper, {schedule}")
    if summary["direct"] is not None:
        ax.plot([0], [summary["direct"][by]], "ks", label="direct link (no relay)")
    ax.set_xlabel("relays K")
    ax.set_ylabel(f"{by} ({capacity_unit})")
    ax.set_yscale("log")
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(out / DESIGN_FIGURE, dpi=110)
    plt.close(fig)
