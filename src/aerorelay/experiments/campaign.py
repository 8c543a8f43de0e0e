"""Campaign runner: expands studies into runs and flies them on dask.distributed.

Each run writes its own folder ``OUT/runs/<study>/<group>/seed<k>`` atomically (see
``store.run_folder.publish_run``); ``OUT/manifest.json`` records every run's scenario hash, seed,
status, wall time, package version and error. A run whose folder holds ``metrics.json`` for the
same scenario and the same solver settings is finished and never recomputed, so re-running a command resumes it: an
interrupted campaign loses no finished run. A run that raises is recorded as failed and the
campaign goes on.
"""

from __future__ import annotations

import json
import logging
import os
import time
import traceback
from dataclasses import dataclass
from pathlib import Path

from dask.distributed import Client, LocalCluster, as_completed

from .._version import __version__
from ..control.nmpc import NmpcSettings
from ..scenario.run import simulate
from .study import RunSpec, scenario_of

log = logging.getLogger(__name__)


def run_dir(out: Path, spec: RunSpec) -> Path:
    safe = spec.group.replace("/", "_")
    return Path(out) / "runs" / spec.study / safe / f"seed{spec.seed}"


def first_run_per_group(specs: list[RunSpec], out: Path) -> dict[str, RunSpec]:
    """The first finished run (lowest seed) of every group, in study order."""
    firsts = {}
    for s in specs:
        if s.group not in firsts and (run_dir(out, s) / "timeseries.parquet").exists():
            firsts[s.group] = s
    return firsts


def is_finished(out: Path, spec: RunSpec) -> bool:
    """A finished run has metrics.json, the same resolved scenario (its TOML) and was flown by a
    controller with the current solver settings (``NmpcSettings.fingerprint``)."""
    d = run_dir(out, spec)
    if not (d / "metrics.json").exists() or not (d / "scenario.toml").exists():
        return False
    if (d / "scenario.toml").read_text() != spec.scenario_toml:
        return False
    try:
        metrics = json.loads((d / "metrics.json").read_text())
    except (OSError, ValueError):
        return False
    if spec.bound and "capacity_efficiency_mean" not in metrics:
        return False
    return metrics.get("controller") == NmpcSettings().fingerprint()


def execute_run(spec: RunSpec, out: str) -> dict:
    """Fly one run and write its folder; never raises (errors are returned). Runs on a worker."""
    t0 = time.perf_counter()
    record = {"key": spec.key, "study": spec.study, "group": spec.group, "seed": spec.seed,
              "scenario_hash": spec.scenario_hash, "version": __version__, "pid": os.getpid()}
    try:
        if os.environ.get("AERORELAY_FAIL_RUN") and os.environ["AERORELAY_FAIL_RUN"] in spec.key:
            raise RuntimeError(f"failure injected by AERORELAY_FAIL_RUN for {spec.key}")
        result = simulate(scenario_of(spec), with_bound=spec.bound)
        result.save(run_dir(Path(out), spec))
        record.update(status="done", wall_s=time.perf_counter() - t0, c_min=result.metrics["c_min"])
    except Exception as exc:  # recorded, the campaign goes on
        record.update(status="failed", wall_s=time.perf_counter() - t0, error=f"{type(exc).__name__}: {exc}",
                      traceback=traceback.format_exc(limit=8))
    return record


@dataclass
class CampaignResult:
    records: dict[str, dict]
    skipped: int
    ran: int
    failed: int
    wall_s: float


def _write_manifest(out: Path, records: dict[str, dict]) -> None:
    tmp = out / "manifest.json.tmp"
    tmp.write_text(json.dumps(records, indent=1, sort_keys=True))
    tmp.replace(out / "manifest.json")


def load_manifest(out: Path) -> dict[str, dict]:
    f = Path(out) / "manifest.json"
    return json.loads(f.read_text()) if f.exists() else {}


def make_client(scheduler: str | None, n_workers: int | None = None):
    """A dask client: to ``scheduler`` if given, else a local cluster of single-threaded processes."""
    if scheduler:
        return Client(scheduler)
    n = n_workers or max(1, os.cpu_count() or 1)
    cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None)
    return Client(cluster)


def run_campaign(specs: list[RunSpec], out: Path, *, client=None, scheduler: str | None = None,
                 n_workers: int | None = None, progress=None) -> CampaignResult:
    """Run every unfinished spec on dask; ``progress(done, total, record)`` after each run."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    records = load_manifest(out)
    todo = [s for s in specs if not is_finished(out, s)]
    for s in specs:
        if s not in todo:
            rec = records.get(s.key, {})
            if rec.get("status") != "done" or rec.get("scenario_hash") != s.scenario_hash:
                records[s.key] = {"key": s.key, "study": s.study, "group": s.group, "seed": s.seed,
                                  "scenario_hash": s.scenario_hash, "status": "done", "version": __version__,
                                  "wall_s": rec.get("wall_s")}
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
            futures = [client.submit(execute_run, s, str(out), pure=False, key=f"run-{s.study}-{s.scenario_hash}-{s.seed}")
                       for s in todo]
            for fut in as_completed(futures):
                rec = fut.result()
                records[rec["key"]] = rec
                failed += rec["status"] != "done"
                done += 1
                _write_manifest(out, records)
                if progress:
                    progress(done, len(specs), rec)
        finally:
            if own:
                client.close()
    return CampaignResult(records, len(specs) - len(todo), len(todo), failed, time.perf_counter() - t0)
