"""Mission metrics from a per-step log (docs/concepts/spec.md, 'Metrics')."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

from ..control.nmpc import QpStatus
from ..models.obstacles import clearance
from ..models.vehicle import Multirotor
from ..stats import stats_ms
from .exit_status import ExitStatus, exit_fields
from .log_schema import logged_covariance, rotor_count

# A slack below this fraction of mu is the interior-point solver's tolerance (complementarity
# 1e-4), not a relaxation of the alignment constraint: on the nominal tilted mission the slack
# stays <= 1.5e-3 while the constraint is inactive (t < 6 s) and is 5e-3..2e-2 once it binds.
SLACK_ACTIVE_FRACTION_OF_MU = 0.0125
# The soft alignment constraint settles just below mu (slack ~0.01-0.02 on the nominal mission):
# alignment_within_slack_fraction counts steps with (1 - v_12)(1 - v_10) >= mu - this.
ALIGNMENT_TOLERANCE = 0.02


FLIPPED_TILT_DEG = 90.0  # a body tilt beyond this is an inverted vehicle


def safety_metrics(p1: np.ndarray, tilt_deg: np.ndarray, violation: np.ndarray, workspace_min, workspace_max,
                   box_tolerance_m: float, ground_z_m: float = -np.inf, obstacles: tuple = ()) -> dict:
    """Whether the relay stayed in its world: ``box_violation_max_m`` (largest distance outside the
    workspace box, 0 inside), ``min_altitude_m``, ``max_tilt_deg``, ``safety_violations`` (steps
    outside the supervisor's envelope) and the verdict ``unsafe`` with its ``unsafe_reason``: a
    run that left the box (beyond the tolerance), went below the ground (``ground_z_m``, m, no
    tolerance) or flipped is unsafe whatever the QPs reported. With ``obstacles`` (the shapes
    themselves, no margin): ``obstacle_clearance_min_m`` (the smallest signed distance to one, negative
    inside), and a run that entered one is unsafe. A log whose positions or tilts are not all finite
    cannot show the run was safe: it is unsafe, and says at how many steps."""
    reasons, statuses = [], []
    bad = ~(np.all(np.isfinite(p1), axis=1) & np.isfinite(tilt_deg))
    if bad.any():
        reasons.append(f"its position or attitude is not finite at {int(bad.sum())} logged steps (its safety cannot be shown)")
        statuses.append(ExitStatus.NON_FINITE)
        p1, tilt_deg = p1[~bad], tilt_deg[~bad]
    if not len(p1):
        return {"unsafe": True, "unsafe_reason": "; ".join(reasons), "safety_violations": int(np.sum(violation)),
                "box_violation_max_m": math.nan, "min_altitude_m": math.nan, "max_tilt_deg": math.nan, **exit_fields(statuses)}
    outside = np.max(np.c_[np.asarray(workspace_min, float) - p1, p1 - np.asarray(workspace_max, float)], axis=1)
    box = float(max(outside.max(), 0.0))
    if box > box_tolerance_m:
        reasons.append(f"left the workspace by {box:.2f} m")
        statuses.append(ExitStatus.LEFT_WORKSPACE)
    lowest = float(p1[:, 2].min())
    if lowest < ground_z_m:
        reasons.append(f"went below the ground (z = {lowest:.2f} m, ground at {ground_z_m:g} m)")
        statuses.append(ExitStatus.BELOW_GROUND)
    if tilt_deg.max() > FLIPPED_TILT_DEG:
        reasons.append(f"flipped (tilt {tilt_deg.max():.0f} deg)")
        statuses.append(ExitStatus.FLIPPED)
    extra = {}
    if obstacles:
        flown = p1[np.all(np.isfinite(p1), axis=1)]
        worst = float(clearance(obstacles, flown).min()) if len(flown) else math.inf
        extra["obstacle_clearance_min_m"] = worst
        if worst < 0:
            reasons.append(f"entered an obstacle ({-worst:.2f} m deep)")
            statuses.append(ExitStatus.IN_OBSTACLE)
    extra |= exit_fields(statuses)
    return {"unsafe": bool(reasons), "unsafe_reason": "; ".join(reasons), "safety_violations": int(np.sum(violation)),
            "box_violation_max_m": box, "min_altitude_m": float(p1[:, 2].min()), "max_tilt_deg": float(tilt_deg.max()),
            **extra}


def air_metrics(log, prefix: str = "") -> dict:
    """With wind (``sim/air.py`` columns): the wind's mean speed (m/s), the drag's mean and largest
    acceleration (m/s^2) and, with the observer, its estimate's mean error against the drag (m/s^2)."""
    if "wind_x" not in log:
        return {}

    def vec(name: str) -> np.ndarray:
        return np.column_stack([np.asarray(log[f"{name}_{a}"], float) for a in "xyz"])
    wind, drag = vec("wind"), vec(f"{prefix}a_drag")  # the wind is the fleet's, the drag each relay's
    ok = np.all(np.isfinite(drag), axis=1)
    if not ok.any():  # no finite drag logged (a flight cut at its first step): nothing to average
        return {"wind_speed_mean_m_s": float(np.linalg.norm(wind, axis=1).mean()), "drag_accel_mean_m_s2": math.nan,
                "drag_accel_max_m_s2": math.nan}
    out = {"wind_speed_mean_m_s": float(np.linalg.norm(wind, axis=1).mean()),
           "drag_accel_mean_m_s2": float(np.linalg.norm(drag[ok], axis=1).mean()),
           "drag_accel_max_m_s2": float(np.linalg.norm(drag[ok], axis=1).max())}
    if f"{prefix}a_ext_x" in log:
        out["observer_error_mean_m_s2"] = float(np.linalg.norm(vec(f"{prefix}a_ext")[ok] - drag[ok], axis=1).mean())
    return out


SATURATION_BAND = 0.01  # a motor within 1% (of its bound's magnitude) of a bound is saturated


def saturation_metrics(speeds: np.ndarray, inputs: np.ndarray, veh: Multirotor) -> dict:
    """Fraction of steps with any rotor's speed within 1% of a speed bound (``motor_saturation_fraction``)
    and with any rotor's rate command within 1% of a rate bound (``rate_saturation_fraction``)."""
    band = SATURATION_BAND
    motor = (speeds <= veh.omega_min + band * veh.omega_min) | (speeds >= veh.omega_max - band * veh.omega_max)
    rate = (inputs <= veh.omega_dot_min * (1 - band)) | (inputs >= veh.omega_dot_max * (1 - band))
    return {"motor_saturation_fraction": float(np.mean(motor.any(axis=1))),
            "rate_saturation_fraction": float(np.mean(rate.any(axis=1)))}


def outage_durations(outage: np.ndarray, period_s: float) -> dict[str, float | int]:
    """How long each outage lasts (the number a link layer cares about): the count of outage
    events (runs of consecutive steps below the threshold), their mean and longest duration (s)."""
    o = np.asarray(outage, bool).astype(np.int8)
    edges = np.diff(np.concatenate([[0], o, [0]]))
    lengths = (np.flatnonzero(edges == -1) - np.flatnonzero(edges == 1)) * period_s
    return {"outage_events": int(lengths.size), "outage_duration_mean_s": float(lengths.mean()) if lengths.size else 0.0,
            "outage_duration_max_s": float(lengths.max()) if lengths.size else 0.0}


ESTIMATION_ERROR_M = 1.0  # the estimate is "within" when closer than this to the true jammer
ESTIMATION_SETTLE_S = 10.0  # ... and counted from this long after take-off


def estimation_metrics(log, period_s: float) -> dict:
    """For a run that estimated its jammers (``est_<name>_err_m`` columns), the worst jammer's:
    ``estimation_first_within_1m_s`` (first time the error is <= 1 m; the mission's length when
    never), ``estimation_within_1m_after_10s`` (fraction of steps from 10 s on with the error <=
    1 m), ``estimation_err_mean_m``/``_final_m``, ``estimation_std_final_m`` (largest position
    std at the end), ``estimation_nees_final`` (the error's squared Mahalanobis length under the reported covariance
    at the end, ``e' P^-1 e``: chi-square with 3 degrees of freedom when the spread is true, below 7.8 in 95% of runs),
    ``estimation_trusted_final`` (whether every estimate was trusted at the end: the planners plan with it) and
    ``estimator_ms`` (per control step); where the Cramer-Rao bound is logged
    (``est_<name>_crlb_m``): ``estimation_crlb_first_1m_s`` (first time the bound is <= 1 m: before,
    no unbiased estimator has a position std below 1 m), ``estimation_crlb_10s_m`` (the bound at 10 s) and
    ``estimation_within_1m_after_bound`` (the worst jammer's fraction of steps from that time on with
    its error <= 1 m: does the estimator deliver what the path made knowable).
    Empty for an oracle run."""
    names = [c[4:-6] for c in log if c.startswith("est_") and c.endswith("_err_m")]
    if not names:
        return {}
    t = np.asarray(log["t"], float)
    first, within, mean, final, std, nees = [], [], [], [], [], []
    for n in names:
        err = np.asarray(log[f"est_{n}_err_m"], float)
        ok = err <= ESTIMATION_ERROR_M
        first.append(float(t[np.argmax(ok)]) if ok.any() else float(t[-1] + period_s))
        late = t >= ESTIMATION_SETTLE_S
        within.append(float(np.mean(ok[late])) if late.any() else 0.0)
        mean.append(float(err.mean()))
        final.append(float(err[-1]))
        std.append(float(np.asarray(log[f"est_{n}_std_m"], float)[-1]))
        if f"jam_{n}_x" in log and f"est_{n}_cov_xx" in log:
            e = np.array([float(np.asarray(log[f"est_{n}_{a}"], float)[-1] - np.asarray(log[f"jam_{n}_{a}"], float)[-1])
                          for a in "xyz"])
            nees.append(float(e @ np.linalg.lstsq(logged_covariance(log, n), e, rcond=None)[0]))
    out = {"estimation_first_within_1m_s": max(first), "estimation_within_1m_after_10s": min(within),
           "estimation_err_mean_m": max(mean), "estimation_err_final_m": max(final), "estimation_std_final_m": max(std),
           "estimator_ms": stats_ms(np.asarray(log["estimator_ms"], float))}
    if nees:
        out["estimation_nees_final"] = max(nees)
    if all(f"est_{n}_trusted" in log for n in names):
        out["estimation_trusted_final"] = bool(all(float(np.asarray(log[f"est_{n}_trusted"], float)[-1]) > 0.5 for n in names))
    bounds = [np.asarray(log[f"est_{n}_crlb_m"], float) for n in names if f"est_{n}_crlb_m" in log]
    if bounds and all(np.isfinite(b[-1]) for b in bounds):
        worst = np.max(bounds, axis=0)
        knowable = worst <= ESTIMATION_ERROR_M
        out["estimation_crlb_first_1m_s"] = float(t[np.argmax(knowable)]) if knowable.any() else float(t[-1] + period_s)
        out["estimation_crlb_10s_m"] = float(worst[min(np.searchsorted(t, ESTIMATION_SETTLE_S), t.size - 1)])
        if knowable.any():  # from the first time the path made every jammer knowable to 1 m
            after = t >= out["estimation_crlb_first_1m_s"]
            out["estimation_within_1m_after_bound"] = min(
                float(np.mean(np.asarray(log[f"est_{n}_err_m"], float)[after] <= ESTIMATION_ERROR_M)) for n in names)
    return out


def relay_metrics(log, name: str, veh: Multirotor, *, period_s: float, mu: float, workspace_min, workspace_max,
                  box_tolerance_m: float, ground_z_m: float, obstacles: tuple, fallback_fraction_max: float = 1.0) -> dict:
    """One relay's metrics over the steps it flew (a lost relay's steps read NaN): its safety (``safety_metrics``, in
    its own workspace), alignment (``mutual_alignment >= mu``, within ``ALIGNMENT_TOLERANCE``), slack, QP and fallback
    shares, step times (ms), tracking error (m), distance (m), shaft energy (kJ), rotor ranges and saturation, wind.
    More than ``fallback_fraction_max`` of its steps on the brake law or with failed QPs: ``fell_back_reason`` says
    so and its exit statuses end with ``fell_back`` (its controller did not fly it; safe, not complete)."""
    flew = np.isfinite(np.asarray(log[f"{name}.p_x"], float))
    if not flew.any():  # a spare that never launched
        return spare_metrics(log, name) or {"flew": False}

    def col(q: str, kind=float) -> np.ndarray:
        return np.asarray(log[f"{name}.{q}"])[flew].astype(kind)

    p = np.column_stack([col("p_x"), col("p_y"), col("p_z")])
    pd = np.column_stack([col("pd_x"), col("pd_y"), col("pd_z")])
    have = rotor_count(log, name)
    if have != veh.n_rotors:  # before reading them: a log of fewer rotors is named, not a KeyError
        raise ValueError(f"the log has {have} '{name}.Omega_*' columns, the vehicle has {veh.n_rotors} rotors")
    speeds = np.column_stack([col(f"Omega_{i}") for i in range(1, veh.n_rotors + 1)])
    inputs = np.column_stack([col(f"u_{i}") for i in range(1, veh.n_rotors + 1)])
    tilt = np.degrees(np.arccos(np.clip(np.cos(col("phi")) * np.cos(col("theta")), -1, 1)))
    solve, align = col("solve_ms"), col("mutual_alignment")
    slack = np.nan_to_num(col("slack_max"), nan=np.inf)
    out = {
        "alignment_ok_fraction": float(np.mean(align >= mu)),
        "alignment_within_slack_fraction": float(np.mean(align >= mu - ALIGNMENT_TOLERANCE)),
        "slack_active_fraction": float(np.mean(slack > SLACK_ACTIVE_FRACTION_OF_MU * max(mu, 1e-9))),
        "infeasible_fraction": float(np.mean(~col("qp_ok", bool))),
        # QPs the iteration cap stopped on a primal-feasible iterate (NmpcSettings.accept_tol)
        "qp_capped_fraction": float(np.mean(col("qp_status", object) == QpStatus.CAPPED)),
        "fallback_fraction": float(np.mean(col("fallback", bool))),
        "solve_ms": {**stats_ms(solve), "std": float(solve.std())},
        "feedback_ms": stats_ms(col("feedback_ms")),
        "position_error_mean_m": float(np.mean(np.linalg.norm(p - pd, axis=1))),
        "distance_m": float(np.sum(np.linalg.norm(np.diff(p, axis=0), axis=1))),
        "energy_kJ": float(np.sum(veh.shaft_power(speeds)) * period_s / 1e3),
        "taylor_rel_err_max": float(np.max(col("taylor_rel_err"))),
        "final_z_m": float(p[-1, 2]),
        **safety_metrics(p, tilt, col("safety_violation", bool), workspace_min, workspace_max, box_tolerance_m, ground_z_m,
                         obstacles),
        **air_metrics(log, f"{name}."),
        "omega_range_hz": [float(speeds.min()), float(speeds.max())],
        **saturation_metrics(speeds, inputs, veh),
        "omega_dot_range_hz_s": [float(inputs.min()), float(inputs.max())],
        **battery_metrics(log, name),
        **spare_metrics(log, name),
    }
    empty = flew_empty(log, name, period_s)
    statuses = [ExitStatus(s) for s in out["exit_statuses"]]
    if empty:  # flying on an empty battery is unsafe whatever else went well
        out["unsafe_reason"] = "; ".join(r for r in (out["unsafe_reason"], empty) if r)
        out["unsafe"] = True
        statuses.append(ExitStatus.BATTERY_EMPTY)
    worst = max(out["fallback_fraction"], out["infeasible_fraction"])
    if worst > fallback_fraction_max:
        what = "on the brake law" if out["fallback_fraction"] >= out["infeasible_fraction"] else "with failed QPs"
        out["fell_back_reason"] = (f"flew {worst:.1%} of its steps {what} (brake law {out['fallback_fraction']:.1%}, QPs "
                                   f"failed {out['infeasible_fraction']:.1%}), more than verdict.fallback_fraction_max = "
                                   f"{fallback_fraction_max:g}")
        statuses.append(ExitStatus.FELL_BACK)
    out |= exit_fields(statuses)
    return out


def flew_empty(log, name: str, period_s: float) -> str | None:
    """Why relay ``name`` flew on an empty battery (its state of charge at or below 0 at a step it flew: the usable
    energy spent; the simulation logs it empty and ends there, a flight's log may go below), or None. No battery
    modelled: None."""
    if f"{name}.soc" not in log:
        return None
    soc = np.asarray(log[f"{name}.soc"], float)
    below = np.isfinite(soc) & (soc <= 0.0)
    if not below.any():
        return None
    t = np.asarray(log["t"], float)
    return (f"flew on an empty battery from t = {float(t[np.argmax(below)]):.2f} s for {int(below.sum()) * period_s:.2f} s "
            f"(state of charge down to {100.0 * float(soc[below].min()):.0f}% of the usable energy)")


def battery_metrics(log, name: str) -> dict:
    """With a battery (``<relay>.soc``): its state of charge at the last step flown (``soc_final_fraction``) and,
    when it reached its reserve, the first time it did (``battery_reserve_first_s``, s); when it flew home, when it
    turned (``went_home_at_s``), landed (``landed_at_s``) and its state of charge then (``soc_landed_fraction``)."""
    if f"{name}.soc" not in log:
        return {}
    soc = np.asarray(log[f"{name}.soc"], float)
    flew = np.isfinite(soc)
    out = {"soc_final_fraction": float(soc[flew][-1]) if flew.any() else math.nan}
    reserve = np.asarray(log[f"{name}.battery_reserve"], bool) & flew
    t = np.asarray(log["t"], float)
    if reserve.any():
        out["battery_reserve_first_s"] = float(t[np.argmax(reserve)])
    home = np.asarray(log.get(f"{name}.going_home", np.zeros(t.size, bool)), bool)
    if home.any():  # it turned home (and left the network), and once down it left the flight
        k = int(np.argmax(home))
        out["went_home_at_s"] = float(t[k])
        down = ~flew & (np.arange(t.size) > k)
        if down.any():
            out["landed_at_s"] = float(t[np.argmax(down)])
            out["soc_landed_fraction"] = float(soc[np.argmax(down) - 1])
    return out


TAKEOVER_BEFORE_S = 5.0  # the network's rate "before a spare took over": its mean over this long before (s)


def spare_metrics(log, name: str) -> dict:
    """A spare (``<relay>.waiting``): when it launched (``launched_at_s``), when it took a relay's place
    (``took_over_at_s``: the first step it flew in the network) and whose (``took_over_from``); the network's mean
    rate over the ``TAKEOVER_BEFORE_S`` before and after (``c_mean_before_takeover``, ``c_mean_after_takeover``), how
    long it stayed below the one before (``rate_recovered_after_s``; None: not by the end: the sources moved on) and
    the least rate meanwhile (``c_min_after_takeover``). Empty for a relay that is no spare; a
    spare that never launched: ``standby_only``."""
    if f"{name}.waiting" not in log:
        return {}
    t = np.asarray(log["t"], float)
    waiting = np.asarray(log[f"{name}.waiting"], bool)
    if waiting.all():
        return {"standby_only": True}
    out: dict = {"launched_at_s": float(t[np.argmax(~waiting)])}
    ferrying = np.asarray(log[f"{name}.ferrying"], bool)
    flew = np.isfinite(np.asarray(log[f"{name}.p_x"], float))
    placed = flew & ~waiting & ~ferrying & (t >= out["launched_at_s"])
    if not placed.any():
        return out
    k = int(np.argmax(placed))
    out["took_over_at_s"], out["took_over_from"] = float(t[k]), str(log[f"{name}.replaces"][k])
    cap = np.asarray(log["capacity"], float)
    before = cap[(t >= t[k] - TAKEOVER_BEFORE_S) & (t < t[k])]
    after = cap[(t >= t[k]) & (t < t[k] + TAKEOVER_BEFORE_S)]
    out["c_mean_after_takeover"] = float(after.mean())
    if before.size:
        out["c_mean_before_takeover"] = level = float(before.mean())
        back = np.flatnonzero(cap[k:] >= level)
        out["rate_recovered_after_s"] = float(t[k + back[0]] - t[k]) if back.size else None
        stop = k + (back[0] if back.size else len(cap) - k)
        out["c_min_after_takeover"] = float(cap[k:max(stop, k + 1)].min())
    return out


NETWORK_VERDICT = ("unsafe", "unsafe_reason", "exit_status", "exit_sentence", "exit_statuses", "fell_back_reason")  # the network's, not a relay's

# Each relay's metric at the network's top level, whatever its size (one relay: its own value): the worst relay's
# (a share of bad steps, an error or a load: the largest; a share of good steps, a margin or a charge: the smallest),
# the fleet's sum (work done, counts), the envelope of ranges, the slowest relay's step times (the relay with the
# largest mean). What has no fleet meaning stays under ``relays`` only (PER_RELAY).
FLEET_MIN = ("alignment_ok_fraction", "alignment_within_slack_fraction", "final_z_m", "min_altitude_m",
             "obstacle_clearance_min_m", "soc_final_fraction", "soc_landed_fraction", "battery_reserve_first_s",
             "went_home_at_s", "landed_at_s")
FLEET_MAX = ("slack_active_fraction", "infeasible_fraction", "qp_capped_fraction", "fallback_fraction",
             "position_error_mean_m", "taylor_rel_err_max", "box_violation_max_m", "max_tilt_deg",
             "motor_saturation_fraction", "rate_saturation_fraction", "wind_speed_mean_m_s", "drag_accel_mean_m_s2",
             "drag_accel_max_m_s2", "observer_error_mean_m_s2")
FLEET_SUM = ("distance_m", "energy_kJ", "safety_violations", "separation_unguarded_steps")
FLEET_ENVELOPE = ("omega_range_hz", "omega_dot_range_hz_s")
FLEET_SLOWEST = ("solve_ms", "feedback_ms")
# the verdict's (NETWORK_VERDICT), the reference check's (its own top-level counts), a spare's events
PER_RELAY = (*NETWORK_VERDICT, "reference_clipped_steps", "reference_held_steps", "flew", "standby_only", "launched_at_s",
             "took_over_at_s", "took_over_from", "c_mean_after_takeover", "c_mean_before_takeover",
             "rate_recovered_after_s", "c_min_after_takeover")


def _finite_or_nan(values: list[float], pick) -> float:
    kept = [float(v) for v in values if v is not None and not math.isnan(float(v))]
    return pick(kept) if kept else math.nan


def fleet_metrics(relays: Mapping[str, dict]) -> dict:
    """Every relay's metrics at the network's top level by one rule per metric (``FLEET_MIN``, ``FLEET_MAX``,
    ``FLEET_SUM``, ``FLEET_ENVELOPE``, ``FLEET_SLOWEST``; NaN values skipped, all NaN: NaN), over the relays that have
    it: the same keys for one relay and for K (one relay: its values). A relay metric with no rule stays under
    ``relays`` (tests/sim/test_fleet_metrics.py checks that every metric a relay writes has one)."""
    flown = [m for m in relays.values() if m.get("flew", True)]
    keys = list(dict.fromkeys(k for m in flown for k in m))
    out: dict = {}
    for k in keys:
        have = [m[k] for m in flown if k in m]
        if k in FLEET_MIN:
            out[k] = _finite_or_nan(have, min)
        elif k in FLEET_MAX:
            out[k] = _finite_or_nan(have, max)
        elif k in FLEET_SUM:
            out[k] = type(have[0])(sum(have))
        elif k in FLEET_ENVELOPE:
            out[k] = [min(v[0] for v in have), max(v[1] for v in have)]
        elif k in FLEET_SLOWEST:
            out[k] = max(have, key=lambda v: v["mean"] if not math.isnan(v["mean"]) else -math.inf)
    return out


def _mean_taken(values: np.ndarray) -> float:
    """The mean over the steps a hop was taken (NaN when never: a hop of a network flown only after a loss)."""
    taken = values[np.isfinite(values)]
    return float(taken.mean()) if taken.size else math.nan


def traced_metrics(log) -> dict:
    """A ray-traced channel's (``sim/traced.py`` columns): per hop (by ``<tx>-><rx>``) the RMS delay spread's
    mean over the steps (``delay_spread_ns``) and the valid paths' (``paths_mean``), and over every hop and
    step the delay spread's mean and largest (``delay_spread_mean_ns``, ``delay_spread_max_ns``); empty otherwise."""
    hop = {f"delay_spread_ns_{tx}_{rx}": f"{tx}->{rx}" for tx, rx in (c.split(".")[1:3] for c in log if c.startswith("se."))}
    spread = [c for c in hop if c in log]
    if not spread:
        return {}
    values = np.concatenate([np.asarray(log[c], float) for c in spread])
    return {"delay_spread_ns": {hop[c]: float(np.nanmean(np.asarray(log[c], float))) for c in spread},
            "paths_mean": {hop[c]: float(np.nanmean(np.asarray(log[c.replace("delay_spread_ns_", "paths_", 1)], float)))
                           for c in spread},
            "delay_spread_mean_ns": float(np.nanmean(values)), "delay_spread_max_ns": float(np.nanmax(values))}


def handover_metrics(log, sources: Sequence[str]) -> dict:
    """Each route that may end at several base stations (its ``<source>.base_station`` column): the
    handovers it made (``handovers``, the first choice not counted), the shortest time one base station
    served between two handovers (``dwell_min_s``; None without two), the share of the steps each
    served (``served_fraction``); the network's ``handovers`` in all. Empty without such a route."""
    routes, total = {}, 0
    t = np.asarray(log["t"], float)
    for s in sources:
        col = f"{s}.base_station"
        if col not in log:
            continue
        serving = [str(v) for v in log[col]]
        at = [float(t[k]) for k in range(1, len(serving)) if serving[k] != serving[k - 1]]
        served = sorted(set(serving))
        routes[s] = {"handovers": len(at), "dwell_min_s": float(np.min(np.diff(at))) if len(at) > 1 else None,
                     "served_fraction": {b: float(np.mean([v == b for v in serving])) for b in served}}
        total += len(at)
    return {"handovers": total, "routes": routes} if routes else {}


def route_metrics(log, sources: Sequence[str], relays: Sequence[str]) -> dict:
    """Each route that may skip relays (its ``<source>.route`` column: the relays carrying it, ``+``-joined, or
    ``direct``): its route switches (``route_switches``, the first choice not counted), the share of the steps
    each subset served (``carried_by_fraction``); the network's ``route_switches`` in all and each relay's
    ``skipped_fraction`` (the share of the steps no serving route took it). Empty without such a route."""
    routes, total = {}, 0
    carried = np.zeros(len(np.asarray(log["t"])), bool)
    carrying: dict[str, np.ndarray] = {r: carried.copy() for r in relays}
    for s in sources:
        col = f"{s}.route"
        if col not in log:
            continue
        serving = [str(v) for v in log[col]]
        switches = sum(serving[k] != serving[k - 1] for k in range(1, len(serving)))
        routes[s] = {"route_switches": int(switches),
                     "carried_by_fraction": {v: float(np.mean([x == v for x in serving])) for v in sorted(set(serving))}}
        total += switches
        for r in relays:
            carrying[r] |= np.array([r in v.split("+") for v in serving], bool)
    if not routes:
        return {}
    return {"route_switches": int(total), "routes": routes,
            "skipped_fraction": {r: float(np.mean(~c)) for r, c in carrying.items()}}


def loss_phases(t: np.ndarray, loss_times: Sequence[float]) -> dict[str, np.ndarray]:
    """Which of the times ``t`` (s) lie before the first loss and from the last one on (a loss at
    ``t_l`` counts from ``t_l`` itself): ``{"before_loss": mask, "after_loss": mask}``."""
    t = np.asarray(t, float)
    return {"before_loss": t < loss_times[0] - 1e-9, "after_loss": t >= loss_times[-1] - 1e-9}


def compute_metrics(log, *, relays: dict[str, Multirotor], sources: Sequence[str], period_s: float,
                    outage_threshold: float, mu: float, wall_s: float, sim_s: float, min_separation_m: float = 0.0,
                    workspace_min=(-np.inf,) * 3, workspace_max=(np.inf,) * 3, box_tolerance_m: float = 0.05,
                    ground_z_m: float = -np.inf, losses: Sequence[tuple[float, frozenset[str]]] = (),
                    obstacles: tuple = (), workspaces: Mapping[str, tuple[Sequence[float], Sequence[float], float]] | None = None,
                    fallback_fraction_max: float = 1.0) -> dict:
    """Metrics of a run (``sim.log_schema`` log) of any network: the network's rate (``c_min``, ``c_mean``,
    outage below ``outage_threshold``), every route's (``routes``), every hop's mean spectral efficiency
    (``se_mean``, by ``<tx>-><rx>``), the smallest separation between two vehicles (m), per relay
    ``relay_metrics`` (``relays``), the relays' solve times summed per step (``fleet_solve_ms``, ms), the
    jammer estimate's; unsafe when a relay is, or two vehicles came closer than ``min_separation_m`` (> 0).
    A network of one relay also has its relay's metrics at the top level (and its hops' spectral
    efficiencies as ``se_21_mean``, ``se_10_mean``, the paper's names). With relays lost in flight
    (``losses``: ``(t, every relay lost by then)``), a relay's metrics cover the steps it flew, and the rate
    before the first loss and from the last one on is given (``c_mean_before_loss``, ``c_mean_after_loss``, ...)."""
    cap = np.asarray(log["capacity"], float)
    out: dict = {"c_min": float(cap.min()), "c_mean": float(cap.mean()),
                 "outage_fraction": float(np.mean(cap < outage_threshold)), **outage_durations(cap < outage_threshold, period_s)}
    out["routes"] = {s: {"c_min": float(c.min()), "c_mean": float(c.mean()), "outage_fraction": float(np.mean(c < outage_threshold))}
                     for s in sources for c in [np.asarray(log[f"capacity.{s}"], float)]}
    out["se_mean"] = {c[3:].replace(".", "->", 1): _mean_taken(np.asarray(log[c], float)) for c in log if c.startswith("se.")}
    if losses:
        t = np.asarray(log["t"], float)
        out["losses"] = [{"t_s": float(tl), "relays": sorted(lost)} for tl, lost in losses]
        for label, rows in loss_phases(t, [tl for tl, _ in losses]).items():
            if rows.any():
                out[f"c_mean_{label}"], out[f"c_min_{label}"] = float(cap[rows].mean()), float(cap[rows].min())
    sep = np.asarray(log["separation_min"], float)
    out["separation_min_m"] = float(sep.min())
    fleet_ms = np.zeros(cap.size)
    reasons: list[str] = []
    fell_back: list[str] = []
    statuses: list[ExitStatus] = []
    out["relays"] = {}
    for name, veh in relays.items():
        lo, hi, tol = (workspaces or {}).get(name, (workspace_min, workspace_max, box_tolerance_m))
        m = relay_metrics(log, name, veh, period_s=period_s, mu=mu, workspace_min=lo, workspace_max=hi, box_tolerance_m=tol,
                          ground_z_m=ground_z_m, obstacles=obstacles, fallback_fraction_max=fallback_fraction_max)
        solve = np.asarray(log[f"{name}.solve_ms"], float)
        fleet_ms += np.nan_to_num(solve, nan=0.0)
        lost_at = [tl for tl, lost in losses if name in lost]
        if lost_at:
            m["lost_at_s"] = lost_at[0]
        if m.get("unsafe"):  # a spare that never flew has no verdict
            reasons.append(f"relay {name!r}: {m['unsafe_reason']}")
        if m.get("fell_back_reason"):
            fell_back.append(f"relay {name!r}: {m['fell_back_reason']}")
        statuses += [ExitStatus(v) for v in m.get("exit_statuses", []) if v != ExitStatus.COMPLETE.value]
        out["relays"][name] = m
    if min_separation_m > 0 and sep.min() < min_separation_m:
        k = int(np.argmin(sep))
        reasons.append(f"two vehicles {sep[k]:.2f} m apart at t = {float(log['t'][k]):.2f} s, closer than "
                       f"network.min_separation_m = {min_separation_m:g} m")
        statuses.append(ExitStatus.TOO_CLOSE)
    out["fleet_solve_ms"] = stats_ms(fleet_ms)
    flown = [m for m in out["relays"].values() if "fallback_fraction" in m]  # a spare that never flew has none
    # the worst relay's share of brake-law steps and of failed QPs (whatever the network's size: the verdict's inputs)
    out["worst_relay_fallback_fraction"] = max((m["fallback_fraction"] for m in flown), default=0.0)
    out["worst_relay_infeasible_fraction"] = max((m["infeasible_fraction"] for m in flown), default=0.0)
    out |= fleet_metrics(out["relays"])  # the same keys for one relay and for K
    hops = [c for c in log if c.startswith("se.")]
    if len(hops) == 2:  # the paper's two hops by the paper's names: source -> relay (2 -> 1), relay -> bs (1 -> 0)
        out["se_21_mean"], out["se_10_mean"] = (float(np.mean(np.asarray(log[c], float))) for c in hops)
    out |= estimation_metrics(log, period_s)
    out |= traced_metrics(log)
    handover = handover_metrics(log, sources)
    if handover:
        out["handovers"] = handover["handovers"]
        for s, m in handover["routes"].items():
            out["routes"][s] |= m
    chosen = route_metrics(log, sources, list(out["relays"]))
    if chosen:
        out["route_switches"] = chosen["route_switches"]
        for s, m in chosen["routes"].items():
            out["routes"][s] |= m
        for r, f in chosen["skipped_fraction"].items():
            out["relays"][r]["skipped_fraction"] = f
    out["unsafe"] = bool(reasons)
    out["unsafe_reason"] = "; ".join(reasons)
    out["fell_back"] = bool(fell_back)
    out["fell_back_reason"] = "; ".join(fell_back)
    out |= exit_fields(sorted(statuses, key=lambda s: not s.unsafe))  # what made it unsafe first
    out["steps"], out["wall_s"], out["sim_s"] = int(cap.size), float(wall_s), float(sim_s)
    return out
