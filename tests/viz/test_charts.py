"""Line charts: series are drawn where their values say, references dashed, panels tiled."""

import math

import numpy as np

from lanelab.viz.charts import chart_grid, line_chart


def coloured(panel: np.ndarray) -> np.ndarray:
    """(H, W) bool: pixels that are neither white, grey nor black (the series' colours)."""
    spread = panel.max(-1).astype(int) - panel.min(-1).astype(int)
    return spread > 40


def test_a_rising_series_is_drawn_from_bottom_left_to_top_right_and_nan_is_skipped():
    panel = line_chart("f1", {"run": ([0, 1, 2, 3], [0.0, math.nan, 2.0, 3.0])}, size=(200, 300))
    assert panel.shape == (200, 300, 3) and panel.dtype == np.uint8
    rows, columns = np.nonzero(coloured(panel[40:, 60:]))  # the plot area, below the legend
    left, right = columns < columns.mean(), columns > columns.mean()
    assert rows[left].mean() > rows[right].mean()  # image rows grow downwards: left part is lower


def test_the_reference_is_a_dashed_grey_line_and_panels_tile():
    panel = line_chart("f1", {"run": ([0, 1], [0.2, 0.4])}, reference=("prior", 0.3), size=(200, 300))
    grey = np.all(panel == 90, axis=-1)
    row = np.bincount(np.nonzero(grey)[0]).argmax()
    dashes = np.diff(grey[row].astype(int))
    assert (dashes == 1).sum() > 10  # many dashes, not one line
    grid = chart_grid([panel, panel, panel], columns=2)
    assert grid.shape == (400, 600, 3)
    assert np.array_equal(grid[:200, 300:], panel) and np.all(grid[200:, 300:] == 255)
