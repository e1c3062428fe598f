"""The model-input sample of DESIGN.md's "Model contract", read from a clip store.

``ClipDataset(...)[key]`` is a window of F frames of one clip ending at the key's current frame
(oldest first, current last), with the current frame's ground truth:

==================  =================  =======  ===============================================
key                 shape              dtype    meaning
==================  =================  =======  ===============================================
images              (F, 3, H, W)       float32  RGB, normalised with ``mean`` / ``std``
K                   (F, 3, 3)          float32  intrinsics of the resized / cropped images
T_lane_cam          (F, 4, 4)          float32  camera extrinsic
T_world_lane        (F, 4, 4)          float64  ego pose; float64 because world coordinates
                                                reach kilometres, where float32 steps are mm
valid               (F,)               bool     False for padding before the clip's start
labeled             (F,)               bool     the frame has lane labels
timestamp_ns        (F,)               int64    sensor time
frame_index         (F,)               int64    position of the frame in its clip
reset               ()                 bool     clear the model's memory before this sample
padding             ()                 bool     repeats another sample; skip in metrics
clip_id             str                         the clip
tags                dict[str, str]              scenario tags of the current frame
gt_y                (S,)               float32  the y grid of gt_x / gt_z / gt_vis
gt_x, gt_z, gt_vis  (L, S)             float32  lanes at gt_y (see :mod:`targets`)
gt_category         (L,)               int64    OpenLane category ids
gt_track_id         (L,)               int64    lane identity across frames
==================  =================  =======  ===============================================

A frame whose K, poses, lane points or visibility hold NaN or inf (a store written by older
code or by hand: the ingestor drops such frames) raises :class:`~lanelab.finite.NonFiniteError`
naming the store, the clip and the frame's timestamp.

L is the number of kept lanes of this frame (0 when it is unlabeled); the collate pads it.
Padding at clip starts: a window reaching back before its clip's first frame repeats that
first frame (valid False). Anchor3DLane-T, whose sampling Bi²Lane follows, pads with the
current frame instead, unmasked; the first frame is the nearest real frame to the missing
ones and keeps the window in time order, and the mask lets a model ignore it either way.
StreamPETR (SparseLaneSTP's streaming) needs no padding: its memory is reset there instead.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Sequence

import numpy as np
import torch
from torch.utils.data import Dataset

from lanelab.data.augment import PhotometricAugment
from lanelab.data.lateral_shift import LateralShift
from lanelab.data.frame_index import FrameIndex, SampleKey, consecutive_offsets
from lanelab.data.mirror import mirror_categories, mirror_intrinsics, mirror_transforms
from lanelab.data.targets import LaneTargets
from lanelab.data.transforms import Normalise, ResizeCrop
from lanelab.finite import NonFiniteError
from lanelab.store import SPLITS, ClipStore, DataError, FrameRecord
from lanelab.store.image_codec import decode_image


def check_finite(record: FrameRecord, clip_id: str, store: Path) -> None:
    """Raise NonFiniteError naming the clip and frame when the record's numbers hold NaN or inf."""
    arrays = {"K": record.K, "T_lane_cam": record.T_lane_cam, "T_world_lane": record.T_world_lane}
    for i, lane in enumerate(record.lanes):
        arrays.update({f"lanes[{i}].points": lane.points, f"lanes[{i}].visibility": lane.visibility})
    bad = [name for name, values in arrays.items() if not np.isfinite(values).all()]
    if bad:
        raise NonFiniteError(f"{store}: clip {clip_id}, frame timestamp_ns={record.timestamp_ns}: "
                             f"NaN or inf in {', '.join(bad)}")


def mirror_targets(targets: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Lane targets (:class:`LaneTargets` output) of the left-right mirrored frame."""
    return {**targets, "gt_x": -targets["gt_x"], "gt_category": mirror_categories(targets["gt_category"])}


class ClipDataset(Dataset):
    """Windows of frames of the clips of one split of a store.

    ``dataset[i]`` (an int) is the window of ``num_frames`` consecutive frames ending at frame
    i of :attr:`index` (reset at clip starts); samplers ask for other windows with a
    :class:`SampleKey`. ``augment`` (training only) jitters all frames of a sample alike;
    ``lateral_shift`` (training only) sees each sample from an ego moved sideways.
    The store holds no open file: each read opens its clip file in whichever process (a
    DataLoader worker) reads, so nothing is shared across forks.
    """

    def __init__(
        self,
        store_dir: str | Path,
        split: str,
        *,
        num_frames: int,
        resize: ResizeCrop,
        targets: LaneTargets,
        mean: Sequence[float],
        std: Sequence[float],
        augment: PhotometricAugment | None = None,
        lateral_shift: LateralShift | None = None,
    ) -> None:
        self.store = ClipStore(store_dir)
        if split not in SPLITS:
            raise DataError(f"{self.store.root}: no split {split!r} (a store's splits: {', '.join(SPLITS)})")
        clip_ids = [clip.clip_id for clip in self.store.clips_in(split)]
        if not clip_ids:
            raise DataError(f"{self.store.root}: split {split!r} has no clips (clips per split: "
                            f"{self.store.split_counts()}); ingest with split.by=clip so that few logs still fill "
                            "every split, or read another split")
        if num_frames < 1:
            raise DataError(f"num_frames={num_frames}: a sample needs at least one frame")
        self.index = FrameIndex.from_store(self.store, clip_ids)
        self.offsets = consecutive_offsets(num_frames)
        self.resize = resize
        self.targets = targets
        self.normalise = Normalise(mean, std)
        self.augment = augment
        self.lateral_shift = lateral_shift

    def __len__(self) -> int:
        return len(self.index)

    def __getitem__(self, key: int | SampleKey) -> dict[str, Any]:
        if not isinstance(key, SampleKey):
            key = SampleKey(int(key), self.offsets, reset=bool(self.index.is_clip_start(int(key))))
        clip, current = self.index.locate(key.frame)
        clip_id = self.index.clip_ids[clip]
        wanted = current - np.asarray(key.offsets)
        positions = np.maximum(wanted, 0).tolist()  # before the clip's start: its first frame, masked
        first = min(positions)
        records = self.store.read_frames(clip_id, first, current + 1)
        frames = [records[p - first] for p in positions]
        for p in set(positions):
            check_finite(records[p - first], clip_id, self.store.root)

        # Padding repeats a frame: decode and resize each distinct frame once.
        prepared = {p: self.resize(decode_image(records[p - first]), records[p - first].K) for p in set(positions)}
        images = np.stack([prepared[p][0] for p in positions])  # (F, H, W, 3) uint8
        K = np.stack([prepared[p][1] for p in positions])
        T_lane_cam, T_world_lane = (np.stack([getattr(f, name) for f in frames]) for name in ("T_lane_cam", "T_world_lane"))
        now = frames[-1]
        targets = self.targets(now.lanes)
        if key.flip:
            images, K = np.ascontiguousarray(images[:, :, ::-1]), mirror_intrinsics(K, images.shape[2])
            T_lane_cam, T_world_lane = mirror_transforms(T_lane_cam), mirror_transforms(T_world_lane)
            targets = mirror_targets(targets)
        if self.lateral_shift is not None:
            images, T_world_lane, targets = self.lateral_shift(images, K, T_lane_cam, T_world_lane, targets, self.targets.y)
        if self.augment is not None:
            images = self.augment(images)
        return {
            "images": self.normalise(images),
            "K": torch.from_numpy(K).float(),
            "T_lane_cam": torch.from_numpy(T_lane_cam).float(),
            "T_world_lane": torch.from_numpy(T_world_lane).double(),
            "valid": torch.from_numpy(wanted >= 0),
            "labeled": torch.tensor([f.labeled for f in frames]),
            "timestamp_ns": torch.tensor([f.timestamp_ns for f in frames], dtype=torch.int64),
            "frame_index": torch.tensor(positions, dtype=torch.int64),
            "reset": torch.tensor(key.reset),
            "padding": torch.tensor(key.padding),
            "clip_id": clip_id,
            "tags": dict(now.tags),
            "gt_y": torch.from_numpy(self.targets.y).float(),
            **{name: torch.from_numpy(value) for name, value in targets.items()},
        }
