"""A run folder: the files one mission writes, published atomically (a finished folder is complete)."""

from __future__ import annotations

import json
import shutil
from collections.abc import Callable
from pathlib import Path

import pandas as pd

from .outputs import new_sibling, swap_in

SCENARIO_FILE = "scenario.toml"
TIMESERIES_FILE = "timeseries.parquet"
METRICS_FILE = "metrics.json"
BOUND_JSON = "bound.json"
BOUND_PARQUET = "bound.parquet"
MISSION_CSV = "mission.csv"  # a CSV mission's copy, named by the run's scenario.toml
MISSION_ULOG = "mission.ulg"  # a ULog mission's copy


def log_frame(log: dict, columns: list[str]) -> pd.DataFrame:
    """The per-step log as a DataFrame with the documented column order."""
    missing = [c for c in columns if c not in log]
    if missing:
        raise ValueError(f"the mission log lacks the columns {missing} of its vehicle")
    df = pd.DataFrame({c: log[c] for c in columns})
    df["jammer_on"] = df["jammer_on"].astype(bool)
    df["qp_status"] = df["qp_status"].astype(str)
    df["qp_ok"] = df["qp_ok"].astype(bool)
    df["fallback"] = df["fallback"].astype(bool)
    df["safety_violation"] = df["safety_violation"].astype(bool)
    return df


def write_bound_files(bound, out: Path) -> dict:
    """``bound.parquet`` (time series) and ``bound.json`` (summary) into ``out``; returns the summary."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    bound.frame().to_parquet(out / BOUND_PARQUET, index=False)
    summary = bound.summary()
    (out / BOUND_JSON).write_text(json.dumps(summary, indent=2))
    return summary


def publish_run(out: Path, scenario_toml: str, timeseries: pd.DataFrame, metrics: dict, *, bound=None,
                extra: Callable[[Path], None] | None = None) -> None:
    """Write scenario.toml, timeseries.parquet, metrics.json (+ the bound's files, + what ``extra``
    writes, e.g. figures) into a temporary sibling folder, which then replaces ``out`` (only if
    ``out`` is one of the program's own run folders, ``store.outputs``): an interrupted write never
    leaves a half-finished run folder behind, and nobody else's files are ever deleted."""
    out = Path(out)
    tmp = new_sibling(out)
    try:
        (tmp / SCENARIO_FILE).write_text(scenario_toml)
        timeseries.to_parquet(tmp / TIMESERIES_FILE, index=False)
        (tmp / METRICS_FILE).write_text(json.dumps(metrics, indent=2))
        if bound is not None:
            write_bound_files(bound, tmp)
        if extra is not None:
            extra(tmp)
        swap_in(tmp, out, "run")
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
