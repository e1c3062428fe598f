"""OpenLane (annotation JSONs + images) -> one clip store, each segment a clip.

    <annotations>/<split folder>/<segment>/<timestamp>.json  ->  <output>/clips/<segment>.parquet

Every segment folder of the split folders named in ``splits`` (OpenLane's ``training`` and
``validation`` -> the store's ``train`` and ``val`` by default) becomes a clip of that
split, its frames in time order. Each frame gets

- its image: the bytes of ``<images>/<file_path>`` as they are, size from the header, decoded once
  to check them (an image cut short or corrupt fails its segment);
- K, T_lane_cam, lanes and T_world_lane from :func:`~data_ingest.openlane.annotation.read_annotation`
  (the lane frame of an OpenLane store is the evaluator's ground frame, see there). A
  segment whose files carry no ``pose`` (OpenLane before v1.2) gets the identity for every
  frame and is listed under ``clips_without_pose`` in the manifest's options: its frames
  cannot be related to one another;
- ``labeled`` True, and tags: ``openlane.file_path`` (the ground truth's ``file_path``, which
  prediction files repeat); ``openlane.far_to_near``, the lanes the file lists far to near
  (:mod:`lanelab.openlane.lane_order`: exported ground truth lists them so again); for each
  scenario list naming the frame, ``<case>: <label>`` (``curve: Curve``), so that
  :func:`lanelab.metrics.scenarios.tag_scenarios` with groups
  :data:`~lanelab.metrics.scenarios.OPENLANE_TAG_GROUPS` gives the papers' scenario columns; from ``scene.json``,
  ``environment``, ``weather`` and ``daytime`` (its scene, weather and time), the columns of
  SparseLaneSTP's Table 7.

Re-running is cheap: a segment whose annotation files and tags are unchanged (the sha256 the
manifest holds for it), and its split too, keeps its clip. The store is updated as every
writing tool updates one (:class:`~lanelab.store.StoreWriter`; a segment is known by its
folder's name, its clip id): each clip is written atomically and the manifest after each
segment, so an interrupted run resumes. A segment that cannot be read is reported, naming
the file, and the others go on.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Iterator, Mapping, Sequence

import numpy as np

from data_ingest.dataset_adapter import FAILED, KEPT, WRITTEN, adapt_folders, commit_clip, kept_with_pose
from data_ingest.openlane.annotation import Annotation, read_annotation, timestamp_ns
from data_ingest.openlane.config import OpenLaneAdapterConfig
from data_ingest.source_files import fingerprint, labeled_record
from lanelab.json_files import LaneFileError, load_json_object
from lanelab.openlane.file_paths import FILE_PATH_TAG
from lanelab.openlane.lane_order import far_to_near_tag
from lanelab.openlane.lists import OPENLANE_SCENARIOS, read_scenario_lists
from lanelab.store import FrameRecord, StoreWriter

MADE_BY = "lanelab-openlane"
LANE_FRAME = "OpenLane evaluator's ground frame: x right, y forward, z up; origin below the camera"
# scene.json key -> frame tag (the tag keys of the scenario tables)
SCENE_TAGS = {"scene": "environment", "weather": "weather", "time": "daytime"}


@dataclass
class SegmentResult:
    """What became of one segment: status WRITTEN, KEPT or FAILED (error says why)."""

    segment: str
    status: str
    num_frames: int = 0
    has_pose: bool = True
    error: str = ""

    @property
    def name(self) -> str:  # the folder's name, as the summary prints it
        return self.segment


def adapt(cfg: OpenLaneAdapterConfig) -> list[SegmentResult]:
    """Make or update the store ``cfg.output``; one result per segment found, in order.

    Raises ConfigError when the output is a store made by another tool or being written by
    another process, LaneFileError when a scenario list or scene.json cannot be read; a bad
    segment only fails itself.
    """
    case_lists = read_scenario_lists(cfg.scenario_lists) if cfg.scenario_lists else {}
    scenes = _read_scenes(cfg.scene_tags) if cfg.scene_tags else {}
    adapt_segment = partial(_adapt_segment, cfg=cfg, case_lists=case_lists, scenes=scenes)
    return adapt_folders(MADE_BY, {"lane_frame": LANE_FRAME}, cfg.output, cfg.annotations, cfg.splits, adapt_segment,
                         lambda segment, error: SegmentResult(segment, FAILED, error=error))  # fmt: skip


def _adapt_segment(
    writer: StoreWriter,
    segment_dir: Path,
    split: str,
    cfg: OpenLaneAdapterConfig,
    case_lists: Mapping[str, frozenset[str]],
    scenes: Mapping[str, Mapping[str, str]],
) -> SegmentResult:
    """Write and commit one segment's clip unless the store holds it unchanged."""
    segment = segment_dir.name
    scene = scenes.get(segment) or scenes.get(segment.removesuffix("_with_camera_labels"), {})
    paths = sorted(segment_dir.glob("*.json"), key=timestamp_ns)
    if not paths:
        raise LaneFileError(segment_dir, "no annotation files (*.json) in this segment")
    tags = [_frame_tags(f"{segment}/{path.stem}", case_lists, scene) for path in paths]
    source = str(segment_dir.resolve())
    sha256 = fingerprint(paths, tags)
    kept_pose = kept_with_pose(writer, source, split, sha256)
    if kept_pose is not None:
        return SegmentResult(segment, KEPT, len(paths), kept_pose)

    annotations = [read_annotation(path) for path in paths]
    has_pose = all(a.T_world_lane is not None for a in annotations)
    commit_clip(writer, cfg.output, source, split, sha256, [a.timestamp_ns for a in annotations],
                _frames(annotations, tags, Path(cfg.images), has_pose), has_pose)  # fmt: skip
    return SegmentResult(segment, WRITTEN, len(paths), has_pose)


def _frames(
    annotations: Sequence[Annotation], tags: Sequence[dict[str, str]], images: Path, has_pose: bool
) -> Iterator[FrameRecord]:
    """The segment's frames (annotations and their tags), each image read only when its row
    group is written."""
    for annotation, frame_tags in zip(annotations, tags):
        yield labeled_record(
            images / annotation.file_path, f"the file_path of the frame at {annotation.timestamp_ns} ns",
            annotation.timestamp_ns, annotation.K, annotation.T_lane_cam,
            annotation.T_world_lane if has_pose else np.eye(4), annotation.lanes,
            {FILE_PATH_TAG: annotation.file_path, **far_to_near_tag(annotation.far_to_near), **frame_tags},
        )  # fmt: skip


def _frame_tags(key: str, case_lists: Mapping[str, frozenset[str]], scene: Mapping[str, str]) -> dict[str, str]:
    """A frame's scenario tags: its cases (by frame key, "<segment>/<timestamp>") and its scene."""
    tags = {case: OPENLANE_SCENARIOS.get(case, case) for case, keys in case_lists.items() if key in keys}
    return {**tags, **scene}


def _read_scenes(path: str) -> dict[str, dict[str, str]]:
    """scene.json -> segment -> {environment, weather, daytime}."""
    data = load_json_object(path)
    scenes = {}
    for segment, scene in data.items():
        if not isinstance(scene, dict):
            raise LaneFileError(path, f"'{segment}' must map to an object of scene, weather and time")
        scenes[segment] = {tag: str(scene[key]) for key, tag in SCENE_TAGS.items() if key in scene}
    return scenes
