"""Loading a scenario: TOML text, ``--set`` overrides, user trajectory files; validated as data
(``config``), then checked with physics (``checks``) and for the parts it needs (``build``), with
named errors."""

from __future__ import annotations

import logging
import tomllib
from pathlib import Path

from ..config import Scenario, ScenarioError, validate_config
from ..config.applies import dormant, dotted, refusal
from ..config.errors import did_you_mean, is_field
from ..config.scenario import WGS84_SUFFIX
from ..filecheck import not_a_file
from .checks import check_physics
from .parts import check_buildable

log = logging.getLogger(__name__)


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
    why = not_a_file(path)
    if why is not None and why != "no such file" and why != "a folder, not a file":  # those two: said by the caller
        raise ScenarioError(f"{path}: {why}: scenario files are TOML files")
    if path.is_file() and path.stat().st_size > SCENARIO_MAX_BYTES:
        raise ScenarioError(f"{path}: {path.stat().st_size:,} bytes, more than a scenario file holds (at most "
                            f"{SCENARIO_MAX_BYTES // 2**20} MiB of TOML)")
    return path.read_text(encoding="utf-8")


def _apply_to_data(data: dict, updates: dict, unset: list[str]) -> None:
    """Dotted-key ``updates`` set and ``unset`` keys removed in a file's raw tables, before validation
    (a file that is invalid alone may be made valid by them); a key that walks into a value that is not
    a table (or a list index out of range) is a ScenarioError naming it."""
    def walk(key: str, create: bool):
        node: object = data
        parts = key.split(".")
        for depth, part in enumerate(parts[:-1]):
            if isinstance(node, list) and part.isdigit() and int(part) < len(node):
                node = node[int(part)]
            elif isinstance(node, list):
                table = ".".join(parts[:depth])
                raise ScenarioError(f"{key}: the file lists {len(node)} [[{table}]] (numbered 0 to {len(node) - 1}); "
                                    f"{table}.{part} is not one of them (an item by its number, from 0)")
            elif isinstance(node, dict):
                if part not in node:
                    if not create:
                        return None, parts[-1]
                    node[part] = {}
                node = node[part]
            else:
                raise ScenarioError(f"{key}: {parts[depth - 1]!r} is not a table of the scenario here")
        if not isinstance(node, dict | list):
            raise ScenarioError(f"{key}: {parts[-2]!r} is not a table of the scenario here")
        return node, parts[-1]
    for key in unset:
        node, last = walk(key, create=False)
        if isinstance(node, dict) and last in node:
            node.pop(last)
        elif isinstance(node, list) and last.isdigit() and int(last) < len(node):
            node.pop(int(last))
        else:  # nothing removed: an unknown field is an error (as --set's), a known one the file leaves out is said
            loc = tuple(int(p) if p.isdigit() else p for p in key.split("."))
            if not is_field(loc, Scenario):
                raise ScenarioError(f"--unset {key}: not a field of the scenario{did_you_mean(loc, Scenario)}")
            log.warning("--unset %s: the file does not write it: nothing removed (its default applies)", key)
    for key, value in updates.items():
        node, last = walk(key, create=True)
        if isinstance(node, list) and last.isdigit() and int(last) < len(node):
            node[int(last)] = value
        elif isinstance(node, dict):
            node[last] = value
            # a position set at lat/lon replaces the file's local one, and the other way round (the same field)
            other = last.removesuffix(WGS84_SUFFIX) if last.endswith(WGS84_SUFFIX) else last + WGS84_SUFFIX
            if key[: len(key) - len(last)] + other not in updates:  # both set: refused by name at validation
                node.pop(other, None)
        else:
            raise ScenarioError(f"{key}: not a field of the scenario here")


def load_scenario(path: str | Path, set: dict | list[str] | None = None,  # noqa: A002 (the API's word)
                  unset: list[str] | None = None) -> Scenario:
    """Load a TOML scenario file with ``set`` (dotted keys -> values, or ``"key=value"`` strings as on
    the command line) applied and ``unset`` keys removed (e.g. ``["jammer.position"]``), then validate
    it once: updates can make a file valid that is not alone. Raises ScenarioError naming each bad field."""
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
    resolve_files(data, path.parent)
    updates = parse_sets(set) if isinstance(set, list) else dict(set or {})
    _apply_to_data(data, updates, list(unset or []))
    try:
        sc = validate_config(data)
    except RecursionError:
        raise ScenarioError(f"{path}: tables nested too deeply to be a scenario") from None
    _what_does_not_apply(sc, path, updates)
    return check_buildable(check_physics(sc))


def resolve_files(data: dict, folder: Path) -> None:
    """The files a scenario's plain ``data`` names (missions, jammer tracks, a scene, buildings) made absolute,
    relative to ``folder`` (the scenario file's): a run folder's copies re-open from anywhere."""
    given = data.get("sources")
    sources: list = given if isinstance(given, list) else []  # a wrong type is named by validation
    missions = [data.get("mission")] + [s.get("mission") for s in sources if isinstance(s, dict)]
    jammers = [data.get("jammer")] + (data["jammers"] if isinstance(data.get("jammers"), list) else [])
    for mission in (m for m in missions + jammers if isinstance(m, dict)):  # files are named relative to the scenario file
        for key in ("trajectory_csv", "trajectory_ulog", "trajectory_plan", "trajectory_gpx"):
            f = mission.get(key)
            if isinstance(f, str) and f and not Path(f).is_absolute():
                mission[key] = str((folder / f).resolve())
    channel = data.get("channel")
    prop = channel.get("propagation") if isinstance(channel, dict) else None
    if isinstance(prop, dict) and isinstance(prop.get("scene"), str):  # a scene file is named relative to the scenario file
        scene = Path(prop["scene"])
        if scene.suffix.lower() == ".xml" and not scene.is_absolute():
            prop["scene"] = str((folder / scene).resolve())
    buildings = data.get("buildings")
    if isinstance(buildings, dict) and isinstance(buildings.get("geojson"), str):  # relative to the scenario file
        f = Path(buildings["geojson"])
        if not f.is_absolute():
            buildings["geojson"] = str((folder / f).resolve())


def _what_does_not_apply(sc: Scenario, path: Path | None, updates: dict) -> None:
    """``config.applies``: a setting that changes nothing here is refused by name when the file alone says it or an
    update sets it; one of the file's made dormant by an update that switches what applies is named in a warning."""
    keys = {".".join(dotted(k)) for k in updates}
    for field, where, value, default in dormant(sc):
        name = ".".join(dotted(field))
        if not updates or any(name == k or name.startswith(k + ".") for k in keys):  # the update wrote it (or its table)
            raise ScenarioError(refusal(field, where, value, default))
        log.warning("%s: %s = %r (from the file) applies only where %s: with %s it changes nothing", path, field, value,
                    where, ", ".join(f"{k}={v!r}" for k, v in updates.items()))


def apply_updates(data: dict, updates: dict) -> None:
    """Dotted-key ``updates`` (as ``--set`` gives them) written into a scenario's plain ``data`` before it is validated."""
    _apply_to_data(data, updates, [])


def parse_scenario(data: dict) -> Scenario:
    """Validate a scenario from a plain dict (as data, then its physics checks); raises
    ScenarioError with one line per problem (a setting that changes nothing here too: ``config.applies``)."""
    sc = validate_config(data)
    _what_does_not_apply(sc, None, {})
    return check_physics(sc)


def updated(sc: Scenario, updates: dict) -> Scenario:
    """``sc`` with dotted-key ``updates`` (``Scenario.with_updates``), checked like a loaded
    scenario: data, physics, the parts it needs."""
    return check_buildable(check_physics(sc.with_updates(updates)))
