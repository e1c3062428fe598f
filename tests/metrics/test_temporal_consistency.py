"""Temporal consistency: lane jitter after ego-motion compensation, hand-computed cases."""

import math

import numpy as np
import pytest

from lanelab.lanes import NO_TRACK
from lanelab.metrics.openlane import evaluate_frame
from lanelab.metrics.temporal_consistency import (
    PosedLanes,
    carry_lanes,
    clip_jitter,
    frame_jitter,
    matched_track_ids,
    temporal_consistency,
)


def pose(forward=0.0, yaw=0.0):
    """T_world_lane of an ego `forward` metres along the world y axis, turned by yaw."""
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s, 0, 0], [s, c, 0, forward], [0, 0, 1, 0], [0, 0, 0, 1.0]])


def straight(x, y0=0.0, y1=110.0):
    y = np.linspace(y0, y1, 23)
    return np.stack([np.full_like(y, x), y, np.zeros_like(y)], axis=1)


def frame(T, xs, ids=None):
    return PosedLanes(T, [straight(x) for x in xs], ids or [NO_TRACK] * len(xs))


def test_carrying_lanes_undoes_the_ego_motion():
    # A point 10 m ahead of an ego that then drives 1 m forward is 9 m ahead of it.
    carried = carry_lanes(PosedLanes(pose(0.0), [np.array([[1.0, 10.0, 0.0]])], [0]), pose(1.0))
    np.testing.assert_allclose(carried[0], [[1.0, 9.0, 0.0]])


def test_a_static_lane_seen_from_a_turning_ego_does_not_jitter():
    # The world line x = 1.75 (world frame = lane frame at t = 0), seen from 5 poses along a
    # curve: each frame holds its own view of the same line.
    world = np.stack([np.full(200, 1.75), np.linspace(-20, 180, 200), np.zeros(200)], axis=1)
    frames = []
    for k in range(5):
        T = pose(forward=2.0 * k, yaw=0.01 * k)
        local = (world - T[:3, 3]) @ T[:3, :3]  # T^-1 applied to world points
        frames.append(PosedLanes(T, [local[(local[:, 1] > 0) & (local[:, 1] < 110)]], [3]))
    jitter = clip_jitter(frames)
    assert len(jitter) == 4 and np.all(jitter < 1e-9)


def test_predictions_flickering_sideways_jitter_by_the_flicker():
    # Driving 1 m a frame on a straight road; the prediction alternates x = 1.85 / 1.65.
    gt = [frame(pose(k), [1.75]) for k in range(4)]
    pred = [frame(pose(k), [1.75 + 0.1 * (-1) ** k]) for k in range(4)]
    result = temporal_consistency([pred], [gt])
    assert result["jitter"] == pytest.approx(0.2) and result["pairs"] == 3
    assert result["gt_jitter"] == pytest.approx(0.0) and result["gt_pairs"] == 3


def test_track_ids_decide_the_pairs_before_distance():
    before = frame(pose(0), [0.0, 3.5], [7, 8])
    # The predictions swap the GT tracks they match: paired by track, each moved 3.5 m.
    swapped = frame(pose(0), [3.5, 0.0], [7, 8])
    np.testing.assert_allclose(frame_jitter(before, swapped), [3.5, 3.5])
    # Without track ids they pair by distance.
    anonymous = frame(pose(0), [3.5, 0.0])
    np.testing.assert_allclose(frame_jitter(frame(pose(0), [0.0, 3.5]), anonymous), [0.0, 0.0])


def test_lanes_without_track_pair_within_the_gate_only():
    before = frame(pose(0), [0.0])
    np.testing.assert_allclose(frame_jitter(before, frame(pose(0), [1.0])), [1.0])
    assert len(frame_jitter(before, frame(pose(0), [2.0]))) == 0  # beyond 1.5 m
    assert len(frame_jitter(before, frame(pose(0), []))) == 0


def test_pairs_need_two_common_y_samples():
    near = PosedLanes(pose(0), [straight(0.0, 0.0, 3.5)], [1])  # covers the sample y = 3 only
    assert len(frame_jitter(near, PosedLanes(pose(0), [straight(0.0)], [1]))) == 0


def test_no_pairs_give_nan():
    result = temporal_consistency([[frame(pose(0), [0.0])]], [])
    assert math.isnan(result["jitter"]) and result["pairs"] == 0
    assert math.isnan(result["gt_jitter"]) and result["gt_pairs"] == 0


def test_predictions_take_the_track_id_of_their_matched_gt_lane():
    gt, preds = [straight(0.0), straight(4.0)], [straight(4.1), straight(-7.0)]
    result = evaluate_frame(gt, [np.ones(23)] * 2, [1, 1], preds, [1, 1])
    assert result.matched == [(1, 0)]
    assert matched_track_ids(result, [10, 11], len(preds)) == [11, NO_TRACK]
