"""The measurement window: rows kept in order through compaction, each with its grid-cell gains."""

import numpy as np
import pytest

from aerorelay.estimation.window import MeasurementWindow


def test_rows_and_their_cell_gains_survive_compaction():
    """A window of 5 rows (10 slots) after 23 appends holds the last 5, each with the gains it came with."""
    w = MeasurementWindow(5, n_cells=3)
    for k in range(23):
        w.append(float(k), 0, np.full(3, k), np.array([0.0, 0.0, 1.0]), 1.0 + k, cell_gains=np.array([k, 2 * k, 3 * k]))
    idx = w.rows(100)
    np.testing.assert_array_equal(w.t[idx], np.arange(18.0, 23.0))
    np.testing.assert_array_equal(w.cell_gains[idx], np.outer(np.arange(18, 23), [1, 2, 3]))
    np.testing.assert_allclose(np.exp(w.z[idx] / (10.0 / np.log(10.0))), 1.0 + np.arange(18.0, 23.0))


def test_a_row_without_its_cell_gains_raises():
    w = MeasurementWindow(5, n_cells=3)
    with pytest.raises(ValueError, match="3 cell gains"):
        w.append(0.0, 0, np.zeros(3), np.array([0.0, 0.0, 1.0]), 1.0, cell_gains=np.ones(4))
    with pytest.raises(ValueError, match="3 cell gains"):
        w.append(0.0, 0, np.zeros(3), np.array([0.0, 0.0, 1.0]), 1.0)
    MeasurementWindow(5).append(0.0, 0, np.zeros(3), np.array([0.0, 0.0, 1.0]), 1.0)  # no cells kept: none needed
