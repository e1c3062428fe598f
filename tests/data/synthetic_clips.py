"""Small clip stores for the dataset and DataModule tests, built with the clip store's writer.

Frames are PNG (lossless), so a test can read a frame's identity back from its pixels: pixel
value (0, 0, 0) is 10 * (position in clip) + 1 in the red channel and the clip's number in the
green one. The camera looks forward from 1.5 m; the ego drives 1 m per frame along y; every
labeled frame has two straight lanes at x = -1.75 and 1.75 m from y = 0 to 60 m.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from lanelab.lanes import Lane
from lanelab.store import ClipEntry, FrameRecord, Manifest, write_clip, write_manifest

HEIGHT, WIDTH = 48, 64
K = np.array([[60.0, 0.0, 32.0], [0.0, 60.0, 20.0], [0.0, 0.0, 1.0]])
# Camera (x right, y down, z forward) in the lane frame (x right, y forward, z up), 1.5 m up.
T_LANE_CAM = np.array([[1.0, 0, 0, 0], [0, 0, 1, 0], [0, -1, 0, 1.5], [0, 0, 0, 1]])
FRAME_NS = 100_000_000


def lane_record(track_id: int, x: float) -> Lane:
    y = np.arange(0.0, 61.0, 2.0)
    points = np.stack([np.full_like(y, x), y, np.zeros_like(y)], axis=1).astype(np.float32)
    return Lane(points, np.ones(len(y), np.float32), 2, track_id=track_id)


def frame_record(clip: int, position: int, labeled: bool) -> FrameRecord:
    image = np.full((HEIGHT, WIDTH, 3), 128, np.uint8)
    image[0, 0] = (10 * position + 1, clip, 0)  # RGB
    ok, png = cv2.imencode(".png", cv2.cvtColor(image, cv2.COLOR_RGB2BGR))
    assert ok
    pose = np.eye(4)
    pose[1, 3] = float(position)
    return FrameRecord(
        timestamp_ns=clip * 10**12 + position * FRAME_NS,
        image=png.tobytes(),
        image_encoding="png",
        width=WIDTH,
        height=HEIGHT,
        K=K,
        T_lane_cam=T_LANE_CAM,
        T_world_lane=pose,
        labeled=labeled,
        lanes=[lane_record(1, -1.75), lane_record(2, 1.75)] if labeled else [],
        tags={"weather": "sun", "clip": str(clip)},
    )


def build_store(root: Path, clips: dict[str, list[int]], label_every: int = 1) -> Path:
    """A store with clips of these lengths per split; every label_every-th frame labeled."""
    entries, number = [], 0
    for split, lengths in clips.items():
        for length in lengths:
            clip_id = f"clip{number:02d}"
            frames = [frame_record(number, p, p % label_every == 0) for p in range(length)]
            write_clip(root, clip_id, frames)
            entries.append(ClipEntry(clip_id, "synthetic", split, length, frames[0].timestamp_ns,
                                     frames[-1].timestamp_ns))
            number += 1
    write_manifest(root, Manifest(clips=entries))
    return root

