"""A run folder: the files one mission writes, published atomically (a finished folder is complete)."""

from __future__ import annotations

import logging
import os
import shutil
from collections.abc import Callable, Mapping
from pathlib import Path

import pandas as pd

from . import strict_json
from .outputs import new_sibling, swap_in, write_atomic

log = logging.getLogger(__name__)

SCENARIO_FILE = "scenario.toml"
TIMESERIES_FILE = "timeseries.parquet"
METRICS_FILE = "metrics.json"
BOUND_JSON = "bound.json"
BOUND_PARQUET = "bound.parquet"
MISSION_CSV = "mission.csv"  # a CSV mission's copy, named by the run's scenario.toml
MISSION_ULOG = "mission.ulg"  # a ULog mission's copy


def log_frame(log: dict, columns: list[str], types: dict[str, type]) -> pd.DataFrame:
    """The per-step log as a DataFrame with the documented column order, the columns named in
    ``types`` cast to theirs (the rest are floats)."""
    missing = [c for c in columns if c not in log]
    if missing:
        raise ValueError(f"the mission log lacks the columns {missing} of its vehicle")
    df = pd.DataFrame({c: log[c] for c in columns})
    for name, kind in types.items():
        df[name] = df[name].astype(kind)
    return df


def write_bound_files(bound, out: Path) -> dict:
    """``bound.parquet`` (time series) and ``bound.json`` (summary) into ``out``; returns the summary."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    bound.frame().to_parquet(out / BOUND_PARQUET, index=False)
    summary = bound.summary()
    (out / BOUND_JSON).write_text(strict_json.dumps(summary, indent=2))
    return summary


def publish_run(out: Path, scenario_toml: str, timeseries: pd.DataFrame, metrics: dict, *,
                extra: Callable[[Path], None] | None = None) -> None:
    """Write scenario.toml, timeseries.parquet, metrics.json (strict JSON) (+ what ``extra`` writes:
    a mission file's copy) into a temporary sibling folder, which then replaces ``out`` (only if ``out``
    is one of the program's own run folders, ``store.outputs``): an interrupted write never leaves a
    half-finished run folder behind, and nobody else's files are ever deleted."""
    out = Path(out)
    tmp = new_sibling(out)
    try:
        (tmp / SCENARIO_FILE).write_text(scenario_toml)
        timeseries.to_parquet(tmp / TIMESERIES_FILE, index=False)
        (tmp / METRICS_FILE).write_text(strict_json.dumps(metrics, indent=2))
        if extra is not None:
            extra(tmp)
        swap_in(tmp, out, "run")
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


OPTIONAL_FAILED = "optional_outputs_failed"  # metrics.json: optional output -> why it is missing


def add_optional(out: Path, writers: Mapping[str, Callable[[Path], object]], metrics: dict) -> dict[str, str]:
    """Add optional outputs to the published run folder ``out``, each written by its writer into a
    temporary sibling and moved in only when complete: one that fails (a full disk, a figure's
    error) is logged and named in metrics.json (``optional_outputs_failed``, rewritten atomically)
    and never costs the run. Returns the failures (output -> reason)."""
    out = Path(out)
    failed: dict[str, str] = {}
    for name, write in writers.items():
        tmp = new_sibling(out)
        try:
            write(tmp)
            for f in sorted(tmp.iterdir()):
                os.replace(f, out / f.name)
        except Exception as exc:  # optional: reported, never fatal
            failed[name] = f"{type(exc).__name__}: {exc}"
            log.warning("run folder %s: %s not written (%s); the run itself is saved", out, name, failed[name])
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
    if failed:
        metrics[OPTIONAL_FAILED] = {**metrics.get(OPTIONAL_FAILED, {}), **failed}
        try:
            write_atomic(out / METRICS_FILE, strict_json.dumps(metrics, indent=2))
        except OSError as exc:
            log.warning("run folder %s: could not record the missing outputs in %s (%s)", out, METRICS_FILE, exc)
    return failed
