"""Reading a run folder back (``report``, ``export``, ``compare``): each file checked as it is read,
so a damaged or hand-edited folder is a named error (``OutputError`` naming the file and what is
wrong, and how to fly the run again), never a traceback."""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

import pandas as pd

from ..assembly import parse_scenario
from ..config import Scenario, ScenarioError
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
    """``timeseries.parquet`` of a run folder (``columns`` only, when given); OutputError naming the
    file when it is missing, damaged or lacks a column."""
    folder = Path(folder)
    f = folder / TIMESERIES_FILE
    if not f.is_file():
        raise OutputError(f"{f}: missing: the run's time series is not there; {_again(folder)}")
    try:
        return pd.read_parquet(f, columns=columns)
    except Exception as exc:  # pyarrow raises many kinds for a damaged file or a missing column
        raise OutputError(f"{f}: not readable as the run's time series ({type(exc).__name__}: {str(exc)[:200]}); "
                          f"{_again(folder)}") from None


def read_scenario(folder: str | Path) -> Scenario:
    """``scenario.toml`` of a run folder, validated; OutputError naming the file when it is missing or invalid."""
    folder = Path(folder)
    f = folder / SCENARIO_FILE
    try:
        return parse_scenario(tomllib.loads(f.read_text()))
    except FileNotFoundError:
        raise OutputError(f"{f}: missing (not an aerorelay run folder)") from None
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError, ScenarioError) as exc:
        raise OutputError(f"{f}: not a valid scenario ({type(exc).__name__}: {str(exc)[:300]})") from None


def vehicle_paths(df: pd.DataFrame) -> tuple[dict[str, pd.DataFrame], dict[str, pd.DataFrame]]:
    """The relays' and the sources' paths in a run's time series, ``({name: x, y, z}, {name: x, y, z})``,
    whichever log vocabulary it has: one relay's (``p1_*`` the relay, ``p2_*`` the source) or a fleet's
    (``<node>.p_*``; a relay also logs ``<node>.qp_ok``)."""
    xyz = ("x", "y", "z")
    if "p1_x" in df:
        return {"relay": df[[f"p1_{a}" for a in xyz]]}, {"source": df[[f"p2_{a}" for a in xyz]]}
    names = [c[: -len(".p_x")] for c in df.columns if c.endswith(".p_x")]
    relays = {n: df[[f"{n}.p_{a}" for a in xyz]] for n in names if f"{n}.qp_ok" in df}
    sources = {n: df[[f"{n}.p_{a}" for a in xyz]] for n in names if f"{n}.qp_ok" not in df}
    return relays, sources
