"""What the Lightning tests run on: a tiny clip store whose images show their lanes, the tiny
model and data configurations (composed from conf/ as Hydra composes them, with test
overrides) and the Trainer settings.

Frames are 64 x 96 PNGs of a grey road under a pale sky with three painted lanes (yellow solid
on the left, two white solid lines), drawn by lanelab.viz from the labels themselves. The ego
weaves on a bending road, so the lanes move in the image and in the lane frame from frame to
frame (consistently with the ego poses), and they are visible from 3 to 60 m.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
from hydra import compose, initialize_config_dir
from hydra.utils import instantiate
from omegaconf import DictConfig, OmegaConf

from lanelab.data.datamodule import ClipDataModule
from lanelab.lanes import Lane
from lanelab.store import ClipEntry, FrameRecord, Manifest, write_clip, write_manifest
from lanelab.viz import draw_lanes_on_image

CONF = Path(__file__).resolve().parents[2] / "conf"
HEIGHT, WIDTH = 64, 96
K = np.array([[70.0, 0.0, 48.0], [0.0, 70.0, 22.0], [0.0, 0.0, 1.0]])
# Camera (x right, y down, z forward) in the lane frame (x right, y forward, z up), 1.5 m up.
T_LANE_CAM = np.array([[1.0, 0, 0, 0], [0, 0, 1, 0], [0, -1, 0, 1.5], [0, 0, 0, 1]])
LANES = ((1, 8, -5.25), (2, 2, -1.75), (3, 2, 1.75))  # track id, OpenLane category, x at the ego
FRAME_NS = 100_000_000
Y = np.arange(3.0, 61.0, 1.0)


def ego_offset(position: int) -> float:
    """The ego's lateral position (m, world x) at frame `position`; it weaves."""
    return 0.6 * np.sin(0.8 * position)


def lanes_at(position: int) -> list[Lane]:
    """The lanes of frame `position` in its lane frame: a static road that bends (world lanes
    x = x0 + 1.5 sin(y / 40)), seen by the ego at world (ego_offset, 2 m per frame)."""
    records = []
    for track_id, category, x0 in LANES:
        x = x0 + 1.5 * np.sin((Y + 2.0 * position) / 40.0) - ego_offset(position)
        points = np.stack([x, Y, np.zeros_like(Y)], axis=1).astype(np.float32)
        records.append(Lane(points, np.ones(len(Y), np.float32), category, track_id=track_id))
    return records


def frame_record(clip: int, position: int) -> FrameRecord:
    lanes = lanes_at(position)
    image = np.empty((HEIGHT, WIDTH, 3), np.uint8)
    image[: int(K[1, 2])] = (200, 180, 160)  # sky (BGR)
    image[int(K[1, 2]) :] = (90, 90, 90)  # road
    image = draw_lanes_on_image(image, lanes, K, T_LANE_CAM, thickness=1, show_hidden=False)
    ok, png = cv2.imencode(".png", image)
    assert ok
    pose = np.eye(4)
    pose[:2, 3] = ego_offset(position), 2.0 * position
    return FrameRecord(
        timestamp_ns=clip * 10**12 + position * FRAME_NS, image=png.tobytes(), image_encoding="png",
        width=WIDTH, height=HEIGHT, K=K, T_lane_cam=T_LANE_CAM, T_world_lane=pose, labeled=True,
        lanes=lanes, tags={"weather": "sun"},
    )  # fmt: skip


def build_store(root: Path, clip_lengths: list[int]) -> Path:
    """A store of clips of these lengths, all in the train split."""
    entries = []
    for number, length in enumerate(clip_lengths):
        clip_id = f"clip{number:02d}"
        frames = [frame_record(number, p) for p in range(length)]
        write_clip(root, clip_id, frames)
        entries.append(ClipEntry(clip_id, "test", "train", length, frames[0].timestamp_ns, frames[-1].timestamp_ns))
    write_manifest(root, Manifest(clips=entries))
    return root


# The tiny model: conf/model/<name>.yaml with the tiny backbone and these sizes.
TINY_MODEL = [
    "model/backbone=tiny", "model.net.embed_dim=32", "model.net.num_lines=4", "model.net.num_points=6",
    "model.net.query_convs=1", "model.net.mask_dim=8", "model.net.num_layers=2", "model.net.ffn_dim=64",
    "model.net.dropout=0.0", "model.net.dca_levels=2", "model.net.dca_points=2", "model.net.tca_neighbors=4",
    "model.net.num_memory_lines=2", "model.net.x_range=[-10.0,10.0]", "model.net.anchor_span=5.25", "model.net.y_range=[3.0,60.0]",
    "model.net.z_range=[-2.0,2.0]", "model.pictures.num_frames=2",
]  # fmt: skip


def model_config(name: str, *overrides: str) -> DictConfig:
    """conf/model/<name>.yaml (with the tiny overrides and these) as Hydra composes it."""
    with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
        return compose(overrides=[f"+model={name}", *TINY_MODEL, *overrides]).model


def data_module(store: Path, sampler: str, **overrides) -> ClipDataModule:
    """conf/data/clips.yaml with conf/sampler/<sampler>.yaml, every stage on the train split,
    at the test images' size, on the lanes' y range."""
    cfg = OmegaConf.create({
        "data": OmegaConf.load(CONF / "data" / "clips.yaml"),
        "sampler": OmegaConf.load(CONF / "sampler" / f"{sampler}.yaml"),
    })  # fmt: skip
    settings = {
        "store": str(store), "splits": {"train": "train", "val": "train", "test": "train", "predict": "train"},
        "image_size": [HEIGHT, WIDTH], "y_grid": {"start": 3.0, "stop": 60.0, "num": 20},
        "max_lanes": 4, "augment": None,
        "num_workers": 0, **overrides,
    }  # fmt: skip
    cfg.data = OmegaConf.merge(cfg.data, settings)
    return instantiate(cfg.data)


# Trainer settings of every test: CPU, the samplers shard themselves, no console noise.
TRAINER = {
    "accelerator": "cpu",
    "use_distributed_sampler": False,
    "enable_progress_bar": False,
    "enable_model_summary": False,
}
