"""Campaign outputs over seeds (issue 48, item 4): the spread of a group's metric (5th, 25th, 50th,
75th, 95th percentiles by hand), log axes where a sweep is log-spaced, a box plot of C_min and mean C
over the seeds of each run."""

from __future__ import annotations

import numpy as np
import pytest

from aerorelay.experiments.study import Study
from aerorelay.report.summary import distribution
from aerorelay.report.sweeps import box_figure, log_spaced


def test_the_spread_over_seeds_by_hand():
    d = distribution("c_min", np.array([5.0, 1.0, 4.0, 2.0, 3.0]))
    # linear percentiles of 1..5: position q/100 * (n - 1) between the sorted values
    assert (d["c_min.p05"], d["c_min.p25"], d["c_min.median"], d["c_min.p75"], d["c_min.p95"]) == \
        pytest.approx((1.2, 2.0, 3.0, 4.0, 4.8))
    assert d["c_min.values"] == [5.0, 1.0, 4.0, 2.0, 3.0]
    assert "solve_ms.values" not in distribution("solve_ms", np.array([1.0, 2.0]))


@pytest.mark.parametrize("xs,log", [([0.1, 1.0, 10.0, 100.0], True), ([1.0, 3.0, 10.0, 30.0, 100.0], True),
                                    ([1.0, 2.0, 3.0, 4.0], False), ([0.0, 1.0, 10.0], False), ([1.0, 5.0], False)])
def test_log_spaced_sweeps_are_seen(xs, log):
    assert log_spaced(xs) is log


def test_a_box_plot_of_the_seeds_of_each_run():
    study = Study.model_validate({"name": "s", "title": "t", "base": "x.toml", "seeds": 4})
    rng = np.random.default_rng(0)
    groups = {g: {"c_min.values": list(rng.uniform(1e-3, 2e-3, 4)), "c_mean.values": list(rng.uniform(2e-3, 3e-3, 4))}
              for g in ("a", "b")}
    html = box_figure(study, {"groups": groups}, "bit/s/Hz", lambda fig, alt: f"<img alt='{alt}'>")
    assert html is not None and "Spread over seeds" in html and "C_min and mean C over seeds" in html
    assert box_figure(study, {"groups": {"a": {"c_min.values": [1.0, 2.0]}}}, "1", lambda f, a: "x") is None
