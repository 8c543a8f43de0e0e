"""The one log vocabulary of a run, for any number of relays and sources (one row per control step).

Every vehicle's columns are ``<node>.<quantity>`` by its node name (``relay`` and ``source`` in a
file with ``nodes.relay``; ``r1``, ``inspector`` in a network file):

- a relay: its plant state ``p_x p_y p_z`` (m, world ENU), ``phi theta psi`` (rad, ZYX Euler),
  ``v_x v_y v_z`` (m/s, world), ``omega_x omega_y omega_z`` (rad/s, body FLU), ``Omega_1..n`` (rotor
  speeds, Hz), ``u_1..n`` (their rates, Hz/s); its step: ``pd_x pd_y pd_z`` (the planner's position
  reference, m), ``v_up`` / ``v_down`` (its antenna's misalignment toward its upstream node, the
  source side, and its downstream node, the base-station side, on its first route: eq. 11's
  ``v_12`` / ``v_10``), ``mutual_alignment`` (``(1 - v_up)(1 - v_down)``), ``slack_max``,
  ``solve_ms``, ``feedback_ms``, ``qp_ok``, ``qp_status`` (``lost`` once the relay is lost),
  ``fallback``, ``safety_violation``, ``taylor_rel_err`` (the paper's generator's; 0 otherwise);
- a source: ``p_x p_y p_z`` (m) and ``phi theta psi`` (rad; its attitude follows its acceleration).

The links: each hop's SINR ``sinr.<tx>.<rx>`` and spectral efficiency ``se.<tx>.<rx>`` (bit/s/Hz,
``log2(1 + SINR)``); each route's rate ``capacity.<source>`` (eq. 9 over its hops) and the network's
``capacity`` (``models.radio.network_rate``); ``jammer_on``; ``separation_min`` (m, the smallest
distance between two vehicles); each jammer's true position ``jam_<name>_x/y/z`` (m). The random
channel terms, blockage, jammer estimate and wind add their own columns (``sim/perturbations.py``,
``sim/blockage.py``, ``sim/jammer_sensing.py``, ``sim/air.py``: a relay's are ``<relay>.a_drag_x``...); a relay
with a battery (``[platform.battery]``) its state of charge at the step's start ``<relay>.soc`` (the usable
energy left, fraction) and ``<relay>.battery_reserve`` (at or below its reserve), and when it may fly home
``<relay>.going_home`` (it has turned home and left the network; its columns are NaN once it is down).

Run folders written before this vocabulary (one relay: ``p1_x``, ``gamma_21``...) are read through
``LEGACY_COLUMNS`` (``modern_columns``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping, Sequence

import numpy as np

from ..control.nmpc import StepInfo
from ..models.channel import misalignment, mutual_alignment
from ..models.radio import ChannelState, RadioScene
from ..models.state import RIGID, RIGID_NAMES, ROTORS, P
from ..planning.base import Reference

VEHICLE_STATE = RIGID_NAMES  # the state's rigid-body part by name (models.state)
SOURCE_STATE = ("p_x", "p_y", "p_z", "phi", "theta", "psi")
RELAY_STEP = ("pd_x", "pd_y", "pd_z", "v_up", "v_down", "mutual_alignment", "slack_max", "solve_ms", "feedback_ms", "qp_ok",
              "qp_status", "fallback", "safety_violation", "taylor_rel_err")
# the quantities that are not floats, with their types (flags and the QP's status text)
COLUMN_TYPES: dict[str, type] = {"jammer_on": bool, "qp_ok": bool, "qp_status": str, "fallback": bool,
                                 "safety_violation": bool, "battery_reserve": bool,
                                 "going_home": bool, "base_station": str, "waiting": bool, "ferrying": bool,
                                 "replaces": str, "route": str}
NETWORK_COLUMNS = ("capacity", "jammer_on", "separation_min")
# a jammer estimate's position covariance as logged: est_<name>_cov_<entry>, its six entries and where they sit
COV_ENTRIES = (("xx", 0, 0), ("yy", 1, 1), ("zz", 2, 2), ("xy", 0, 1), ("xz", 0, 2), ("yz", 1, 2))


def logged_covariance(log, name: str, k: int = -1) -> np.ndarray:
    """Jammer ``name``'s estimated position covariance ``(3, 3)`` (m^2) at row ``k``, from its six logged entries."""
    cov = np.empty((3, 3))
    for entry, a, b in COV_ENTRIES:
        cov[a, b] = cov[b, a] = float(np.asarray(log[f"est_{name}_cov_{entry}"], float)[k])
    return cov


def column_type(name: str) -> type:
    """A column's type: its quantity's (the part after the last dot) in ``COLUMN_TYPES``, else float."""
    return COLUMN_TYPES.get(name.rsplit(".", 1)[-1], float)


def rotor_quantities(n_rotors: int) -> list[str]:
    """A relay's rotor speeds' (``Omega_i``, Hz) and their rates' (``u_i``, Hz/s) quantities."""
    return [f"Omega_{i}" for i in range(1, n_rotors + 1)] + [f"u_{i}" for i in range(1, n_rotors + 1)]


def relay_columns(name: str, n_rotors: int) -> list[str]:
    """A relay's columns, in order."""
    return [f"{name}.{q}" for q in (*VEHICLE_STATE, *rotor_quantities(n_rotors), *RELAY_STEP)]


def source_columns(name: str) -> list[str]:
    return [f"{name}.{q}" for q in SOURCE_STATE]


def hop_columns(hops: Iterable[tuple[str, str]]) -> list[str]:
    hops = list(hops)
    return [f"sinr.{tx}.{rx}" for tx, rx in hops] + [f"se.{tx}.{rx}" for tx, rx in hops]


def jammer_columns(scene: RadioScene) -> list[str]:
    """The true jammer positions' columns ``jam_<name>_x/y/z`` (m, world)."""
    return [f"jam_{j.name}_{a}" for j in scene.jammers for a in "xyz"]


def jammer_values(scene: RadioScene, t: float) -> dict[str, float]:
    """Every jammer's true position at ``t`` by its ``jammer_columns`` names."""
    return dict(zip(jammer_columns(scene), [float(v) for j in scene.jammers for v in j.position_at(t)], strict=True))


def log_columns(relays: Mapping[str, int], sources: Sequence[str], scene: RadioScene,
                later_hops: Sequence[tuple[str, str]] = ()) -> list[str]:
    """A run's columns, in order: ``t``, every relay's (``relays``: name -> rotor count), every source's,
    the scene's hops and then ``later_hops`` (links the network takes after a relay is lost), the routes',
    the network's, the jammers'."""
    cols = ["t"]
    for name, n in relays.items():
        cols += relay_columns(name, n)
    for s in sources:
        cols += source_columns(s)
    cols += hop_columns([*scene.hops, *(h for h in later_hops if h not in scene.hops)])
    cols += [f"capacity.{route[0]}" for route in scene.all_routes]
    if scene.schedule != "tdma":  # the time slots of the schedule each route's rate took (network.schedule)
        cols += [f"slots.{route[0]}" for route in scene.all_routes]
    return cols + list(NETWORK_COLUMNS) + jammer_columns(scene)


def relay_row(name: str, x: np.ndarray, R: np.ndarray, info: StepInfo, ref: Reference, p_up: np.ndarray,
              p_down: np.ndarray, violation: bool) -> dict[str, object]:
    """A relay's values at a step: its plant state ``x`` (12 + n rotor speeds) with attitude ``R`` (body to
    world), its NMPC's step ``info`` (input ``u``, n), the planner's ``ref``, its antenna's misalignments toward
    its upstream node at ``p_up`` and its downstream node at ``p_down`` (m, world), the supervisor's ``violation``."""
    n = info.u.shape[0]
    if x.shape != (12 + n,):
        raise ValueError(f"log row of {name!r}: state {x.shape} does not match the {n}-rotor input")
    row: dict[str, object] = {f"{name}.{q}": float(v) for q, v in zip(VEHICLE_STATE, x[RIGID], strict=True)}
    row |= {f"{name}.{q}": float(v) for q, v in zip(rotor_quantities(n), np.r_[x[ROTORS], info.u], strict=True)}
    v_up, v_down = float(misalignment(x[P], R, p_up)), float(misalignment(x[P], R, p_down))
    step = {"pd_x": ref.p_ref[0], "pd_y": ref.p_ref[1], "pd_z": ref.p_ref[2], "v_up": v_up, "v_down": v_down,
            "mutual_alignment": float(mutual_alignment(v_up, v_down)), "slack_max": info.slack_max,
            "solve_ms": info.solve_ms, "feedback_ms": info.feedback_ms, "qp_ok": info.ok, "qp_status": info.status,
            "fallback": info.fallback, "safety_violation": violation, "taylor_rel_err": ref.taylor_rel_err}
    return row | {f"{name}.{q}": step[q] for q in RELAY_STEP}


def gone_row(name: str, n_rotors: int, status: str = "lost") -> dict[str, object]:
    """A relay's columns at a step it does not fly (lost, landed, or a spare waiting: ``status`` "standby"): NaN,
    its flags false, ``qp_status`` ``status``."""
    row: dict[str, object] = {c: math.nan for c in relay_columns(name, n_rotors)}
    return row | {f"{name}.qp_ok": False, f"{name}.qp_status": status, f"{name}.fallback": False,
                  f"{name}.safety_violation": False}


def source_row(name: str, p: np.ndarray, eta: np.ndarray) -> dict[str, float]:
    return {f"{name}.{q}": float(v) for q, v in zip(SOURCE_STATE, [*p, *eta], strict=True)}


def link_row(scene: RadioScene, t: float, state: ChannelState) -> dict[str, float]:
    """The links' values of ``state`` (the scene's channel at ``t``): every hop's SINR and spectral
    efficiency, every route's rate, the network's, whether a jammer radiates, the jammers' positions."""
    row = {f"sinr.{tx}.{rx}": float(g) for (tx, rx), g in zip(state.hops, state.sinr, strict=True)}
    row |= {f"se.{tx}.{rx}": math.log2(1.0 + float(g)) for (tx, rx), g in zip(state.hops, state.sinr, strict=True)}
    row |= {f"capacity.{route[0]}": float(c) for route, c in zip(scene.all_routes, state.route_capacity, strict=True)}
    if scene.schedule != "tdma":
        row |= {f"slots.{route[0]}": float(n) for route, n in zip(scene.all_routes, state.slots, strict=True)}
    row["capacity"] = float(state.capacity)
    row["jammer_on"] = float(any(float(j.power_at(t)) > 0 for j in scene.jammers))
    return row | jammer_values(scene, t)


def separation_min(points: np.ndarray) -> float:
    """The smallest distance (m) between two of ``points`` ``(n, 3)``; inf for fewer than two."""
    n = len(points)
    if n < 2:
        return math.inf
    if n <= 8:  # a few vehicles: pairwise in Python (numpy's broadcast cost 70 us a step for two)
        rows = [tuple(map(float, p)) for p in points]
        return min(math.dist(rows[i], rows[j]) for i in range(n) for j in range(i + 1, n))
    d = np.linalg.norm(points[:, None, :] - points[None, :, :], axis=-1)
    return float(d[np.triu_indices(n, 1)].min())


def new_log(columns: list[str], n_steps: int, kind_of: Callable[[str], type] = column_type) -> dict[str, np.ndarray]:
    """An empty per-step log: a float, bool or object (text) array per column, by ``kind_of``."""
    def empty(kind: type) -> np.ndarray:
        return np.zeros(n_steps, dtype=bool) if kind is bool else np.empty(n_steps, dtype=object) if kind is str \
            else np.empty(n_steps)
    return {c: empty(kind_of(c)) for c in columns}


def record_row(log: dict[str, np.ndarray], k: int, row: dict, columns: list[str], who: str = "log row") -> None:
    """Write step ``k``'s ``row`` (by column name) into ``log``; at the first step, a column declared
    but not recorded, or recorded but not declared, is an error."""
    if k == 0 and set(row) != set(columns):
        raise ValueError(f"{who}: columns {sorted(set(columns) ^ set(row))} not both declared and recorded")
    for name, val in row.items():
        log[name][k] = val


def steps_flown(log: dict[str, np.ndarray], flown: int) -> dict[str, np.ndarray]:
    """The log's first ``flown`` steps (a flight ended early keeps what it flew)."""
    return {c: v[:flown] for c, v in log.items()}


# -- what a log holds ------------------------------------------------------------------------------------
def relays_in(columns: Iterable[str]) -> list[str]:
    """The relays of a log, in its order (each has ``<name>.pd_x``)."""
    return [c[:-5] for c in columns if c.endswith(".pd_x")]


def sources_in(columns: Iterable[str]) -> list[str]:
    """The sources of a log, in its order (each has ``<name>.phi`` and no reference)."""
    cols = list(columns)
    relays = set(relays_in(cols))
    return [c[:-4] for c in cols if c.endswith(".phi") and c[:-4] not in relays]


def rotor_count(columns: Iterable[str], relay: str) -> int:
    """How many rotors ``relay``'s columns have."""
    return sum(1 for c in columns if c.startswith(f"{relay}.Omega_"))


# -- run folders written before the one vocabulary ---------------------------------------------------------
_OLD_RELAY = dict(zip(("p1_x", "p1_y", "p1_z", "phi1", "theta1", "psi1", "v1_x", "v1_y", "v1_z", "omega1_x", "omega1_y",
                       "omega1_z"), VEHICLE_STATE, strict=True))
_OLD_SOURCE = dict(zip(("p2_x", "p2_y", "p2_z", "phi2", "theta2", "psi2"), SOURCE_STATE, strict=True))
_OLD_STEP = {"pd_x": "pd_x", "pd_y": "pd_y", "pd_z": "pd_z", "v_12": "v_up", "v_10": "v_down",
             "mutual_alignment": "mutual_alignment", "slack_max": "slack_max", "solve_ms": "solve_ms",
             "feedback_ms": "feedback_ms", "qp_ok": "qp_ok", "qp_status": "qp_status", "fallback": "fallback",
             "safety_violation": "safety_violation", "taylor_rel_err": "taylor_rel_err",
             **{f"a_drag_{a}": f"a_drag_{a}" for a in "xyz"}, **{f"a_ext_{a}": f"a_ext_{a}" for a in "xyz"}}
# old one-relay column -> the one vocabulary's (the relay 'relay', the source 'source', the base station 'bs')
LEGACY_COLUMNS: dict[str, str] = {
    **{old: f"relay.{new}" for old, new in (_OLD_RELAY | _OLD_STEP).items()},
    **{old: f"source.{new}" for old, new in _OLD_SOURCE.items()},
    "gamma_21": "sinr.source.relay", "gamma_10": "sinr.relay.bs", "se_21": "se.source.relay", "se_10": "se.relay.bs",
}


def is_legacy(columns: Iterable[str]) -> bool:
    """Whether a log's columns are the one-relay names written before the one vocabulary (``p1_x``...)."""
    return "p1_x" in set(columns)


def modern_columns(columns: Iterable[str]) -> dict[str, str]:
    """The renaming that reads an old one-relay log in the one vocabulary (``{}`` for a current log):
    ``LEGACY_COLUMNS`` and the rotor columns ``Omega_i`` / ``u_i`` -> ``relay.Omega_i`` / ``relay.u_i``."""
    cols = list(columns)
    if not is_legacy(cols):
        return {}
    out = {c: LEGACY_COLUMNS[c] for c in cols if c in LEGACY_COLUMNS}
    out |= {c: f"relay.{c}" for c in cols if (c.startswith("Omega_") or c.startswith("u_")) and c.split("_", 1)[1].isdigit()}
    return out
