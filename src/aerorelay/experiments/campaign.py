"""Campaign runner: expands studies into runs and flies them on dask.distributed.

Each run writes its own folder ``OUT/runs/<study>/<group>/seed<k>`` atomically (see
``store.run_folder.publish_run``); ``OUT/manifest.json`` records every run's scenario hash, seed,
status, wall time, package version and error. A run whose folder holds ``metrics.json`` for the
same scenario and the same solver settings is finished and never recomputed, so re-running a command resumes it: an
interrupted campaign loses no finished run. A run that raises is recorded as failed and the
campaign goes on.
"""

from __future__ import annotations

import fcntl
import json
import logging
import os
import time
import traceback
from dataclasses import dataclass
from enum import StrEnum
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq
from dask.distributed import Client, LocalCluster, as_completed

from .._version import __version__
from ..assembly.parts import nmpc_settings
from ..control.network import THREADS_VARIABLE
from ..planning.plugins import load as load_plugins
from ..sim.units import metric_value_problem
from ..store import strict_json
from ..store.outputs import check_output_folder, mark, write_atomic
from ..store.run_folder import BOUND_JSON, METRICS_FILE, SCENARIO_FILE, TIMESERIES_FILE
from .run import simulate
from .study import RunSpec, scenario_of

log = logging.getLogger(__name__)


def folder_name(group: str) -> str:
    """A run group's folder name: the group with ``%``, ``/``, ``\\`` and control characters
    percent-encoded (``a/b`` -> ``a%2Fb``, never ``a_b``'s), and ``.`` / ``..`` spelled ``%2E``: one
    folder per group, never outside its study's."""
    if group in (".", ".."):
        return group.replace(".", "%2E")
    return "".join(f"%{ord(c):02X}" if c in "%/\\" or ord(c) < 32 else c for c in group)


def run_dir(out: Path, spec: RunSpec) -> Path:
    return Path(out) / "runs" / spec.study / folder_name(spec.group) / f"seed{spec.seed}"


def first_run_per_group(specs: list[RunSpec], out: Path) -> dict[str, RunSpec]:
    """The first verified finished run (lowest seed) of every group, in study order."""
    firsts: dict[str, RunSpec] = {}
    for s in specs:
        if s.group not in firsts and is_finished(out, s):
            firsts[s.group] = s
    return firsts


def _run_problem(d: Path, spec: RunSpec) -> str | None:
    """Why the run folder ``d`` is not a finished, trustworthy run of ``spec`` (None: it is)."""
    for name in (SCENARIO_FILE, METRICS_FILE, TIMESERIES_FILE):
        f = d / name
        if not f.is_file() or f.stat().st_size == 0:
            return f"{name} missing or empty"
    try:
        expected = spec.scenario_toml
        if any(f in expected for f in ("trajectory_csv", "trajectory_ulog", "trajectory_plan", "trajectory_gpx")):
            sc = scenario_of(spec)  # the run folder names its own copy
            expected = sc.to_toml(sc.mission.copy_name)
        if (d / SCENARIO_FILE).read_text() != expected:
            return "another scenario"
        metrics = json.loads((d / METRICS_FILE).read_text())
        rows = pq.read_metadata(d / TIMESERIES_FILE).num_rows
    except (OSError, ValueError, pa.ArrowException) as exc:
        return f"unreadable: {type(exc).__name__}: {exc}"
    if not isinstance(metrics, dict) or rows != metrics.get("steps"):
        return f"{TIMESERIES_FILE} has {rows} rows, metrics.json says {metrics.get('steps') if isinstance(metrics, dict) else '?'}"
    if (bad := metric_value_problem(metrics)) is not None:
        return f"metrics.json edited or damaged: {bad} is not a number"
    if spec.bound and ("capacity_efficiency_mean" not in metrics or not (d / BOUND_JSON).is_file()):
        return "no bound"
    if metrics.get("unsafe", False):
        return f"unsafe: {metrics.get('unsafe_reason', '')}"
    if metrics.get("controller") != nmpc_settings(scenario_of(spec)).fingerprint():
        return "flown with other solver settings"
    return None


def is_finished(out: Path, spec: RunSpec) -> bool:
    """A finished run is verified, not assumed: scenario.toml (the same resolved scenario),
    metrics.json (parses; flown with the current solver settings, ``NmpcSettings.fingerprint``;
    not unsafe) and timeseries.parquet (a readable footer with the metrics' row count), each
    non-empty, and the bound's files when the study asks for them."""
    return _run_problem(run_dir(out, spec), spec) is None


def execute_run(spec: RunSpec, out: str) -> dict:
    """Fly one run and write its folder; never raises (errors are returned). Runs on a worker."""
    t0 = time.perf_counter()
    os.environ.setdefault(THREADS_VARIABLE, "1")  # a worker per core already: its relays step one after another
    record = {"key": spec.key, "study": spec.study, "group": spec.group, "seed": spec.seed,
              "scenario_hash": spec.scenario_hash, "version": __version__, "pid": os.getpid()}
    try:
        load_plugins(spec.plugins)  # a user's planners, on this worker too (a fresh process)
        result = simulate(scenario_of(spec), with_bound=spec.bound)
        result.save(run_dir(Path(out), spec))
        m = result.metrics
        unsafe, fell_back = m["unsafe"], bool(m.get("fell_back"))
        status = RunStatus.UNSAFE if unsafe else (RunStatus.FELL_BACK if fell_back else RunStatus.DONE)
        record.update(status=status, wall_s=time.perf_counter() - t0, c_min=m["c_min"])
        if unsafe:
            record["error"] = f"unsafe: {m['unsafe_reason']}"
        elif fell_back:
            record["error"] = f"fell back: {m['fell_back_reason']}"
    except Exception as exc:  # recorded, the campaign goes on
        record.update(status=RunStatus.FAILED, wall_s=time.perf_counter() - t0, error=f"{type(exc).__name__}: {exc}",
                      traceback=traceback.format_exc(limit=8))
    return record


@dataclass
class CampaignResult:
    records: dict[str, dict]
    skipped: int
    ran: int
    failed: int
    wall_s: float


class RunStatus(StrEnum):
    """A campaign run's outcome in the manifest (compares equal to its text): flown and safe, raised,
    or flown but unsafe (left its world; its numbers are not used)."""

    DONE = "done"
    FELL_BACK = "fell_back"  # flown and safe, but a relay's controller did not fly it (its numbers kept, marked)
    FAILED = "failed"
    UNSAFE = "unsafe"


class CampaignBusyError(RuntimeError):
    """Another campaign holds the folder's lock."""


LOCK_FILE = ".campaign.lock"


def _write_manifest(out: Path, records: dict[str, dict]) -> None:
    write_atomic(out / "manifest.json", strict_json.dumps(records, indent=1, sort_keys=True))


def load_manifest(out: Path) -> dict[str, dict]:
    """The campaign's manifest; a corrupt or foreign one (not a JSON object of run records) is
    set aside as ``manifest.json.corrupt`` with a warning, and rebuilt from the run folders."""
    f = Path(out) / "manifest.json"
    if not f.exists():
        return {}
    try:
        data = json.loads(f.read_text())
        if isinstance(data, dict) and all(isinstance(v, dict) for v in data.values()):
            return data
        why = "not a JSON object of run records"
    except (OSError, ValueError) as exc:
        why = f"{type(exc).__name__}: {exc}"
    log.warning("%s is unreadable (%s): rebuilt from the run folders", f, why)
    os.replace(f, f.with_suffix(".json.corrupt"))
    return {}


def make_client(scheduler: str | None, n_workers: int | None = None):
    """A dask client: to ``scheduler`` if given (a named error after 10 s when it does not answer),
    else a local cluster of single-threaded processes."""
    if scheduler:
        try:
            return Client(scheduler, timeout="10s")
        except (OSError, TimeoutError) as exc:
            raise CampaignBusyError(f"--scheduler {scheduler}: no dask scheduler answers there ({exc})") from None
    n = n_workers or max(1, os.cpu_count() or 1)
    cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=":0")
    return Client(cluster)


def _record(spec: RunSpec, status: str, **extra) -> dict:
    return {"key": spec.key, "study": spec.study, "group": spec.group, "seed": spec.seed,
            "scenario_hash": spec.scenario_hash, "status": status, "version": __version__, **extra}


def run_campaign(specs: list[RunSpec], out: Path, *, client=None, scheduler: str | None = None,
                 n_workers: int | None = None, progress=None, wait: bool = False) -> CampaignResult:
    """Run every unfinished spec on dask; ``progress(done, total, record)`` after each run. One
    campaign per folder: a second one refuses (CampaignBusyError) unless ``wait``."""
    out = check_output_folder(out, "campaign")
    out.mkdir(parents=True, exist_ok=True)
    with open(out / LOCK_FILE, "w") as lock:
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | (0 if wait else fcntl.LOCK_NB))
        except BlockingIOError:
            raise CampaignBusyError(f"--out {out}: another campaign is running in this folder (lock {LOCK_FILE}); "
                                    "wait for it or pass --wait") from None
        mark(out, "campaign")
        return _run_locked(specs, out, client, scheduler, n_workers, progress)


def _run_locked(specs, out: Path, client, scheduler, n_workers, progress) -> CampaignResult:
    records = load_manifest(out)
    todo = [s for s in specs if not is_finished(out, s)]
    for s in specs:
        if s not in todo:
            rec = records.get(s.key, {})
            if rec.get("status") != RunStatus.DONE or rec.get("scenario_hash") != s.scenario_hash:
                records[s.key] = _record(s, RunStatus.DONE, wall_s=rec.get("wall_s"))
    _write_manifest(out, records)
    t0 = time.perf_counter()
    done = len(specs) - len(todo)
    if progress:
        progress(done, len(specs), None)
    failed = 0
    if todo:
        own = client is None
        client = client or make_client(scheduler, n_workers)
        try:
            futures = {client.submit(execute_run, s, str(out), pure=False, key=f"run-{s.study}-{s.scenario_hash}-{s.seed}"): s
                       for s in todo}
            for fut in as_completed(list(futures)):
                spec = futures.pop(fut)
                try:
                    rec = fut.result()
                except Exception as exc:  # a worker that died (KilledWorker) fails its run, not the campaign
                    rec = _record(spec, RunStatus.FAILED, error=f"{type(exc).__name__}: {exc}")
                fut.release()  # a finished run is never recomputed after a worker loss
                records[rec["key"]] = rec
                failed += rec["status"] != RunStatus.DONE
                done += 1
                _write_manifest(out, records)
                if progress:
                    progress(done, len(specs), rec)
        finally:
            if own:
                cluster = getattr(client, "cluster", None)
                client.close()
                if cluster is not None:  # the local cluster's worker processes end with it
                    cluster.close()
    return CampaignResult(records, len(specs) - len(todo), len(todo), failed, time.perf_counter() - t0)
