"""A fleet's run as figures (``sim.fleet`` log): the network's rate and each route's, each hop's
SINR, and the vehicles' paths seen from above and from the side."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
import plotly.graph_objects as go  # noqa: E402

from ..config import Scenario  # noqa: E402
from .figures import bound_figure, jammer_traces  # noqa: E402

FLEET_FIGURES = ("rates.png", "sinr.png", "paths.png")


def fig_rates(df: pd.DataFrame, sc: Scenario):
    """The network's rate (every source at it) and each route's capacity alone, with the outage threshold."""
    unit, scale = ("Mbit/s", 1e-6) if sc.channel.physical else ("bit/s/Hz", 1.0)
    fig, ax = plt.subplots(figsize=(7, 3.2))
    for route in sc.route_list:
        ax.semilogy(df["t"], df[f"capacity.{route[0]}"] * scale, lw=0.8, label=f"route {' -> '.join(route)} alone")
    ax.semilogy(df["t"], df["capacity"] * scale, lw=1.6, color="k", label="network rate")
    ax.axhline(sc.channel.outage * scale, color="r", ls="--", lw=0.8, label="outage threshold")
    ax.set_xlabel("t (s)")
    ax.set_ylabel(f"rate ({unit})")
    ax.legend(fontsize=7)
    fig.tight_layout()
    return fig


def fig_sinr(df: pd.DataFrame, sc: Scenario):
    """Each hop's SINR (dB)."""
    fig, ax = plt.subplots(figsize=(7, 3.2))
    for c in [c for c in df.columns if c.startswith("sinr.")]:
        _, tx, rx = c.split(".")
        ax.plot(df["t"], 10 * np.log10(np.maximum(df[c].to_numpy(float), 1e-30)), lw=0.8, label=f"{tx} -> {rx}")
    ax.set_xlabel("t (s)")
    ax.set_ylabel("SINR (dB)")
    ax.legend(fontsize=7)
    fig.tight_layout()
    return fig


def fig_paths(df: pd.DataFrame, sc: Scenario):
    """Every vehicle's path from above (x, y) and from the side (x, z); the base station and the jammers."""
    fig, (top, side) = plt.subplots(1, 2, figsize=(10, 4))
    for name in [r.name for r in sc.relay_list] + [s.name for s in sc.source_list]:
        x, y, z = (df[f"{name}.p_{a}"].to_numpy(float) for a in "xyz")
        for ax, v in ((top, y), (side, z)):
            ax.plot(x, v, lw=1.0, label=name)
            ax.plot(x[0], v[0], "o", ms=3, color=ax.lines[-1].get_color())
    for ax, i in ((top, 1), (side, 2)):
        ax.plot(sc.nodes.bs[0], sc.nodes.bs[i], "k^", label="bs")
        for j in sc.jammer_configs:
            ax.plot(df[f"jam_{j.name}_x"], df[f"jam_{j.name}_{'yz'[i - 1]}"], "rx", ms=4, label=f"jammer {j.name!r}")
        ax.set_xlabel("x (m)")
        ax.set_aspect("equal", adjustable="datalim")
    top.set_ylabel("y (m)")
    side.set_ylabel("z (m)")
    top.legend(fontsize=7)
    fig.tight_layout()
    return fig


def fleet_trajectory_html(df: pd.DataFrame, sc: Scenario) -> str:
    """A self-contained interactive 3D view of every vehicle (a relay's path coloured by the network's
    rate), each relay's reference, the base station and the jammers."""
    unit = sc.channel.capacity_unit
    traces = []
    for i, r in enumerate(sc.relay_list):
        bar = dict(title=dict(text=f"network rate ({unit})", side="right"), x=1.0, len=0.6, y=0.35) if i == 0 else None
        traces.append(go.Scatter3d(x=df[f"{r.name}.p_x"], y=df[f"{r.name}.p_y"], z=df[f"{r.name}.p_z"], mode="lines",
                                   name=f"relay {r.name}", text=[f"t={t:.2f}s R={c:.3g}" for t, c in zip(df["t"], df["capacity"],
                                                                                                        strict=True)],
                                   line=dict(color=df["capacity"], colorscale="Viridis", width=6, colorbar=bar)))
        traces.append(go.Scatter3d(x=df[f"{r.name}.pd_x"], y=df[f"{r.name}.pd_y"], z=df[f"{r.name}.pd_z"], mode="lines",
                                   name=f"{r.name} reference", line=dict(width=2, dash="dot")))
    for s in sc.source_list:
        traces.append(go.Scatter3d(x=df[f"{s.name}.p_x"], y=df[f"{s.name}.p_y"], z=df[f"{s.name}.p_z"], mode="lines",
                                   name=f"source {s.name}", line=dict(width=4)))
    traces.append(go.Scatter3d(x=[sc.nodes.bs[0]], y=[sc.nodes.bs[1]], z=[sc.nodes.bs[2]], mode="markers", name="bs",
                               marker=dict(color="black", size=5)))
    fig = go.Figure([*traces, *jammer_traces(sc, df["t"].to_numpy())])
    routes = "; ".join(" -> ".join(r) for r in sc.route_list)
    fig.update_layout(title=f"{sc.name}: {routes}", height=720,
                      scene=dict(aspectmode="data", xaxis_title="x (m)", yaxis_title="y (m)", zaxis_title="z (m)"),
                      legend=dict(x=0.0, y=1.0, xanchor="left", yanchor="top", bgcolor="rgba(255,255,255,0.7)"),
                      margin=dict(l=10, r=80, t=50, b=10))
    return fig.to_html(include_plotlyjs=True, full_html=True)


def write_fleet_figures(df: pd.DataFrame, sc: Scenario, out: Path) -> None:
    """Write ``rates.png``, ``sinr.png``, ``paths.png`` and ``trajectory.html`` into ``out``."""
    for name, make in zip(FLEET_FIGURES, (fig_rates, fig_sinr, fig_paths), strict=True):
        fig = make(df, sc)
        fig.savefig(Path(out) / name, dpi=110)
        plt.close(fig)
    (Path(out) / "trajectory.html").write_text(fleet_trajectory_html(df, sc))


def fig_network_bound(bound: pd.DataFrame, sc: Scenario):
    """A fleet's network bound over time: the static upper bound, the refined configuration's rate and
    the flyable fleet path's (``aerorelay bound`` on a fleet)."""
    series: list[tuple[str, dict]] = [("static", dict(color="0.4", ls="--", label="static upper bound (relaxed axes, grid)")),
                                      ("achieved", dict(color="C2", lw=1.6, label="refined configuration (one axis per relay)"))]
    if "flyable" in bound:
        series.append(("flyable", dict(color="C0", lw=1.2, label="flyable fleet path (from the starts, speed-limited)")))
    return bound_figure(bound, sc, series, "network rate", "network bound")
