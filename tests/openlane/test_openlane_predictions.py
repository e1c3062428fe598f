"""Predicted lanes -> OpenLane prediction files that the evaluator reads."""

import json

import numpy as np
import pytest

from lanelab.lanes import Lane
from lanelab.openlane.file_paths import file_path_of, json_path
from lanelab.openlane.read import read_prediction
from lanelab.openlane.write import write_prediction
from lanelab.store import FrameRecord

FILE_PATH = "validation/segment-x/155840113564752100.jpg"


def lane(category, visibility):
    y = np.arange(len(visibility), dtype=np.float32) * 10 + 5
    points = np.stack([np.full_like(y, 1.5), y, np.zeros_like(y)], -1)
    return Lane(points, np.array(visibility, dtype=np.float32), category)


def test_only_visible_points_are_written_and_short_lanes_left_out(tmp_path):
    lanes = [lane(2, [1, 1, 0.9, 0.4, 0.0]), lane(7, [1, 0.2, 0.1]), lane(20, [0.8, 0.6])]
    path = write_prediction(tmp_path, FILE_PATH, lanes)
    assert path == tmp_path / "validation/segment-x/155840113564752100.json" == json_path(tmp_path, FILE_PATH)

    data = json.loads(path.read_text())
    assert data["file_path"] == FILE_PATH
    assert [line["category"] for line in data["lane_lines"]] == [2, 20]
    assert data["lane_lines"][0]["xyz"] == [[1.5, 5.0, 0.0], [1.5, 15.0, 0.0], [1.5, 25.0, 0.0]]
    np.testing.assert_allclose(data["lane_lines"][0]["visibility"], [1, 1, 0.9])

    frame = read_prediction(path)
    assert frame.file_path == FILE_PATH and frame.categories == [2, 20]
    assert frame.lanes[1].shape == (2, 3)


def test_a_frame_without_the_file_path_tag_is_named():
    frame = FrameRecord(123, b"", "jpeg", 1, 1, np.eye(3), np.eye(4), np.eye(4), True)
    with pytest.raises(KeyError, match="123 ns"):
        file_path_of(frame)
    frame.tags["openlane.file_path"] = FILE_PATH
    assert file_path_of(frame) == FILE_PATH
