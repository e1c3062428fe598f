"""Reading the official JSON layout: the GT frame conversion, evaluate(), malformed files."""

import json

import numpy as np
import pytest

from lanelab.metrics.openlane import evaluate, evaluate_frames
from lanelab.openlane.ground_frame import camera_lane_to_ground, ground_from_camera
from lanelab.openlane.read import OpenLaneFormatError, read_ground_truth, read_prediction

CAMERA_HEIGHT = 1.5
# Camera axes aligned with the vehicle, 1.6 m ahead and 0.1 m left of its origin.
EXTRINSIC = [[1, 0, 0, 1.6], [0, 1, 0, 0.1], [0, 0, 1, CAMERA_HEIGHT], [0, 0, 0, 1]]


def gt_json(file_path, lanes, categories=None, extrinsic=EXTRINSIC):
    """GT file for ground-frame lanes (N, 3): with EXTRINSIC, a ground point (x, y, z) is
    (y, -x, z - height) in the Waymo camera axes (forward, left, up)."""
    lane_lines = []
    for i, points in enumerate(lanes):
        p = np.asarray(points, dtype=float)
        xyz = np.stack([p[:, 1], -p[:, 0], p[:, 2] - CAMERA_HEIGHT])
        lane_lines.append({
            "xyz": xyz.tolist(),
            "visibility": [1.0] * len(p),
            "category": (categories or [1] * len(lanes))[i],
            "uv": [],
        })
    return {"file_path": file_path, "extrinsic": extrinsic, "intrinsic": np.eye(3).tolist(),
            "lane_lines": lane_lines}


def pred_json(file_path, lanes, categories=None):
    return {"file_path": file_path, "lane_lines": [
        {"xyz": np.asarray(p, dtype=float).tolist(), "category": (categories or [1] * len(lanes))[i]}
        for i, p in enumerate(lanes)
    ]}


def write(path, obj):
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(obj if isinstance(obj, str) else json.dumps(obj))
    return path


def straight(x, y0=1.0, y1=110.0):
    return [[x, y0, 0.0], [x, y1, 0.0]]


def test_ground_frame_conversion_keeps_only_the_camera_height():
    T = ground_from_camera(np.array(EXTRINSIC, dtype=float))
    points = camera_lane_to_ground(np.array([[10.0, 20.0], [1.0, -2.0], [-1.5, -1.0]]), T)
    # Waymo camera (forward, left, up) -> ground (right, forward, up) under the camera.
    np.testing.assert_array_equal(points, [[-1.0, 10.0, 0.0], [2.0, 20.0, 0.5]])


def test_ground_frame_conversion_of_a_rotated_camera():
    yaw = 0.1
    c, s = np.cos(yaw), np.sin(yaw)
    extrinsic = np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 2.0], [0, 0, 0, 1]])
    points = camera_lane_to_ground(np.array([[10.0], [0.0], [0.0]]), ground_from_camera(extrinsic))
    # A point 10 m along a camera yawed left by 0.1 rad lies ahead and to the left (x < 0).
    np.testing.assert_allclose(points, [[-10 * s, 10 * c, 2.0]], atol=1e-12)


def test_evaluate_pairs_by_file_path_and_sums_over_frames(tmp_path):
    names = ["validation/seg/a.jpg", "validation/seg/b.jpg"]
    write(tmp_path / "gt/validation/seg/a.json", gt_json(names[0], [straight(0.0), straight(4.0)]))
    write(tmp_path / "gt/validation/seg/b.json", gt_json(names[1], [straight(-3.0)], [21]))
    # The prediction files sit at each other's place: pairing follows their file_path.
    write(tmp_path / "pred/validation/seg/b.json", pred_json(names[0], [straight(0.3)]))
    write(tmp_path / "pred/validation/seg/a.json", pred_json(names[1], [straight(-3.0), straight(8.0)], [20, 1]))
    test_list = write(tmp_path / "test_list.txt", "\n".join(names) + "\n")

    result = evaluate(tmp_path / "gt", tmp_path / "pred", test_list)
    assert result["num_frames"] == 2
    assert (result["gt_lanes"], result["pred_lanes"], result["matched"]) == (3, 3, 2)
    assert (result["recall"], result["precision"]) == (2 / 3, 2 / 3)
    assert result["f1"] == pytest.approx(2 / 3)
    assert result["category_accuracy"] == 1.0  # includes the 20-for-21 rule
    assert result["x_error_close"] == pytest.approx(0.15)  # mean of 0.3 and 0.0
    assert result["z_error_far"] == pytest.approx(0.0)


@pytest.fixture
def dataset(tmp_path):
    """A valid one-frame dataset; tests break one thing in it."""
    name = "validation/seg/a.jpg"
    gt = write(tmp_path / "gt/validation/seg/a.json", gt_json(name, [straight(0.0)]))
    pred = write(tmp_path / "pred/validation/seg/a.json", pred_json(name, [straight(0.0)]))
    test_list = write(tmp_path / "test_list.txt", name + "\n")
    return tmp_path, gt, pred, test_list


def run(dataset):
    root, _, _, test_list = dataset
    return evaluate(root / "gt", root / "pred", test_list)


def test_valid_dataset_scores_perfectly(dataset):
    assert run(dataset)["f1"] == 1.0


@pytest.mark.parametrize(
    "which, change, problem",
    [
        ("pred", lambda d: d.pop("lane_lines"), "missing key 'lane_lines'"),
        ("pred", lambda d: d.pop("file_path"), "missing key 'file_path'"),
        ("pred", lambda d: d["lane_lines"][0].pop("category"), "missing key 'category' in lane_lines[0]"),
        ("pred", lambda d: d["lane_lines"][0].update(xyz=[[0]] * 2), "lane_lines[0].xyz must be"),
        ("pred", lambda d: d["lane_lines"][0].update(xyz=[]), "lane_lines[0].xyz must"),
        ("pred", lambda d: d["lane_lines"][0].update(xyz=[[0, 1, 0], [0, 2]]), "lane_lines[0].xyz must"),
        ("pred", lambda d: d["lane_lines"][0].update(category="left"), "category must be an integer"),
        ("pred", lambda d: d.update(file_path="validation/seg/other.jpg"), "names no ground-truth frame"),
        ("gt", lambda d: d.pop("extrinsic"), "missing key 'extrinsic'"),
        ("gt", lambda d: d.update(intrinsic=[[1, 0], [0, 1]]), "'intrinsic' must have shape (3, 3)"),
        ("gt", lambda d: d["lane_lines"][0].update(xyz=[[0, 1, 2]] * 2), "lane_lines[0].xyz must have shape (3, N)"),
        ("gt", lambda d: d["lane_lines"][0].update(visibility=[1.0]), "1 visibility values for 2 points"),
        ("gt", lambda d: d["lane_lines"][0].update(category=1.5), "category must be an integer"),
        ("gt", lambda d: d.update(lane_lines={}), "'lane_lines' must be a list"),
    ],
)
def test_malformed_files_name_the_file_and_the_problem(dataset, which, change, problem):
    path = dataset[1] if which == "gt" else dataset[2]
    data = json.loads(path.read_text())
    change(data)
    path.write_text(json.dumps(data))
    with pytest.raises(OpenLaneFormatError) as error:
        run(dataset)
    assert str(path) in str(error.value) and problem in str(error.value)


def test_unreadable_files_are_format_errors(dataset):
    _, gt, pred, _ = dataset
    pred.write_text("{not json")
    with pytest.raises(OpenLaneFormatError, match="not valid JSON"):
        run(dataset)
    pred.unlink()
    with pytest.raises(OpenLaneFormatError, match="cannot read the file"):
        run(dataset)
    gt.write_text("[1, 2]")
    with pytest.raises(OpenLaneFormatError, match="top level must be a JSON object"):
        read_ground_truth(gt)


def test_prediction_categories_go_through_int_like_the_official_reader(tmp_path):
    path = write(tmp_path / "p.json", pred_json("x.jpg", [straight(0.0)] * 3, [3.7, "4", True]))
    assert read_prediction(path).categories == [3, 4, 1]


def test_evaluate_frames_gives_each_listed_frame_with_its_id(tmp_path):
    names = ["validation/seg/a.jpg", "validation/seg/b.jpg"]
    for name, x in zip(names, (0.0, 3.0)):
        rel = name.replace("jpg", "json")
        write(tmp_path / "gt" / rel, gt_json(name, [straight(x)]))
        write(tmp_path / "pred" / rel, pred_json(name, [straight(x + 0.1)]))
    test_list = write(tmp_path / "test_list.txt", "\n".join(names) + "\n")
    frames = evaluate_frames(tmp_path / "gt", tmp_path / "pred", test_list)
    assert [frame_id for frame_id, _ in frames] == ["validation/seg/a.json", "validation/seg/b.json"]
    assert all(result.matched == [(0, 0)] for _, result in frames)
