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
from pathlib import Path
from typing import Iterator, Mapping, Sequence

import numpy as np

from data_ingest.openlane.annotation import Annotation, read_annotation, timestamp_ns
from data_ingest.openlane.config import OpenLaneAdapterConfig
from data_ingest.source_files import FAILED, KEPT, WRITTEN, fingerprint, read_image_file
from lanelab.config_checks import ConfigError
from lanelab.json_files import LaneFileError, load_json_object
from lanelab.openlane.file_paths import FILE_PATH_TAG
from lanelab.openlane.lane_order import far_to_near_tag
from lanelab.openlane.lists import OPENLANE_SCENARIOS, read_scenario_lists
from lanelab.store import (
    MADE_BY_OPTION,
    WITHOUT_POSE,
    ClipEntry,
    FrameRecord,
    SourceEntry,
    StoreBusy,
    StoreRefused,
    StoreWriter,
    file_sha256,
    write_clip,
)

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


def adapt(cfg: OpenLaneAdapterConfig) -> list[SegmentResult]:
    """Make or update the store ``cfg.output``; one result per segment found, in order.

    Raises ConfigError when the output is a store made by another tool or being written by
    another process, LaneFileError when a scenario list or scene.json cannot be read; a bad
    segment only fails itself.
    """
    case_lists = read_scenario_lists(cfg.scenario_lists) if cfg.scenario_lists else {}
    scenes = _read_scenes(cfg.scene_tags) if cfg.scene_tags else {}
    try:
        writer = StoreWriter(cfg.output, {MADE_BY_OPTION: MADE_BY, "lane_frame": LANE_FRAME}, _segment_of,
                             marks=[WITHOUT_POSE])
    except (StoreRefused, StoreBusy) as err:
        raise ConfigError(str(err)) from None
    results = []
    with writer:
        for folder, split in cfg.splits.items():
            split_dir = Path(cfg.annotations) / folder
            if not split_dir.is_dir():
                print(f"lanelab-openlane: no split folder {split_dir}, skipped")
                continue
            for segment_dir in sorted(path for path in split_dir.iterdir() if path.is_dir()):
                segment = segment_dir.name
                scene = scenes.get(segment) or scenes.get(segment.removesuffix("_with_camera_labels"), {})
                try:
                    result = _adapt_segment(segment_dir, split, cfg, writer, case_lists, scene)
                except ValueError as err:  # LaneFileError names the file; the store's own checks name the clip
                    result = SegmentResult(segment, FAILED, error=str(err))
                results.append(result)
    return results


def _adapt_segment(
    segment_dir: Path,
    split: str,
    cfg: OpenLaneAdapterConfig,
    writer: StoreWriter,
    case_lists: Mapping[str, frozenset[str]],
    scene: Mapping[str, str],
) -> SegmentResult:
    """Write and commit one segment's clip unless the store holds it unchanged."""
    segment = segment_dir.name
    paths = sorted(segment_dir.glob("*.json"), key=timestamp_ns)
    if not paths:
        raise LaneFileError(segment_dir, "no annotation files (*.json) in this segment")
    tags = [_frame_tags(f"{segment}/{path.stem}", case_lists, scene) for path in paths]
    source = str(segment_dir.resolve())
    sha256 = fingerprint(paths, tags)
    if writer.kept_sha256(source, split) == sha256:
        return SegmentResult(segment, KEPT, len(paths), segment not in writer.manifest.options[WITHOUT_POSE])

    annotations = [read_annotation(path) for path in paths]
    has_pose = all(a.T_world_lane is not None for a in annotations)
    path = write_clip(cfg.output, segment, _frames(annotations, tags, Path(cfg.images), has_pose))
    clip = ClipEntry(segment, source, split, len(paths), annotations[0].timestamp_ns, annotations[-1].timestamp_ns,
                     file_sha256(path))
    writer.commit(SourceEntry(source, sha256, len(paths)), [clip], marks=[] if has_pose else [WITHOUT_POSE])
    return SegmentResult(segment, WRITTEN, len(paths), has_pose)


def _frames(
    annotations: Sequence[Annotation], tags: Sequence[dict[str, str]], images: Path, has_pose: bool
) -> Iterator[FrameRecord]:
    """The segment's frames (annotations and their tags), each image read only when its row
    group is written."""
    for annotation, frame_tags in zip(annotations, tags):
        frame = f"the file_path of the frame at {annotation.timestamp_ns} ns"
        image, encoding, width, height = read_image_file(images / annotation.file_path, frame)
        yield FrameRecord(
            timestamp_ns=annotation.timestamp_ns,
            image=image,
            image_encoding=encoding,
            width=width,
            height=height,
            K=annotation.K,
            T_lane_cam=annotation.T_lane_cam,
            T_world_lane=annotation.T_world_lane if has_pose else np.eye(4),
            labeled=True,
            lanes=annotation.lanes,
            tags={FILE_PATH_TAG: annotation.file_path, **far_to_near_tag(annotation.far_to_near), **frame_tags},
        )


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


def _segment_of(source: str) -> str:
    """The segment a source (its folder) holds: the folder's name, which is its clip's id."""
    return Path(source).name
