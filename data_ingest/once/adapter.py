"""ONCE-3DLanes (label JSONs + images) -> one clip store, each sequence a clip.

    <root>/<split folder>/<sequence>/cam01/<stamp>.json  ->  <output>/clips/<sequence>.parquet

Every sequence folder of the split folders named in ``splits`` (the release's ``train``, ``val``
and ``test`` -> the store's splits of the same names by default) becomes a clip of that split,
its frames ordered by stamp (the release's 2 Hz). Each frame gets

- its image: ``cam01/<stamp>.jpg`` beside the label, or ``<images>/<sequence>/cam01/<stamp>.jpg``
  (the release's ``data`` folder), the bytes as they are, decoded once to check them;
- K (the calibration's left 3 x 3), the store's fixed camera as T_lane_cam
  (:mod:`lanelab.once.camera`, LATR's 1.5 m and 0.3 degrees by default), and the lanes in the
  lane frame (:mod:`~data_ingest.once.labeled_frame`);
- T_world_lane from the sequence's ONCE annotations when ``poses`` is given and holds the
  sequence's file (:mod:`~data_ingest.once.poses`); otherwise the identity, and the clip is listed under
  ``clips_without_pose`` in the manifest's options (:data:`lanelab.store.WITHOUT_POSE`): its
  frames cannot be related to one another, and lanelab-train refuses it to a temporal model
  unless told to run single-frame (``without_ego_motion=single_frame``);
- ``labeled`` True, and tags: ``once.label_path`` (``<sequence>/cam01/<stamp>.json``, where
  lanelab-eval ``format=once`` writes the frame's files) and ``openlane.far_to_near``
  (:mod:`lanelab.openlane.lane_order`).

Empty label files (0 bytes; the release has some) are skipped, as LATR's loader skips them. A
sequence whose labels, images or poses cannot be used fails alone, its message naming the file:
a label that is not JSON, without ``calibration`` or with one that is not ``[K | 0]`` (3, 4),
NaN or inf anywhere, lane points behind the camera, a missing or corrupt image, a sequence of
one frame (nothing to relate it to). Re-running is cheap and resumes as ``lanelab-openlane`` does
(:class:`~lanelab.store.StoreWriter`): a sequence whose labels, tags and poses are unchanged
keeps its clip.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Iterator, Sequence

import numpy as np

from data_ingest.dataset_adapter import FAILED, KEPT, WRITTEN, adapt_folders, commit_clip, kept_with_pose
from data_ingest.once.config import OnceAdapterConfig
from data_ingest.once.labeled_frame import LabeledFrame, read_labeled_frame
from data_ingest.once.poses import read_world_from_camera, sequence_file
from data_ingest.source_files import fingerprint, labeled_record
from lanelab.data_paths import path_inside
from lanelab.json_files import LaneFileError
from lanelab.once.camera import fixed_T_lane_cam
from lanelab.once.file_paths import CAMERA, LABEL_PATH_TAG, label_path
from lanelab.openlane.lane_order import far_to_near_tag
from lanelab.store import FrameRecord, StoreWriter, file_sha256
from lanelab.store.schema import CLIPS_DIR, CLIP_SUFFIX

MADE_BY = "lanelab-once"
LANE_FRAME = "LATR's ONCE ground frame: x right, y forward, z up; origin on the ground below the fixed camera"


@dataclass
class SequenceResult:
    """What became of one sequence: status WRITTEN, KEPT or FAILED (error says why); empty: the
    label files skipped for being empty."""

    sequence: str
    status: str
    num_frames: int = 0
    has_pose: bool = True
    empty: int = 0
    error: str = ""

    @property
    def name(self) -> str:  # the folder's name, as the summary prints it
        return self.sequence


def adapt(cfg: OnceAdapterConfig) -> list[SequenceResult]:
    """Make or update the store ``cfg.output``; one result per sequence found, in order.

    Raises ConfigError when the output is a store made by another tool or with another camera,
    or being written by another process; a bad sequence only fails itself.
    """
    camera = {"height": float(cfg.camera.height), "pitch_deg": float(cfg.camera.pitch_deg)}
    T_lane_cam = fixed_T_lane_cam(camera["height"], camera["pitch_deg"])
    adapt_sequence = partial(_adapt_sequence, cfg=cfg, T_lane_cam=T_lane_cam)
    return adapt_folders(MADE_BY, {"lane_frame": LANE_FRAME, "camera": camera}, cfg.output, cfg.root, cfg.splits,
                         adapt_sequence, lambda sequence, error: SequenceResult(sequence, FAILED, error=error))  # fmt: skip


def _adapt_sequence(
    writer: StoreWriter, sequence_dir: Path, split: str, cfg: OnceAdapterConfig, T_lane_cam: np.ndarray
) -> SequenceResult:
    """Write and commit one sequence's clip unless the store holds it unchanged."""
    sequence = sequence_dir.name
    labels = sorted((sequence_dir / CAMERA).glob("*.json"), key=lambda path: (len(path.stem), path.stem))
    paths = [path for path in labels if path.stat().st_size > 0]
    if not paths:
        raise LaneFileError(sequence_dir / CAMERA, "no label files (cam01/*.json, not empty) in this sequence")
    if len(paths) < 2:
        raise LaneFileError(paths[0], "the only frame of its sequence: a clip needs 2 frames or more")
    pose_file = sequence_file(cfg.poses, sequence) if cfg.poses else None
    if pose_file is not None and not pose_file.exists():
        pose_file = None  # a sequence without annotations: a clip without ego motion, as without poses=
    tags = [{LABEL_PATH_TAG: label_path(sequence, path.stem)} for path in paths]
    source = str(sequence_dir.resolve())
    pose_sha = file_sha256(pose_file) if pose_file is not None else None
    sha256 = fingerprint(paths, {"tags": tags, "poses": str(pose_file), "poses_sha256": pose_sha})
    kept_pose = kept_with_pose(writer, source, split, sha256)
    if kept_pose is not None:
        return SequenceResult(sequence, KEPT, len(paths), kept_pose, len(labels) - len(paths))

    frames = [read_labeled_frame(path, T_lane_cam) for path in paths]
    poses = _world_from_lane(pose_file, paths, T_lane_cam) if pose_file is not None else None
    has_pose = poses is not None
    path_inside(Path(cfg.output) / CLIPS_DIR, f"{sequence}{CLIP_SUFFIX}", f"sequence {sequence!r}")  # names a file
    commit_clip(writer, cfg.output, source, split, sha256, [frame.timestamp_ns for frame in frames],
                _records(sequence_dir, cfg.images, frames, tags, T_lane_cam, poses), has_pose)  # fmt: skip
    return SequenceResult(sequence, WRITTEN, len(frames), has_pose, len(labels) - len(paths))


def _world_from_lane(pose_file: Path, labels: Sequence[Path], T_lane_cam: np.ndarray) -> list[np.ndarray]:
    """T_world_lane (4, 4) of each label's frame from the sequence's annotation file."""
    world_from_camera = read_world_from_camera(pose_file)
    camera_from_lane = np.linalg.inv(T_lane_cam)
    missing = [path.stem for path in labels if path.stem not in world_from_camera]
    if missing:
        raise LaneFileError(pose_file, f"no pose for frame {missing[0]} ({len(missing)} labeled frames without one)")
    return [world_from_camera[path.stem] @ camera_from_lane for path in labels]


def _records(
    sequence_dir: Path,
    images: str | None,
    frames: Sequence[LabeledFrame],
    tags: Sequence[dict[str, str]],
    T_lane_cam: np.ndarray,
    poses: Sequence[np.ndarray] | None,
) -> Iterator[FrameRecord]:
    """The sequence's frames, each image read only when its row group is written."""
    for i, (frame, frame_tags) in enumerate(zip(frames, tags)):
        relative = frame_tags[LABEL_PATH_TAG].removesuffix(".json") + ".jpg"
        image_path = (sequence_dir.parent / relative if images is None
                      else path_inside(images, relative, f"image {relative!r}"))  # fmt: skip
        yield labeled_record(
            image_path, f"the image of label {relative[:-4]}.json", frame.timestamp_ns, frame.K, T_lane_cam,
            np.eye(4) if poses is None else poses[i], frame.lanes, {**frame_tags, **far_to_near_tag(frame.far_to_near)},
        )  # fmt: skip
