"""Loading a scenario: TOML text, ``--set`` overrides, user trajectory files; validated as data
(``config``), then checked with physics (``checks``) and for the parts it needs (``build``), with
named errors."""

from __future__ import annotations

import tomllib
from pathlib import Path

from ..config import Scenario, ScenarioError, validate_config
from .checks import check_physics
from .parts import check_buildable


def parse_sets(items: list[str] | None) -> dict:
    """``["a.b=1", "c=[1, 2]"]`` -> ``{"a.b": 1, "c": [1, 2]}``: values parsed as TOML (a bare word
    that is not TOML is taken as a string); a malformed item raises ScenarioError naming it."""
    out = {}
    for item in items or []:
        key, sep, text = item.partition("=")
        if not sep or not key.strip():
            raise ScenarioError(f"--set {item!r}: write dotted.key=value")
        try:
            value = tomllib.loads(f"v = {text.strip()}")["v"]
        except tomllib.TOMLDecodeError:
            value = text.strip()
        out[key.strip()] = value
    return out


SCENARIO_MAX_BYTES = 4 * 2**20  # a scenario is a small TOML file: a larger one is refused before it is read


def _scenario_text(path: Path) -> str:
    """The scenario file's text: a regular file (not a device such as /dev/zero, a FIFO that may never
    end, or a socket) of at most ``SCENARIO_MAX_BYTES``; ScenarioError naming it otherwise."""
    if path.exists() and not path.is_dir() and not path.is_file():
        raise ScenarioError(f"{path}: not a regular file (a device, a FIFO or a socket): scenario files are TOML files")
    if path.is_file() and path.stat().st_size > SCENARIO_MAX_BYTES:
        raise ScenarioError(f"{path}: {path.stat().st_size:,} bytes, more than a scenario file holds (at most "
                            f"{SCENARIO_MAX_BYTES // 2**20} MiB of TOML)")
    return path.read_text(encoding="utf-8")


def load_scenario(path: str | Path, set: dict | list[str] | None = None) -> Scenario:  # noqa: A002 (the API's word)
    """Load and validate a TOML scenario file, then apply ``set`` (dotted keys -> values, or
    ``"key=value"`` strings as on the command line); raises ScenarioError naming each bad field."""
    path = Path(path)
    try:
        data = tomllib.loads(_scenario_text(path))
    except FileNotFoundError:
        raise ScenarioError(f"{path}: no such scenario file") from None
    except IsADirectoryError:
        raise ScenarioError(f"{path}: is a folder, not a scenario file") from None
    except UnicodeDecodeError as exc:
        raise ScenarioError(f"{path}: not UTF-8 text (byte {exc.start}): scenario files are UTF-8 TOML") from None
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{path}: not valid TOML: {exc}") from None
    except RecursionError:
        raise ScenarioError(f"{path}: tables nested too deeply to be a scenario") from None
    given = data.get("sources")
    sources: list = given if isinstance(given, list) else []  # a wrong type is named by validation
    missions = [data.get("mission")] + [s.get("mission") for s in sources if isinstance(s, dict)]
    for mission in (m for m in missions if isinstance(m, dict)):  # mission files are named relative to the scenario file
        for key in ("trajectory_csv", "trajectory_ulog"):
            f = mission.get(key)
            if isinstance(f, str) and f and not Path(f).is_absolute():
                mission[key] = str((path.parent / f).resolve())
    try:
        sc = validate_config(data)
    except RecursionError:
        raise ScenarioError(f"{path}: tables nested too deeply to be a scenario") from None
    updates = parse_sets(set) if isinstance(set, list) else (set or {})
    if updates:
        sc = sc.with_updates(updates)
    return check_buildable(check_physics(sc))


def parse_scenario(data: dict) -> Scenario:
    """Validate a scenario from a plain dict (as data, then its physics checks); raises
    ScenarioError with one line per problem."""
    return check_physics(validate_config(data))


def updated(sc: Scenario, updates: dict) -> Scenario:
    """``sc`` with dotted-key ``updates`` (``Scenario.with_updates``), checked like a loaded
    scenario: data, physics, the parts it needs."""
    return check_buildable(check_physics(sc.with_updates(updates)))
