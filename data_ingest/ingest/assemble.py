"""Frames from a log's contents: each image with its calibration, pose, extrinsic, label and tags.

For the images of a log, in stamp order (all lookups vectorised over the log):

- calibration: the nearest calibration message (within ``tolerances.calibration_s`` if set);
- ego pose ``T_world_lane = T_world_base · T_base_lane``, world <- ego interpolated in the TF tree;
- extrinsic ``T_lane_cam = T_lane_base · T_base_cam``, ego <- the image's ``frame_id``;
- label: the nearest image within ``tolerances.label_s`` takes a label; its points, in the
  label's frame at the label's stamp, are carried through the world frame into that image's
  lane frame: ``p_lane = T_world_lane(t_image)^-1 · T_world_F(t_label) · p``;
- tags: the last tags message stamped at most ``tolerances.tags_s`` after the image.

An image that cannot be completed is dropped with a reason, as is one whose K, pose, extrinsic
or matched label (lane points, visibility) holds NaN or inf, whose K is not a pinhole matrix
(:func:`~lanelab.geometry.intrinsics.pinhole_problem`), or whose ``openlane.file_path`` tag is
absolute or leads out of its folder (it would decide where lanelab-eval writes the frame's
files); images without a label stay as unlabeled frames. Poses are never interpolated across a
gap in /tf longer than ``tolerances.max_tf_gap_s``, nor from /tf samples that a clock jumping back
made ambiguous (:mod:`~data_ingest.ingest.tf_tree`): those images are dropped too. A log whose
TF tree never connects the world, ego and camera frames is unusable (:class:`LogError`).
"""

from __future__ import annotations

from collections import Counter, defaultdict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

import numpy as np
import torch

from data_ingest.ingest.config import LogReading
from data_ingest.ingest.errors import LogError
from data_ingest.ingest.messages import LanesMsg
from data_ingest.ingest.scan import ImageRef, LogContents
from data_ingest.ingest.tf_tree import TfTree
from lanelab.data_paths import path_problem
from lanelab.geometry import T_BASE_LANE, T_LANE_BASE, invert
from lanelab.geometry.intrinsics import pinhole_problem
from lanelab.lanes import Lane
from lanelab.openlane.file_paths import FILE_PATH_TAG
from lanelab.store import FrameRecord

_T_BASE_LANE = T_BASE_LANE.numpy()
_T_LANE_BASE = T_LANE_BASE.numpy()


@dataclass(frozen=True)
class PlannedFrame:
    """A frame ready to be written but for its image bytes (``record.image`` is empty; they are in ``image.data``)."""

    record: FrameRecord
    image: ImageRef


@dataclass
class Assembled:
    frames: list[PlannedFrame] = field(default_factory=list)  # in time order
    dropped: Counter = field(default_factory=Counter)  # frames dropped, by reason
    notes: list[str] = field(default_factory=list)  # label and TF problems, one line each


def assemble(path: Path, contents: LogContents, cfg: LogReading) -> Assembled:
    """Complete every image of ``contents`` into a frame, or drop it with a reason."""
    out = Assembled(dropped=Counter(contents.dropped))
    images = _in_stamp_order(contents.images, cfg.topics.image, out)
    if not images:
        return out
    _check_tree(path, contents.tf, cfg, {image.frame_id for image in images})
    stamps = np.array([image.stamp_ns for image in images], dtype=np.int64)
    keep = _Keep(np.ones(len(images), dtype=bool), out.dropped)
    K = _calibrations(contents, images, stamps, cfg, keep)
    T_world_base = _lookup(contents.tf, cfg.frames.world, cfg.frames.ego, stamps, keep, "ego pose", cfg)
    T_base_cam = np.empty((len(images), 4, 4))
    frame_ids = np.array([image.frame_id for image in images])
    for frame_id in np.unique(frame_ids):
        on = frame_ids == frame_id
        T_base_cam[on] = _lookup(contents.tf, cfg.frames.ego, str(frame_id), stamps, keep, "camera extrinsic", cfg,
                                 on)[on]
    T_world_lane = T_world_base @ _T_BASE_LANE
    T_lane_cam = _T_LANE_BASE @ T_base_cam

    kept = np.flatnonzero(keep.mask)
    lanes, non_finite = _labels(contents, stamps[kept], T_world_lane[kept], cfg, out.notes)
    keep.drop(np.isin(np.arange(len(images)), kept[non_finite]),
              f"label on {cfg.topics.lanes} has NaN or inf lane points or visibility")
    tags = _tags(contents, stamps[kept], cfg)
    unsafe = _unsafe_file_paths(tags, stamps[kept], cfg.topics.tags, out.notes)
    keep.drop(np.isin(np.arange(len(images)), kept[unsafe]),
              f"tag {FILE_PATH_TAG} on {cfg.topics.tags} is absolute or leads out of its folder")
    for n, i in enumerate(kept):
        if not keep.mask[i]:
            continue
        image = images[i]
        record = FrameRecord(
            timestamp_ns=int(image.stamp_ns), image=b"", image_encoding=image.encoding,
            width=image.width, height=image.height, K=K[i], T_lane_cam=T_lane_cam[i],
            T_world_lane=T_world_lane[i], labeled=n in lanes, lanes=lanes.get(n, []), tags=tags[n])
        out.frames.append(PlannedFrame(record, image))
    out.notes += contents.tf.problems()
    if contents.tf.conflicts:
        out.notes.append("TF frames with two parents (the first kept): " + ", ".join(
            f"{child} under {parent} ({n} ignored)" for (child, parent), n in sorted(contents.tf.conflicts.items())))
    return out


def _in_stamp_order(images: Sequence[ImageRef], topic: str, out: Assembled) -> list[ImageRef]:
    """Images sorted by stamp (a note says how many came out of order); repeated stamps dropped."""
    stamps = np.array([image.stamp_ns for image in images], dtype=np.int64)
    back = np.diff(stamps) < 0
    if back.any():
        out.notes.append(f"{topic}: {int(back.sum())} image stamps out of order (largest step back "
                         f"{-np.diff(stamps).min() / 1e9:.3f} s); frames are ordered by stamp")
    ordered = [images[i] for i in np.argsort(stamps, kind="stable")]
    unique = [image for k, image in enumerate(ordered) if k == 0 or image.stamp_ns != ordered[k - 1].stamp_ns]
    if len(unique) < len(ordered):
        out.dropped["repeated image timestamp (the first image kept)"] += len(ordered) - len(unique)
    return unique


def _check_tree(path: Path, tf: TfTree, cfg: LogReading, camera_frames: set[str]) -> None:
    """Raise LogError unless the TF tree connects world <- ego <- every camera frame."""
    world, ego = cfg.frames.world, cfg.frames.ego
    for a, b, what in [(world, ego, "world and ego"),
                       *((ego, camera, "ego and camera") for camera in sorted(camera_frames))]:
        if not tf.connected(a, b):
            raise LogError(f"{path}: the TF tree never connects the {what} frames {a!r} and {b!r} "
                           f"(frames.world={world}, frames.ego={ego}, camera from the images' frame_id); "
                           f"/tf and /tf_static hold: {tf.describe()}")


def nearest_stamp(stamps: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """Index into sorted ``stamps`` (M,) of the nearest to each of ``targets`` (N,) -> (N,) int."""
    right = np.clip(np.searchsorted(stamps, targets), 0, len(stamps) - 1)
    left = np.clip(right - 1, 0, len(stamps) - 1)
    return np.where(np.abs(stamps[left] - targets) <= np.abs(stamps[right] - targets), left, right)


@dataclass
class _Keep:
    """Which images are still in, (N,) bool, and why the others were dropped."""

    mask: np.ndarray
    dropped: Counter

    def drop(self, which: np.ndarray, reason: str) -> None:
        """Drop the images of ``which`` (N,) bool still in; count them under ``reason``."""
        which = which & self.mask
        if which.any():
            self.dropped[reason] += int(which.sum())
            self.mask &= ~which


def _calibrations(contents: LogContents, images: Sequence[ImageRef], stamps: np.ndarray, cfg: LogReading,
                  keep: _Keep) -> np.ndarray:
    """K (N, 3, 3) of each image from the nearest calibration; drops images without a usable one."""
    topic, tolerance = cfg.topics.calibration, cfg.tolerances.calibration_s
    if not contents.calibrations:
        keep.drop(keep.mask, f"no calibration message on {topic}")
        return np.zeros((len(stamps), 3, 3))
    calibrations = sorted(contents.calibrations, key=lambda c: c.stamp_ns)
    cal_stamps = np.array([c.stamp_ns for c in calibrations], dtype=np.int64)
    index = nearest_stamp(cal_stamps, stamps)
    K = np.stack([c.K for c in calibrations])[index]
    if tolerance is not None:
        keep.drop(np.abs(cal_stamps[index] - stamps) > tolerance * 1e9,
                  f"no calibration on {topic} within tolerances.calibration_s={tolerance}")
    problems = np.array([pinhole_problem(c.K) for c in calibrations])[index]
    for problem in sorted(set(problems) - {""}):
        keep.drop(problems == problem, f"calibration K on {topic} is not a pinhole matrix: {problem}")
    sizes = np.array([(c.width, c.height) for c in calibrations], dtype=np.int64)[index]  # 0: not said
    actual = np.array([(image.width, image.height) for image in images], dtype=np.int64)
    keep.drop((sizes > 0).all(axis=1) & (sizes != actual).any(axis=1),
              "image size differs from its calibration's width x height")
    return K


def _lookup(tf: TfTree, target: str, source: str, stamps: np.ndarray, keep: _Keep, what: str, cfg: LogReading,
            where: np.ndarray | None = None) -> np.ndarray:
    """T_target_source (N, 4, 4) at the ``stamps`` of images ``where`` (N,) bool (default all).

    Drops the images where it is undefined (outside the TF samples, across a gap longer than
    ``tolerances.max_tf_gap_s``, from ambiguous samples) or not finite, each with its reason.
    """
    where = np.ones(len(stamps), dtype=bool) if where is None else where
    T = np.full((len(stamps), 4, 4), np.nan)
    T[where], _, faults = tf.lookup(target, source, stamps[where], _max_gap_ns(cfg))
    for (child, kind), undefined in faults.items():
        which = np.zeros(len(stamps), dtype=bool)
        which[where] = undefined
        keep.drop(which, f"no {what}: {_fault_reason(tf, child, kind, cfg)}")
    keep.drop(where & ~np.isfinite(T).all(axis=(1, 2)), f"{what} {target} <- {source} has NaN or inf")
    return T


def _max_gap_ns(cfg: LogReading) -> int | None:
    gap = cfg.tolerances.max_tf_gap_s
    return None if gap is None else int(gap * 1e9)


def _fault_reason(tf: TfTree, child: str, kind: str, cfg: LogReading) -> str:
    """Why the TF edge parent <- ``child`` gives no transform (a kind of :meth:`TfTree.lookup`'s faults)."""
    edge = f"TF {tf.parent(child)} -> {child}"
    if kind == "outside":
        return f"{edge} has no samples around the image time (it covers {tf.time_range(child)})"
    if kind == "gap":
        return (f"{edge} would be interpolated across a gap between samples longer than "
                f"tolerances.max_tf_gap_s={cfg.tolerances.max_tf_gap_s}")
    return f"{edge} is ambiguous at the image time (its stamps go back in time, or disagree at one stamp)"


def _labels(contents: LogContents, stamps: np.ndarray, T_world_lane: np.ndarray, cfg: LogReading,
            notes: list[str]) -> tuple[dict[int, list[Lane]], np.ndarray]:
    """Lanes of the frames (by index into ``stamps``) that a label matches, and the frames whose
    label holds NaN or inf points or visibility (int array, to drop); other problems go to ``notes``."""
    topic, world = cfg.topics.lanes, cfg.frames.world
    non_finite: list[int] = []
    if not contents.labels or not len(stamps):
        if contents.labels:
            notes.append(f"{topic}: {len(contents.labels)} labels, but no frame to match them")
        return {}, np.array(non_finite, dtype=np.int64)
    label_stamps = np.array([label.stamp_ns for label in contents.labels], dtype=np.int64)
    frame = nearest_stamp(stamps, label_stamps)
    near = np.abs(stamps[frame] - label_stamps) <= cfg.tolerances.label_s * 1e9
    if not near.all():
        notes.append(f"{topic}: {int((~near).sum())} labels matched no image within tolerances.label_s="
                     f"{cfg.tolerances.label_s}")
    # A frame matched by several labels takes the nearest.
    best: dict[int, int] = {}
    for k in np.flatnonzero(near):
        f = int(frame[k])
        if f not in best or abs(label_stamps[k] - stamps[f]) < abs(label_stamps[best[f]] - stamps[f]):
            best[f] = int(k)
    by_frame_id: dict[str, list[tuple[int, int]]] = defaultdict(list)  # label frame_id -> [(frame, label)]
    for f, k in best.items():
        by_frame_id[contents.labels[k].frame_id].append((f, k))

    lanes: dict[int, list[Lane]] = {}
    for frame_id, pairs in sorted(by_frame_id.items()):
        if not contents.tf.connected(world, frame_id):
            notes.append(f"{topic}: {len(pairs)} labels in frame {frame_id!r}, which the TF tree never connects "
                         f"to {world!r}: dropped")
            continue
        T_world_label, valid, _ = contents.tf.lookup(world, frame_id, label_stamps[[k for _, k in pairs]],
                                                     _max_gap_ns(cfg))
        valid &= np.isfinite(T_world_label).all(axis=(1, 2))
        if not valid.all():
            notes.append(f"{topic}: {int((~valid).sum())} labels in frame {frame_id!r} at times TF cannot place "
                         f"in {world!r}: dropped")
        frames = [f for f, _ in pairs]
        T_lane_label = invert(torch.from_numpy(T_world_lane[frames])).numpy() @ T_world_label
        for (f, k), T, ok in zip(pairs, T_lane_label, valid):
            if not ok:
                continue
            label = contents.labels[k]
            if np.isfinite(label.points).all() and np.isfinite(label.visibility).all():
                lanes[f] = _lanes_in_lane_frame(label, T)
            else:
                non_finite.append(f)
    return lanes, np.array(non_finite, dtype=np.int64)


def _lanes_in_lane_frame(label: LanesMsg, T_lane_label: np.ndarray) -> list[Lane]:
    """A label's lanes (all points finite) mapped by T_lane_label (4, 4): float32 points sorted by y."""
    lane = np.repeat(np.arange(len(label.num_points)), label.num_points)  # (P,) lane of each point
    points = label.points @ T_lane_label[:3, :3].T + T_lane_label[:3, 3]
    order = np.lexsort((points[:, 1], lane))  # by lane, then y
    counts = np.bincount(lane[order], minlength=len(label.num_points))
    split_at = np.cumsum(counts)[:-1]
    return [Lane(p, v, int(category), track_id=int(track_id))
            for track_id, category, p, v, n in zip(label.track_ids, label.categories,
                                                   np.split(points[order].astype(np.float32), split_at),
                                                   np.split(label.visibility[order].astype(np.float32), split_at),
                                                   counts)
            if n]


def _unsafe_file_paths(tags: list[dict[str, str]], stamps: np.ndarray, topic: str, notes: list[str]) -> np.ndarray:
    """Frames (int array into ``tags``) whose :data:`FILE_PATH_TAG` would put their OpenLane files
    outside the folder they are written to; a note per value names it and the frames' times."""
    frames: dict[str, list[int]] = defaultdict(list)
    for n, frame_tags in enumerate(tags):
        value = frame_tags.get(FILE_PATH_TAG)
        if value and path_problem(value):  # an empty one names no file (store_file_path's default)
            frames[value].append(n)
    for value, which in frames.items():
        times = ", ".join(f"{stamps[n] / 1e9:.3f}" for n in which[:3]) + (", ..." if len(which) > 3 else "")
        notes.append(f"{topic}: tag {FILE_PATH_TAG} {value!r} {path_problem(value)}: the {len(which)} frame(s) "
                     f"it names (at {times} s) are refused, a path from a log never decides where files go")
    return np.array(sorted(n for which in frames.values() for n in which), dtype=np.int64)


def _tags(contents: LogContents, stamps: np.ndarray, cfg: LogReading) -> list[dict[str, str]]:
    """Per frame, the tags of the last tags message stamped at most tolerances.tags_s after it ({} if none)."""
    if not contents.tags:
        return [{} for _ in stamps]
    tags = sorted(contents.tags, key=lambda t: t.stamp_ns)
    tag_stamps = np.array([t.stamp_ns for t in tags], dtype=np.int64)
    index = np.searchsorted(tag_stamps, stamps + int(cfg.tolerances.tags_s * 1e9), side="right") - 1
    return [dict(tags[i].tags) if i >= 0 else {} for i in index]
