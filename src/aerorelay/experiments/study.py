"""A study: a base scenario plus a declarative set of variations, expanded into runs.

A study TOML names a ``base`` scenario (a path relative to the folder above the studies folder: the
repository root for ``experiments/``; an absolute path as it is), a list of
``[[runs]]`` (an id and dotted-key ``set`` updates), an optional ``[grid]`` whose cartesian
product multiplies the runs, ``seeds`` Monte Carlo repetitions, and ``[[paper]]`` reference
numbers, and ``[[claims]]``: the paper's qualitative claims as conditions on the study's
metrics (see ``Claim``), judged in the report. ``--quick`` shortens missions to ``quick_duration_s`` and uses ``quick_seeds`` seeds.
A run without any random element (no finite-K fading, no CSI or process noise) is flown once,
whatever ``seeds`` says: its repetitions would be identical.
"""

from __future__ import annotations

import hashlib
import itertools
import logging
import math
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from ..assembly import load_scenario, parse_scenario, updated
from ..config import Scenario, ScenarioError
from ..filecheck import not_a_file

MAX_RUNS = 10_000  # runs one study may make (a 216,000-run grid spent minutes validating before any output)

log = logging.getLogger(__name__)


class StudyError(ValueError):
    """A study file is invalid or names something that does not exist."""


class RunVariation(BaseModel):
    """One run group: ``set`` dotted-key updates on the study's base, or on its own ``base``
    scenario (relative to the folder above the studies folder, as the study's own ``base``)."""

    model_config = ConfigDict(extra="forbid")
    id: str = Field(min_length=1, max_length=100, description="the group's name: its runs' folders and the claims' metric@id")
    set: dict[str, Any] = Field(default_factory=dict, description="dotted-key updates on the scenario, as --set")
    base: str | None = Field(None, description="this group's own scenario file (default the study's base), relative to "
                             "the folder above the studies folder")

    @field_validator("id")
    @classmethod
    def _a_folder_name(cls, v: str) -> str:
        """A run id names its folder: no path separator, control character, or ``.``/``..``."""
        if v in (".", "..") or any(c in v for c in "/\\") or any(ord(c) < 32 for c in v):
            raise ValueError(f"run id {v!r} must not be '.' or '..' nor hold '/', '\\' or control characters "
                             "(it names the run's folder)")
        return v


class PaperValue(BaseModel):
    """A number the paper reports, shown beside the run's in the report."""

    model_config = ConfigDict(extra="forbid")
    run: str = Field(description="the run group (its id) the number compares with")
    metric: str = Field(description="the metric of metrics.json (dotted for a table's entry)")
    value: float = Field(description="the paper's value, in the metric's unit")
    note: str = Field("", description="where it comes from or what differs")


def parse_term(text: str) -> list[tuple[str, str]]:
    """``"metric@group"`` or ``"metric@group / metric@group"`` -> ``[(group, metric), ...]``."""
    parts = [p.strip() for p in text.split(" / ")]
    if len(parts) > 2 or any("@" not in p for p in parts):
        raise ValueError(f"{text!r}: write metric@run or metric@run / metric@run")
    return [(p.split("@", 1)[1], p.split("@", 1)[0]) for p in parts]


class Condition(BaseModel):
    """``left op right * factor + tol``; ``left`` and ``right`` are ``metric@run`` or a ratio
    ``metric@run / metric@run``; ``value`` replaces ``right`` by a number."""

    model_config = ConfigDict(extra="forbid")
    left: str = Field(description="metric@run, or metric@run / metric@run")
    op: Literal["<", "<=", ">", ">="] = Field(description="the comparison")
    right: str | None = Field(None, description="metric@run or a ratio (or give value)")
    value: float | None = Field(None, description="a number in place of right")
    factor: float = Field(1.0, description="right is multiplied by this")
    tol: float = Field(0.0, description="then this is added to right")

    @model_validator(mode="after")
    def _one_right_side(self):
        if (self.right is None) == (self.value is None):
            raise ValueError("give exactly one of right (metric@run) and value (a number)")
        parse_term(self.left)
        if self.right is not None:
            parse_term(self.right)
        return self

    def runs(self) -> set[str]:
        terms = [self.left] + ([self.right] if self.right else [])
        return {g for t in terms for g, _ in parse_term(t)}


class Explanation(BaseModel):
    """A measured cause of a difference from the paper, computed from a run of the study
    (``report/explain.py``): ``ceiling`` (the best relay pose's capacity against ``paper``),
    ``jammer_noise`` (the jammer's interference against the noise along the run),
    ``fading`` (the fading arithmetic at the run's SNRs for each of ``k_db``)."""

    model_config = ConfigDict(extra="forbid")
    kind: Literal["ceiling", "jammer_noise", "fading"] = Field(description="which cause is measured")
    run: str = Field(description="the run group it is measured on")
    paper: float | None = Field(None, description="ceiling: the paper's number the best pose is compared with")
    k_db: list[float] = Field(default_factory=list, description="fading: the Rician K factors (dB) evaluated")
    note: str = Field("", description="text added after the measured sentence")


class Claim(BaseModel):
    """A qualitative claim of the paper, held when every condition holds. ``why``: measured causes
    shown when it does not hold; ``contradiction``: where the paper's own numbers disagree (both
    numbers, as text)."""

    model_config = ConfigDict(extra="forbid")
    text: str = Field(min_length=1, description="the claim as the paper makes it")
    all: list[Condition] = Field(min_length=1, description="the conditions that must all hold")
    why: list[Explanation] = Field(default_factory=list, description="measured causes shown when it does not hold")
    contradiction: str = Field("", description="where the paper's own numbers disagree (both numbers, as text)")


class RankingTerm(BaseModel):
    """One term of the distance to the paper: ``metric`` of the run whose pairing key is ``at``
    (divided by the one at ``over`` if given) against ``paper``; ``scale`` log: log10(ours /
    paper), rel: (ours - paper) / paper, abs: ours - paper."""

    model_config = ConfigDict(extra="forbid")
    metric: str = Field(description="the metric compared")
    at: str = Field(description="the pairing key's value of the run it is read from")
    over: str | None = Field(None, description="the pairing key's value of the run it is divided by, if any")
    paper: float = Field(description="the paper's value")
    scale: Literal["log", "rel", "abs"] = Field("log", description="log10(ours / paper), relative or absolute difference")


class Ranking(BaseModel):
    """Rank the grid's combinations (all grid keys but ``pair_key``) by their RMS distance to the
    paper's numbers."""

    model_config = ConfigDict(extra="forbid")
    pair_key: str = Field(description="the grid key whose values pair runs within a combination")
    terms: list[RankingTerm] = Field(min_length=1, description="the distance's terms")


class Tradeoff(BaseModel):
    """A trade-off figure: each run id a series (its grid groups its points), ``y[i]`` against
    ``x`` (group means), with ``bounds[i]`` (the run's capacity bound, e.g. at its speed limit)
    drawn as a dashed line in the series' colour: the front a user picks a point from."""

    model_config = ConfigDict(extra="forbid")
    x: str = Field("energy_kJ", description="the metric along x")
    y: list[str] = Field(default_factory=lambda: ["c_mean", "c_min"], min_length=1, description="the metrics along y, one "
                         "panel each")
    bounds: list[str | None] = Field(default_factory=list, description="per y, the bound summary's entry drawn dashed "
                                     "(or null)")
    title: str = Field("", description="the figure's title")

    @model_validator(mode="after")
    def _one_bound_per_y(self):
        if self.bounds and len(self.bounds) != len(self.y):
            raise ValueError(f"tradeoff.bounds has {len(self.bounds)} entries, y has {len(self.y)}: one bound (or null) per y")
        return self


class Study(BaseModel):
    """A study file (``experiments/*.toml``): run groups on a base scenario, a grid, seeds, the paper's numbers
    and claims to check, figures."""

    model_config = ConfigDict(extra="forbid")
    name: str = Field(pattern=r"^[a-z0-9_]+$", description="the study's name (aerorelay reproduce NAME)")
    title: str = Field(description="one line: what the study asks")
    description: str = Field("", description="what it does, for the report")
    base: str = Field(description="the scenario file every run starts from, relative to the folder above the studies "
                      "folder (absolute paths as they are)")
    quick_duration_s: float | None = Field(None, gt=0, description="--quick: the missions' length, s")
    runs: list[RunVariation] = Field(default_factory=lambda: [RunVariation(id="base")], description="the run groups")
    grid: dict[str, list[Any]] = Field(default_factory=dict, description="dotted keys and their values: every run group at "
                                       "every combination")
    seeds: int = Field(1, ge=1, description="Monte Carlo seeds per run (scenario seed 0, 1, ...)")
    quick_seeds: int = Field(1, ge=1, description="--quick: seeds per run")
    paper: list[PaperValue] = Field(default_factory=list, description="the paper's numbers shown beside the runs'")
    compare_trajectories: list[tuple[str, str]] = Field(default_factory=list, description="[group, group] pairs drawn in "
                                                        "one interactive 3D view")
    claims: list[Claim] = Field(default_factory=list, description="the paper's claims, checked on the runs")
    bound: bool = Field(False, description="compute each run's capacity bound: efficiency metrics and bound figures")
    bound_figures: list[list[str]] = Field(default_factory=list, description="groups drawn together with the bound of the "
                                           "first one's scenario, one figure each")
    estimation_figures: list[tuple[str, str]] = Field(default_factory=list, description="[estimated group, oracle group] "
                                                      "pairs: the estimate's error over time with its 2-sigma band, and "
                                                      "both runs' capacity")
    ranking: Ranking | None = Field(None, description="rank the grid's combinations by their distance to the paper")
    tradeoffs: list[Tradeoff] = Field(default_factory=list, description="trade-off figures")
    why: list[Explanation] = Field(default_factory=list, description="measured causes of the study's differences from "
                                   "the paper (beside the claims' own)")

    @model_validator(mode="after")
    def _a_bounded_campaign(self):
        """Every grid key has values, and the study makes at most ``MAX_RUNS`` runs (counted before any is expanded)."""
        empty = [k for k, v in self.grid.items() if not v]
        if empty:
            raise ValueError(f"grid.{empty[0]}: an empty list makes no runs; give it one value at least (or leave the key out)")
        n = len(self.runs) * math.prod(len(v) for v in self.grid.values()) * max(self.seeds, self.quick_seeds)
        if n > MAX_RUNS:
            raise ValueError(f"runs x grid x seeds make {n:,} runs, more than the {MAX_RUNS:,} a campaign takes (each is "
                             "validated before the first flies and writes its own folder); split the study or thin its grid")
        return self

    @model_validator(mode="after")
    def _unique_runs(self):
        """Two runs with one id would share a folder (the grid cannot make two groups alike: every run but
        ``base`` carries its own id before the grid's label)."""
        ids = [r.id for r in self.runs]
        twice = sorted({i for i in ids if ids.count(i) > 1})
        if twice:
            raise ValueError(f"runs: id {twice[0]!r} appears {ids.count(twice[0])} times (each run needs its own id: it names "
                             "its folder)")
        return self

    @model_validator(mode="after")
    def _references_exist(self):
        """Every run a claim, a paper value or a trajectory comparison names exists: renaming a
        run cannot drop a claim silently."""
        groups = set(group_names(self))
        named = {(f"claim {c.text!r}", g) for c in self.claims for cond in c.all for g in cond.runs()}
        named |= {(f"paper value {p.metric}", p.run) for p in self.paper}
        named |= {("compare_trajectories", g) for pair in self.compare_trajectories for g in pair}
        named |= {("bound_figures", g) for fig in self.bound_figures for g in fig}
        named |= {("estimation_figures", g) for pair in self.estimation_figures for g in pair}
        named |= {(f"why ({e.kind})", e.run) for e in [*self.why, *(w for c in self.claims for w in c.why)]}
        if self.ranking is not None and self.ranking.pair_key not in self.grid:
            raise ValueError(f"ranking.pair_key {self.ranking.pair_key!r} is not a grid key ({sorted(self.grid)})")
        missing = sorted(f"{where}: run {g!r}" for where, g in named if g not in groups)
        if missing:
            raise ValueError("unknown runs (" + "; ".join(missing) + f"); runs: {sorted(groups)}")
        return self


@dataclass(frozen=True)
class RunSpec:
    """One run of a campaign: where it goes and the fully resolved scenario it flies."""

    study: str
    group: str  # the run id without the seed: runs of one group are Monte Carlo repetitions
    seed: int
    scenario_toml: str
    bound: bool = False  # compute the capacity bound with the run
    plugins: tuple = ()  # planning.plugins.Plugin: the users' planner modules a worker imports before flying it

    @property
    def key(self) -> str:
        return f"{self.study}/{self.group}/seed{self.seed}"

    @property
    def scenario_hash(self) -> str:
        return hashlib.sha256(self.scenario_toml.encode()).hexdigest()[:16]


def _fmt(v) -> str:
    if isinstance(v, float) and math.isinf(v):
        return "inf"
    return str(v)


def load_study(path: Path) -> Study:
    """A study file, or StudyError naming it: not a regular file (a FIFO or a device is refused before it is read),
    not UTF-8, not TOML, not a study."""
    path = Path(path)
    try:
        why = not_a_file(path)
        if why is not None:
            raise StudyError(f"{path}: {why} (a study is a TOML file)")
        return Study.model_validate(tomllib.loads(path.read_text(encoding="utf-8")))
    except (ValidationError, tomllib.TOMLDecodeError) as exc:
        raise StudyError(f"{path}: {exc}") from None
    except UnicodeDecodeError as exc:
        raise StudyError(f"{path}: not UTF-8 text (byte {exc.start}): study files are UTF-8 TOML") from None
    except (OSError, RecursionError) as exc:
        raise StudyError(f"{path}: cannot be read: {exc}") from None


def read_studies(folder: Path) -> tuple[list[Study], dict[Path, str]]:
    """Every study file in ``folder`` in file-name order, and why each file that is not a study cannot be one."""
    files = sorted(Path(folder).glob("*.toml"))
    if not files:
        raise StudyError(f"{folder}: no study files (*.toml) there" + ("" if Path(folder).is_dir() else " (no such folder)"))
    studies, broken = [], {}
    for f in files:
        try:
            studies.append(load_study(f))
        except StudyError as exc:
            broken[f] = str(exc)
    return studies, broken


def find_studies(folder: Path, names: list[str] | None = None) -> list[Study]:
    """Studies in ``folder`` (all, or those named), in file-name order. A file that cannot be a study is an error when
    every study is asked for; with names, only when a name is not found among the others (said with it)."""
    studies, broken = read_studies(folder)
    if broken and not names:
        raise StudyError("; ".join(broken.values()))
    if names:
        known = {s.name: s for s in studies}
        missing = [n for n in names if n not in known]
        if missing:
            unread = f"; files that are no study: {'; '.join(broken.values())}" if broken else ""
            raise StudyError(f"unknown study {missing}; available: {sorted(known)}{unread}")
        for why in broken.values():
            log.warning("%s (the studies asked for are elsewhere)", why)
        studies = [known[n] for n in names]
    return studies


def _combos(study) -> tuple[list[str], list[tuple]]:
    keys = list(study.grid)
    return keys, (list(itertools.product(*study.grid.values())) if keys else [()])


def _group(run_id: str, keys: list[str], combo: tuple) -> str:
    label = ",".join(f"{k.split('.')[-1]}={_fmt(v)}" for k, v in zip(keys, combo, strict=True))
    return label if run_id == "base" and label else (f"{run_id}[{label}]" if label else run_id)


def _number(v) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)


def sweep_series(study) -> list[tuple[str, str, list[tuple[float, str]]]]:
    """The study's swept numeric parameters as series ``(parameter, label, [(value, group), ...])``:
    each numeric ``[grid]`` key against its values, one series per run and combination of the
    other keys; and, without a grid, a dotted key every run sets to a different number."""
    keys, combos = _combos(study)
    out = []
    for key in keys:
        if len(study.grid[key]) < 2 or not all(_number(v) for v in study.grid[key]):
            continue
        for run in study.runs:
            series: dict[str, list[tuple[float, str]]] = {}
            for combo in combos:
                rest = ",".join(f"{k.split('.')[-1]}={_fmt(v)}" for k, v in zip(keys, combo, strict=True) if k != key)
                value = combo[keys.index(key)]
                series.setdefault(rest, []).append((float(value), _group(run.id, keys, combo)))
            for rest, points in series.items():
                label = ",".join(x for x in (run.id if run.id != "base" else "", rest) if x)
                out.append((key, label, sorted(points)))
    if not keys and len(study.runs) >= 3:
        shared = set.intersection(*(set(r.set) for r in study.runs))
        for key in sorted(shared):
            values = [r.set[key] for r in study.runs]
            if all(_number(v) for v in values) and len(set(values)) == len(values):
                out.append((key, "", sorted((float(r.set[key]), r.id) for r in study.runs)))
    return out


def combinations(study, pair_key: str) -> dict[str, dict[str, str]]:
    """Grid combinations without ``pair_key``: ``{combination label: {pair value: group}}``."""
    keys, combos = _combos(study)
    out: dict[str, dict[str, str]] = {}
    for run in study.runs:
        for combo in combos:
            rest = [(k, v) for k, v in zip(keys, combo, strict=True) if k != pair_key]
            label = ",".join(f"{k.split('.')[-1]}={_fmt(v)}" for k, v in rest)
            pair = _fmt(dict(zip(keys, combo, strict=True))[pair_key])
            out.setdefault(label, {})[pair] = _group(run.id, keys, combo)
    return out


def groups_of_run(study, run_id: str) -> list[str]:
    """The groups one ``[[runs]]`` entry expands into (one per grid combination)."""
    keys, combos = _combos(study)
    return [_group(run_id, keys, combo) for combo in combos]


def group_names(study) -> list[str]:
    """The study's run groups (run ids times grid labels), in expansion order."""
    keys, combos = _combos(study)
    return [_group(run.id, keys, combo) for run in study.runs for combo in combos]


def expand(study: Study, root: Path, *, quick: bool = False, notices: list[str] | None = None) -> list[RunSpec]:
    """All runs of a study, each with its validated, fully resolved scenario. A run with nothing
    random is flown once whatever ``seeds`` says (its repetitions would be identical): each such
    group is said in ``notices`` when given."""
    bases: dict[str, Scenario] = {}
    for path in {study.base, *(r.base for r in study.runs if r.base)}:
        try:
            bases[path] = load_scenario(root / path)
        except ScenarioError as exc:
            raise StudyError(f"study {study.name}: base scenario {path}: {exc}") from None
    grid_keys, combos = _combos(study)
    seeds = study.quick_seeds if quick else study.seeds
    specs = []
    for run in study.runs:
        base = bases[run.base or study.base]
        for combo in combos:
            updates = dict(run.set)
            updates.update(zip(grid_keys, combo, strict=True))
            group = _group(run.id, grid_keys, combo)
            where = f"study {study.name}, run {group}"
            deterministic = not _updated(base, updates, where).stochastic
            if deterministic and seeds > 1 and notices is not None:
                notices.append(f"study {study.name}, run {group}: nothing random (no finite-K fading, CSI or process noise, "
                               f"shadowing or estimated jammer), so its {seeds} seeds would be identical: flown once")
            if quick and study.quick_duration_s is not None and notices is not None:
                sc = _updated(base, updates, where)
                end = min(study.quick_duration_s, sc.duration_s)
                late = [f"{r.name} at {r.lost_at_s:g} s" for r in sc.relay_list if r.lost_at_s is not None and r.lost_at_s >= end]
                if late:
                    notices.append(f"study {study.name}, run {group}: quick mode ends it at {end:g} s, before its relay "
                                   f"loss ({', '.join(late)}): flown without the loss (the full campaign flies it)")
            for s in range(1 if deterministic else seeds):  # more seeds would fly the same run again
                u = dict(updates)
                u["seed"] = base.seed + s
                if quick and study.quick_duration_s is not None:
                    u["sim.duration_s"] = min(study.quick_duration_s, base.duration_s)
                u["name"] = f"{study.name}/{group}"
                specs.append(RunSpec(study.name, group, s, _updated(base, u, where).to_toml(), study.bound))
    return specs


def _updated(base: Scenario, updates: dict, where: str) -> Scenario:
    try:
        return updated(base, updates)
    except ScenarioError as exc:
        raise StudyError(f"{where}: {exc}") from None


def scenario_of(spec: RunSpec) -> Scenario:

    return parse_scenario(tomllib.loads(spec.scenario_toml))
