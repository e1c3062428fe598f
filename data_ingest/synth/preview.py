"""Contact sheet of generated drives: frames with their GT lanes drawn, and a top view.

One row per log: the first frame as rendered, a few frames spread over the drive with
the ground-truth lanes projected on them, then the top view of the last one, under a caption with the
log's name and scenario. Written as a PNG so a person sees what was generated.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

import cv2
import numpy as np
import torch

from data_ingest.synth.frame import CameraModel, SynthFrame
from lanelab.atomic_file import atomic_output
from lanelab.geometry.frames import extrinsic_base_to_lane
from lanelab.viz import draw_lanes_on_image, draw_top_view

CAPTION_HEIGHT = 22


@dataclass
class PreviewRow:
    """The frames kept from one log for its row of the contact sheet."""

    name: str
    camera: CameraModel
    scenario: dict[str, str]
    frames: list[SynthFrame] = field(default_factory=list)


def frames_to_keep(num_frames: int, count: int) -> set[int]:
    """Indices of ``count`` frames spread evenly over a drive of ``num_frames``."""
    if num_frames <= 0:
        return set()
    return {int(i) for i in np.linspace(0, num_frames - 1, min(count, num_frames)).round()}


def _row_image(row: PreviewRow, tile_width: int) -> np.ndarray:
    cam = row.camera
    T_lane_cam = extrinsic_base_to_lane(torch.as_tensor(cam.T_base_cam, dtype=torch.float64)).numpy()
    scale = tile_width / cam.width
    tile_height = int(round(cam.height * scale))
    # the first frame once as rendered, so the markings can be seen without the GT over them
    pictures = [(row.frames[0].image, "image")]
    pictures += [(draw_lanes_on_image(f.image, f.lanes, cam.K, T_lane_cam), f"GT t={f.timestamp_ns / 1e9:.1f}s")
                 for f in row.frames]
    tiles = []
    for picture, label in pictures:
        tile = cv2.resize(picture, (tile_width, tile_height), interpolation=cv2.INTER_AREA)
        cv2.putText(tile, label, (4, tile_height - 6), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (255, 255, 255), 1, cv2.LINE_AA)
        tiles.append(tile)
    last = row.frames[-1]
    tiles.append(draw_top_view(last.lanes, size=(tile_height, max(tile_height // 2, 60)), title="top"))
    strip = np.concatenate(tiles, axis=1)
    caption = np.full((CAPTION_HEIGHT, strip.shape[1], 3), 20, np.uint8)
    text = row.name + "  " + "  ".join(f"{k}={v}" for k, v in sorted(row.scenario.items()))
    cv2.putText(caption, text, (4, 15), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (230, 230, 230), 1, cv2.LINE_AA)
    return np.concatenate([caption, strip], axis=0)


def contact_sheet(rows: Sequence[PreviewRow], tile_width: int = 320) -> np.ndarray:
    """Stack one row per log into a BGR picture; rows are padded to the widest."""
    images = [_row_image(row, tile_width) for row in rows if row.frames]
    if not images:
        raise ValueError("no frames to preview")
    width = max(image.shape[1] for image in images)
    padded = [np.pad(image, ((0, 0), (0, width - image.shape[1]), (0, 0))) for image in images]
    return np.concatenate(padded, axis=0)


def write_contact_sheet(path: Path, rows: Sequence[PreviewRow], tile_width: int = 320) -> Path:
    """Write the contact sheet PNG atomically (temporary file, then rename)."""
    ok, data = cv2.imencode(".png", contact_sheet(rows, tile_width))
    if not ok:
        raise RuntimeError(f"could not encode the preview {path}")
    with atomic_output(path) as tmp:
        tmp.write_bytes(data.tobytes())
    return Path(path)
