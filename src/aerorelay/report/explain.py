"""Measured causes of differences from the paper ("why our numbers differ"), computed from runs.

Each function reads a finished run of the campaign (its scenario, log and, for the ceiling, its
capacity bound) and returns one sentence with the numbers it measured.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..assembly.parts import build_scene, scenario_bound
from ..experiments.campaign import first_run_per_group, run_dir
from ..experiments.study import Explanation, RunSpec, scenario_of
from ..models.channel import end_to_end_capacity
from ..models.fading import RicianFading
from ..models.geometry import rotation_batch
from ..sim.log_schema import relays_in
from .folders import read_timeseries


def ceiling(spec: RunSpec, out: Path, paper: float | None) -> str:
    """The static bound's minimum over the mission: no relay pose reaches a higher C_min."""
    b = scenario_bound(scenario_of(spec)).summary()
    smin, pmin = b["static"]["min"], b["path_maxmin"]["min"]
    text = (f"ceiling: on this scenario no relay pose anywhere in the workspace, at any attitude the platform can hold, "
            f"keeps C above {smin:.3g} all mission long (best path from the start at <= "
            f"{b['resolution']['max_speed_m_s']:g} m/s: {pmin:.3g})")
    if paper is not None:
        verdict = "above what the model allows as implemented" if paper > smin else "within reach"
        text += f"; the paper's {paper:.3g} is {verdict} (x{paper / smin:.2g} the ceiling)"
    return text + "."


def jammer_noise(spec: RunSpec, out: Path) -> str:
    """Every jammer's interference against the noise, at the BS and along the run's relay path
    (the scene's channel, ``RadioScene.interference``)."""
    sc = scenario_of(spec)
    df = read_timeseries(run_dir(out, spec))
    scene = build_scene(sc)
    noise = scene.budget.noise_power
    r = relays_in(df.columns)[0]  # the (first) relay's path
    p1 = df[[f"{r}.p_x", f"{r}.p_y", f"{r}.p_z"]].to_numpy()
    t = df["t"].to_numpy()
    R1 = rotation_batch(df[[f"{r}.phi", f"{r}.theta", f"{r}.psi"]].to_numpy())
    peak = np.array([j.power for j in scene.jammers])
    relay, bs = scene.node("relay"), scene.fixed_pose("bs")
    at_relay, at_bs = np.empty(len(t)), np.empty(len(t))
    for k in range(len(t)):
        pose = scene.pose("relay", p1[k], R1[k])
        em = scene.emitters(float(t[k]), {"relay": pose, "source": pose, "bs": bs}, powers=peak)
        at_relay[k] = float(scene.interference(em, pose, relay.antenna.pattern)) / noise
        at_bs[k] = float(scene.interference(em, bs, scene.node("bs").antenna.pattern)) / noise
    where = ", ".join(f"{j.power:g} W '{j.name}' {np.linalg.norm(j.position_at(0.0) - bs.position):.2f} m from the BS"
                      for j in scene.jammers) or "no jammer"
    return (f"jammer vs noise: with {where} and {noise:g} W of noise, the jammers add {at_bs.max():.1%} to the BS's noise "
            f"and at most {at_relay.max():.1%} (mean {at_relay.mean():.1%}) to the relay's along run '{spec.group}': "
            f"switching them off, or knowing them later, can change the SINRs by about that much and the capacity by less.")


def fading(spec: RunSpec, out: Path, k_db: list[float]) -> str:
    """Mean capacity under unit-mean Rician fading of every link, at the run's SNRs (its unfaded log)."""
    df = read_timeseries(run_dir(out, spec))
    hops = [c for c in df.columns if c.startswith("sinr.")]
    if len(hops) != 2:
        return f"fading: run '{spec.group}' has {len(hops)} hops; this estimate is the one relay's two (eq. 9)"
    g21, g10 = df[hops[0]].to_numpy(float), df[hops[1]].to_numpy(float)
    c0 = float(np.mean(end_to_end_capacity(g21, g10)))
    parts = []
    for k in k_db:
        if math.isinf(k):
            continue
        fad = RicianFading(k, seed=0)
        draws = [float(np.mean(end_to_end_capacity(g21 * fad.power_gain(g21.size), g10 * fad.power_gain(g10.size))))
                 for _ in range(20)]
        parts.append(f"K = {k:g} dB: {np.mean(draws) / c0 - 1:+.1%}")
    return (f"fading: unit-mean Rician fading of every link changes the mean capacity of run '{spec.group}' "
            f"(mean SNRs {np.mean(g21):.3g} and {np.mean(g10):.3g}, where log2(1 + x) is nearly linear) by "
            + ", ".join(parts) + " (20 draws of the whole mission each): a controller cannot gain or lose much from it.")


def explain(e: Explanation, specs: list[RunSpec], out: Path) -> str:
    """One measured cause as a sentence (or why it could not be computed)."""
    spec = first_run_per_group(specs, out).get(e.run)
    if spec is None:
        return f"{e.kind}: run '{e.run}' has no results in this campaign."
    if e.kind == "ceiling":
        text = ceiling(spec, out, e.paper)
    elif e.kind == "jammer_noise":
        text = jammer_noise(spec, out)
    else:
        text = fading(spec, out, e.k_db)
    return text + (f" {e.note}" if e.note else "")
