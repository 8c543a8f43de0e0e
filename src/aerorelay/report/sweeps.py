"""A swept parameter against C_min and mean C: one figure per swept key of a study (a custom
sweep's ``[grid]``, or runs that each set one key to another number), means over seeds."""

from __future__ import annotations

import html

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from ..experiments.study import Study, sweep_series  # noqa: E402

MAX_SERIES = 8  # curves per figure; more are left to the study's table


def sweep_figures(study: Study, study_sum: dict, unit: str, png) -> list[str]:
    """HTML figures (``png(fig, alt)`` embeds one) of every swept parameter of ``study`` against
    C_min and mean C from the study's summary (``study_sum["groups"]``); groups without results
    are left out of their curve."""
    groups = study_sum.get("groups", {})
    by_key: dict[str, list[tuple[str, list[tuple[float, str]]]]] = {}
    for key, label, points in sweep_series(study):
        by_key.setdefault(key, []).append((label, points))
    out = []
    for key, series in by_key.items():
        if len(series) > MAX_SERIES:  # a full factorial's every combination: the study's table says it better
            continue
        fig, axes = plt.subplots(1, 2, figsize=(9, 3.2))
        drawn = False
        for label, points in series:
            xs = [x for x, g in points if g in groups]
            if len(xs) < 2:
                continue
            for ax, metric in zip(axes, ("c_min", "c_mean"), strict=True):
                ys = [groups[g][metric] for x, g in points if g in groups]
                ax.plot(xs, ys, "o-", label=label or None)
            drawn = True
        if not drawn:
            plt.close(fig)
            continue
        for ax, name in zip(axes, ("C_min", "mean C"), strict=True):
            ax.set_xlabel(key)
            ax.set_ylabel(f"{name} ({unit})")
            ax.grid(alpha=0.3)
        if any(label for label, _ in series):
            axes[1].legend(fontsize=7)
        fig.suptitle(f"{study.title}: {key}", fontsize=10)
        fig.tight_layout()
        out.append(f"<h3>Swept: <code>{html.escape(key)}</code></h3>" + png(fig, f"{key} against C_min and mean C"))
    return out
