"""Contact sheet of generated drives: frames with their GT lanes drawn, and a top view.

One row per log: the first frame as rendered, a few frames spread over the drive with
the ground-truth lanes projected on them, then the top view of the last one (wide enough for
every lane, at least ±20 m), under a caption with the log's name and scenario; a legend of the
colours (the categories drawn, hidden parts) closes the sheet. Written as a PNG so a person
sees what was generated.
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
from lanelab.viz.lanes import fit_x_range, top_view_width
from lanelab.viz.panels import categories_of, stack_rows

CAPTION_HEIGHT = 22
TOP_VIEW_Y_RANGE = (0.0, 200.0)  # metres ahead: the ground truth's range


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
    x_range = fit_x_range(last.lanes, TOP_VIEW_Y_RANGE)
    size = (tile_height, top_view_width(tile_height, x_range, TOP_VIEW_Y_RANGE))
    tiles.append(draw_top_view(last.lanes, size, x_range, TOP_VIEW_Y_RANGE, title="top view"))
    strip = np.concatenate(tiles, axis=1)
    caption = np.full((CAPTION_HEIGHT, strip.shape[1], 3), 20, np.uint8)
    text = row.name + "  " + "  ".join(f"{k}={v}" for k, v in sorted(row.scenario.items()))
    cv2.putText(caption, text, (4, 15), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (230, 230, 230), 1, cv2.LINE_AA)
    return np.concatenate([caption, strip], axis=0)


def contact_sheet(rows: Sequence[PreviewRow], tile_width: int = 320) -> np.ndarray:
    """Stack one row per log into a BGR picture, rows padded to the widest, over a legend of
    the categories drawn and the hidden-part line."""
    drawn = [row for row in rows if row.frames]
    if not drawn:
        raise ValueError("no frames to preview")
    categories = categories_of(*(frame.lanes for row in drawn for frame in row.frames))
    tile_height = round(drawn[0].camera.height * tile_width / drawn[0].camera.width)
    return stack_rows([_row_image(row, tile_width) for row in drawn], categories, tile_height, kinds=("hidden part",))


def write_contact_sheet(path: Path, rows: Sequence[PreviewRow], tile_width: int = 320) -> Path:
    """Write the contact sheet PNG atomically (temporary file, then rename)."""
    ok, data = cv2.imencode(".png", contact_sheet(rows, tile_width))
    if not ok:
        raise RuntimeError(f"could not encode the preview {path}")
    with atomic_output(path) as tmp:
        tmp.write_bytes(data.tobytes())
    return Path(path)
