"""A tiny ONCE-3DLanes release written from the format: labels, tiny JPEG images, sequence poses."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

from data_ingest.once.adapter import adapt
from data_ingest.once.config import CameraConfig, OnceAdapterConfig

CALIBRATION = [[1000.0, 0.0, 960.0, 0.0], [0.0, 1000.0, 540.0, 0.0], [0.0, 0.0, 1.0, 0.0]]
# split folder -> sequence -> frame stamps (ms)
SEQUENCES = {"train": {"000027": [1616005402699, 1616005403199, 1616005403699]},
             "val": {"000076": [1616100800400, 1616100800900, 1616100801400]},
             "test": {"000112": [1616200000000, 1616200000500]}}  # fmt: skip
WITH_POSES = "000076"  # the sequence given ONCE annotations with poses


@dataclass
class TinyOnce:
    root: Path  # <root>/<split>/<sequence>/cam01/<stamp>.json and .jpg
    poses: Path  # <poses>/<sequence>/<sequence>.json
    labels: dict[str, dict] = field(default_factory=dict)  # "<split>/<sequence>/cam01/<stamp>.json" -> content


def camera_lanes(k: int) -> list[list[list[float]]]:
    """Three lanes in the camera frame (x right, y down, z forward); the middle one far to near."""
    z = np.linspace(4.0, 40.0, 7)
    lanes = []
    for i, x0 in enumerate((-1.8, 0.1 * k, 1.9)):
        points = np.stack([x0 + 0.002 * z**2, 1.5 - 0.01 * z + 0.001 * k, z], axis=1)
        lanes.append((points[::-1] if i == 1 else points).round(4).tolist())
    return lanes


def write_label(path: Path, content: dict) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(content))


def write_image(path: Path) -> None:
    ok, data = cv2.imencode(".jpg", np.full((8, 16, 3), 90, np.uint8))
    path.write_bytes(data.tobytes())


def write_tiny_once(root: Path) -> TinyOnce:
    tiny = TinyOnce(root / "once", root / "data")
    for split, sequences in SEQUENCES.items():
        for sequence, stamps in sequences.items():
            frames = []
            for k, stamp in enumerate(stamps):
                content = {"lanes": camera_lanes(k), "calibration": CALIBRATION}
                relative = f"{split}/{sequence}/cam01/{stamp}.json"
                write_label(tiny.root / relative, content)
                write_image(tiny.root / relative.replace(".json", ".jpg"))
                tiny.labels[relative] = content
                quaternion = Rotation.from_euler("z", 0.01 * k).as_quat()
                frames.append({"frame_id": str(stamp), "pose": [*quaternion, 5.0 * k, 0.2 * k, 0.0]})
            if sequence == WITH_POSES:
                calib = {"cam01": {"cam_to_velo": np.eye(4).tolist()}}
                write_label(tiny.poses / sequence / f"{sequence}.json", {"calib": calib, "frames": frames})
    return tiny


def adapter_config(tiny: TinyOnce, output: Path, poses: bool = True) -> OnceAdapterConfig:
    return OnceAdapterConfig(root=str(tiny.root), output=str(output), poses=str(tiny.poses) if poses else None,
                             splits={"train": "train", "val": "val", "test": "test"},
                             camera=CameraConfig(height=1.5, pitch_deg=0.3))  # fmt: skip


def adapt_tiny_once(tiny: TinyOnce, output: Path, poses: bool = True) -> Path:
    """The clip store lanelab-once writes from the tiny release (every sequence written); its path."""
    results = adapt(adapter_config(tiny, output, poses))
    sequences = sum(len(sequences) for sequences in SEQUENCES.values())
    assert [r.status for r in results] == ["written"] * sequences, [r.error for r in results]
    return output
