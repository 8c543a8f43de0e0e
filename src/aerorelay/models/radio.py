"""The radio scene and the one channel implementation behind every consumer (paper eq. 5-9).

A ``RadioScene`` holds named nodes with roles (base station, source, relay), each with an antenna
(a pattern and its axis in the node's body frame), any number of jammers (``models.jammer``) and
the link budget. ``RadioScene.evaluate(t, poses)`` returns the SINR of every hop of the route
(source -> relay -> base station, any length) and the end-to-end capacity. The closed loop's true
channel, the initial link budget, the capacity bound, the capacity planner, baseline B and the
report all call it.

Units: positions m (world frame), powers W, bandwidth normalized (B = 1 gives bit/s/Hz). A pose
is a position and the antenna axis in the world (``NodePose``); numpy arrays broadcast, so one
call evaluates one pose or a grid of relay positions ``(M, 1, 3)`` x antenna axes ``(1, K, 3)``.
``link_gain`` and ``route_capacity`` also take CasADi expressions (baseline B's NLP).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from functools import reduce
from itertools import combinations
from typing import Any, Literal

import casadi as ca
import numpy as np

from . import checks
from .antenna import AntennaPattern
from .backend import is_symbolic, ops
from .geometry import E3
from .jammer import HiddenJammer, Jammer
from .propagation import PathGain

Role = Literal["base_station", "source", "relay"]
ROLES = ("base_station", "source", "relay")


@dataclass(frozen=True)
class Antenna:
    """An antenna: its pattern and its axis in the node's body frame (unit; dipoles along body z)."""

    pattern: AntennaPattern
    axis: np.ndarray = field(default_factory=lambda: E3.copy())

    def __post_init__(self):
        checks.has_method("Antenna", "pattern", self.pattern, "gain_from_cos", "an antenna pattern")
        checks.vector("Antenna", "axis", self.axis, unit=True)

    def world_axis(self, R) -> np.ndarray:
        """The axis in the world for a body-to-world rotation ``R`` (``(..., 3, 3)``)."""
        R = np.asarray(R, float)
        if np.array_equal(self.axis, E3):
            return R[..., :, 2]
        return np.einsum("...ij,j->...i", R, np.asarray(self.axis, float))


@dataclass(frozen=True)
class Node:
    """A radio node: ``name``, ``role``, antenna; ``position`` (m, world) for a fixed node (its
    attitude is then the identity), None for a vehicle whose pose the simulation gives."""

    name: str
    role: Role
    antenna: Antenna
    position: np.ndarray | None = None

    def __post_init__(self):
        checks.text("Node", "name", self.name)
        who = f"Node({self.name!r})"
        checks.one_of(who, "role", self.role, ROLES)
        if not isinstance(self.antenna, Antenna):
            raise checks.InvalidInput(f"{who}.antenna: must be an Antenna, got {type(self.antenna).__name__}")
        if self.position is not None:
            checks.vector(who, "position", self.position)


@dataclass(frozen=True)
class LinkBudget:
    """Transmit power ``P_U`` and noise power ``sigma^2`` (W), bandwidth ``B`` (normalized)."""

    tx_power: float = 1.0
    noise_power: float = 1.0
    bandwidth: float = 1.0

    def __post_init__(self):
        for name in ("tx_power", "noise_power", "bandwidth"):
            checks.number("LinkBudget", name, getattr(self, name), lo=0.0, lo_open=True)


@dataclass(frozen=True)
class NodePose:
    """Where a node is (``(..., 3)`` m, world) and where its antenna points (``(..., 3)`` unit, world);
    numpy arrays, or CasADi 3-vectors for a symbolic evaluation (baseline B's NLP)."""

    position: Any
    axis: Any


@dataclass(frozen=True)
class Emitter:
    """A jammer at one instant: position (m), boresight (unit, world), pattern, radiated power (W)."""

    position: np.ndarray | None  # None: a silent jammer whose position was not asked
    axis: np.ndarray
    pattern: AntennaPattern
    power: float


@dataclass(frozen=True)
class ChannelState:
    """One evaluation of the channel: per hop (every link of every route once, in route order) the
    SINR and the interference ``sum_j F_Jj^2 P_J`` at its receiver (W); the capacity of each route
    (``route_capacity``, eq. 9 with any number of hops) and the network's rate ``capacity`` (every
    hop of every route in its own slot: ``network_rate``; the route's capacity for one route). A route that
    may end at any of several base stations (``RadioScene.handover``) counts with its serving end or its
    best one (``RadioScene.evaluate``'s ``ends``)."""

    hops: tuple[tuple[str, str], ...]
    sinr: tuple[np.ndarray, ...]
    interference: tuple[np.ndarray, ...]
    capacity: np.ndarray
    route_capacity: tuple[np.ndarray, ...] = ()
    # per route, the rate of each route it may take (``RadioScene.candidate_routes``; a fixed route: one)
    candidates: tuple[tuple[np.ndarray, ...], ...] = ()
    # per route, the time slots of the schedule its rate was given by (``RadioScene.schedule``; empty: time division,
    # one slot per hop; 1: full duplex; numeric evaluations only)
    slots: tuple[np.ndarray, ...] = ()

    def spectral_efficiency(self) -> tuple[np.ndarray, ...]:
        """``log2(1 + Gamma_k)`` per hop, bit/s/Hz (eq. 8 with B = 1)."""
        return tuple(np.log2(1.0 + g) for g in self.sinr)


def _given(v):
    """A given jammer position or power: CasADi expressions as they are, numbers as floats."""
    if is_symbolic(v):
        return v
    v = np.asarray(v, float)
    return float(v) if v.ndim == 0 else v


def _dot(a, b):
    """``<a, b>`` over the last axis, broadcasting; an outer grid ``(M, 1, 3) x (1, K, 3)`` as one matmul."""
    if is_symbolic(a, b):
        return ops(a, b).dot(a, b)
    a, b = np.asarray(a, float), np.asarray(b, float)
    if a.ndim == 3 and b.ndim == 3 and a.shape[1] == 1 and b.shape[0] == 1:
        return a[:, 0, :] @ b[0].T
    if b.ndim == 1:
        return a @ b
    if a.ndim == 1:
        return b @ a
    return np.einsum("...i,...i->...", a, b)


def _gain(pattern: AntennaPattern, c):
    return pattern.symbolic_gain_from_cos(c) if is_symbolic(c) else pattern.gain_from_cos(c)


def link_gain(p_tx, b_tx, pat_tx: AntennaPattern, p_rx, b_rx, pat_rx: AntennaPattern, path: PathGain | None = None):
    """``G_tx(th_D) G_rx(th_A) / |p_rx - p_tx|^2`` (eq. 6; eq. 7 with the jammer as transmitter);
    with ``path``, ``G_tx G_rx K |p_rx - p_tx|^-n`` (``models/propagation.py``).

    ``b_tx``, ``b_rx``: antenna axes (unit, world); each gain from the cosine of the angle between
    the link and the axis at that end. numpy (broadcast) or CasADi 3-vectors.
    """
    if is_symbolic(p_tx, b_tx, p_rx, b_rx):
        p_tx, b_tx, p_rx, b_rx = (v if is_symbolic(v) else ca.DM(np.asarray(v, float)) for v in (p_tx, b_tx, p_rx, b_rx))
    else:
        p_tx, p_rx = np.asarray(p_tx, float), np.asarray(p_rx, float)
    d = p_rx - p_tx
    n2 = _dot(d, d)
    n = ops(n2).sqrt(n2)
    g = _gain(pat_tx, _dot(d, b_tx) / n) * _gain(pat_rx, -_dot(d, b_rx) / n)
    return g / n2 if path is None or path.is_paper else g * path.gain_between(p_tx, p_rx, n2)


def spectral_efficiency(gamma):
    """``log2(1 + Gamma)`` in bit/s/Hz (eq. 8 with B = 1); ``log1p`` for CasADi expressions."""
    if is_symbolic(gamma):
        return ops(gamma).log1p(gamma) / np.log(2.0)
    return np.log2(1.0 + np.asarray(gamma, float))


def route_capacity(sinrs: Sequence, bandwidth: float = 1.0):
    """End-to-end capacity of a route with equal time shares: ``C = B / sum_k 1/log2(1 + Gamma_k)``
    (eq. 9 for two hops, ``B a b / (a + b)``). Zero when any hop is dead. numpy (broadcast) or CasADi."""
    se = [spectral_efficiency(g) for g in sinrs]
    if is_symbolic(*se):
        return bandwidth / sum(1.0 / s for s in se)
    se = list(np.broadcast_arrays(*se))
    # B prod_k s_k / sum_k prod_(j != k) s_j: the same value, written so that two hops give eq. 9's
    # B a b / (a + b) operation for operation
    num = np.prod(se, axis=0)
    den = sum(np.prod([s for j, s in enumerate(se) if j != k], axis=0) for k in range(len(se)))
    alive = np.all([s > 0 for s in se], axis=0)
    with np.errstate(invalid="ignore"):
        out = bandwidth * np.where(alive, num / np.where(alive, den, 1.0), 0.0)
    if np.any(np.isinf(se)):  # a hop of zero length (two nodes on one point): its share of the time is 0
        with np.errstate(divide="ignore"):
            out = np.where(np.isnan(out), bandwidth / sum(1.0 / s for s in se), out)
    return out


def rate_of_routes(capacities: Sequence):
    """The network's rate from its routes' capacities ``C_r`` (each route's hops in their own slots):
    ``1 / sum_r 1 / C_r``, which is ``network_rate`` since ``C_r = B / sum_k 1/log2(1 + Gamma_k)``;
    zero when a route is dead. numpy (broadcast) or CasADi."""
    if is_symbolic(*capacities):
        return 1.0 / sum(1.0 / c for c in capacities)
    caps = list(np.broadcast_arrays(*(np.asarray(c, float) for c in capacities)))
    alive = np.all([c > 0 for c in caps], axis=0)
    return np.where(alive, 1.0 / sum(1.0 / np.where(alive, c, 1.0) for c in caps), 0.0)


def network_rate(route_sinrs: Sequence[Sequence], bandwidth: float = 1.0):
    """The rate every source of a network gets when every hop of every route has its own time slot
    (no two hops interfere; the jammers reach every receiver): ``R = B / sum_s sum_{k in route s}
    1/log2(1 + Gamma_{s,k})``, which is eq. 9 for one route of two hops. Zero when any hop is dead.
    ``route_sinrs``: per route, its hops' SINRs; numpy (broadcast) or CasADi."""
    se = [spectral_efficiency(g) for r in route_sinrs for g in r]
    if is_symbolic(*se):
        return bandwidth / sum(1.0 / s for s in se)
    se = list(np.broadcast_arrays(*se))
    alive = np.all([s > 0 for s in se], axis=0)
    with np.errstate(divide="ignore"):
        inv = sum(1.0 / np.where(alive, s, 1.0) for s in se)
    return bandwidth * np.where(alive, 1.0 / inv, 0.0)


SCHEDULES = ("tdma", "spatial_reuse", "full_duplex")


def schedule_rate(schedule: str, sinr: Sequence, base: Sequence, cross, relays_rx: Sequence[bool], hops: Sequence,
                  bandwidth: float, self_interference: float):
    """One route's rate and the time slots of the schedule that gives it, its ``H`` hops (in order) each with its
    SINR alone ``sinr`` (``S_k / N_k``: no other hop transmitting) and ``base`` ``N_k`` (noise plus the jammers'
    interference, W; so the signal ``S_k = sinr_k N_k``); ``cross(i, j)``: hop ``i``'s transmitter received at hop
    ``j``'s receiver (W). numpy (broadcast) or CasADi.

    - ``"tdma"``: one slot per hop, ``B / sum_k 1/log2(1 + S_k / N_k)`` (eq. 9).
    - ``"spatial_reuse"``: for each reuse distance ``m = 2..H``, slot ``j`` carries the hops ``k = j (mod m)`` at
      once (hops ``m >= 2`` apart share no node), each hop's SINR counting the slot's other transmitters,
      ``S_k / (N_k + sum_{i in slot, i != k} cross(i, k))``; a slot carries the bits its worst hop can, so the route
      delivers ``B / sum_slots 1 / min_{k in slot} log2(1 + SINR_k)``; the best ``m`` is taken (``m = H`` is time
      division itself). One relay (two hops sharing it): time division exactly.
    - ``"full_duplex"``: every hop at once, each receiver hearing every other transmitter but its own hop's and, where
      it transmits too (a relay: ``relays_rx``), its own transmission suppressed to ``self_interference`` (W):
      ``B min_k log2(1 + S_k / (N_k + SI_k + sum_{i != k, tx_i != rx_k} cross(i, k)))``; time division where it gives
      more (a full-duplex relay also runs half duplex).

    Returns ``(rate, slots)`` (the chosen schedule's number of slots; numeric only)."""
    H = len(sinr)
    symbolic = is_symbolic(*sinr)
    signal = [g * n for g, n in zip(sinr, base, strict=True)]
    tdma = route_capacity(list(sinr), bandwidth)
    if schedule == "tdma" or H == 1:
        return tdma, H
    lo = ca.fmin if symbolic else np.minimum
    hi = ca.fmax if symbolic else np.maximum
    options = [(tdma, H)]
    if schedule == "spatial_reuse":
        for m in range(2, H):
            slot_rates = []
            for j in range(m):
                members = list(range(j, H, m))
                se = [spectral_efficiency(signal[k] / (base[k] + sum(cross(i, k) for i in members if i != k)))
                      for k in members]
                slot_rates.append(bandwidth * reduce(lo, se))
            options.append((rate_of_routes(slot_rates), m))
    elif schedule == "full_duplex":
        se = []
        for k in range(H):
            heard = sum(cross(i, k) for i in range(H) if i != k and hops[i][0] != hops[k][1])
            se.append(spectral_efficiency(signal[k] / (base[k] + (self_interference if relays_rx[k] else 0.0) + heard)))
        options.append((bandwidth * reduce(lo, se), 1))
    else:
        raise ValueError(f"schedule must be one of {', '.join(SCHEDULES)}, got {schedule!r}")
    rate = reduce(hi, [r for r, _ in options])
    if symbolic:
        return rate, H
    stack = np.stack(np.broadcast_arrays(*[np.asarray(r, float) for r, _ in options]))
    slots = np.asarray([n for _, n in options])[np.argmax(stack, axis=0)]
    return rate, slots


def relay_subsets(relays: Sequence[str]) -> tuple[tuple[str, ...], ...]:
    """Every subsequence of ``relays`` (their order kept): all of them first, then by one fewer, down to none (the
    direct link); within a size in ``itertools.combinations``' order."""
    return tuple(c for n in range(len(relays), -1, -1) for c in combinations(tuple(relays), n))


def route_via(route: Sequence[str]) -> str:
    """The relays carrying ``route`` (source first, base station last), as a label: their names joined by '+', or
    'direct' (the log's ``<source>.route``, the bound's ``route_combinations``)."""
    return "+".join(route[1:-1]) or "direct"


@dataclass(frozen=True)
class RadioScene:
    """Nodes, jammers, link budget and the routes data takes (node names, a source first, a base
    station last): ``route`` for one, ``routes`` for a network (then ``route`` is ignored)."""

    nodes: tuple[Node, ...]
    jammers: tuple[Jammer, ...] = ()
    budget: LinkBudget = LinkBudget()
    route: tuple[str, ...] = ("source", "relay", "bs")
    path_gain: PathGain = PathGain()  # deterministic large-scale propagation of every link
    routes: tuple[tuple[str, ...], ...] = ()  # a network's routes (empty: the one ``route``)
    # per route of ``all_routes``, the base stations it may end at (its serving end among them; empty: its end is
    # fixed); ``()``: every route's end fixed
    handover: tuple[tuple[str, ...], ...] = ()
    # how a route's hops share the time (``SCHEDULES``; the routes always take turns): "tdma", one slot per hop;
    # "spatial_reuse", hops sharing no node in one slot, each the others' interference; "full_duplex", every hop at once
    # with the relays' self-interference suppressed by ``self_interference_db`` (dB below the transmit power)
    schedule: str = "tdma"
    self_interference_db: float = 110.0
    # per route of ``all_routes``, the relays it may skip (its configured relays in order; the serving route takes a
    # subsequence of them: route selection over relay subsets); ``()``: every route takes the relays named on it
    skips: tuple[tuple[str, ...], ...] = ()

    def __post_init__(self):
        for field_name, items, kind in (("nodes", self.nodes, Node), ("jammers", self.jammers, Jammer)):
            bad = [type(x).__name__ for x in items if not isinstance(x, kind)]
            if bad:
                raise checks.InvalidInput(f"RadioScene.{field_name}: must hold {kind.__name__} objects, got {bad[0]}")
        if not isinstance(self.budget, LinkBudget):
            raise checks.InvalidInput(f"RadioScene.budget: must be a LinkBudget, got {type(self.budget).__name__}")
        checks.has_method("RadioScene", "path_gain", self.path_gain, "gain_from_d2", "a path gain (models.propagation)")
        names = [n.name for n in self.nodes]
        if len(set(names)) != len(names):
            raise ValueError(f"radio scene: node names must be unique, got {names}")
        for route in self.all_routes:
            missing = [r for r in route if r not in names]
            if missing or len(route) < 2:
                raise ValueError(f"radio scene: route {list(route)} must name >= 2 of the nodes {names}")
            if self.node(route[0]).role != "source" or self.node(route[-1]).role != "base_station":
                raise ValueError("radio scene: the route must start at a source and end at a base station")
            if len(set(route)) != len(route):
                raise ValueError(f"radio scene: route {list(route)} passes a node twice")
        if self.handover:
            if len(self.handover) != len(self.all_routes):
                raise ValueError(f"radio scene: handover gives {len(self.handover)} routes' base stations for "
                                 f"{len(self.all_routes)} routes")
            for route, ends in zip(self.all_routes, self.handover, strict=True):
                wrong = [e for e in ends if e not in names or self.node(e).role != "base_station"]
                if wrong or (ends and route[-1] not in ends):
                    raise ValueError(f"radio scene: route {list(route)} may end at {list(ends)}: each a base station, "
                                     "its serving end among them")
        if self.skips:
            if len(self.skips) != len(self.all_routes):
                raise ValueError(f"radio scene: skips gives {len(self.skips)} routes' relays for {len(self.all_routes)} routes")
            for route, relays in zip(self.all_routes, self.skips, strict=True):
                wrong = [r for r in relays if r not in names or self.node(r).role != "relay"]
                if wrong or tuple(route[1:-1]) not in relay_subsets(relays):
                    raise ValueError(f"radio scene: route {list(route)} may skip {list(relays)}: each a relay, the route's "
                                     "relays a subsequence of them")
        for j in self.jammers:
            if j.point_at is not None and j.point_at not in names:
                raise ValueError(f"jammer {j.name!r}: point_at {j.point_at!r} is not a node ({', '.join(names)})")
        checks.one_of("RadioScene", "schedule", self.schedule, SCHEDULES)

    def world_view(self) -> RadioScene:
        """The scene as the relay knows it: nodes, antennas, link budget and propagation, and each
        jammer's antenna but not where it is or what it radiates (``HiddenJammer``): planners and
        controllers are built from this, the truth stays in the plant and the metrics."""
        return replace(self, jammers=tuple(HiddenJammer.of(j) for j in self.jammers))

    def node(self, name: str) -> Node:
        for n in self.nodes:
            if n.name == name:
                return n
        raise KeyError(f"radio scene has no node {name!r}")

    def name_of(self, role: Role) -> str:
        """The first node with this role."""
        return next(n.name for n in self.nodes if n.role == role)

    def without(self, lost) -> RadioScene:
        """The scene with the relays named in ``lost`` gone: every route through one skips it (two
        routes that become one are one), the nodes removed; the jammers as they are (their powers
        were set for the whole fleet)."""
        lost = set(lost)
        routes: list[tuple[str, ...]] = []
        ends: list[tuple[str, ...]] = []
        for r, e in zip(self.all_routes, self.route_ends, strict=True):
            kept = tuple(n for n in r if n not in lost)
            if kept not in routes:
                routes.append(kept)
                ends.append(e)
        nodes = tuple(n for n in self.nodes if n.name not in lost)
        return replace(self, nodes=nodes, route=routes[0], routes=tuple(routes) if len(routes) > 1 else (),
                       handover=tuple(ends) if self.handover else (),
                       skips=tuple(tuple(r for r in s if r not in lost) for s in self.skips) if self.skips else ())

    def handed_to(self, leaving: str, node: Node) -> RadioScene:
        """The scene with ``node`` (a spare relay) in the place of relay ``leaving`` on every route, ``leaving``'s
        node gone; the jammers as they are (one aimed at ``leaving`` aims at ``node``)."""
        if self.node(leaving).role != "relay" or node.role != "relay":
            raise ValueError(f"handed_to: {leaving!r} and {node.name!r} must both be relays")
        routes = tuple(tuple(node.name if n == leaving else n for n in r) for r in self.all_routes)
        nodes = tuple(node if n.name == leaving else n for n in self.nodes)
        jammers = tuple(replace(j, point_at=node.name) if j.point_at == leaving else j for j in self.jammers)
        skips = tuple(tuple(node.name if n == leaving else n for n in s) for s in self.skips)
        return replace(self, nodes=nodes, jammers=jammers, route=routes[0], routes=routes if len(routes) > 1 else (),
                       skips=skips)

    @property
    def node_names(self) -> frozenset[str]:
        """The names of the scene's nodes."""
        return frozenset(n.name for n in self.nodes)

    @property
    def route_ends(self) -> tuple[tuple[str, ...], ...]:
        """Per route of ``all_routes``, the base stations it may end at (``handover``; empty: its end is fixed)."""
        return self.handover or ((),) * len(self.all_routes)

    def serving(self, ends: Sequence[str]) -> RadioScene:
        """The scene with each route ending at ``ends`` (a base station each, one it may end at)."""
        return self.serving_routes(tuple(r[:-1] + (str(e),) for r, e in zip(self.all_routes, ends, strict=True)))

    def serving_routes(self, routes: Sequence[Sequence[str]]) -> RadioScene:
        """The scene with each route served by ``routes`` (one of its ``candidate_routes`` each, the handover rule's
        choice; a plain scene, without ``handover`` and ``skips``, takes any: ``planning.network_bound.end_choices``)."""
        served: tuple[tuple[str, ...], ...] = tuple(tuple(str(n) for n in r) for r in routes)
        return replace(self, route=served[0], routes=served if len(served) > 1 else ())

    def configured(self) -> RadioScene:
        """The scene with each route taking every relay it may skip (``skips``; its serving end kept): the network as
        configured, whose planner places every relay on its route."""
        if not self.skips:
            return self
        return self.serving_routes(tuple((r[0], *s, r[-1]) for r, s in zip(self.all_routes, self.skips, strict=True)))

    @property
    def route_choice(self) -> bool:
        """Whether a route may change in flight: its end (``handover``) or the relays that carry it (``skips``)."""
        return any(self.handover) or any(self.skips)

    @property
    def candidate_routes(self) -> tuple[tuple[tuple[str, ...], ...], ...]:
        """Per route, every route it may take: each subset of the relays it may skip (``skips``; from all of them
        down to none, in ``relay_subsets``' order; else its own relays), each with every base station it may end at,
        in ``handover``'s order (else its own end). The serving route is among them."""
        out = []
        for i, (r, e) in enumerate(zip(self.all_routes, self.route_ends, strict=True)):
            subsets = relay_subsets(self.skips[i]) if self.skips else (tuple(r[1:-1]),)
            out.append(tuple((r[0], *sub, b) for sub in subsets for b in (e or (r[-1],))))
        return tuple(out)

    @property
    def all_routes(self) -> tuple[tuple[str, ...], ...]:
        """The routes data takes: ``routes``, or the one ``route``."""
        return tuple(tuple(r) for r in self.routes) if self.routes else (tuple(self.route),)

    @property
    def hops(self) -> tuple[tuple[str, str], ...]:
        """Every link of every route once (a link two routes share is one hop), in route order; a route
        that may end at several base stations with each (``candidate_routes``: the order does not
        depend on which serves)."""
        out: list[tuple[str, str]] = []
        for routes in self.candidate_routes:
            for route in routes:
                out += [h for h in zip(route[:-1], route[1:], strict=True) if h not in out]
        return tuple(out)

    def route_hops(self) -> tuple[tuple[int, ...], ...]:
        """Per route, the indices in ``hops`` of its links, in order."""
        hops = self.hops
        return tuple(tuple(hops.index(h) for h in zip(r[:-1], r[1:], strict=True)) for r in self.all_routes)

    def candidate_hops(self) -> tuple[tuple[tuple[int, ...], ...], ...]:
        """Per route, per route it may take (``candidate_routes``), the indices in ``hops`` of its links."""
        hops = self.hops
        return tuple(tuple(tuple(hops.index(h) for h in zip(r[:-1], r[1:], strict=True)) for r in routes)
                     for routes in self.candidate_routes)

    @property
    def fading_links(self) -> int:
        """Links a fading draw multiplies: every hop, then every (hop receiver, jammer) pair."""
        return len(self.hops) * (1 + len(self.jammers))

    def link_ends(self) -> list[tuple[str, str, int | None]]:
        """``(tx, rx, jammer index or None)`` per link, in ``fading_links`` order."""
        out: list[tuple[str, str, int | None]] = [(tx, rx, None) for tx, rx in self.hops]
        for _, rx in self.hops:
            out += [(j.name, rx, i) for i, j in enumerate(self.jammers)]
        return out

    def end_antennas(self, link: tuple[str, str, int | None], poses: Mapping[str, NodePose], emitters: Sequence[Emitter]):
        """``(pattern_tx, axis_tx, pattern_rx, axis_rx)`` of a link of ``link_ends`` (a jammer's from ``emitters``)."""
        a, b, j = link
        pat_tx, b_tx = (self.node(a).antenna.pattern, poses[a].axis) if j is None else (emitters[j].pattern, emitters[j].axis)
        return pat_tx, b_tx, self.node(b).antenna.pattern, poses[b].axis

    def fixed_pose(self, name: str) -> NodePose:
        """Pose of a fixed node (identity attitude)."""
        n = self.node(name)
        if n.position is None:
            raise ValueError(f"node {name!r} moves: its pose comes from the simulation")
        return NodePose(np.asarray(n.position, float), n.antenna.world_axis(np.eye(3)))

    def pose(self, name: str, position, R) -> NodePose:
        """Pose of node ``name`` at ``position`` with body-to-world rotation ``R``."""
        return NodePose(np.asarray(position, float), self.node(name).antenna.world_axis(R))

    def with_fixed(self, poses: Mapping[str, NodePose]) -> dict[str, NodePose]:
        """``poses`` with every fixed node's pose added where it is missing."""
        return {n.name: self.fixed_pose(n.name) for n in self.nodes if n.position is not None and n.name not in poses} | dict(poses)

    def emitters(self, t: float, poses: Mapping[str, NodePose], *, positions=None, powers=None) -> list[Emitter]:
        """Every jammer at time ``t``: true position and power, or the given ``positions`` ``(nJ, 3)``
        and ``powers`` ``(nJ,)`` (what a controller knows); boresights track their target node."""
        out = []
        for i, j in enumerate(self.jammers):
            power = _given(powers[i]) if powers is not None else float(j.power_at(t))
            silent = not is_symbolic(power) and power == 0.0
            # a silent jammer adds nothing wherever it is (``interference`` skips it): its position is not asked
            p = _given(positions[i]) if positions is not None else None if silent else j.position_at(t)
            target = poses[j.point_at].position if j.point_at is not None and not silent else None
            axis = np.asarray(j.boresight, float) if p is None else j.axis(p, target)
            out.append(Emitter(p, axis, j.pattern, power))
        return out

    def interference(self, emitters: Sequence[Emitter], rx: NodePose, pat_rx: AntennaPattern, fading=None, gains=None):
        """``sum_j F_Jj^2 P_J`` at a receiver (eq. 7), W; ``fading`` one power gain per emitter; ``gains`` each
        emitter's link power gain ``F_Jj^2`` given (a ray-traced channel's) instead of ``link_gain``."""
        total = 0.0
        for i, e in enumerate(emitters):
            if not is_symbolic(e.power) and e.power == 0.0:
                continue
            f = gains[i] if gains is not None else link_gain(e.position, e.axis, e.pattern, rx.position, rx.axis, pat_rx,
                                                             self.path_gain)
            if fading is not None:
                f = f * fading[i]
            total = total + f * e.power
        return total

    def evaluate(self, t: float, poses: Mapping[str, NodePose], *, jammer_positions=None, jammer_powers=None,
                 fading=None, link_gains=None, ends: Literal["best", "serving"] = "best") -> ChannelState:
        """SINR of every hop (eq. 5) and the end-to-end capacity (eq. 9) with the nodes at ``poses``
        (fixed nodes may be omitted). The jammers are the true ones at ``t`` unless
        ``jammer_positions`` ``(nJ, 3)`` / ``jammer_powers`` ``(nJ,)`` say what a controller knows;
        ``fading``: ``fading_links`` power gains (hops first, then each receiver's jammer links);
        ``link_gains``: the same links' power gains, antennas included, given instead of eq. 6-7's (a
        ray-traced channel, ``sim/traced.py``); ``fading`` multiplies them as it does eq. 6-7's.
        ``ends``: a route that may end at several base stations (``handover``) counts with the best of
        them (``"best"``: what a planner or a bound can reach, per element of a grid) or with the one
        serving it now (``"serving"``: its end in ``all_routes``, the network's truth)."""
        if ends not in ("best", "serving"):
            raise ValueError(f"evaluate: ends must be 'best' or 'serving', got {ends!r}")
        poses = self.with_fixed(poses)
        emitters = self.emitters(t, poses, positions=jammer_positions, powers=jammer_powers)
        b, nh, nj = self.budget, len(self.hops), len(emitters)
        sinrs, interference = [], []
        with np.errstate(divide="ignore", invalid="ignore"):  # a jammer on a receiver: infinite interference
            for k, (tx, rx) in enumerate(self.hops):
                h = link_gains[k] if link_gains is not None else link_gain(
                    poses[tx].position, poses[tx].axis, self.node(tx).antenna.pattern,
                    poses[rx].position, poses[rx].axis, self.node(rx).antenna.pattern, self.path_gain)
                if fading is not None:
                    h = h * fading[k]
                jam_fade = None if fading is None else fading[nh + k * nj: nh + (k + 1) * nj]
                jam_gains = None if link_gains is None else link_gains[nh + k * nj: nh + (k + 1) * nj]
                i_rx = self.interference(emitters, poses[rx], self.node(rx).antenna.pattern, jam_fade, jam_gains)
                if not is_symbolic(i_rx):
                    i_rx = np.nan_to_num(i_rx, nan=np.inf)
                sinrs.append(h * b.tx_power / (i_rx + b.noise_power))  # eq. 5
                interference.append(i_rx)
        if self.schedule != "tdma":
            if link_gains is not None:
                raise ValueError(f"evaluate: schedule {self.schedule!r} needs the links between the hops' transmitters and "
                                 "receivers, which a ray-traced channel's gains do not give: time division only")
            return self._scheduled(poses, sinrs, interference, ends)
        if not self.route_choice:
            per_route = [[sinrs[k] for k in r] for r in self.route_hops()]
            routes = tuple(route_capacity(r, b.bandwidth) for r in per_route)
            rate = routes[0] if len(routes) == 1 else network_rate(per_route, b.bandwidth)
            return ChannelState(self.hops, tuple(sinrs), tuple(interference), rate, routes, tuple((c,) for c in routes))
        candidates = tuple(tuple(route_capacity([sinrs[k] for k in hs], b.bandwidth) for hs in route)
                           for route in self.candidate_hops())
        if ends == "serving":
            chosen = tuple(c[rs.index(r)] for c, rs, r in zip(candidates, self.candidate_routes, self.all_routes, strict=True))
        else:
            most = ca.fmax if is_symbolic(*sinrs) else np.maximum
            chosen = tuple(reduce(most, c) for c in candidates)
        rate = chosen[0] if len(chosen) == 1 else rate_of_routes(chosen)
        return ChannelState(self.hops, tuple(sinrs), tuple(interference), rate, chosen, candidates)

    def _scheduled(self, poses: Mapping[str, NodePose], sinrs: list, interference: list, ends: str) -> ChannelState:
        """``evaluate``'s rates under ``schedule`` (not time division): each route's by ``schedule_rate`` from its hops'
        signals (``sinrs`` times their noise and jammers' interference) and the links between their transmitters
        and receivers; the routes take turns (``rate_of_routes``); a route that may end at several base stations
        with its best or serving end, as ``evaluate``."""
        b = self.budget
        hops = self.hops
        base = [i + b.noise_power for i in interference]

        def cross(k_tx: int, k_rx: int):
            """The transmitter of hop ``k_tx`` into the receiver of hop ``k_rx``: its received power (W)."""
            tx, rx = hops[k_tx][0], hops[k_rx][1]
            return b.tx_power * link_gain(poses[tx].position, poses[tx].axis, self.node(tx).antenna.pattern,
                                          poses[rx].position, poses[rx].axis, self.node(rx).antenna.pattern, self.path_gain)

        def rate(hs: Sequence[int]):
            relays = {hops[k][1] for k in hs[:-1]}  # every receiver but the last transmits too
            return schedule_rate(self.schedule, [sinrs[k] for k in hs], [base[k] for k in hs],
                                 lambda i, j: cross(hs[i], hs[j]), [hops[k][1] in relays for k in hs],
                                 [hops[k] for k in hs], b.bandwidth, b.tx_power * 10.0 ** (-self.self_interference_db / 10.0))

        per_route = [[rate(hs) for hs in route] for route in self.candidate_hops()]
        candidates = tuple(tuple(c for c, _ in route) for route in per_route)
        if ends == "serving" or not self.route_choice:
            pick = [rs.index(r) for rs, r in zip(self.candidate_routes, self.all_routes, strict=True)]
            chosen = tuple(per_route[i][j][0] for i, j in enumerate(pick))
            slots = tuple(per_route[i][j][1] for i, j in enumerate(pick))
        elif is_symbolic(*sinrs):
            chosen, slots = tuple(reduce(ca.fmax, c) for c in candidates), ()
        else:  # each route's best end, and the slots of its schedule there
            chosen = tuple(reduce(np.maximum, c) for c in candidates)
            slots = tuple(np.choose(np.argmax(np.stack(np.broadcast_arrays(*[np.asarray(c, float) for c, _ in route])), axis=0),
                                    np.broadcast_arrays(*[np.asarray(n) for _, n in route])) for route in per_route)
        rate_all = chosen[0] if len(chosen) == 1 else rate_of_routes(chosen)
        return ChannelState(hops, tuple(sinrs), tuple(interference), rate_all, chosen, candidates,
                            () if is_symbolic(*sinrs) else slots)

    def relay_grid(self, t: float, positions, axes, poses: Mapping[str, NodePose], *, jammer_positions=None,
                   jammer_powers=None, relay: str | None = None, fading=None) -> np.ndarray:
        """End-to-end capacity ``(M, K)`` for relay positions ``(M, 3)`` x relay antenna axes ``(K, 3)``
        (world), the other moving nodes at ``poses``, the jammers as in ``evaluate``; ``fading`` as
        there, each link's gain a scalar or ``(M, 1)`` (per relay position). ``relay``: the node
        placed on the grid (default: the scene's first relay)."""
        relay = relay or self.name_of("relay")
        P = np.atleast_2d(np.asarray(positions, float))[:, None, :]
        B = np.atleast_2d(np.asarray(axes, float))[None, :, :]
        state = self.evaluate(t, {**poses, relay: NodePose(P, B)}, jammer_positions=jammer_positions, jammer_powers=jammer_powers,
                              fading=fading)
        return np.broadcast_to(state.capacity, (P.shape[0], B.shape[1]))

    def describe(self) -> str:
        """The scene's assumptions in words (``bound.json``, reports)."""
        def pattern(p: AntennaPattern) -> str:
            return f"{type(p).__name__.removesuffix('Pattern').lower()} (peak gain {p.g_bar:g})"

        parts = []
        for n in self.nodes:
            where = f" at {np.round(np.asarray(n.position, float), 2).tolist()} m" if n.position is not None else ""
            parts.append(f"{n.role} '{n.name}'{where}: {pattern(n.antenna.pattern)} antenna, axis "
                         f"{np.round(n.antenna.axis, 3).tolist()} in its body frame")
        for j in self.jammers:
            where = "moving along timed waypoints" if j.path is not None else f"fixed at {np.round(j.position, 2).tolist()} m"
            aim = f", pointed at '{j.point_at}'" if j.point_at else ""
            parts.append(f"jammer '{j.name}' {where}, {j.power:g} W peak, {type(j.schedule).__name__}, "
                         f"{pattern(j.pattern)}{aim}")
        if not self.jammers:
            parts.append("no jammer")
        b = self.budget
        routes = "; ".join(" -> ".join(r[:-1]) + (f" -> any of {'/'.join(e)}" if e else f" -> {r[-1]}")
                           for r, e in zip(self.all_routes, self.route_ends, strict=True))
        parts.append(f"P_U {b.tx_power:g} W, noise {b.noise_power:g} W, B {b.bandwidth:g}; "
                     f"{'route' if len(self.all_routes) == 1 else 'routes'} {routes}")
        if not self.path_gain.is_paper:
            parts.append(self.path_gain.describe())
        return "; ".join(parts)
