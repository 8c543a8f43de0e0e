"""The capacity figure marks where the network changed: each handover (labelled with the new base station) and
each spare taking a relay's place, at the step the log shows it."""

from pathlib import Path

import matplotlib
import numpy as np
import pandas as pd

import aerorelay as ar
from aerorelay.report.figures import fig_capacity

matplotlib.use("Agg")
ROOT = Path(__file__).resolve().parents[2]


def test_handovers_and_take_overs_are_marked_where_the_log_has_them():
    t = np.arange(0.0, 10.0, 0.5)
    station = np.where(t < 3.0, "depot", np.where(t < 7.0, "substation", "depot"))
    ferrying = (t >= 1.0) & (t < 4.0)
    df = pd.DataFrame({"t": t, "capacity": np.full(t.size, 2.0), "se.inspector.r1": np.ones(t.size), "jammer_on": np.ones(t.size, bool),
                       "inspector.base_station": station, "spare.ferrying": ferrying,
                       "spare.replaces": np.where(t >= 1.0, "r1", ""), "spare.waiting": t < 1.0})
    fig = fig_capacity(df, ar.load_scenario(ROOT / "scenarios" / "relay_shifts.toml"))
    ax = fig.axes[0]
    marks = sorted(float(line.get_xdata()[0]) for line in ax.lines if line.get_linestyle() == ":")
    assert marks == [3.0, 4.0, 7.0]
    texts = {a.get_text() for a in ax.texts}
    assert texts == {"to substation", "to depot", "spare in r1's place"}
