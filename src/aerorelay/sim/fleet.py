"""Flies a fleet: every relay its own vehicle, NMPC (with its supervisor and fail-safe) and plant,
every source its own mission, one fleet planner, the network's true channel. A relay lost in flight
(``losses``) is gone from then on: every route through it skips it, the planner is rebuilt for the
smaller fleet from where the others are, and its columns read NaN (``qp_status`` "lost").

The log names each vehicle's columns ``<node>.<quantity>`` (``r1.p_x``, ``r1.phi``,
``inspector.p_z``), each hop's SINR ``sinr.<tx>.<rx>``, each route's capacity ``capacity.<source>``
and the network's rate ``capacity`` (``models.radio.network_rate``); ``separation_min`` (m) is the
smallest distance between two vehicles at the step. Units as in the one-relay log.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace

import casadi as ca
import numpy as np

from ..control.relay import RelayController
from ..models.geometry import constant_acceleration_path, rotation_zyx
from ..models.mission import SourceTrajectory
from ..models.radio import RadioScene
from ..models.streams import generator, stream
from ..models.vehicle import Multirotor
from ..planning.fleet import FleetInput, FleetPlanner
from .air import Air
from .blockage import Blockage
from .closed_loop import (
    LOG_COLUMN_TYPES,
    MissionResult,
    SimSettings,
    jammer_columns,
    jammer_values,
    known_jammers,
    new_log,
    record_row,
    step_count,
    steps_flown,
)
from .exit_status import ExitStatus
from .realtime import full_collections_paused

VEHICLE_STATE = ("p_x", "p_y", "p_z", "phi", "theta", "psi", "v_x", "v_y", "v_z", "omega_x", "omega_y", "omega_z")
SOURCE_STATE = ("p_x", "p_y", "p_z", "phi", "theta", "psi")
SEPARATION_MARGIN_M = 0.1  # each relay's NMPC keeps this much more than min_separation_m: its soft constraint's slack stays inside
GONE_CLEARANCE_M = 10.0  # a lost relay in another's separation constraint: the separation plus this below that relay's own
# plan, never reached within a step (a fixed point 100 m or 1 km away scaled the constraint until the QP stopped converging)
RELAY_STEP = ("pd_x", "pd_y", "pd_z", "solve_ms", "feedback_ms", "qp_ok", "qp_status", "fallback", "safety_violation")


@dataclass(frozen=True, kw_only=True)
class FleetRelay:
    """One relay of the fleet: its name, vehicle, controller, plant step and start (m, world)."""

    name: str
    vehicle: Multirotor
    controller: RelayController
    plant: ca.Function
    start: np.ndarray


def fleet_columns(relays: list[FleetRelay], sources: list[str], scene: RadioScene,
                  hops: Sequence[tuple[str, str]] = ()) -> list[str]:
    """The fleet log's columns, in order; ``hops``: links the network takes later (after a relay is
    lost), logged after the scene's own."""
    cols = ["t"]
    for r in relays:
        n = r.vehicle.n_rotors
        cols += [f"{r.name}.{q}" for q in VEHICLE_STATE]
        cols += [f"{r.name}.Omega_{i}" for i in range(1, n + 1)] + [f"{r.name}.u_{i}" for i in range(1, n + 1)]
        cols += [f"{r.name}.{q}" for q in RELAY_STEP]
    for s in sources:
        cols += [f"{s}.{q}" for q in SOURCE_STATE]
    cols += [f"sinr.{tx}.{rx}" for tx, rx in (*scene.hops, *(h for h in hops if h not in scene.hops))]
    cols += [f"capacity.{route[0]}" for route in scene.all_routes]
    cols += ["capacity", "jammer_on", "separation_min"]
    return cols + jammer_columns(scene)


def column_type(name: str) -> type:
    """A fleet column's type: the one-relay log's type of its quantity (flags, the QP status), else float."""
    return LOG_COLUMN_TYPES.get(name.rsplit(".", 1)[-1], float)


def gone_row(r: FleetRelay) -> dict[str, object]:
    """A lost relay's columns at a step: NaN, its flags false, ``qp_status`` "lost"."""
    n = r.vehicle.n_rotors
    names = [*VEHICLE_STATE, *(f"Omega_{i}" for i in range(1, n + 1)), *(f"u_{i}" for i in range(1, n + 1)), *RELAY_STEP]
    row: dict[str, object] = {f"{r.name}.{q}": math.nan for q in names}
    return row | {f"{r.name}.qp_ok": False, f"{r.name}.qp_status": "lost", f"{r.name}.fallback": False,
                  f"{r.name}.safety_violation": False}


def route_neighbours(scene: RadioScene) -> dict[str, tuple[str, str]]:
    """Each relay's two neighbours on its first route: (upstream, toward the base station), the nodes
    its NMPC's alignment terms look at (MRAV-2 and the base station of the paper's one relay)."""
    out: dict[str, tuple[str, str]] = {}
    for route in scene.all_routes:
        for i in range(1, len(route) - 1):
            out.setdefault(route[i], (route[i - 1], route[i + 1]))
    return out


def separation_min(points: np.ndarray) -> float:
    """The smallest distance (m) between two of ``points`` ``(n, 3)``; inf for fewer than two."""
    if len(points) < 2:
        return math.inf
    d = np.linalg.norm(points[:, None, :] - points[None, :, :], axis=-1)
    return float(d[np.triu_indices(len(points), 1)].min())


class FleetLoop:
    """Flies the fleet: ``run(progress)`` returns a MissionResult whose log is the fleet log."""

    def __init__(self, *, scene: RadioScene, relays: list[FleetRelay], sources: dict[str, SourceTrajectory],
                 planner: FleetPlanner, settings: SimSettings, separation_m: float = 0.0,
                 losses: Sequence[tuple[float, frozenset[str]]] = (),
                 replanner: Callable[[frozenset[str], Mapping[str, np.ndarray]], FleetPlanner] | None = None,
                 air: Air | None = None, blockage: Blockage | None = None):
        """``losses``: ``(t, every relay lost by then)`` in time order (s); ``replanner(lost, positions)``
        builds the planner of the fleet without ``lost`` from the survivors' positions (m, world)."""
        if losses and replanner is None:
            raise ValueError("FleetLoop: relays are lost in flight (losses) but no replanner builds the smaller fleet's planner")
        self.scene, self.relays, self.sources, self.planner, self.settings = scene, relays, sources, planner, settings
        self.separation_m = separation_m
        self.losses, self.replanner = list(losses), replanner
        self.planner_ms: list[float] = []  # the fleet planner's time per step, ms (aerorelay bench)
        later = [h for _, lost in self.losses for h in scene.without(lost).hops]
        self.columns = fleet_columns(relays, list(sources), scene, later)
        self.air = air  # [wind]: every relay's plant steps through it, its observer feeds its NMPC
        self.blockage = blockage if blockage is not None and blockage.active else None  # obstacles that block radio
        if self.blockage is not None:
            self.nlos_columns = list(dict.fromkeys(c for s in (scene, *(scene.without(lost) for _, lost in self.losses))
                                                   for c in self.blockage.columns(s)))
            self.columns += self.nlos_columns
        if air is not None:
            self.columns += air.wind_columns() + [c for r in relays for c in air.columns(r.name, f"{r.name}.")]
        # the plant's random channel terms on every link (each its own draw, shadowing along each link's own
        # geometry), unknown to the planners and NMPCs; logged per link (sim/perturbations.py)
        self.perturbations = settings.link_perturbations(scene)
        if self.perturbations.active and self.losses:
            raise ValueError("FleetLoop: random channel terms with relays lost in flight are not flown yet (the links change)")
        self.columns += self.perturbations.columns
        # what the fleet knows: the sources and the jammers with CSI noise (one stream); each relay's process noise its own
        self.csi_rng = generator(settings.seed, "csi")
        self.process_rngs = {r.name: np.random.default_rng(child)
                             for r, child in zip(relays, stream(settings.seed, "process").spawn(len(relays)), strict=True)}
        self.neighbours_of = route_neighbours(scene)
        self.bs = scene.fixed_pose(scene.name_of("base_station")).position
        self._bs_path = np.repeat(self.bs[:, None], relays[0].controller.spec.horizon + 1, axis=1)
        self.gravity = relays[0].vehicle.gravity

    def _known_sources(self, truth: dict) -> dict:
        """Every source as the fleet knows it over its optical link: its position with CSI noise (m), its
        velocity and acceleration."""
        noise = self.settings.csi_noise_m
        if noise <= 0:
            return truth
        return {n: replace(s, p=s.p + self.csi_rng.normal(0.0, noise, 3)) for n, s in truth.items()}

    def _process_noise(self, relay: str) -> np.ndarray:
        """One relay's process noise for a step: accelerations (m/s^2, world) and angular accelerations
        (rad/s^2, body), from its own stream."""
        st = self.settings
        if st.process_noise_v <= 0 and st.process_noise_w <= 0:
            return np.zeros(6)
        rng = self.process_rngs[relay]
        return np.concatenate([rng.normal(0.0, st.process_noise_v, 3), rng.normal(0.0, st.process_noise_w, 3)])

    def _predicted(self, x: dict[str, np.ndarray], src: dict) -> dict[str, np.ndarray]:
        """Every vehicle's positions over the NMPC's horizon ``(3, N + 1)`` (m, world): a relay's latest
        plan, shifted by the step flown since (one step old; its current position held before its
        first plan), a source at constant acceleration."""
        spec = self.relays[0].controller.spec
        tk = spec.ts * np.arange(spec.horizon + 1)
        out = {}
        for r in self.relays:
            nmpc = r.controller.nmpc
            if nmpc.initialized:
                out[r.name] = nmpc.plan()[0][0:3].copy()
            else:
                out[r.name] = np.repeat(x[r.name][0:3, None], spec.horizon + 1, axis=1)
        for name, s in src.items():
            out[name] = constant_acceleration_path(s.p, s.v, s.a, tk)
        return out

    def _lose(self, lost: frozenset[str], x: dict[str, np.ndarray]) -> None:
        """The relays ``lost`` are gone: the scene's routes skip them, the planner is rebuilt for the
        others from where they are."""
        assert self.replanner is not None  # checked in __init__
        self.scene = self.scene.without(lost)
        self.planner = self.replanner(lost, {n: xs[0:3].copy() for n, xs in x.items() if n not in lost})
        self.neighbours_of = route_neighbours(self.scene)

    def run(self, progress=None) -> MissionResult:
        st = self.settings
        period = st.period_s
        n_steps = step_count(st.duration_s, period)
        x = {r.name: r.vehicle.hover_state(r.start) for r in self.relays}
        u = {r.name: np.zeros(r.vehicle.n_rotors) for r in self.relays}
        log = new_log(self.columns, n_steps, column_type)
        sinr_columns = [c for c in self.columns if c.startswith("sinr.")]
        pending, lost = list(self.losses), frozenset[str]()
        wall0 = time.perf_counter()
        aborted, flown, exit_status = None, n_steps, None
        with full_collections_paused():
            for k in range(n_steps):
                t = k * period
                while pending and t >= pending[0][0] - 1e-9:
                    lost = pending.pop(0)[1]
                    self._lose(lost, x)
                flying = {n: xs for n, xs in x.items() if n not in lost}
                truth = {name: path.state(t) for name, path in self.sources.items()}
                src = self._known_sources(truth)  # over the optical links, with CSI noise
                positions = {**{n: xs[0:3].copy() for n, xs in flying.items()}, **{n: s.p for n, s in src.items()},
                             self.scene.name_of("base_station"): self.bs}
                velocities = {**{n: xs[6:9].copy() for n, xs in flying.items()}, **{n: s.v for n, s in src.items()}}
                eta = {**{n: xs[3:6] for n, xs in flying.items()}, **{n: s.attitude(self.gravity) for n, s in src.items()}}
                R = {n: rotation_zyx(e) for n, e in eta.items()}  # every vehicle's attitude, body to world
                axes = {n: Rn[:, 2] for n, Rn in R.items()}
                known = known_jammers(self.scene, t, st.senses_jammer_state, st.csi_noise_m, self.csi_rng)
                t0 = time.perf_counter()
                refs = self.planner.update(FleetInput(t=t, dt=period, positions=positions, velocities=velocities, axes=axes,
                                                      accelerations={n: s.a for n, s in src.items()},
                                                      jammer_positions=known[0], jammer_powers=known[1]))
                self.planner_ms.append((time.perf_counter() - t0) * 1e3)
                row: dict[str, object] = {"t": t}
                if self.air is not None:
                    self.air.begin()
                    row |= self.air.wind_values()
                predicted = self._predicted(x, src)  # every vehicle over the horizon: the relays' latest plans
                for r in self.relays:
                    if r.name in lost:
                        row |= gone_row(r) | (dict.fromkeys(self.air.columns(r.name, f"{r.name}."), math.nan) if self.air else {})
                        continue
                    up, down = self.neighbours_of[r.name]
                    others = None
                    if r.controller.spec.neighbours:
                        gone = predicted[r.name] - [[0.0], [0.0], [self.separation_m + GONE_CLEARANCE_M]]  # out of reach
                        others = np.vstack([gone if n in lost else q for n, q in predicted.items() if n != r.name])
                    zero = np.zeros(3)
                    P = r.controller.parameters(refs[r.name], zero, zero, zero, others, self.separation_m + SEPARATION_MARGIN_M,
                                                p2_path=predicted[up], p0_path=predicted.get(down, self._bs_path),
                                                a_ext=self.air.estimate(r.name) if self.air else None)
                    info = r.controller.step(x[r.name], u[r.name], P, shift=period >= r.controller.spec.ts - 1e-12)
                    u[r.name] = info.u
                    xs, n = x[r.name], r.vehicle.n_rotors
                    if self.air is not None:
                        row |= self.air.values(r.name, xs, f"{r.name}.")
                    row |= {f"{r.name}.{q}": v for q, v in zip(VEHICLE_STATE, xs[0:12], strict=True)}
                    row |= {f"{r.name}.Omega_{i}": xs[11 + i] for i in range(1, n + 1)}
                    row |= {f"{r.name}.u_{i}": info.u[i - 1] for i in range(1, n + 1)}
                    row |= {f"{r.name}.pd_{a}": v for a, v in zip("xyz", refs[r.name].p_ref, strict=True)}
                    row |= {f"{r.name}.solve_ms": info.solve_ms, f"{r.name}.feedback_ms": info.feedback_ms,
                            f"{r.name}.qp_ok": info.ok, f"{r.name}.qp_status": info.status,
                            f"{r.name}.fallback": info.fallback,
                            f"{r.name}.safety_violation": bool(r.controller.last_violations)}
                true_positions = positions | {n: s.p for n, s in truth.items()}
                poses = {n: self.scene.pose(n, true_positions[n], R[n]) for n in R}
                for name, s in truth.items():
                    row |= {f"{name}.{q}": v for q, v in zip(SOURCE_STATE, [*s.p, *eta[name]], strict=True)}
                gains = None
                if self.perturbations.active:  # fading and shadowing on every link, each its own
                    true_velocities = velocities | {n: s.v for n, s in truth.items()} | {self.scene.name_of("base_station"): np.zeros(3)}
                    gains, values = self.perturbations.step(t, true_positions, true_velocities)
                    row |= values
                if self.blockage is not None:  # a link through an obstacle that blocks radio loses its nlos_loss_db
                    blocked, values = self.blockage.step(self.scene, t, true_positions)
                    gains = blocked if gains is None else gains * blocked
                    row |= dict.fromkeys(self.nlos_columns, math.nan) | values
                state = self.scene.evaluate(t, poses, fading=gains)
                row |= dict.fromkeys(sinr_columns, math.nan)  # a hop the network does not take now
                row |= {f"sinr.{tx}.{rx}": float(g) for (tx, rx), g in zip(state.hops, state.sinr, strict=True)}
                row |= {f"capacity.{route[0]}": float(c) for route, c in zip(self.scene.all_routes, state.route_capacity,
                                                                            strict=True)}
                row["capacity"] = float(state.capacity)
                row["jammer_on"] = float(any(float(j.power_at(t)) > 0 for j in self.scene.jammers))
                row["separation_min"] = separation_min(np.array([true_positions[n] for n in (*flying, *src)]))
                row |= jammer_values(self.scene, t)
                record_row(log, k, row, self.columns, "fleet log row")
                for r in self.relays:
                    if r.name not in lost:
                        d = self._process_noise(r.name)
                        x[r.name] = (self.air.advance(r.name, x[r.name], u[r.name], d) if self.air
                                     else np.asarray(r.plant(x[r.name], u[r.name], d)).ravel())
                bad = [n for n, xs in x.items() if n not in lost and not np.all(np.isfinite(xs))]
                if bad:
                    aborted, flown = f"relay {bad[0]!r}: the plant's state became non-finite after t = {t:.3f} s", k + 1
                    exit_status = ExitStatus.NON_FINITE.value
                    break
                if progress is not None:
                    progress(k + 1, n_steps)
        wall = time.perf_counter() - wall0
        if flown < n_steps:
            log = steps_flown(log, flown)
        first = self.relays[0].controller
        return MissionResult(log=log, wall_s=wall, sim_s=(flown - 1) * period,
                             qp_failures=sum(r.controller.nmpc.failures for r in self.relays),
                             controller=first.nmpc.settings.fingerprint(),
                             fallback_episodes=sum(r.controller.fallback_episodes for r in self.relays), aborted=aborted,
                             exit_status=exit_status)
