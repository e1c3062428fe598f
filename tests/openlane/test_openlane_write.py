"""OpenLane JSON files of lanes in the lane frame read back, through lanelab.openlane.read,
as the same lanes, for a camera that is pitched, turned and away from the lane-frame origin."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from lanelab.lanes import Lane
from lanelab.metrics import evaluate
from lanelab.openlane.read import read_ground_truth, read_prediction
from lanelab.openlane.write import ground_truth_json, prediction_json

K = np.array([[1000.0, 0.0, 480.0], [0.0, 1000.0, 360.0], [0.0, 0.0, 1.0]])


def camera(pitch: float, yaw: float, position: tuple[float, float, float]) -> np.ndarray:
    """T_lane_cam of a camera looking along y, pitched down by `pitch`, then turned left by
    `yaw` (radians), at `position` in the lane frame."""
    optical = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])  # OpenCV axes in lane axes
    c, s = np.cos(-pitch), np.sin(-pitch)
    down = np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])  # about x
    c, s = np.cos(yaw), np.sin(yaw)
    left = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])  # about z
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = left @ down @ optical, position
    return T


def lanes() -> list[Lane]:
    y = np.linspace(3.0, 80.0, 40)
    return [
        Lane(np.stack([x0 + 1e-3 * y**2, y, 0.02 * y], axis=1), (y < 60).astype(float), category, score=1.0)
        for x0, category in ((-1.8, 2), (1.7, 1), (5.2, 21))
    ]


@pytest.mark.parametrize("position", [(0.0, 0.0, 1.5), (0.3, 1.8, 1.6)], ids=["above-origin", "offset"])
def test_ground_truth_files_read_back_in_the_lane_frame(tmp_path, position):
    T_lane_cam = camera(np.deg2rad(3.0), np.deg2rad(1.0), position)
    path = tmp_path / "gt.json"
    path.write_text(json.dumps(ground_truth_json("clip/1.jpg", lanes(), K, T_lane_cam)))
    frame = read_ground_truth(path)
    assert frame.file_path == "clip/1.jpg"
    for lane, points, visibility, category in zip(lanes(), frame.lanes, frame.visibility, frame.categories):
        np.testing.assert_allclose(points, lane.points, atol=1e-9)
        np.testing.assert_array_equal(visibility, lane.visibility)
        assert category == lane.category


def test_predictions_equal_to_the_ground_truth_score_one(tmp_path: Path):
    for directory, content in (
        ("gt", ground_truth_json("clip/1.jpg", lanes(), K, camera(0.05, 0.0, (0.0, 1.8, 1.5)))),
        ("pred", prediction_json("clip/1.jpg", [Lane(l.points[l.visibility > 0], l.visibility[l.visibility > 0],
                                                        l.category, score=0.9) for l in lanes()])),
    ):  # fmt: skip
        (tmp_path / directory / "clip").mkdir(parents=True)
        (tmp_path / directory / "clip" / "1.json").write_text(json.dumps(content))
    (tmp_path / "list.txt").write_text("clip/1.jpg\n")
    prediction = read_prediction(tmp_path / "pred" / "clip" / "1.json")
    assert prediction.categories == [2, 1, 21]
    scores = evaluate(tmp_path / "gt", tmp_path / "pred", tmp_path / "list.txt")
    assert scores["f1"] == 1.0 and scores["category_accuracy"] == 1.0 and scores["x_error_close"] < 1e-9


def test_scores_stay_with_their_lanes_when_a_lane_is_left_out():
    hidden = Lane(lanes()[0].points, np.zeros(40), 2, score=0.8)
    content = prediction_json("clip/1.jpg", [hidden, *lanes()[1:]], scores=[0.8, 0.7, 0.6])
    assert [(line["category"], line["score"]) for line in content["lane_lines"]] == [(1, 0.7), (21, 0.6)]
    assert "score" not in prediction_json("clip/1.jpg", lanes())["lane_lines"][0]
