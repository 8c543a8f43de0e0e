"""The controller side of a relay network, one control step: the network's planner on what the network
knows, then every relay's stage parameters (its route neighbours' predicted paths, the other vehicles'
plans for the separation) and its NMPC. ``sim.closed_loop.ClosedLoop`` flies it over the plant;
``Controller`` (``ar.controller``, any network) steps it from outside with measured states, ``OneRelay`` adapts
it to one relay and one source."""

from __future__ import annotations

import logging
import math
import os
import time
from collections.abc import Callable, Iterable, Mapping
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace
from typing import TypeVar

import casadi as ca
import numpy as np

from ..models.battery import Battery
from ..models.geometry import constant_acceleration_path, rotation_zyx
from ..models.mission import SourceState as PathState
from ..models.radio import Node, RadioScene
from ..models.state import ETA, YAW, P, V, state_vector
from ..models.vehicle import Multirotor
from ..planning.base import PlannerFailed, Reference, ReferenceCheck
from ..planning.fleet import FleetInput, FleetPlanner
from ..planning.home import HomeSettings
from .nmpc import StepInfo
from .readings import JammersFromReadings
from .relay_step import Command, RelayStep, SourceState, StaleSettings, beyond_reach, checked_source

log = logging.getLogger(__name__)
T = TypeVar("T")
R = TypeVar("R")

SEPARATION_MARGIN_M = 0.1  # each relay's NMPC keeps this much more than min_separation_m: its soft constraint's slack stays inside
UNUSED_ROW_OFFSET_M = 1000.0  # a separation row with no vehicle to fill it looks at a point this far below the relay's own
# plan: the bounded row (control.terms.separation_margin) reads 2 d^2 there, constant to 1e-7, and never binds
UNGUARDED_FACTOR = 2.0  # a vehicle left out of a relay's rows is counted when its path comes within this many separations


THREADS_VARIABLE = "AERORELAY_RELAY_THREADS"


def relay_threads() -> int:
    """How many relays' controllers step at once: ``AERORELAY_RELAY_THREADS`` (0: one per core, up to the relays; 1:
    one after another), default 0. A resource of the machine, not of the scenario: the flight is the same either way,
    bit for bit (a campaign's workers, a process per core already, step their relays one after another)."""
    text = os.environ.get(THREADS_VARIABLE, "0").strip()
    try:
        n = int(text)
    except ValueError:
        n = -1
    if not 0 <= n <= 256:
        raise ValueError(f"{THREADS_VARIABLE} must be a whole number 0..256 (0: one thread per core), got {text!r}")
    return n


def separation_rows(own: np.ndarray, others: Mapping[str, np.ndarray], rows: int, separation_m: float
                    ) -> tuple[np.ndarray, list[str], list[str]]:
    """A relay's separation rows: the ``rows`` vehicles of ``others`` (name -> predicted positions ``(3, N + 1)``, m)
    whose paths come nearest to its own ``own`` over the horizon, stacked ``(3 rows, N + 1)`` (a row without a vehicle
    looks far below ``own``); their names, and the names of the vehicles left out whose paths come within
    ``UNGUARDED_FACTOR`` separations of ``own`` (no row keeps the relay from them)."""
    near = sorted(others, key=lambda n: float(np.min(np.linalg.norm(others[n] - own, axis=0))))
    kept, left = near[:rows], near[rows:]
    far = own - np.array([[0.0], [0.0], [UNUSED_ROW_OFFSET_M]])
    stacked = np.vstack([others[n] for n in kept] + [far] * (rows - len(kept)))
    close = UNGUARDED_FACTOR * separation_m
    unguarded = [n for n in left if float(np.min(np.linalg.norm(others[n] - own, axis=0))) < close]
    return stacked, kept, unguarded


@dataclass(frozen=True, kw_only=True)
class LoopRelay:
    """One relay of the network: its name, vehicle, stepper (its controller, without a planner of its
    own), plant step ``(x, u, d) -> x`` (None when flown outside) and start (m, world)."""

    name: str
    vehicle: Multirotor
    stepper: RelayStep
    plant: ca.Function | None
    start: np.ndarray
    battery: Battery | None = None
    home: HomeSettings | None = None  # where and how it flies home when its battery says so (None: it does not)
    spare: Node | None = None  # a spare's radio node (``standby``): it waits outside the network until it takes over

    @property
    def controller(self):
        return self.stepper.controller


def route_neighbours(scene: RadioScene) -> dict[str, tuple[str, str]]:
    """Each relay's two neighbours on its first route: (upstream, toward the base station), the nodes
    its NMPC's alignment terms look at (MRAV-2 and the base station of the paper's one relay)."""
    out: dict[str, tuple[str, str]] = {}
    for route in scene.all_routes:
        for i in range(1, len(route) - 1):
            out.setdefault(route[i], (route[i - 1], route[i + 1]))
    return out


class NetworkController:
    """Plans and controls every relay of a network for one step (``step``); ``lose`` takes relays out."""

    def __init__(self, *, scene: RadioScene, relays: list[LoopRelay], planner: FleetPlanner | None, period_s: float,
                 separation_m: float = 0.0,
                 replanner: Callable[[RadioScene, Mapping[str, np.ndarray], float], FleetPlanner] | None = None,
                 planner_name: str = "planner", threads: int | None = None):
        """``replanner(scene, positions, t0)``: the planner of the network ``scene`` (relays lost, gone home or taken
        over), its references starting where its relays are (m, world) at ``t0`` (s). ``planner_name``: how its
        references' check names it (``planning.base.ReferenceCheck``; the registered name). ``threads``: how many
        relays' controllers step at once (``each``; 0: one per core, up to the relays; None: ``relay_threads()``)."""
        self.scene, self.relays, self.period = scene, relays, period_s
        self.check = ReferenceCheck(planner_name, {r.name: (np.asarray(r.controller.spec.workspace_min, float),
                                                            np.asarray(r.controller.spec.workspace_max, float))
                                                   for r in relays})
        self.planner: FleetPlanner | None = planner  # None once no relay is left in the network
        self._kept_out_before = 0  # the steps earlier planners moved a reference out of an obstacle's margin
        self.separation_m, self.replanner = separation_m, replanner
        self.neighbours_of = route_neighbours(scene)
        self.sources = list(dict.fromkeys(route[0] for route in scene.all_routes))
        self.bs_name = scene.name_of("base_station")
        self.bs = scene.fixed_pose(self.bs_name).position
        self.stations = {n.name: scene.fixed_pose(n.name).position for n in scene.nodes if n.role == "base_station"}
        # the NMPCs' prediction times (every relay's OCP has one horizon: ocp_spec); no relay (the direct link): none
        self.tk = relays[0].controller.spec.ts * np.arange(relays[0].controller.spec.horizon + 1) if relays else np.zeros(1)
        self.bs_path = np.repeat(self.bs[:, None], len(self.tk), axis=1)
        self.station_paths = {n: np.repeat(p[:, None], len(self.tk), axis=1) for n, p in self.stations.items()}
        self.gravity = relays[0].vehicle.gravity if relays else 9.81  # a source's thrust direction (no relay: unused)
        # the relays' plans enter another relay's stage parameters: a relay next to another on a route (a route of
        # more than one relay), the separation rows
        self.plans_needed = any(r.controller.spec.neighbours for r in relays) or any(len(route) > 3 for route in scene.all_routes)
        self.planner_ms = 0.0  # the last step's planner time (ms; without work the planner runs beside the loop: off_loop_s)
        self.last_plan: tuple | None = None  # (t, sources, jammers) the planner was last given (plan)
        # per relay, the steps on which a vehicle came within UNGUARDED_FACTOR separations beyond its separation rows
        self.unguarded: dict[str, int] = dict.fromkeys((r.name for r in relays), 0)
        threads = relay_threads() if threads is None else threads
        self.threads = min(len(relays), os.cpu_count() or 1) if threads == 0 else min(threads, len(relays))
        self._pool: ThreadPoolExecutor | None = None

    def each(self, step: Callable[[T], R], items: Iterable[T]) -> list[R]:
        """``[step(item) for item in items]``, on ``threads`` threads when there are several: every relay's step reads
        what the control period shares (the references, the predicted plans) and writes only its own controller, and
        its NMPC runs in C without Python's lock, so the relays step at once as on a computer each (the results are
        the same, bit for bit, in the same order)."""
        items = list(items)
        if self.threads <= 1 or len(items) < 2:
            return [step(i) for i in items]
        if self._pool is None:
            self._pool = ThreadPoolExecutor(max_workers=self.threads, thread_name_prefix="relay")
        return list(self._pool.map(step, items))

    def close(self) -> None:
        """Stop the relays' threads (a flight's end; ``each`` starts them again when called)."""
        if self._pool is not None:
            self._pool.shutdown(wait=True)
            self._pool = None

    def lose(self, lost: frozenset[str], positions: Mapping[str, np.ndarray], t0: float = 0.0) -> None:
        """The relays ``lost`` are gone: the scene's routes skip them, the planner is rebuilt for the
        others from where they are (``positions``, m, world) at ``t0`` (s)."""
        self.recompose(self.scene.without(lost), positions, t0)

    def recompose(self, scene: RadioScene, positions: Mapping[str, np.ndarray], t0: float) -> None:
        """The network flies ``scene`` from now on (relays gone, spares in their places): its planner rebuilt from
        where its relays are (``positions``, m, world) at ``t0`` (s); no relay left: the sources reach the base
        station directly, nothing to plan."""
        if self.replanner is None:
            raise ValueError("network controller: the network changes but no replanner builds its planner")
        scene = scene.configured()  # every relay on its route again (route selection picks the subset anew)
        self.scene = scene
        left = any(n.role == "relay" for n in scene.nodes)
        self._kept_out_before = self.kept_out_steps
        self.planner = self.replanner(scene, positions, t0) if left else None
        self.neighbours_of = route_neighbours(self.scene)

    @property
    def kept_out_steps(self) -> int:
        """The steps on which a planner's reference was moved out of an obstacle's margin (``planning.keep_out``),
        over every planner the network flew."""
        return self._kept_out_before + int(getattr(self.planner, "kept_out_steps", 0))

    def hand_over(self, routes) -> None:
        """Each route is now served by ``routes`` (one of its candidates each, the handover rule's choice: its end, the
        relays that carry it): a relay's NMPC looks toward its serving route's neighbours (a skipped relay, off every
        route, toward the base station)."""
        self.scene = self.scene.serving_routes(routes)
        self.neighbours_of = route_neighbours(self.scene)

    def neighbours(self, relay: str) -> tuple[str, str]:
        """A relay's two neighbours on its first route; a relay out of the network (flying home) has none: the
        base station stands for both."""
        return self.neighbours_of.get(relay, (self.bs_name, self.bs_name))

    def plan(self, t: float, x: Mapping[str, np.ndarray], sources: Mapping, jammers) -> dict[str, Reference]:
        """The network planner's references from the flying relays' states ``x`` and the ``sources`` as known
        (``p``, ``v``, ``a``; their attitudes follow their accelerations), ``jammers`` ``(positions, powers, std)``."""
        pj, powers, std = jammers
        self.last_plan = (t, sources, jammers)  # what the planner was given (a step backend replaying the planner reads it)
        if self.planner is None:
            self.planner_ms = 0.0
            return {}
        eta = {**{n: xs[ETA] for n, xs in x.items()}, **{n: s.attitude(self.gravity) for n, s in sources.items()}}
        t0 = time.perf_counter()
        try:
            refs = self.planner.update(FleetInput(
            t=t, dt=self.period, positions={**{n: xs[P].copy() for n, xs in x.items()}, **{n: s.p for n, s in sources.items()},
                                            **self.stations},
            velocities={**{n: xs[V].copy() for n, xs in x.items()}, **{n: s.v for n, s in sources.items()}},
            axes={n: rotation_zyx(e)[:, 2] for n, e in eta.items()}, yaws={n: float(xs[YAW]) for n, xs in x.items()},
            accelerations={n: s.a for n, s in sources.items()}, jammer_positions=pj, jammer_powers=powers, jammer_std_m=std))
        except Exception as exc:  # a planner that raises is named (its own error kept as the cause)
            raise PlannerFailed(f"planner {self.check.name!r} raised at t = {t:.3f} s: {type(exc).__name__}: {exc}") from exc
        off_loop = float(getattr(self.planner, "off_loop_s", 0.0))  # a route planned beside the loop (planning.fleet_capacity)
        self.planner_ms = (time.perf_counter() - t0 - off_loop) * 1e3
        return self.check(t, refs, x)  # every relay present, finite, inside its workspace: else held or clipped

    def relay(self, name: str) -> LoopRelay:
        """Relay ``name`` of the network (its vehicle, its ``RelayStep``); a ValueError naming the relays otherwise."""
        for r in self.relays:
            if r.name == name:
                return r
        raise ValueError(f"no relay {name!r} in the network ({', '.join(r.name for r in self.relays)})")

    def predicted(self, x: Mapping[str, np.ndarray], sources: Mapping) -> dict[str, np.ndarray]:
        """Every vehicle's positions over the NMPC's horizon ``(3, N + 1)`` (m, world): a relay's latest
        plan, shifted by the step flown since (one step old; its current position held before its
        first plan), a source at constant acceleration."""
        out = {}
        for r in self.relays if self.plans_needed else ():
            plan = r.stepper.guess()  # the Python NMPC's, or the C library's that flies the relay
            out[r.name] = plan[P].copy() if plan is not None else np.repeat(x[r.name][P, None], len(self.tk), axis=1)
        for name, s in sources.items():
            out[name] = constant_acceleration_path(s.p, s.v, s.a, self.tk)
        return out

    def parameters(self, r: LoopRelay, ref: Reference, predicted: Mapping[str, np.ndarray], lost: frozenset[str],
                   a_ext: np.ndarray | None) -> np.ndarray:
        """Relay ``r``'s stage parameters on ``ref``: its neighbours on its route, the nearest other vehicles' plans
        (``separation_rows``; ``lost``: out of the flight, in no row)."""
        up, down = self.neighbours(r.name)
        others = None
        if r.controller.spec.neighbours:
            own = predicted[r.name]
            candidates = {n: q for n, q in predicted.items() if n != r.name and n not in lost}
            others, _, unguarded = separation_rows(own, candidates, r.controller.spec.neighbours, self.separation_m)
            if unguarded:
                if not self.unguarded[r.name]:
                    log.warning("relay %r: %s within %g m of its plan but beyond its %d separation rows "
                                "(network.separation_neighbours)", r.name, ", ".join(unguarded),
                                UNGUARDED_FACTOR * self.separation_m, r.controller.spec.neighbours)
                self.unguarded[r.name] += 1
        return r.stepper.parameters(ref, p2_path=predicted.get(up, self.bs_path),
                                    p0_path=predicted.get(down, self.station_paths.get(down, self.bs_path)), others=others,
                                    separation_m=self.separation_m + SEPARATION_MARGIN_M, a_ext=a_ext)


class Controller:
    """The controller of any network, stepped from outside (``ar.controller(sc)``): ``step(t, relay_states, sources)``
    each control period with every relay's measured state and every source as known, by name (aerorelay's frames:
    world ENU, body FLU; ``flight.frames`` converts at an autopilot's edge), returns ``{relay: Command}``: the rotor
    speeds and their rates (what aerorelay's plant flies) and the setpoints an autopilot accepts (position, velocity,
    acceleration, attitude with the collective thrust normalized to hover, body rates: the relay's state one period
    ahead under the command, by its own model), the step's computation time and whether it met its deadline. The same
    type for any number of relays; ``one_relay()`` is the explicit adapter for one relay and one source (``step(t, x,
    source) -> Command``).

    It owns, per relay, what the transports must not each write again: the telemetry check (a state with a
    non-finite entry, stamped ahead of the clock or behind the last trusted one, or a jump no vehicle of its thrust
    can make: held and ``Command.rejected`` says why), the state sanity warnings, the external-force observer
    (``[wind]``, as ``ar.simulate`` gives every relay), the stale-input failsafe (a relay whose state is missing, older
    than ``hold_after_s`` or not trusted holds where it last was, lands after ``land_after_s``, the network planning
    with its last state) and the model it plans with (``autopilot``: thrust along body z). A source missing, stale or
    not finite holds every relay. A malformed state, a clock going backwards, or a first step without a trusted state
    of every relay, is a ValueError naming it. Stepped over aerorelay's plant it flies what ``ar.simulate`` flies
    (tested, in gusty wind too)."""

    def __init__(self, controller: NetworkController, jammers: Callable[[float], tuple],
                 estimated: JammersFromReadings | None = None):
        """``jammers(t)``: the jammers as the network knows them at ``t`` (positions ``(nJ, 3)`` m, the powers it plans
        with W, the position std m or None); ``estimated``: the jammers are estimated from the readings ``step`` is
        handed (then ``jammers`` is its view)."""
        self.controller, self.jammers, self.estimated = controller, jammers, estimated
        self.period = controller.period
        self._t_last: float | None = None
        self._read_at: tuple[float, dict[str, np.ndarray]] | None = None  # where the next readings were taken
        self.lost: set[str] = set()  # relays taken out of the network (``lose``)
        self.lost_at: dict[str, float] = {}  # when (s, the caller's clock; NaN: not said)
        self._source_trusted: dict[str, tuple[float, np.ndarray, np.ndarray]] = {}  # each source's last trusted report

    @property
    def relays(self) -> list[str]:
        return [r.name for r in self.controller.relays]

    @property
    def sources(self) -> list[str]:
        return list(self.controller.sources)

    @property
    def stale(self) -> StaleSettings:
        """The stale-input settings (every relay's)."""
        return self.controller.relays[0].stepper.stale

    def one_relay(self) -> OneRelay:
        """The explicit adapter for one relay and one source: ``step(t, x, source) -> Command`` (a ValueError naming the
        relays and sources otherwise)."""
        return OneRelay(self)

    def relay(self, name: str) -> LoopRelay:
        """Relay ``name`` (its vehicle, its ``RelayStep``)."""
        return self.controller.relay(name)

    def _last(self) -> dict[str, np.ndarray]:
        return {r.name: x for r in self.controller.relays if (x := r.stepper.last_state) is not None}

    def lose(self, relays, t: float = math.nan) -> None:
        """Take ``relays`` out of the network for good (a link that stayed down, a relay sent home): the routes
        skip them and the others are planned again from where they last were; their commands keep holding and
        then landing them. ``t``: when (s), kept in ``lost_at``."""
        new = set(relays) - self.lost
        if not new:
            return
        unknown = new - set(self.relays)
        if unknown:
            raise ValueError(f"lose: no relay {sorted(unknown)} in the network ({', '.join(self.relays)})")
        self.lost |= new
        self.lost_at |= dict.fromkeys(sorted(new), float(t))
        self.controller.lose(frozenset(self.lost), {n: xs[P].copy() for n, xs in self._last().items()},
                             float(t) if math.isfinite(t) else 0.0)

    def problem(self, t: float, name: str, x: np.ndarray | None, stamp: float) -> str | None:
        """Why relay ``name``'s state ``x`` (stamped ``stamp``) cannot be flown at ``t``: missing, not trusted or stale
        (older than ``hold_after_s``); None when it can (what a transport gates its first step on)."""
        if x is None:
            return "no relay state"
        if self.stale.too_old(t, stamp):
            return f"relay state {t - stamp:.3f} s old"
        return self.relay(name).stepper.problem(t, x, stamp)

    def source_problem(self, t: float, source: SourceState | None) -> str | None:
        """Why a source as known cannot be planned with at ``t``: missing, not finite, stamped ahead of the clock, or
        older than ``hold_after_s``; None when it can."""
        if source is None:
            return "no source"
        why = self.controller.relays[0].stepper.check.problem(t, None, t, source)
        if why is None and source.stamp is not None and self.stale.too_old(t, source.stamp):
            why = f"source {t - source.stamp:.3f} s old"
        return why

    def _source_reach(self, t: float, name: str, source: SourceState) -> str | None:
        """Why source ``name``'s report cannot follow its last trusted one (``relay_step.beyond_reach`` with
        ``StaleSettings.source_accel_max_m_s2``); a report that can is kept as the trusted one."""
        stamp = t if source.stamp is None else float(source.stamp)
        last = self._source_trusted.get(name)
        why = None if last is None else beyond_reach(last, stamp, source.p, source.v, self.stale.source_accel_max_m_s2,
                                                     self.stale, "source")
        if why is None:
            self._source_trusted[name] = (stamp, np.asarray(source.p, float).copy(), np.asarray(source.v, float).copy())
        return why

    def step(self, t: float, relay_states: Mapping[str, np.ndarray | None], sources: Mapping[str, SourceState | None],
             *, stamps: Mapping[str, float | None] | None = None,
             readings: Mapping[str, float] | None = None) -> dict[str, Command]:
        """One control period at ``t`` (s): every relay's full state ``(p, eta, v, omega, Omega)`` (m, rad ZYX, m/s,
        rad/s FLU, Hz) by name (None or absent: none arrived), measured at ``stamps[relay]`` (s; absent or None: ``t``),
        every source as known by name; ``{relay: Command}``. ``readings``: with ``jammer.localization = "estimated"``,
        what each receiver (a relay, the base station with ``estimation.use_bs``) measured over the last period,
        interference plus noise (W), taken where the relays were at the last step."""
        t0 = time.perf_counter()
        t = float(t)
        if not np.isfinite(t):
            raise ValueError(f"step: t must be a finite time (s), got {t}")
        if self._t_last is not None and t < self._t_last:
            raise ValueError(f"step: t = {t:.6g} s is before the previous step's {self._t_last:.6g} s (the clock went backwards)")
        if readings:
            self._check_readings(readings)
        for what, given_map in (("relay_states", relay_states), ("sources", sources)):
            if not hasattr(given_map, "keys"):
                raise ValueError(f"step: {what} must map each name to its {'state' if what == 'relay_states' else 'source'} "
                                 f"(relays {', '.join(self.relays)}; sources {', '.join(self.sources)}), got "
                                 f"{type(given_map).__name__} (one relay and one source: ar.controller(...).one_relay().step(t, x, source))")
        unknown = sorted(set(relay_states) - set(self.relays))
        if unknown:
            raise ValueError(f"step: no relay {unknown} in the network ({', '.join(self.relays)})")
        given: dict[str, np.ndarray] = {}
        for r in self.controller.relays:
            state = relay_states.get(r.name)
            if state is None:
                continue
            given[r.name] = state_vector(state, r.vehicle.n_rotors, f"step: relay_states[{r.name!r}]")
        src = {name: checked_source(sources.get(name)) for name in self.controller.sources}
        stamp = {n: t if stamps is None or stamps.get(n) is None else float(stamps[n]) for n in given}  # type: ignore[arg-type]
        # not trusted (Command.rejected says why), or merely stale (older than hold_after_s): either holds
        rejected = {n: w for n, x in given.items() if (w := self.relay(n).stepper.problem(t, x, stamp[n])) is not None}
        fresh = {n: x for n, x in given.items() if n not in rejected and not self.stale.too_old(t, stamp[n])}
        never = [n for n in self.relays if n not in fresh and not self.relay(n).stepper.has_state]
        if never:
            said = [f"{n}: {rejected.get(n) or ('no relay state' if n not in given else 'stale')}" for n in never]
            raise ValueError(f"step: no trusted state for {never} and none before ({'; '.join(said)}): the first step "
                             "needs every relay's (nothing to hold)")
        self._t_last = t
        source_why = {n: w for n, s in src.items() if (w := self.source_problem(t, s)) is not None}
        source_why |= {n: w for n, s in src.items() if s is not None and n not in source_why
                       and (w := self._source_reach(t, n, s)) is not None}
        for r in self.controller.relays:
            if r.name in fresh:
                r.stepper.accept(t, stamp[r.name], fresh[r.name])
            if r.name not in fresh or source_why:  # no input of its NMPC this period: its observer restarts after
                r.stepper.missed()
        last = self._last()
        if readings:
            at, states = self._read_at if self._read_at is not None else (t, last)
            assert self.estimated is not None
            self.estimated.add(at, states, readings)
        self._read_at = (t, last)
        if source_why:  # the network cannot plan without its sources: every relay holds
            told = "; ".join(f"{n}: {w}" for n, w in source_why.items())
            return {r.name: replace(r.stepper.hold_command(t, t0), rejected=f"source {told}") for r in self.controller.relays}
        known = {n: PathState(s.p, s.v, s.a) for n, s in src.items() if s is not None}
        # a relay without a fresh state planned at its last state; a lost one not at all
        x = {n: last[n] for n in self.relays if n not in self.lost}
        refs = self.controller.plan(t, x, known, self.jammers(t))
        predicted = self.controller.predicted({**x, **{n: last[n] for n in self.lost}}, known)
        for n in self.lost & set(predicted):  # a lost relay still flies (it holds and lands): kept clear where it last was
            predicted[n] = np.repeat(last[n][P, None], predicted[n].shape[1], axis=1)
        def command(r: LoopRelay) -> Command:
            if r.name not in fresh or r.name in self.lost:
                cmd = r.stepper.hold_command(t, t0)
                return replace(cmd, rejected=rejected[r.name]) if r.name in rejected else cmd
            params = self.controller.parameters(r, refs[r.name], predicted, frozenset(), None)
            info: StepInfo = r.stepper.act(x[r.name], params)
            return r.stepper.command(t, x[r.name], info, refs[r.name], t0)
        relays = self.controller.relays
        return dict(zip((r.name for r in relays), self.controller.each(command, relays), strict=True))

    def _check_readings(self, readings: Mapping[str, float]) -> None:
        if self.estimated is None:
            raise ValueError("step: readings given, but the scenario's jammers are not estimated "
                             "(jammer.localization = 'estimated')")
        for name, w in readings.items():
            if not (isinstance(w, int | float | np.floating) and np.isfinite(w) and w >= 0):
                raise ValueError(f"step: readings[{name!r}] must be a finite power >= 0 W, got {w!r}")


class OneRelay:
    """One relay and one source stepped as the paper's problem (``ar.controller(sc).one_relay()``): ``step(t,
    relay_state, source)`` returns the relay's ``Command``, a thin adapter over the network's ``Controller``
    (``network``): ``step(t, {relay: x}, {source: s})[relay]``."""

    def __init__(self, network: Controller):
        if len(network.relays) != 1 or len(network.sources) != 1:
            raise ValueError(f"OneRelay: one relay and one source, got relays {network.relays} and sources {network.sources}")
        self.network = network
        self.name, self.source = network.relays[0], network.sources[0]
        self.part = network.relay(self.name)

    @property
    def vehicle(self) -> Multirotor:
        return self.part.vehicle

    @property
    def period(self) -> float:
        return self.network.period

    @property
    def stale(self) -> StaleSettings:
        return self.network.stale

    @property
    def observer(self):
        return self.part.stepper.observer

    @property
    def estimated(self) -> JammersFromReadings | None:
        return self.network.estimated

    def jammers(self, t: float) -> tuple:
        return self.network.jammers(t)

    def step(self, t: float, relay_state: np.ndarray | None, source: SourceState | None, *,
             state_stamp: float | None = None, readings: Mapping[str, float] | None = None) -> Command:
        """One control step at ``t`` (s): ``relay_state`` the full state ``(p, eta, v, omega, Omega)`` (m, rad ZYX, m/s,
        rad/s FLU, Hz; None: no new state), measured at ``state_stamp`` (None: ``t``); ``source`` as the relay knows it;
        ``readings`` as ``Controller.step`` takes them."""
        return self.network.step(t, {self.name: relay_state}, {self.source: source}, stamps={self.name: state_stamp},
                                 readings=readings)[self.name]
