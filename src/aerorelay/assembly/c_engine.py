"""The generated C library as the simulation's engine (``controller.backend = "c"``; issue 80, item 3).

A relay whose controller says ``backend = "c"`` flies each control step through its own C tree (``assembly.codegen``:
the tree ``aerorelay codegen`` writes, without the C planner: the stage parameters come from the network's planner as
for Python's controller), built once per controller into the cache (``store.cache``: keyed by the tree's every file
and the BLASFEO kernels it is built with) and loaded through ctypes. The Python controller stays the reference: the
same engine source, the same flags and the same BLASFEO kernels (``Tree.simd``, as this process's engine ran them), so
the commands are Python's bit for bit (tests/control/test_c_engine.py); what reads the controller during a flight reads
the C library's: the plan the next step starts from (``RelayStep.guess``: the other relays' separation rows, the
obstacles' planes), the fail-safe's state and counts (the verdict's, the metrics'), the QP's failures. It is installed
where a flight's controller is made (``ar.simulate``, campaigns, ``ar.controller`` and what flies through it: MAVLink,
ROS 2), so every path honours it.
"""

from __future__ import annotations

import hashlib
import logging
import shutil
import tempfile
import time
import weakref
from dataclasses import replace
from pathlib import Path

import numpy as np

from ..config import Scenario, ScenarioError
from ..control.network import NetworkController
from ..control.nmpc import StepInfo, _HpipmEngine
from ..control.relay_step import RelayStep
from ..store.cache import cache_dir, cache_lock, entry_is_intact, publish_checked
from .codegen import CController, Tree, build_shared, write_tree

log = logging.getLogger(__name__)


def _digest(folder: Path, simd: bool) -> str:
    """The tree's key: every file's path and bytes, and the BLASFEO kernels it is built with."""
    h = hashlib.sha256(f"SIMD={int(simd)}".encode())
    for path in sorted(p for p in folder.rglob("*") if p.is_file()):
        h.update(str(path.relative_to(folder)).encode() + b"\0" + path.read_bytes() + b"\0")
    return h.hexdigest()[:16]


def built_tree(sc: Scenario, control: NetworkController, relay: str) -> tuple[Tree, Path]:
    """Relay ``relay``'s C tree (no C planner) from the flight's own ``control`` and its shared library, built once per
    tree into the cache (concurrent builders serialize on the entry's lock; a corrupt entry is rebuilt)."""
    folder = cache_dir()
    with tempfile.TemporaryDirectory(dir=folder, prefix=".ctree_") as tmp:
        tree = write_tree(sc, Path(tmp) / "tree", planner=False, relay=relay, control=control)
        lib = folder / f"ctree_{_digest(tree.folder, tree.simd)}.so"
        if not entry_is_intact(lib):
            with cache_lock(lib):
                if not entry_is_intact(lib):  # nobody built it while we waited
                    t0 = time.perf_counter()
                    log.warning("building relay %s's C library for controller.backend = 'c' (make SIMD=%d; once per "
                                "controller, then cached: %s)", relay, int(tree.simd), lib)
                    publish_checked(build_shared(tree), lib)
                    log.info("built in %.1f s", time.perf_counter() - t0)
    return replace(tree, folder=lib.parent), lib


class CStep:
    """A relay's step flown by its C library (``RelayStep.backend``): the command, the fail-safe's state mirrored into
    the Python controller's counters (which the metrics and the verdict read), the QP failures counted, the plan the next
    step starts from (``guess``)."""

    def __init__(self, controller: CController, relay: str):
        self.c, self.relay = controller, relay
        weakref.finalize(self, controller.close)  # at most 64 C controllers live in a process: freed with the step

    def __call__(self, step: RelayStep, x, u_prev, P, shift: bool) -> StepInfo:
        t0 = time.perf_counter()
        _, info, u = self.c.step(x, u_prev, P, shift)
        ms = (time.perf_counter() - t0) * 1e3
        active, episodes, handovers, unsafe = self.c.failsafe_state()
        rc = step.controller
        if episodes > rc.fallback_episodes:
            log.warning("fail-safe (relay %s's C library): the brake law flies (episode %d)", self.relay, episodes)
        rc.fallback_active, rc.fallback_episodes, rc.safety_handovers = active, episodes, handovers
        rc.last_violations = ["outside the safety envelope (the C library's supervisor)"] if unsafe else []
        tried = info.qp_status != -2  # -2: no QP this step (bad input, the brake law without a try)
        ok = bool(info.ok)
        if tried and not ok:
            rc.nmpc.failures += 1
        status = _HpipmEngine.status_of(ok, info.qp_status, bool(info.capped)) if tried else "no QP"
        return StepInfo(u=u, ok=ok, status=status, prep_ms=0.0, feedback_ms=ms, slack_max=float(info.slack_max),
                        qp_iters=int(info.iterations), fallback=bool(info.fallback))

    def guess(self) -> np.ndarray | None:
        """The plan the next step starts from (``(nxa, N + 1)``; None before the first step)."""
        return self.c.guess()

    def close(self) -> None:
        self.c.close()


def c_relays(sc: Scenario) -> list[tuple[int, str]]:
    """The relays (index, name) whose controller says ``backend = "c"`` (``[controller]`` or its ``[relays.controller]``)."""
    return [(i, r.name) for i, r in enumerate(sc.relay_list) if sc.controller_of(i).backend == "c"]


def refuse_c_engines(sc: Scenario, what: str) -> None:
    """A ScenarioError naming the field when a relay of ``sc`` flies its C library and ``what`` (a command that flies or
    times Python's controller as its reference) cannot honour it."""
    for i, name in c_relays(sc):
        raise ScenarioError(f"{sc.controller_field(i, ('backend',))}: 'c' (relay {name} flies its C library): {what}; "
                            "set it to 'python' here")


def install_c_engines(sc: Scenario, control: NetworkController) -> list[str]:
    """Every relay of ``control`` built to fly its C library (``RelayStep.engine``: its ``controller.backend``) flies it
    from now on; the relays so flown. No make or C compiler: a ScenarioError naming the field, before any build."""
    wanted = [r.name for r in control.relays if r.stepper.engine == "c"]
    if wanted and (shutil.which("make") is None or (shutil.which("gcc") or shutil.which("cc")) is None):
        i = next(i for i, r in enumerate(sc.relay_list) if r.name == wanted[0])
        raise ScenarioError(f"{sc.controller_field(i, ('backend',))}: 'c' builds each relay's C library with make and a C "
                            "compiler, and this machine has no make or cc on PATH: install them (build-essential) or use "
                            "'python'")
    for name in wanted:
        tree, lib = built_tree(sc, control, name)
        step = control.relay(name).stepper
        step.backend = CStep(CController(lib, tree), name)
        step.controller.guess_source = step.backend.guess  # the plan the C library starts its next step from
    return wanted


def close_c_engines(control: NetworkController, relays: list[str]) -> None:
    """Free the C controllers of ``relays`` (``install_c_engines``'): a campaign's worker flies run after run."""
    for name in relays:
        backend = control.relay(name).stepper.backend
        if isinstance(backend, CStep):
            backend.close()
