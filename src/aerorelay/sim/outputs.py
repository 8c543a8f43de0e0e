"""Write a mission's outputs into a run folder, atomically (a finished folder is complete)."""

from __future__ import annotations

import json
import shutil
import tempfile
from pathlib import Path

import pandas as pd

from .closed_loop import MissionResult, log_columns
from .metrics import compute_metrics


def log_frame(result: MissionResult) -> pd.DataFrame:
    """The per-step log as a DataFrame with the documented column order."""
    columns = log_columns(result.scenario.platform.vehicle().n_rotors)
    missing = [c for c in columns if c not in result.log]
    if missing:
        raise ValueError(f"the mission log lacks the columns {missing} of its vehicle")
    df = pd.DataFrame({c: result.log[c] for c in columns})
    df["jammer_on"] = df["jammer_on"].astype(bool)
    df["qp_status"] = df["qp_status"].astype(str)
    df["fallback"] = df["fallback"].astype(bool)
    return df


def write_run(result: MissionResult, out: Path, *, figures: bool = True, bound=None) -> dict:
    """Write scenario.toml, timeseries.parquet, metrics.json (+ figures) to ``out``; return the metrics.

    Everything is first written to a temporary sibling folder which then replaces ``out``, so an
    interrupted write never leaves a half-finished run folder behind.
    """
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    sc = result.scenario
    metrics = compute_metrics(result.log, sc, wall_s=result.wall_s, sim_s=result.sim_s)
    metrics["controller"] = result.controller
    metrics["fallback_episodes"] = result.fallback_episodes
    if bound is not None:  # how far from what the physics allows (planning/bound.py)
        metrics["capacity_efficiency_mean"] = metrics["c_mean"] / float(bound.path_mean.mean())
        metrics["capacity_efficiency_min"] = metrics["c_min"] / float(bound.path_maxmin.min())
        metrics["bound"] = bound.summary()
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    try:
        (tmp / "scenario.toml").write_text(sc.to_toml())
        df = log_frame(result)
        df.to_parquet(tmp / "timeseries.parquet", index=False)
        (tmp / "metrics.json").write_text(json.dumps(metrics, indent=2))
        if bound is not None:
            from ..planning.bound import write_bound

            write_bound(bound, tmp)
        if figures:
            from ..report.figures import write_run_figures

            write_run_figures(df, sc, tmp, bound.frame() if bound is not None else None)
        if out.exists():
            shutil.rmtree(out)
        tmp.rename(out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return metrics
