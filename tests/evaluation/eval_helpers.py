"""A small prediction set in the official OpenLane layout, with hand-computed scores.

Three frames of straight lanes (x constant, y from 1 to 110 m, z = 0) seen by a camera 1.5 m
above the ground frame, looking ahead:

- a: GT x = -1.8, 1.8; predictions -1.7 (0.1 m off), 1.8 -> 2 TP both ways;
- b: GT x = 0; predictions 0 and a false positive at 6 -> recall 1/1, precision 1/2;
- c: GT x = -1.8, 1.8; prediction 1.8 with the wrong category -> recall 1/2, precision 1/1.

Over all: 5 GT, 5 predictions, 4 TP each way (R = P = F1 = 0.8), 4 matched pairs of which
3 with the right category (0.75), x error close = far = (0.1 + 0 + 0 + 0) / 4 = 0.025 m.
Scenario lists: curve = {a} (F1 1.0); night = {b, c} (R = P = 2/3, F1 2/3).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

CAMERA_HEIGHT = 1.5
# Waymo camera axes aligned with the vehicle, 1.5 m above its ground plane.
EXTRINSIC = [[1.0, 0, 0, 0], [0, 1.0, 0, 0], [0, 0, 1.0, CAMERA_HEIGHT], [0, 0, 0, 1.0]]
INTRINSIC = [[100.0, 0, 80.0], [0, 100.0, 60.0], [0, 0, 1.0]]  # a 160 x 120 camera
NAMES = {frame: f"validation/segment-{seg}/15584011356475{i}00.jpg"
         for i, (frame, seg) in enumerate([("a", 1), ("b", 1), ("c", 2)])}
GT = {"a": [(-1.8, 1), (1.8, 1)], "b": [(0.0, 1)], "c": [(-1.8, 1), (1.8, 1)]}
PRED = {"a": [(-1.7, 1), (1.8, 1)], "b": [(0.0, 1), (6.0, 1)], "c": [(1.8, 2)]}


def straight(x: float) -> np.ndarray:
    y = np.linspace(1.0, 110.0, 12)
    return np.stack([np.full_like(y, x), y, np.zeros_like(y)], -1)


def gt_json(file_path: str, lanes: list[tuple[float, int]]) -> dict:
    """Ground truth: a ground-frame point (x, y, z) is (y, -x, z - height) in the Waymo camera axes."""
    lane_lines = []
    for x, category in lanes:
        p = straight(x)
        xyz = np.stack([p[:, 1], -p[:, 0], p[:, 2] - CAMERA_HEIGHT])
        lane_lines.append({"xyz": xyz.tolist(), "visibility": [1.0] * len(p), "category": category})
    return {"file_path": file_path, "extrinsic": EXTRINSIC, "intrinsic": INTRINSIC, "lane_lines": lane_lines}


def pred_json(file_path: str, lanes: list[tuple[float, int]]) -> dict:
    return {"file_path": file_path,
            "lane_lines": [{"xyz": straight(x).tolist(), "category": category} for x, category in lanes]}


@dataclass
class PredictionSet:
    gt: Path
    pred: Path
    test_list: Path
    scenario_lists: Path

    def pred_file(self, frame: str) -> Path:
        return self.pred / NAMES[frame].replace(".jpg", ".json")


def write_prediction_set(root: Path) -> PredictionSet:
    data = PredictionSet(root / "gt", root / "pred", root / "test_list.txt", root / "lists")
    for frame, name in NAMES.items():
        for folder, content in ((data.gt, gt_json(name, GT[frame])), (data.pred, pred_json(name, PRED[frame]))):
            path = folder / name.replace(".jpg", ".json")
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(json.dumps(content))
    data.test_list.write_text("".join(f"{name}\n" for name in NAMES.values()))
    data.scenario_lists.mkdir()
    (data.scenario_lists / "1000_curve.txt").write_text(NAMES["a"] + "\n")
    (data.scenario_lists / "night_case.txt").write_text(NAMES["b"] + "\n" + NAMES["c"] + "\n")
    return data
