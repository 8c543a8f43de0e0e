"""How a run ended, as a value with a sentence (issue 46; RotorPy's ExitStatus): from hand-made
logs through the safety verdict, every status that applies in order, the first as ``exit_status``."""

from __future__ import annotations

import numpy as np

from aerorelay.models.obstacles import Box
from aerorelay.sim.exit_status import SENTENCES, ExitStatus
from aerorelay.sim.metrics import safety_metrics

WS = dict(workspace_min=[-5.0, -5.0, 0.5], workspace_max=[5.0, 5.0, 10.0], box_tolerance_m=0.05, ground_z_m=0.0)


def _verdict(p, tilt, **kw):
    p = np.asarray(p, float)
    return safety_metrics(p, np.asarray(tilt, float), np.zeros(len(p), bool), **WS, **kw)


def test_a_run_inside_its_world_is_complete():
    m = _verdict([[0, 0, 2], [1, 1, 3]], [5, 10])
    assert (m["exit_status"], m["exit_statuses"], m["unsafe"]) == ("complete", [], False)
    assert m["exit_sentence"] == "flown to the end inside its world"


def test_every_way_out_is_named_in_order():
    m = _verdict([[0, 0, 2], [7, 0, 2], [0, 0, -1], [1, 1, 1]], [5, 10, 10, 120],
                 obstacles=(Box((0.5, 0.5, 0.5), (1.5, 1.5, 1.5)),))
    assert m["exit_statuses"] == ["left_workspace", "below_ground", "flipped", "in_obstacle"]
    assert m["exit_status"] == "left_workspace" and m["unsafe"]
    nan = _verdict([[0, 0, 2], [np.nan, 0, 2]], [5, 5])
    assert nan["exit_status"] == "non_finite" and nan["unsafe"]


def test_every_status_has_its_sentence():
    assert set(SENTENCES) == set(ExitStatus) and all(ExitStatus(s.value).sentence for s in ExitStatus)
