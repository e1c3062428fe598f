"""Lane targets: resampling at fixed y (hand cases), which lanes are kept."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from lanelab.data.targets import LANE_KEYS, LaneTargets, resample_lane


def lane(x, y, z, visibility=None, track_id=7, category=2):
    points = np.stack(np.broadcast_arrays(x, y, z), axis=1).astype(np.float32)
    visibility = np.ones(len(points), np.float32) if visibility is None else np.asarray(visibility, np.float32)
    return SimpleNamespace(track_id=track_id, category=category, points=points, visibility=visibility)


def test_straight_lane_is_resampled_exactly_with_zero_visibility_outside_its_range():
    straight = lane(1.5, np.array([10.0, 20.0, 30.0, 40.0, 50.0]), 0.1)
    y = np.arange(0.0, 61.0, 5.0)
    x, z, vis = resample_lane(straight.points, straight.visibility, y).T
    inside = (y >= 10) & (y <= 50)
    np.testing.assert_allclose(x[inside], 1.5, atol=1e-6)
    np.testing.assert_allclose(z[inside], 0.1, atol=1e-6)
    np.testing.assert_array_equal(vis, inside.astype(float))


def test_curved_lane_interpolates_between_its_points():
    # x = y^2 / 100 at y = 0, 10, 20, 30: halfway between points the polyline gives the chords' middles.
    ys = np.array([0.0, 10.0, 20.0, 30.0])
    curved = lane(ys**2 / 100, ys, ys / 10)
    x, z, vis = resample_lane(curved.points, curved.visibility, np.array([0.0, 5.0, 15.0, 25.0, 30.0, 35.0])).T
    np.testing.assert_allclose(x[:5], [0.0, 0.5, 2.5, 6.5, 9.0], atol=1e-6)
    np.testing.assert_allclose(z[:5], [0.0, 0.5, 1.5, 2.5, 3.0], atol=1e-6)
    np.testing.assert_array_equal(vis, [1, 1, 1, 1, 1, 0])


def test_visibility_is_interpolated_then_thresholded():
    ys = np.array([0.0, 10.0, 20.0, 30.0])
    occluded_far = lane(0.0, ys, 0.0, visibility=[1, 1, 0, 0])
    _, _, vis = resample_lane(occluded_far.points, occluded_far.visibility, np.array([5.0, 12.0, 16.0, 25.0])).T
    np.testing.assert_array_equal(vis, [1, 1, 0, 0])  # 1, 0.8, 0.4, 0


def test_targets_shapes_and_dropped_lanes():
    targets = LaneTargets(np.linspace(3.0, 103.0, 101))
    ys = np.arange(0.0, 80.0, 2.0)
    kept = lane(1.75, ys, 0.0, track_id=3, category=8)
    lanes = [
        kept,
        lane(0.0, np.array([20.0]), 0.0),  # a single point
        lane(0.0, np.array([110.0, 150.0]), 0.0),  # beyond the grid
        lane(0.0, ys, 0.0, visibility=np.zeros(len(ys))),  # wholly occluded
    ]
    out = targets(lanes)
    assert set(out) == set(LANE_KEYS)
    assert out["gt_x"].shape == out["gt_z"].shape == out["gt_vis"].shape == (1, 101)
    assert out["gt_x"].dtype == np.float32
    assert out["gt_category"].tolist() == [8] and out["gt_track_id"].tolist() == [3]
    assert out["gt_category"].dtype == out["gt_track_id"].dtype == np.int64

    empty = targets([])
    assert empty["gt_x"].shape == (0, 101)

