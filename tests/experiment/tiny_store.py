"""A tiny clip store for the experiment tests, written with the clip store's writer, and the
overrides that train the tiny experiment on it in a temporary folder.

Frames are 64 x 96 PNGs: a grey road under a pale sky with three painted lanes drawn from
the labels themselves. The ego drives 2 m per frame and sways sideways, so the lanes move
in the image and in the lane frame as the poses say. Two clips per split; the val and test
clips are foggy (their tag), which only the tags say.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from lanelab.lanes import Lane
from lanelab.store import ClipEntry, FrameRecord, Manifest, write_clip, write_manifest
from lanelab.viz import draw_lanes_on_image

HEIGHT, WIDTH = 64, 96
K = np.array([[70.0, 0.0, 48.0], [0.0, 70.0, 24.0], [0.0, 0.0, 1.0]])
# Camera axes (x right, y down, z forward) in the lane frame (x right, y forward, z up), 1.5 m up.
T_LANE_CAM = np.array([[1.0, 0, 0, 0], [0, 0, 1, 0], [0, -1, 0, 1.5], [0, 0, 0, 1]])
LANE_X = {1: -5.25, 2: -1.75, 3: 1.75}  # track id -> world x of the lane line
Y = np.arange(3.0, 103.0, 2.0)
SPLITS = {"train": 2, "val": 1, "test": 1}  # clips per split
FRAMES_PER_CLIP = 6


def _frame(clip: int, position: int, weather: str) -> FrameRecord:
    sway = 0.5 * np.sin(0.9 * position + clip)
    lanes = [
        Lane(np.stack([np.full_like(Y, x - sway), Y, np.zeros_like(Y)], 1).astype(np.float32),
             np.ones(len(Y), np.float32), 2, track_id=track)
        for track, x in LANE_X.items()
    ]  # fmt: skip
    image = np.full((HEIGHT, WIDTH, 3), 90, np.uint8)
    image[: int(K[1, 2])] = (200, 180, 160)
    image = draw_lanes_on_image(image, lanes, K, T_LANE_CAM, thickness=1, show_hidden=False)
    ok, png = cv2.imencode(".png", image)
    assert ok
    pose = np.eye(4)
    pose[:2, 3] = sway, 2.0 * position
    return FrameRecord(
        timestamp_ns=position * 100_000_000, image=png.tobytes(), image_encoding="png", width=WIDTH, height=HEIGHT,
        K=K, T_lane_cam=T_LANE_CAM, T_world_lane=pose, labeled=True, lanes=lanes,
        tags={"weather": weather, "occlusion": "none"},
    )  # fmt: skip


def build_store(root: Path) -> Path:
    entries, number = [], 0
    for split, count in SPLITS.items():
        for _ in range(count):
            clip_id = f"clip{number:02d}"
            weather = "sun" if split == "train" else "fog"
            frames = [_frame(number, p, weather) for p in range(FRAMES_PER_CLIP)]
            write_clip(root, clip_id, frames)
            entries.append(ClipEntry(clip_id, "tiny", split, len(frames), frames[0].timestamp_ns, frames[-1].timestamp_ns))
            number += 1
    write_manifest(root, Manifest(clips=entries))
    return root


def tiny_overrides(store: Path, out: Path, *more: str) -> list[str]:
    """The tiny experiment on the tiny store, writing under out, without a logger."""
    return ["experiment=tiny", f"data.store={store}", f"paths.output_dir={out}", "logger=none", *more]
