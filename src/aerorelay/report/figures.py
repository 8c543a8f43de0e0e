"""Paper-style figures of one mission (matplotlib PNG) and an interactive 3D view (plotly HTML)."""

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


def fig_trajectory_3d(df: pd.DataFrame, sc: Scenario):
    fig = plt.figure(figsize=(6, 5))
    ax = fig.add_subplot(projection="3d")
    ax.plot(df["p1_x"], df["p1_y"], df["p1_z"], color=RELAY, label="MRAV-1 (relay)")
    ax.plot(df["p2_x"], df["p2_y"], df["p2_z"], color=SOURCE, label="MRAV-2 (source)")
    ax.plot(df["pd_x"], df["pd_y"], df["pd_z"], color=RELAY, ls=":", lw=1, label="relay reference")
    ax.scatter(*sc.nodes.bs, color="k", s=30, label="BS")
    for i, (name, P) in enumerate(jammer_tracks(sc, df["t"].to_numpy())):
        ax.scatter(*P[0], color="r", s=30, label="jammer" if i == 0 else None)
        if np.ptp(P, axis=0).max() > 1e-9:
            ax.plot(P[:, 0], P[:, 1], P[:, 2], color="r", lw=1, label=f"{name} (moving)")
    for i, (c, col) in enumerate(((("p1_x", "p1_y", "p1_z"), RELAY), (("p2_x", "p2_y", "p2_z"), SOURCE))):
        ax.scatter(*[df[k].iloc[0] for k in c], color=col, marker="o", s=15, label="start (o)" if i == 0 else None)
        ax.scatter(*[df[k].iloc[-1] for k in c], color=col, marker="^", s=25, label="end (^)" if i == 0 else None)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_zlabel("z (m)")
    ax.legend(loc="upper left", fontsize=7)
    ax.set_title(_run_title(sc), fontsize=9)
    return fig


def _run_title(sc: Scenario) -> str:
    """Scenario, planner and NMPC variant: what flew."""
    return f"{sc.name} ({sc.controller.planner} planner, {sc.controller.variant} NMPC)"


def fig_capacity(df: pd.DataFrame, sc: Scenario, bound: pd.DataFrame | None = None):
    fig, axes = plt.subplots(2, 1, figsize=(7, 5), sharex=True)
    ax = axes[0]
    if bound is not None:  # what the physics allows, behind the run
        ax.semilogy(bound["t"], bound["static"], color="0.6", lw=1, ls="--", label="static bound (best pose per instant)")
        ax.semilogy(bound["t"], bound["path_maxmin"], color="C1", lw=2.4, alpha=0.6, label="path bound (best minimum)")
        ax.semilogy(bound["t"], bound["path_mean"], color="C2", lw=1.0, ls=(0, (4, 2)), label="path bound (best mean, <= v_max)")
        if "flyable_mean" in bound:
            ax.semilogy(bound["t"], bound["flyable_mean"], color="C4", lw=1.0, ls=":", label="flyable path (best mean found, exactly <= v_max)")
    ax.semilogy(df["t"], np.maximum(df["capacity"], 1e-12), color="k", label="end-to-end C")
    ax.axhline(sc.channel.outage, color="r", ls="--", lw=1, label="outage threshold")
    _shade_jammer_off(ax, df)
    ax.set_ylabel(f"C ({sc.channel.capacity_unit})")
    ax.legend(fontsize=7)
    ax = axes[1]
    ax.semilogy(df["t"], np.maximum(df["se_21"], 1e-12), label=r"$\log_2(1+\Gamma_{21})$")
    ax.semilogy(df["t"], np.maximum(df["se_10"], 1e-12), label=r"$\log_2(1+\Gamma_{10})$")
    _shade_jammer_off(ax, df)
    ax.set_ylabel("spectral efficiency (bit/s/Hz)")
    ax.set_xlabel("t (s)")
    ax.legend(fontsize=7)
    fig.tight_layout()
    return fig


def fig_constraints(df: pd.DataFrame, sc: Scenario):
    p = sc.platform
    fig, axes = plt.subplots(4, 1, figsize=(7, 8), sharex=True)
    for i in range(1, sum(1 for c in df.columns if c.removeprefix("Omega_").isdigit()) + 1):
        axes[0].plot(df["t"], df[f"Omega_{i}"], lw=0.8, label=f"rotor {i}")
        axes[1].plot(df["t"], df[f"u_{i}"], lw=0.6, label=f"rotor {i}")
    for ax, lo, hi, lab in ((axes[0], p.omega_min_hz, p.omega_max_hz, r"$\Omega$ (Hz)"),
                            (axes[1], p.omega_dot_min_hz_s, p.omega_dot_max_hz_s, r"$\dot\Omega$ (Hz/s)")):
        ax.axhline(lo, color="r", ls="--", lw=1, label="bounds")
        ax.axhline(hi, color="r", ls="--", lw=1)
        ax.set_ylabel(lab)
        ax.legend(fontsize=6, ncol=4, loc="upper right")
    axes[2].plot(df["t"], df["slack_max"], color="C3")
    axes[2].set_ylabel(r"slack $\pi$ (-)")
    axes[3].plot(df["t"], df["mutual_alignment"], color="C2", label=r"$(1-v_{12})(1-v_{10})$")
    axes[3].axhline(sc.controller.mu, color="r", ls="--", lw=1, label=r"$\mu$")
    axes[3].set_ylabel("mutual alignment (-)")
    axes[3].set_xlabel("t (s)")
    axes[3].legend(fontsize=7)
    fig.tight_layout()
    return fig


def fig_tracking(df: pd.DataFrame, sc: Scenario):
    fig, axes = plt.subplots(3, 1, figsize=(7, 6), sharex=True)
    for _i, ax_name in enumerate("xyz"):
        axes[0].plot(df["t"], df[f"p1_{ax_name}"] - df[f"pd_{ax_name}"], label=f"e_p{ax_name}")
    axes[0].set_ylabel("position error (m)")
    axes[0].legend(fontsize=7)
    for name in ("phi1", "theta1", "psi1"):
        axes[1].plot(df["t"], np.degrees(df[name]), label=name)
    axes[1].set_ylabel("relay attitude (deg)")
    axes[1].legend(fontsize=7)
    axes[2].plot(df["t"], df["v_12"], label=r"$v_{12}$")
    axes[2].plot(df["t"], df["v_10"], label=r"$v_{10}$")
    axes[2].set_ylabel("misalignment (-)")
    axes[2].set_xlabel("t (s)")
    axes[2].legend(fontsize=7)
    fig.tight_layout()
    return fig


def trajectory_html(df: pd.DataFrame, sc: Scenario, *, include_plotlyjs=True) -> str:
    """A self-contained interactive 3D view of both vehicles, the BS and the jammers."""
    hover = [f"t={t:.2f}s C={c:.2e}" for t, c in zip(df["t"], df["capacity"], strict=False)]
    fig = go.Figure([
        go.Scatter3d(x=df["p1_x"], y=df["p1_y"], z=df["p1_z"], mode="lines", name="MRAV-1 (relay)",
                     line=dict(color=df["capacity"], colorscale="Viridis", width=6,
                               colorbar=dict(title=dict(text=f"C ({sc.channel.capacity_unit})", side="right"), x=1.0, len=0.6, y=0.35)),
                     text=hover),
        go.Scatter3d(x=df["p2_x"], y=df["p2_y"], z=df["p2_z"], mode="lines", name="MRAV-2 (source)",
                     line=dict(color=SOURCE, width=4)),
        go.Scatter3d(x=df["pd_x"], y=df["pd_y"], z=df["pd_z"], mode="lines", name="relay reference",
                     line=dict(color=RELAY, width=2, dash="dot")),
        go.Scatter3d(x=[sc.nodes.bs[0]], y=[sc.nodes.bs[1]], z=[sc.nodes.bs[2]], mode="markers", name="BS",
                     marker=dict(color="black", size=5)),
        *jammer_traces(sc, df["t"].to_numpy()),
    ])
    fig.update_layout(title=_run_title(sc), height=720,
                      scene=dict(aspectmode="data", xaxis_title="x (m)", yaxis_title="y (m)", zaxis_title="z (m)",
                                 camera=dict(eye=dict(x=1.5, y=1.5, z=0.8))),
                      legend=dict(x=0.0, y=1.0, xanchor="left", yanchor="top", bgcolor="rgba(255,255,255,0.7)"),
                      margin=dict(l=10, r=80, t=50, b=10))
    return fig.to_html(include_plotlyjs=include_plotlyjs, full_html=True)


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


FIGURES = {
    "trajectory_3d.png": fig_trajectory_3d,
    "capacity.png": fig_capacity,
    "constraints.png": fig_constraints,
    "tracking.png": fig_tracking,
}


def write_run_figures(df: pd.DataFrame, sc: Scenario, out: Path, bound: pd.DataFrame | None = None) -> None:
    """Write every PNG figure and ``trajectory.html`` into ``out`` (``capacity.png`` with the bound behind)."""
    for name, make in FIGURES.items():
        fig = fig_capacity(df, sc, bound) if name == "capacity.png" else make(df, sc)
        fig.savefig(out / name, dpi=110)
        plt.close(fig)
    (out / "trajectory.html").write_text(trajectory_html(df, sc))
