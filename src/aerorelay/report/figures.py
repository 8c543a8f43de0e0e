"""A run's figures, for any network (matplotlib PNG) and an interactive 3D view (plotly HTML), read from
its log in the one vocabulary (``sim.log_schema``)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
import plotly.graph_objects as go  # noqa: E402

from ..assembly.parts import build_jammer  # noqa: E402
from ..config import Scenario  # noqa: E402
from ..sim.log_schema import relays_in, rotor_count, sources_in  # noqa: E402

RELAY, SOURCE = "#d4a017", "#7b3fa0"


def jammer_tracks(sc: Scenario, t: np.ndarray) -> list[tuple[str, np.ndarray]]:
    """Every jammer's name and positions ``(len(t), 3)`` (m) at the times ``t`` (s)."""
    return [(j.name, np.array([j.position_at(float(tk)) for tk in t])) for j in map(build_jammer, sc.jammer_configs)]


def jammer_traces(sc: Scenario, t: np.ndarray) -> list:
    """plotly traces: a marker at each jammer's start and its track when it moves."""
    out = []
    for name, P in jammer_tracks(sc, t):
        moving = bool(np.ptp(P, axis=0).max() > 1e-9)
        out.append(go.Scatter3d(x=P[:, 0] if moving else P[:1, 0], y=P[:, 1] if moving else P[:1, 1],
                                z=P[:, 2] if moving else P[:1, 2], mode="lines" if moving else "markers", name=name,
                                line=dict(color="red", width=3), marker=dict(color="red", size=5)))
    return out


def _shade_jammer_off(ax, df):
    off = ~df["jammer_on"].to_numpy(bool)
    if off.any():
        ax.fill_between(df["t"], 0, 1, where=off, color="0.85", alpha=0.6, transform=ax.get_xaxis_transform(),
                        label="jammer OFF", step="mid")


def _relays(df: pd.DataFrame) -> list[str]:
    return relays_in(df.columns)


# the paper's names for the vehicles a scenario names as the paper does (a node's label follows its name, whatever the
# network's size)
PAPER_LABELS = {"relay": "MRAV-1 (relay)", "source": "MRAV-2 (source)"}


def _xyz(df: pd.DataFrame, node: str, q: str = "p") -> list[pd.Series]:
    return [df[f"{node}.{q}_{a}"] for a in "xyz"]


def fig_trajectory_3d(df: pd.DataFrame, sc: Scenario):
    """Every relay's path (its reference dotted) and every source's in 3D, the base station, the jammers."""
    fig = plt.figure(figsize=(6, 5))
    ax = fig.add_subplot(projection="3d")
    relays, sources = _relays(df), sources_in(df.columns)
    for i, r in enumerate(relays):
        colour = RELAY if i == 0 else f"C{i}"
        ax.plot(*_xyz(df, r), color=colour, label=PAPER_LABELS.get(r, f"relay {r}"))
        ax.plot(*_xyz(df, r, "pd"), color=colour, ls=":", lw=1, label=f"{r} reference")
    for i, s in enumerate(sources):
        ax.plot(*_xyz(df, s), color=SOURCE if i == 0 else f"C{i + len(relays)}", label=PAPER_LABELS.get(s, f"source {s}"))
    for b in sc.base_station_list:
        ax.scatter(*b.position, color="k", s=30, label="BS" if len(sc.base_station_list) == 1 else f"BS {b.name}")
    for i, (name, P) in enumerate(jammer_tracks(sc, df["t"].to_numpy())):
        ax.scatter(*P[0], color="r", s=30, label="jammer" if i == 0 else None)
        if np.ptp(P, axis=0).max() > 1e-9:
            ax.plot(P[:, 0], P[:, 1], P[:, 2], color="r", lw=1, label=f"{name} (moving)")
    for i, node in enumerate(relays + sources):
        finite = df[f"{node}.p_x"].notna().to_numpy()  # a relay lost in flight ends where it was lost
        xs = [c[finite] for c in _xyz(df, node)]
        ax.scatter(*[c.iloc[0] for c in xs], color="k", marker="o", s=15, label="start (o)" if i == 0 else None)
        ax.scatter(*[c.iloc[-1] for c in xs], color="k", marker="^", s=25, label="end (^)" if i == 0 else None)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_zlabel("z (m)")
    ax.legend(loc="upper left", fontsize=7)
    ax.set_title(run_title(sc), fontsize=9)
    return fig


def run_title(sc: Scenario) -> str:
    """Scenario, planner and NMPC variant (a network's: its relays, sources and planner): what flew."""
    n, m = len(sc.relay_list), len(sc.source_list)
    return (f"{sc.name} ({n} relay{'s' * (n != 1)}, {m} source{'s' * (m != 1)}, {sc.planner} planner, "
            f"{sc.controller.variant} NMPC)")


def fig_capacity(df: pd.DataFrame, sc: Scenario, bound: pd.DataFrame | None = None):
    """The network's rate (the one relay's end-to-end capacity) with each route's alone when there are
    several, the bound behind it when given, the outage threshold; every hop's spectral efficiency."""
    fig, axes = plt.subplots(2, 1, figsize=(7, 5), sharex=True)
    ax = axes[0]
    if bound is not None:  # what the physics allows, behind the run
        for column, style in BOUND_SERIES:
            if column in bound:
                ax.semilogy(bound["t"], bound[column], **style)
    routes = [c for c in df.columns if c.startswith("capacity.")]
    if len(routes) > 1:
        for c in routes:
            ax.semilogy(df["t"], np.maximum(df[c], 1e-12), lw=0.8, label=f"route of {c[9:]} alone")
    ax.semilogy(df["t"], np.maximum(df["capacity"], 1e-12), color="k", label="end-to-end C" if len(routes) <= 1 else "network rate")
    ax.axhline(sc.channel.outage, color="r", ls="--", lw=1, label="outage threshold")
    _shade_jammer_off(ax, df)
    _mark_operations(ax, df)
    ax.set_ylabel(f"C ({sc.channel.capacity_unit})")
    ax.legend(fontsize=7)
    ax = axes[1]
    for c in [c for c in df.columns if c.startswith("se.")]:
        _, tx, rx = c.split(".")
        ax.semilogy(df["t"], np.maximum(df[c], 1e-12), lw=0.9, label=f"{tx} -> {rx}")
    _shade_jammer_off(ax, df)
    ax.set_ylabel(r"$\log_2(1+\Gamma)$ per hop (bit/s/Hz)")
    ax.set_xlabel("t (s)")
    ax.legend(fontsize=7)
    fig.tight_layout()
    return fig


def _mark_operations(ax, df: pd.DataFrame) -> None:
    """Vertical lines where the network changed: a handover (``<source>.base_station``, labelled with the new
    station) and a spare taking a relay's place (``<spare>.ferrying`` ending)."""
    t = df["t"].to_numpy()
    events = []
    for c in [c for c in df.columns if c.endswith(".base_station")]:
        v = df[c].astype(str).to_numpy()
        events += [(t[k], f"to {v[k]}") for k in np.flatnonzero(v[1:] != v[:-1]) + 1]
    for c in [c for c in df.columns if c.endswith(".ferrying")]:
        v = df[c].to_numpy(bool)
        spare = c[: -len(".ferrying")]
        events += [(t[k], f"{spare} in {df[f'{spare}.replaces'].iloc[k]}'s place") for k in np.flatnonzero(v[:-1] & ~v[1:]) + 1]
    for i, (when, text) in enumerate(events):
        ax.axvline(when, color="0.3", ls=":", lw=0.8, label="handover / take-over" if i == 0 else None)
        ax.annotate(text, (when, 0.98), xycoords=("data", "axes fraction"), fontsize=6, rotation=90, va="top", ha="right")


# the bounds' series behind a run's capacity: one relay's (planning/bound.py) and a network's (planning/network_bound.py)
BOUND_SERIES: tuple[tuple[str, dict], ...] = (
    ("static", dict(color="0.6", lw=1, ls="--", label="static bound (best pose per instant)")),
    ("path_maxmin", dict(color="C1", lw=2.4, alpha=0.6, label="path bound (best minimum)")),
    ("path_mean", dict(color="C2", lw=1.0, ls=(0, (4, 2)), label="path bound (best mean, <= v_max)")),
    ("flyable_mean", dict(color="C4", lw=1.0, ls=":", label="flyable path (best mean found, exactly <= v_max)")),
    ("achieved", dict(color="C2", lw=1.2, label="refined configuration (one axis per relay)")),
    ("flyable", dict(color="C0", lw=1.0, ls=":", label="flyable fleet path (lower path bound, jointly optimized)")))


def fig_constraints(df: pd.DataFrame, sc: Scenario, relay: str | None = None):
    """A relay's rotor speeds and their rates against its platform's bounds, its NMPC's slack and its
    mutual alignment against mu."""
    relays = _relays(df)
    relay = relay or relays[0]
    names = [r.name for r in sc.relay_list]
    p = sc.platform_of(names.index(relay)) if relay in names else sc.platform
    fig, axes = plt.subplots(4, 1, figsize=(7, 8), sharex=True)
    for i in range(1, rotor_count(df.columns, relay) + 1):
        axes[0].plot(df["t"], df[f"{relay}.Omega_{i}"], lw=0.8, label=f"rotor {i}")
        axes[1].plot(df["t"], df[f"{relay}.u_{i}"], lw=0.6, label=f"rotor {i}")
    for ax, lo, hi, lab in ((axes[0], p.omega_min_hz, p.omega_max_hz, r"$\Omega$ (Hz)"),
                            (axes[1], p.omega_dot_min_hz_s, p.omega_dot_max_hz_s, r"$\dot\Omega$ (Hz/s)")):
        ax.axhline(lo, color="r", ls="--", lw=1, label="bounds")
        ax.axhline(hi, color="r", ls="--", lw=1)
        ax.set_ylabel(lab)
        ax.legend(fontsize=6, ncol=4, loc="upper right")
    axes[2].plot(df["t"], df[f"{relay}.slack_max"], color="C3")
    axes[2].set_ylabel(r"slack $\pi$ (-)")
    axes[3].plot(df["t"], df[f"{relay}.mutual_alignment"], color="C2", label=r"$(1-v_{up})(1-v_{down})$")
    axes[3].axhline(sc.controller.mu, color="r", ls="--", lw=1, label=r"$\mu$")
    axes[3].set_ylabel("mutual alignment (-)")
    axes[3].set_xlabel("t (s)")
    axes[3].legend(fontsize=7)
    axes[0].set_title(f"relay {relay}", fontsize=9)
    fig.tight_layout()
    return fig


def fig_tracking(df: pd.DataFrame, sc: Scenario, relay: str | None = None):
    """A relay's position error against its reference, its attitude, its misalignment toward its
    upstream and downstream nodes."""
    relay = relay or _relays(df)[0]
    fig, axes = plt.subplots(3, 1, figsize=(7, 6), sharex=True)
    for a in "xyz":
        axes[0].plot(df["t"], df[f"{relay}.p_{a}"] - df[f"{relay}.pd_{a}"], label=f"e_p{a}")
    axes[0].set_ylabel("position error (m)")
    axes[0].legend(fontsize=7)
    for q in ("phi", "theta", "psi"):
        axes[1].plot(df["t"], np.degrees(df[f"{relay}.{q}"]), label=q)
    axes[1].set_ylabel("attitude (deg)")
    axes[1].legend(fontsize=7)
    axes[2].plot(df["t"], df[f"{relay}.v_up"], label=r"$v_{up}$ (toward the source side, $v_{12}$)")
    axes[2].plot(df["t"], df[f"{relay}.v_down"], label=r"$v_{down}$ (toward the base station side, $v_{10}$)")
    axes[2].set_ylabel("misalignment (-)")
    axes[2].set_xlabel("t (s)")
    axes[2].legend(fontsize=7)
    axes[0].set_title(f"relay {relay}", fontsize=9)
    fig.tight_layout()
    return fig


def fig_paths(df: pd.DataFrame, sc: Scenario):
    """Every vehicle's path from above (x, y) and from the side (x, z); the base station and the jammers."""
    fig, (top, side) = plt.subplots(1, 2, figsize=(10, 4))
    for name in _relays(df) + sources_in(df.columns):
        x, y, z = (df[f"{name}.p_{a}"].to_numpy(float) for a in "xyz")
        for ax, v in ((top, y), (side, z)):
            ax.plot(x, v, lw=1.0, label=name)
            ax.plot(x[0], v[0], "o", ms=3, color=ax.lines[-1].get_color())
    for ax, i in ((top, 1), (side, 2)):
        for b in sc.base_station_list:
            ax.plot(b.position[0], b.position[i], "k^", label=b.name)
        for j in sc.jammer_configs:
            ax.plot(df[f"jam_{j.name}_x"], df[f"jam_{j.name}_{'yz'[i - 1]}"], "rx", ms=4, label=f"jammer {j.name!r}")
        ax.set_xlabel("x (m)")
        ax.set_aspect("equal", adjustable="datalim")
    top.set_ylabel("y (m)")
    side.set_ylabel("z (m)")
    top.legend(fontsize=7)
    fig.tight_layout()
    return fig


def trajectory_html(df: pd.DataFrame, sc: Scenario) -> str:
    """A self-contained interactive 3D view of every vehicle (a relay's path coloured by the network's
    rate), each relay's reference, the base station and the jammers."""
    unit = sc.channel.capacity_unit
    traces = []
    for i, name in enumerate(_relays(df)):
        bar = dict(title=dict(text=f"network rate ({unit})", side="right"), x=1.0, len=0.6, y=0.35) if i == 0 else None
        traces.append(go.Scatter3d(x=df[f"{name}.p_x"], y=df[f"{name}.p_y"], z=df[f"{name}.p_z"], mode="lines",
                                   name=f"relay {name}", text=[f"t={t:.2f}s R={c:.3g}" for t, c in zip(df["t"], df["capacity"],
                                                                                                        strict=True)],
                                   line=dict(color=df["capacity"], colorscale="Viridis", width=6, colorbar=bar)))
        traces.append(go.Scatter3d(x=df[f"{name}.pd_x"], y=df[f"{name}.pd_y"], z=df[f"{name}.pd_z"], mode="lines",
                                   name=f"{name} reference", line=dict(width=2, dash="dot")))
    for s in sources_in(df.columns):
        traces.append(go.Scatter3d(x=df[f"{s}.p_x"], y=df[f"{s}.p_y"], z=df[f"{s}.p_z"], mode="lines",
                                   name=f"source {s}", line=dict(width=4)))
    traces += [go.Scatter3d(x=[b.position[0]], y=[b.position[1]], z=[b.position[2]], mode="markers", name=b.name,
                            marker=dict(color="black", size=5)) for b in sc.base_station_list]
    fig = go.Figure([*traces, *jammer_traces(sc, df["t"].to_numpy())])
    routes = "; ".join(" -> ".join(r) for r in sc.route_list)
    fig.update_layout(title=f"{sc.name}: {routes}", height=720,
                      scene=dict(aspectmode="data", xaxis_title="x (m)", yaxis_title="y (m)", zaxis_title="z (m)"),
                      legend=dict(x=0.0, y=1.0, xanchor="left", yanchor="top", bgcolor="rgba(255,255,255,0.7)"),
                      margin=dict(l=10, r=80, t=50, b=10))
    return fig.to_html(include_plotlyjs=True, full_html=True)


def bound_figure(bound: pd.DataFrame, sc: Scenario, series: list[tuple[str, dict]], ylabel: str, title: str):
    """A bound's series over time on a log axis, each ``(column, matplotlib style with its label)``,
    with the outage threshold: the figure ``aerorelay bound`` writes."""
    fig, ax = plt.subplots(figsize=(7, 3.4))
    for column, style in series:
        ax.semilogy(bound["t"], bound[column], **style)
    ax.axhline(sc.channel.outage, color="r", ls=":", lw=1, label="outage threshold")
    ax.set_xlabel("t (s)")
    ax.set_ylabel(f"{ylabel} ({sc.channel.capacity_unit})")
    ax.set_title(f"{sc.name}: {title}", fontsize=9)
    ax.legend(fontsize=7)
    fig.tight_layout()
    return fig


def fig_bound(bound: pd.DataFrame, sc: Scenario):
    """The capacity bounds of a scenario over time and the flyable path (``aerorelay bound``)."""
    return bound_figure(bound, sc, [
        ("static", dict(color="0.4", ls="--", label="static bound (best pose per instant)")),
        ("path_maxmin", dict(color="C1", lw=2.4, alpha=0.6, label="path bound, best minimum")),
        ("path_mean", dict(color="C2", lw=1.0, ls=(0, (4, 2)), label="path bound, best mean")),
        ("flyable_mean", dict(color="C4", lw=1.0, ls=":", label="flyable path, best mean found (exactly <= v_max)")),
    ], "C", "capacity bounds")


def fig_network_bound(bound: pd.DataFrame, sc: Scenario):
    """A fleet's network bound over time: the static upper bound, the refined configuration's rate, the
    upper path bound and the flyable fleet path's (``aerorelay bound`` on a fleet)."""
    series: list[tuple[str, dict]] = [("static", dict(color="0.4", ls="--", label="static upper bound (relaxed axes, grid)")),
                                      ("achieved", dict(color="C2", lw=1.6, label="refined configuration (one axis per relay)"))]
    if "path_mean" in bound:
        series.append(("path_mean", dict(color="C1", lw=1.2, ls=(0, (4, 2)), label="upper path bound (<= v_max from the starts)")))
    if "flyable" in bound:
        series.append(("flyable", dict(color="C0", lw=1.2, label="flyable fleet path (lower path bound, jointly optimized)")))
    return bound_figure(bound, sc, series, "network rate", "network bound")


def write_run_figures(df: pd.DataFrame, sc: Scenario, out: Path, bound: pd.DataFrame | None = None) -> None:
    """Write every figure of a run into ``out``: ``capacity.png`` (the bound behind), ``trajectory_3d.png``,
    ``paths.png``, ``trajectory.html`` and per relay ``constraints_<relay>.png`` and ``tracking_<relay>.png`` (the
    same names for one relay and for K)."""
    relays = _relays(df)
    figures = [("capacity.png", fig_capacity(df, sc, bound)), ("trajectory_3d.png", fig_trajectory_3d(df, sc)),
               ("paths.png", fig_paths(df, sc))]
    for r in relays:
        figures += [(f"constraints_{r}.png", fig_constraints(df, sc, r)), (f"tracking_{r}.png", fig_tracking(df, sc, r))]
    for name, fig in figures:
        fig.savefig(Path(out) / name, dpi=110)
        plt.close(fig)
    (Path(out) / "trajectory.html").write_text(trajectory_html(df, sc))
