"""Reading a run folder back (``report``, ``export``, ``compare``): each file checked as it is read,
so a damaged or hand-edited folder is a named error (``OutputError`` naming the file and what is
wrong, and how to fly the run again), never a traceback."""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow.parquet as pq

from ..assembly import parse_scenario
from ..assembly.load import resolve_files
from ..config import Scenario, ScenarioError
from ..filecheck import not_a_file
from ..sim.log_schema import modern_columns, relays_in, sources_in
from ..sim.units import metric_value_problem
from ..store.outputs import OutputError
from ..store.run_folder import METRICS_FILE, SCENARIO_FILE, TIMESERIES_FILE


def _again(folder: Path) -> str:
    return f"fly it again: aerorelay run {folder / SCENARIO_FILE} --out NEW_FOLDER"


def read_metrics(folder: str | Path) -> dict:
    """``metrics.json`` of a run folder: a JSON object whose quantities are numbers (or null);
    OutputError naming the file and the first bad entry otherwise."""
    folder = Path(folder)
    f = folder / METRICS_FILE
    why = not_a_file(f)
    if why is not None and why != "no such file":  # a FIFO would block the read, a loop raise
        raise OutputError(f"{f}: {why}: not an aerorelay run folder's metrics")
    try:
        m = json.loads(f.read_text())
    except FileNotFoundError:
        raise OutputError(f"{f}: missing (not an aerorelay run folder, or its run did not finish)") from None
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise OutputError(f"{f}: not readable JSON ({type(exc).__name__}: {exc}): the file is damaged; {_again(folder)}") from None
    if not isinstance(m, dict):
        raise OutputError(f"{f}: not a metrics object (a JSON {type(m).__name__}); {_again(folder)}")
    bad = metric_value_problem(m)
    if bad is not None:
        raise OutputError(f"{f}: {bad} is not a number (the file was edited or damaged); {_again(folder)}")
    return m


def read_timeseries(folder: str | Path, columns: list[str] | None = None) -> pd.DataFrame:
    """``timeseries.parquet`` of a run folder (``columns`` only, when given) in the one log vocabulary
    (``sim.log_schema``): a folder written before it (one relay's ``p1_x``, ``gamma_21``...) is read
    through ``modern_columns``, its route's ``capacity.source`` and its ``separation_min`` (the relay to
    the source, m) derived; OutputError naming the file when it is missing, damaged or lacks a column."""
    folder = Path(folder)
    f = folder / TIMESERIES_FILE
    why = not_a_file(f)
    if why is not None:
        raise OutputError(f"{f}: {'missing' if why == 'no such file' else why}: the run's time series is not there; "
                          f"{_again(folder)}")
    try:
        names = pq.read_schema(f).names
        rename = modern_columns(names)
        if not rename:
            return pd.read_parquet(f, columns=columns)
        back = {new: old for old, new in rename.items()}
        derived = {"capacity.source", "separation_min"}
        wanted = None if columns is None else list(dict.fromkeys(
            [back.get(c, c) for c in columns if c not in derived]
            + (["capacity"] if "capacity.source" in columns else [])
            + ([f"p{i}_{a}" for i in (1, 2) for a in "xyz"] if "separation_min" in columns else [])))
        df = pd.read_parquet(f, columns=wanted)
    except Exception as exc:  # pyarrow raises many kinds for a damaged file or a missing column
        raise OutputError(f"{f}: not readable as the run's time series ({type(exc).__name__}: {str(exc)[:200]}); "
                          f"{_again(folder)}") from None
    if "capacity" in df:
        df["capacity.source"] = df["capacity"]
    if "p1_x" in df and "p2_x" in df:
        df["separation_min"] = np.linalg.norm(df[[f"p1_{a}" for a in "xyz"]].to_numpy() - df[[f"p2_{a}" for a in "xyz"]].to_numpy(),
                                              axis=1)
    df = df.rename(columns=rename)
    return df if columns is None else df[columns]


def read_scenario(folder: str | Path) -> Scenario:
    """``scenario.toml`` of a run folder, validated; OutputError naming the file when it is missing or invalid."""
    folder = Path(folder)
    f = folder / SCENARIO_FILE
    why = not_a_file(f)
    if why is not None and why != "no such file":
        raise OutputError(f"{f}: {why}: not an aerorelay run folder's scenario")
    try:
        data = tomllib.loads(f.read_text())
        resolve_files(data, folder)  # its copied files (mission.csv, ...) beside it, wherever it is read from
        return parse_scenario(data)
    except FileNotFoundError:
        raise OutputError(f"{f}: missing (not an aerorelay run folder)") from None
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError, ScenarioError) as exc:
        raise OutputError(f"{f}: not a valid scenario ({type(exc).__name__}: {str(exc)[:300]})") from None


def vehicle_paths(df: pd.DataFrame) -> tuple[dict[str, pd.DataFrame], dict[str, pd.DataFrame]]:
    """The relays' and the sources' paths in a run's time series (``read_timeseries``'s vocabulary),
    ``({name: x, y, z}, {name: x, y, z})``."""
    xyz = ("x", "y", "z")
    return ({n: df[[f"{n}.p_{a}" for a in xyz]] for n in relays_in(df.columns)},
            {n: df[[f"{n}.p_{a}" for a in xyz]] for n in sources_in(df.columns)})
