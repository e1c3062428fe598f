"""A tiny hand-made OpenLane dataset in the official layout, with everything known.

Two segments: ``validation/segment-val`` (3 frames, v1.2 files with ``pose``) and
``training/segment-train`` (2 frames, no pose). The lanes are static in the world: three
lines ahead of the vehicle at frame 0, sampled every 4 m from 10 to 98 m, visible to 80 m,
on a road rising 1 %. Each frame's file holds them in its Waymo camera axes (x forward, y
left, z up), with ``uv`` computed here from the pinhole model alone; the third lane is
stored far to near (its near end stays beyond y = 3 m: the official evaluator drops a
far-to-near lane that ends before, a quirk the store's sorted lanes do not share). Images
are small JPEGs.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from data_ingest.openlane.config import OpenLaneAdapterConfig, load_openlane_config

WIDTH, HEIGHT = 192, 128
INTRINSIC = np.array([[100.0, 0.0, 96.0], [0.0, 100.0, 64.0], [0.0, 0.0, 1.0]])
FIRST_STAMP = 155840113564752100  # 18 digits, 10 ns units
FRAME_STEP = 10_000_000  # 100 ms
VAL_SEGMENT, TRAIN_SEGMENT = "segment-val", "segment-train"
# (lateral offset left of the vehicle in m, category, track id or None): a left curb without
# track id, a white solid and a white dash line.
LANES = [(5.4, 20, None), (1.8, 2, 11), (-1.8, 1, 12)]
REVERSED_LANE = 2  # stored far to near in the files
DISTANCES = np.arange(10.0, 101.0, 4.0)  # metres ahead of the vehicle at frame 0


def rotation(yaw: float, pitch: float) -> np.ndarray:
    """(3, 3): yaw about z (left), then pitch about y (nose down for pitch > 0)."""
    cy, sy, cp, sp = np.cos(yaw), np.sin(yaw), np.cos(pitch), np.sin(pitch)
    R_yaw = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    R_pitch = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    return R_yaw @ R_pitch


def transform(R: np.ndarray, t) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, t
    return T


# Waymo camera -> vehicle: 1.5 m ahead, 0.1 m right, 2 m up, yawed and pitched a little.
EXTRINSIC = transform(rotation(0.01, 0.03), [1.5, -0.1, 2.0])


def pose(index: int) -> np.ndarray:
    """Vehicle -> world at frame index: 2 m further along and turning slowly each frame."""
    return transform(rotation(0.05 + 0.01 * index, 0.0), [10.0 + 2.0 * index, 5.0, 0.3])


def world_lanes() -> list[np.ndarray]:
    """(N, 3) world points of each lane of LANES, near to far as seen from frame 0."""
    x = DISTANCES
    lanes = []
    for lateral, _, _ in LANES:
        vehicle = np.stack([x, np.full_like(x, lateral), 0.01 * x, np.ones_like(x)])
        lanes.append((pose(0) @ vehicle)[:3].T)
    return lanes


def visibility() -> np.ndarray:
    """(N,): the points up to 80 m ahead at frame 0 are visible."""
    return (DISTANCES <= 80.0).astype(float)


def pixels(xyz_waymo: np.ndarray) -> np.ndarray:
    """(2, N) pixels of Waymo-camera points (3, N): u = fx (-y)/x + cx, v = fy (-z)/x + cy."""
    x, y, z = xyz_waymo
    fx, fy, cx, cy = INTRINSIC[0, 0], INTRINSIC[1, 1], INTRINSIC[0, 2], INTRINSIC[1, 2]
    return np.stack([fx * -y / x + cx, fy * -z / x + cy])


def stamp(index: int) -> int:
    return FIRST_STAMP + index * FRAME_STEP


@dataclass
class TinyOpenLane:
    """Where the tiny dataset lies, and what it holds."""

    root: Path
    annotations: Path
    images: Path
    test_list: Path
    scenario_lists: Path
    scene_tags: Path
    world_lanes: list[np.ndarray] = field(default_factory=world_lanes)

    def json_path(self, split: str, segment: str, index: int) -> Path:
        return self.annotations / split / segment / f"{stamp(index)}.json"


def frame_json(split: str, segment: str, index: int, with_pose: bool) -> dict:
    """The annotation of one frame (the vehicle at pose(index), written only with_pose)."""
    T_world_vehicle = pose(index)
    camera_from_world = np.linalg.inv(T_world_vehicle @ EXTRINSIC)
    lane_lines = []
    for i, (world, (_, category, track_id)) in enumerate(zip(world_lanes(), LANES)):
        xyz = (camera_from_world @ np.vstack([world.T, np.ones(len(world))]))[:3]
        vis = visibility()
        if i == REVERSED_LANE:
            xyz, vis = xyz[:, ::-1], vis[::-1]
        lane = {"xyz": xyz.tolist(), "uv": pixels(xyz).tolist(), "visibility": vis.tolist(),
                "category": category, "attribute": 0}
        if track_id is not None:
            lane["track_id"] = track_id
        lane_lines.append(lane)
    data = {
        "intrinsic": INTRINSIC.tolist(),
        "extrinsic": EXTRINSIC.tolist(),
        "file_path": f"{split}/{segment}/{stamp(index)}.jpg",
        "lane_lines": lane_lines,
    }
    if with_pose:
        data["pose"] = T_world_vehicle.tolist()
    return data


def write_tiny_openlane(root: Path) -> TinyOpenLane:
    """Write the dataset under root: annotations/, images/, test_list.txt, lists/, scene.json."""
    data = TinyOpenLane(root, root / "annotations", root / "images", root / "test_list.txt",
                        root / "lists", root / "scene.json")
    rng = np.random.default_rng(0)
    frames = [("validation", VAL_SEGMENT, i, True) for i in range(3)]
    frames += [("training", TRAIN_SEGMENT, i, False) for i in range(2)]
    for split, segment, index, with_pose in frames:
        path = data.json_path(split, segment, index)
        path.parent.mkdir(parents=True, exist_ok=True)
        annotation = frame_json(split, segment, index, with_pose)
        path.write_text(json.dumps(annotation))
        image = data.images / annotation["file_path"]
        image.parent.mkdir(parents=True, exist_ok=True)
        pixels_bgr = rng.integers(0, 255, (HEIGHT, WIDTH, 3), dtype=np.uint8)
        image.write_bytes(cv2.imencode(".jpg", pixels_bgr)[1].tobytes())
    val_images = [f"validation/{VAL_SEGMENT}/{stamp(i)}.jpg" for i in range(3)]
    data.test_list.write_text("\n".join(val_images) + "\n")
    data.scenario_lists.mkdir()
    (data.scenario_lists / "1000_curve.txt").write_text(val_images[1] + "\n")
    # another leading folder, as the lists of the test cases may have
    (data.scenario_lists / "1000_night.txt").write_text(
        "".join(f"test/night_case/{VAL_SEGMENT}/{stamp(i)}.jpg\n" for i in (0, 2)))
    data.scene_tags.write_text(json.dumps({
        VAL_SEGMENT: {"scene": "highway", "weather": "clear", "time": "night"},
    }))
    return data


def adapter_config(data: TinyOpenLane, output: Path, *overrides: str) -> OpenLaneAdapterConfig:
    """The adapter's options for the dataset, composed as lanelab-openlane composes them."""
    return load_openlane_config([
        f"annotations={data.annotations}", f"images={data.images}", f"output={output}",
        f"scenario_lists={data.scenario_lists}", f"scene_tags={data.scene_tags}", *overrides,
    ])
