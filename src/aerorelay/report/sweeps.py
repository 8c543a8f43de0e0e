"""A swept parameter against C_min and mean C: one figure per swept key of a study (a custom
sweep's ``[grid]``, or runs that each set one key to another number), means over seeds."""

from __future__ import annotations

import html

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from ..experiments.study import Study, sweep_series  # noqa: E402

MAX_SERIES = 8  # curves per figure; more are left to the study's table


def log_spaced(xs: list[float]) -> bool:
    """Whether swept values are spread on a log scale: at least three, all positive, spanning more than a
    decade, their ratios closer to constant than their differences."""
    x = np.asarray(sorted(xs), float)
    if x.size < 3 or x[0] <= 0 or x[-1] / x[0] < 10:
        return False
    ratios, diffs = x[1:] / x[:-1], np.diff(x)
    return bool(np.std(np.log(ratios)) < np.std(diffs / diffs.mean()))


def box_figure(study: Study, study_sum: dict, unit: str, png) -> str | None:
    """C_min and mean C over the seeds of every group with three or more: median, quartiles, 5-95 %
    whiskers (``summary.json``'s ``.values``), the seeds as points."""
    groups = {g: v for g, v in study_sum.get("groups", {}).items() if len(v.get("c_min.values", [])) >= 3}
    if not groups:
        return None
    names = list(groups)
    fig, axes = plt.subplots(1, 2, figsize=(9, 3.4))
    for ax, key, title in zip(axes, ("c_min", "c_mean"), ("C_min", "mean C"), strict=True):
        data = [groups[g][f"{key}.values"] for g in names]
        ax.boxplot(data, whis=(5, 95), showfliers=False)
        for i, vals in enumerate(data, 1):
            ax.plot(np.full(len(vals), i) + np.linspace(-0.15, 0.15, len(vals)), vals, ".", color="#4a78b0", alpha=0.5, ms=3)
        ax.set_xticks(range(1, len(names) + 1))
        ax.set_xticklabels([n if len(n) <= 24 else n[:22] + "..." for n in names], rotation=60, ha="right", fontsize=6)
        ax.set_ylabel(f"{title} ({unit})")
        ax.set_title(f"{title} over each run's seeds (n = {min(len(d) for d in data)}-{max(len(d) for d in data)})",
                     fontsize=9)
        ax.grid(axis="y", alpha=0.3)
    fig.suptitle(f"{study.title}: the spread over seeds (box: quartiles and median; whiskers: 5-95 %)", fontsize=10)
    fig.tight_layout()
    return "<h3>Spread over seeds</h3>" + png(fig, "C_min and mean C over seeds, per run")


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
        drawn, seeded = False, False
        for label, points in series:
            xs = [x for x, g in points if g in groups]
            if len(xs) < 2:
                continue
            for ax, metric in zip(axes, ("c_min", "c_mean"), strict=True):
                gs = [g for x, g in points if g in groups]
                ys = [groups[g][metric] for g in gs]
                lo = [groups[g].get(f"{metric}.p05", groups[g][metric]) for g in gs]
                hi = [groups[g].get(f"{metric}.p95", groups[g][metric]) for g in gs]
                line = ax.plot(xs, ys, "o-", label=label or None)[0]
                if any(h > l_ for l_, h in zip(lo, hi, strict=True)):  # several seeds: their 5-95 % band
                    ax.fill_between(xs, lo, hi, color=line.get_color(), alpha=0.15, lw=0)
                    seeded = True
            drawn = True
        if not drawn:
            plt.close(fig)
            continue
        log_x = log_spaced([x for _, points in series for x, _ in points])
        for ax, name in zip(axes, ("C_min", "mean C"), strict=True):
            ax.set_xlabel(key + (" (log scale)" if log_x else ""))
            if log_x:
                ax.set_xscale("log")
            ax.set_ylabel(f"{name} ({unit})")
            ax.grid(alpha=0.3)
        if any(label for label, _ in series):
            axes[1].legend(fontsize=7)
        fig.suptitle(f"{study.title}: {key}" + (" (mean over seeds, 5-95 % band)" if seeded else ""), fontsize=10)
        fig.tight_layout()
        out.append(f"<h3>Swept: <code>{html.escape(key)}</code></h3>" + png(fig, f"{key} against C_min and mean C"))
    return out
