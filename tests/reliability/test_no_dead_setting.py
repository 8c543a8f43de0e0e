"""No dead setting (issue 60, item 4), for every field of a relay's own controller (``[relays.controller]``, generated
from the schema, not a hand list): written for one relay of a two-relay chain, each field either changes what is built
(``fingerprint``) under at least one network planner, or is refused by name, or is in ``DESCRIPTIVE`` (reviewed).
Before 2026-12-05 ``[relays.controller.capacity] speed_m_s`` was accepted and changed nothing any network planner
built. Not yet checked here: a field honoured under one planner but silently unused under another. Below it, the rest
of the schema in the one-relay preset and the chain: a sample on every run (another each day), all of it with
``AERORELAY_AUDIT=1``."""

from __future__ import annotations

import datetime
import functools
import os
import random
import typing

import pytest
from pydantic import BaseModel

import aerorelay as ar
from aerorelay.assembly.parts import build
from aerorelay.config import ScenarioError
from aerorelay.config.controller import ControllerConfig

from .fingerprint import fingerprint

CHAIN = "scenarios/chain_two_relays.toml"
PLANNERS = ("capacity", "trajectory_generator", "equidistant")
DESCRIPTIVE: frozenset[str] = frozenset()  # fields that describe and change nothing built (reviewed): none yet


def leaves(model: type[BaseModel], prefix: tuple[str, ...] = ()):
    for name, f in model.model_fields.items():
        ann = f.annotation
        if isinstance(ann, type) and issubclass(ann, BaseModel):
            yield from leaves(ann, (*prefix, name))
        else:
            yield (*prefix, name), f


def bounds(f) -> tuple[float, float]:
    lo, hi = -1e9, 1e9
    for m in f.metadata:
        lo = max(lo, getattr(m, "ge", None) if getattr(m, "ge", None) is not None else lo)
        hi = min(hi, getattr(m, "le", None) if getattr(m, "le", None) is not None else hi)
        if getattr(m, "gt", None) is not None:
            lo = max(lo, m.gt + 1e-9)
    return lo, hi


def changed(path: tuple[str, ...], f, shared) -> object:
    """A valid value other than the shared one."""
    ann = f.annotation
    if typing.get_origin(ann) is typing.Literal:
        return next(v for v in typing.get_args(ann) if v != shared)
    literal = next((a for a in typing.get_args(ann) if typing.get_origin(a) is typing.Literal), None)  # Literal | None
    if literal is not None:
        return next(v for v in typing.get_args(literal) if v != shared)
    if ann is bool:
        return not shared
    if path[-1] == "planner":
        return "capacity"
    if path[0] == "workspace":
        return [shared[0] - 1.0 if path[-1] == "min" else shared[0] + 1.0, *shared[1:]]
    if isinstance(shared, str):
        return shared + "x"
    if isinstance(shared, list) and shared and all(isinstance(v, (int, float)) for v in shared):
        return [shared[0] + 1.0, *shared[1:]]
    if isinstance(shared, list) and shared and all(isinstance(v, list) and v and isinstance(v[-1], (int, float)) for v in shared):
        return [*shared[:-1], [*shared[-1][:-1], shared[-1][-1] + 1.0]]  # the last waypoint 1 m higher
    if isinstance(shared, list) and shared and all(isinstance(v, list) and len(v) > 3 for v in shared):
        return [[v[0], *reversed(v[1:-1]), v[-1]] for v in shared]  # each route's relays in the other order
    if isinstance(shared, list) and all(isinstance(v, str) for v in shared):
        return [*shared, "a part passed from Python"]
    lo, hi = bounds(f)
    if ann is int:
        return shared + 1 if shared + 1 <= hi else shared - 1
    base = shared if shared is not None else min(max(1.0, lo), hi)
    if shared is None:
        return base
    new = base * 0.7 if base > 0 else min(0.5, hi)
    return new if lo <= new <= hi else min(base * 1.3, hi)


FIELDS = [(p, f) for p, f in leaves(ControllerConfig)]


QUICK = {"network.route": False, "bound.max_minutes": 60.0}  # no pre-flight route: the planners' settings are built alike


@functools.cache
def base_fingerprint(planner: str) -> str:
    return fingerprint(build(ar.load_scenario(CHAIN, set={**QUICK, "controller.planner": planner})))


@pytest.mark.parametrize("path", [".".join(p) for p, _ in FIELDS])
def test_no_relay_setting_is_dead(path):
    shared = ar.load_scenario(CHAIN).controller
    dead, unnamed = [], []
    for path_, f in FIELDS:
        if ".".join(path_) != path:
            continue
        path = path_  # noqa: PLW2901
        name = ".".join(path)
        value = getattr(shared, path[0])
        for part in path[1:]:
            value = getattr(value, part)
        new = changed(path, f, value)
        alive = False
        for planner in PLANNERS:
            key = f"relays.0.controller.{name}"
            try:
                sc = ar.load_scenario(CHAIN, set={**QUICK, "controller.planner": planner, key: new})
            except ScenarioError as exc:
                if f"relays[0].controller.{name}" not in str(exc) and f"controller.{name}" not in str(exc):
                    unnamed.append(f"{name}: {exc}")
                alive = True
                break
            if fingerprint(build(sc)) != base_fingerprint(planner):
                alive = True
                break
        if not alive and name not in DESCRIPTIVE:
            dead.append(f"{name} = {new!r}")
    assert not unnamed, f"refused without naming the field: {unnamed}"
    assert not dead, f"accepted and changing nothing any network planner builds: {dead}"


def test_the_fingerprint_is_one_per_file_and_sees_a_relays_speed_limit():
    a = fingerprint(build(ar.load_scenario(CHAIN)))
    assert fingerprint(build(ar.load_scenario(CHAIN))) == a
    assert fingerprint(build(ar.load_scenario(CHAIN, set={"description": "words"}))) == a
    assert fingerprint(build(ar.load_scenario(CHAIN, set={"relays.0.controller.capacity.speed_m_s": 0.4}))) != a


@pytest.mark.parametrize("path", [".".join(p) for p, _ in FIELDS])
def test_each_relay_field_has_a_changed_value_the_schema_accepts(path):
    f = dict((".".join(p), f) for p, f in FIELDS)[path]
    shared = ar.load_scenario(CHAIN).controller
    value = shared
    for part in path.split("."):
        value = getattr(value, part)
    assert changed(tuple(path.split(".")), f, value) != value


# --- the rest of the schema (issue 60, item 4): every leaf of every section but the relays' controllers (above), the
# platform (its fields rebuild the NMPC: `python -m tests.reliability.test_no_dead_setting` audits them from the command
# line) and the lists of nodes, in the one-relay nominal preset and in the chain: honoured (what is built or bounded
# changes), refused by name (config.applies: it does not apply there), or reviewed below.
SCHEMA_CONTEXTS = {"one": ("scenarios/nominal_tilted.toml", {}), "chain": (CHAIN, QUICK)}
SECTIONS_ELSEWHERE = {"relays", "sources", "base_stations", "controller", "platform", "jammers", "obstacles", "buildings"}
REVIEWED = {  # what changes nothing built, and why that is right (reviewed 2026-12-06)
    "name": "a label", "description": "a label", "seed": "the runs' random streams (their draws, not what is built)",
    "bound.max_minutes": "a limit on the bound's work, not what it is",
    "sim.max_minutes": "a limit on the flight's work (refused above it, before it starts), not what is flown",
    "world.mission_max_distance_m": "a load check's threshold (a mission farther is refused)",
    "network.route": "the capacity planner's pre-flight route: the chain here flies the equidistant planner",
    "channel.propagation.model": "'log_distance' at its defaults (n = 2, d0 = 1 m, PL(d0) of free space) is free space",
    "injected": "written by a run flown with parts passed from Python: names what the file cannot say (run folders)",
    "verdict.fallback_fraction_max": "the verdict's threshold: what a run reads (fell_back), not what is flown",
}


def _schema_leaves():
    from aerorelay.config.scenario import Scenario

    def model_of(ann):
        if isinstance(ann, type) and issubclass(ann, BaseModel):
            return ann
        return next((a for a in typing.get_args(ann) if isinstance(a, type) and issubclass(a, BaseModel)), None)

    def walk(model, prefix):
        for name, f in model.model_fields.items():
            m = model_of(f.annotation)
            listed = typing.get_origin(f.annotation) is list or any(typing.get_origin(a) is list for a in typing.get_args(f.annotation))
            if m is not None and not listed:
                yield from walk(m, (*prefix, name))
            else:
                yield (*prefix, name), f

    return [(p, f) for p, f in walk(Scenario, ()) if p[0] not in SECTIONS_ELSEWHERE]


SCHEMA = _schema_leaves()


def _built(sc) -> str:
    from aerorelay.assembly.parts import bound_problem, network_bound_problem

    bound = network_bound_problem(sc) if sc.shape.bound == "network" else bound_problem(sc)
    return fingerprint((build(sc), bound, sc.duration_s, sc.seed))


@functools.cache
def _base_built(ctx: str) -> str:
    path, quick = SCHEMA_CONTEXTS[ctx]
    return _built(ar.load_scenario(path, set=quick))


EVERY = [(".".join(p), ctx) for p, _ in SCHEMA for ctx in sorted(SCHEMA_CONTEXTS)]
AUDIT_SAMPLE = 16  # settings x contexts audited on every run (the whole audit: AERORELAY_AUDIT=1, about 2 min on 2 cores)
# every run audits a sample, another each day (CI included); the whole of it from the command line, nightly:
#   AERORELAY_AUDIT=1 python -m pytest tests/reliability/test_no_dead_setting.py
AUDIT = EVERY if os.environ.get("AERORELAY_AUDIT") else sorted(
    random.Random(datetime.date.today().toordinal()).sample(EVERY, min(AUDIT_SAMPLE, len(EVERY))))


@pytest.mark.parametrize("path,ctx", AUDIT)
def test_no_setting_of_the_schema_is_dead(path, ctx):
    file, quick = SCHEMA_CONTEXTS[ctx]
    p, f = next((p, f) for p, f in SCHEMA if ".".join(p) == path)
    base = ar.load_scenario(file, set=quick)
    value: object = base
    for part in p:
        value = getattr(value, part, None)
    if value is None and p[0] in ("jammer", "mission", "nodes", "geo", "wind", "buildings") and getattr(base, p[0], 0) is None:
        pytest.skip(f"[{p[0]}] is not in this file")
    new = changed(p, f, value)
    try:
        sc = ar.load_scenario(file, set={**quick, path: new})
    except ScenarioError as exc:  # named: the field, or its section when the section does not apply here
        assert p[-1] in str(exc) or str(exc).startswith(f"{'.'.join(p[:-1])}:"), f"{path} = {new!r} refused unnamed: {exc}"
        return
    if _built(sc) == _base_built(ctx):
        assert path in REVIEWED, f"{path} = {new!r} accepted in {file} and changes nothing built, bounded or flown"
