"""Summary statistics shared by the metrics and the benchmark (no dependency on either)."""

from __future__ import annotations

import numpy as np


def stats_ms(values) -> dict:
    """Mean, p50, p95, p99 and max of timings (ms in, ms out)."""
    v = np.asarray(values, float)
    return {"mean": float(v.mean()), "p50": float(np.percentile(v, 50)), "p95": float(np.percentile(v, 95)),
            "p99": float(np.percentile(v, 99)), "max": float(v.max())}
