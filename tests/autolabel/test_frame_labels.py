"""Per-frame labels: tracked lines carried into a frame's lane frame agree with the true lanes there."""

from __future__ import annotations

import numpy as np

from data_ingest.autolabel.frame_labels import frame_labels
from data_ingest.autolabel.surface import RoadSurface
from data_ingest.autolabel.tracker import Line

RADIUS = 200.0  # m, a left-hand bend
K = np.array([[416.0, 0.0, 240.0], [0.0, 416.0, 180.0], [0.0, 0.0, 1.0]])
T_LANE_CAM = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, -1.0, 0.0, 1.5], [0.0, 0.0, 0.0, 1.0]])


def bend_poses(count: int) -> np.ndarray:
    """T_world_lane (count, 4, 4) every metre along a circle about (0, RADIUS): x right, y forward, z up."""
    theta = np.arange(count) / RADIUS
    poses = np.tile(np.eye(4), (count, 1, 1))
    poses[:, :3, 0] = np.stack([np.sin(theta), -np.cos(theta), np.zeros(count)], axis=1)
    poses[:, :3, 1] = np.stack([np.cos(theta), np.sin(theta), np.zeros(count)], axis=1)
    poses[:, :3, 3] = np.stack([RADIUS * np.sin(theta), RADIUS * (1 - np.cos(theta)), np.zeros(count)], axis=1)
    return poses


def test_lines_carried_into_a_frame_lie_on_the_true_lanes_and_are_visible_where_the_camera_sees_them():
    poses = bend_poses(400)
    surface = RoadSurface(poses)
    nodes = np.arange(0, 399)
    lines = [Line(7, 1, nodes, np.full(len(nodes), -1.75), False), Line(9, 21, nodes, np.full(len(nodes), 1.75), False)]
    t = 50
    lanes = frame_labels(surface, lines, 1.0, t, poses[t], K, T_LANE_CAM, (480, 360), range_m=120.0)
    assert [(lane.track_id, lane.category) for lane in lanes] == [(7, 1), (9, 21)]
    for lane, d in zip(lanes, (-1.75, 1.75)):
        y = lane.points[:, 1]
        assert y[0] < 1.0 and 115.0 < y[-1] <= 120.0 and np.all(np.diff(y) > 0)  # from the ego out to the range
        world = lane.points @ poses[t][:3, :3].T + poses[t][:3, 3]
        np.testing.assert_allclose(np.linalg.norm(world[:, :2] - [0.0, RADIUS], axis=1), RADIUS + d, atol=0.01)
        np.testing.assert_allclose(lane.points[:, 2], 0.0, atol=1e-6)
        # Visible exactly where the point projects into the image (a flat road hides nothing).
        cam = (lane.points - T_LANE_CAM[:3, 3]) @ T_LANE_CAM[:3, :3]
        uv = cam[:, :2] / cam[:, 2:] @ K[:2, :2].T + K[:2, 2]
        inside = (cam[:, 2] > 0) & (uv[:, 0] >= 0) & (uv[:, 0] < 480) & (uv[:, 1] >= 0) & (uv[:, 1] < 360)
        np.testing.assert_array_equal(lane.visibility > 0, inside)
        assert not inside[y < 3.0].any() and inside[(y > 10.0) & (y < 60.0)].all()
