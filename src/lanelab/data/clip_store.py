"""The clip store, format version 1 (DESIGN.md, "Clip store contract"): defined here, once.

A store is a directory that pyarrow, DuckDB or Spark read without lanelab::

    <store>/manifest.json            format, version, source logs (sha256), clips and their splits
    <store>/clips/<clip_id>.parquet  one row per frame, in time order (:data:`CLIP_SCHEMA`)

Clip files are written in row groups of :data:`ROW_GROUP_FRAMES` frames, so reading a
window of frames opens one file and reads only the row groups that hold the window.
Every write is atomic (:func:`lanelab.atomic_file.atomic_output`). Writers (the ingestor in
``data_ingest``) and readers (the datasets) both go through this module.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Iterable, Iterator, Sequence

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

from lanelab.atomic_file import atomic_output

FORMAT_NAME = "lanelab-clips"
FORMAT_VERSION = 1
MANIFEST_NAME = "manifest.json"
CLIPS_DIR = "clips"
ROW_GROUP_FRAMES = 8  # a window of F frames touches at most ceil(F / 8) + 1 row groups
SPLITS = ("train", "val", "test")
# Parquet dictionary-encodes only these repetitive strings (trying it on image bytes costs a
# third of the writing time for nothing); statistics are kept for timestamps only.
_DICTIONARY_COLUMNS = ["image_encoding", "tags.key_value.key", "tags.key_value.value"]
ZSTD_LEVEL = -1  # zstd's fast mode: most bytes are JPEG/PNG already; 20 % quicker than level 1, 1.5 % larger

LANE_TYPE = pa.struct([
    ("track_id", pa.int64()),
    ("category", pa.int32()),
    ("points", pa.list_(pa.list_(pa.float32()))),  # (P, 3): [x, y, z] in the lane frame, y ascending
    ("visibility", pa.list_(pa.float32())),  # (P,) in [0, 1]
])

CLIP_SCHEMA = pa.schema(
    [
        ("timestamp_ns", pa.int64()),
        ("image", pa.binary()),  # bytes as they came from the drive log
        ("image_encoding", pa.string()),  # jpeg | png | rgb8 | bgr8 | mono8
        ("width", pa.int32()),
        ("height", pa.int32()),
        ("K", pa.list_(pa.float64())),  # 9 values, row-major
        ("T_lane_cam", pa.list_(pa.float64())),  # 16 values, row-major
        ("T_world_lane", pa.list_(pa.float64())),  # 16 values, row-major
        ("labeled", pa.bool_()),
        ("lanes", pa.list_(LANE_TYPE)),
        ("tags", pa.map_(pa.string(), pa.string())),
    ],
    metadata={"lanelab.format": FORMAT_NAME, "lanelab.version": str(FORMAT_VERSION)},
)


class ManifestError(ValueError):
    """A store's manifest is missing, garbled or of a format this lanelab cannot read; names the file."""


@dataclass(eq=False)
class LaneRecord:
    """One 3D lane line of a frame.

    points: (P, 3) float32, [x, y, z] in the frame's lane frame, y ascending.
    visibility: (P,) float32 in [0, 1].
    """

    track_id: int
    category: int
    points: np.ndarray
    visibility: np.ndarray


@dataclass(eq=False)
class FrameRecord:
    """One row of a clip file: a camera frame with its calibration, pose and labels.

    K: (3, 3) float64 intrinsics in pixels. T_lane_cam: (4, 4) float64 camera extrinsic
    (maps camera points into the lane frame). T_world_lane: (4, 4) float64 ego pose.
    ``lanes`` is empty when ``labeled`` is False (temporal history only).
    """

    timestamp_ns: int
    image: bytes
    image_encoding: str
    width: int
    height: int
    K: np.ndarray
    T_lane_cam: np.ndarray
    T_world_lane: np.ndarray
    labeled: bool
    lanes: list[LaneRecord] = field(default_factory=list)
    tags: dict[str, str] = field(default_factory=dict)


@dataclass(frozen=True)
class SourceEntry:
    """A drive log a store was made from."""

    path: str
    sha256: str
    num_frames: int


@dataclass(frozen=True)
class ClipEntry:
    """A clip of a store; ``source`` is the ``path`` of its :class:`SourceEntry`."""

    clip_id: str
    source: str
    split: str
    num_frames: int
    first_timestamp_ns: int
    last_timestamp_ns: int


@dataclass
class Manifest:
    """``manifest.json``: the store's sources and clips.

    ``options``: how the store was made (the ingestor's options); readers may ignore it.
    """

    sources: list[SourceEntry] = field(default_factory=list)
    clips: list[ClipEntry] = field(default_factory=list)
    options: dict[str, Any] = field(default_factory=dict)


# --- manifest ------------------------------------------------------------------------------

def manifest_path(store_dir: str | Path) -> Path:
    return Path(store_dir) / MANIFEST_NAME


def read_manifest(store_dir: str | Path) -> Manifest:
    """Read ``<store_dir>/manifest.json``; :class:`ManifestError` names the file and the fault."""
    path = manifest_path(store_dir)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ManifestError(f"{path}: no clip store manifest there") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as err:
        raise ManifestError(f"{path}: cannot read the manifest: {err}") from None
    if not isinstance(data, dict) or data.get("format") != FORMAT_NAME:
        found = data.get("format") if isinstance(data, dict) else type(data).__name__
        raise ManifestError(f"{path}: not a {FORMAT_NAME} manifest (format: {found!r})")
    if data.get("version") != FORMAT_VERSION:
        raise ManifestError(f"{path}: format version {data.get('version')!r} is not supported "
                            f"(this lanelab reads version {FORMAT_VERSION})")
    try:
        return Manifest(
            sources=[SourceEntry(**entry) for entry in data["sources"]],
            clips=[ClipEntry(**entry) for entry in data["clips"]],
            options=dict(data.get("options", {})),
        )
    except (KeyError, TypeError) as err:
        raise ManifestError(f"{path}: malformed manifest: {err}") from None


def write_manifest(store_dir: str | Path, manifest: Manifest) -> Path:
    """Write ``<store_dir>/manifest.json`` atomically; return its path."""
    path = manifest_path(store_dir)
    path.parent.mkdir(parents=True, exist_ok=True)
    data = {
        "format": FORMAT_NAME,
        "version": FORMAT_VERSION,
        "sources": [asdict(entry) for entry in manifest.sources],
        "clips": [asdict(entry) for entry in manifest.clips],
        "options": manifest.options,
    }
    with atomic_output(path) as tmp:
        tmp.write_text(json.dumps(data, indent=1) + "\n", encoding="utf-8")
    return path


# --- clip files ----------------------------------------------------------------------------

def clip_path(store_dir: str | Path, clip_id: str) -> Path:
    return Path(store_dir) / CLIPS_DIR / f"{clip_id}.parquet"


def write_clip(store_dir: str | Path, clip_id: str, frames: Iterable[FrameRecord]) -> Path:
    """Write the frames of a clip (strictly increasing timestamps) atomically; return the file's path.

    ``frames`` may be a generator: they are written :data:`ROW_GROUP_FRAMES` at a time, so
    only one row group's images are held in memory.
    """
    path = clip_path(store_dir, clip_id)
    path.parent.mkdir(parents=True, exist_ok=True)
    last_stamp = None
    with atomic_output(path) as tmp:
        with pq.ParquetWriter(tmp, CLIP_SCHEMA, compression="zstd", compression_level=ZSTD_LEVEL,
                              write_statistics=["timestamp_ns"], use_dictionary=_DICTIONARY_COLUMNS) as writer:
            for batch in _batches(frames, ROW_GROUP_FRAMES):
                for frame in batch:
                    if last_stamp is not None and frame.timestamp_ns <= last_stamp:
                        raise ValueError(f"clip {clip_id!r}: frames are not in strictly increasing time order")
                    last_stamp = frame.timestamp_ns
                writer.write_table(_frames_to_table(batch))
        if last_stamp is None:
            raise ValueError(f"clip {clip_id!r} has no frames")
    return path


def _batches(items: Iterable[FrameRecord], size: int) -> Iterator[list[FrameRecord]]:
    batch: list[FrameRecord] = []
    for item in items:
        batch.append(item)
        if len(batch) == size:
            yield batch
            batch = []
    if batch:
        yield batch


def _offsets(counts: Sequence[int]) -> pa.Array:
    return pa.array(np.concatenate([[0], np.cumsum(counts, dtype=np.int64)]).astype(np.int32))


def _matrix_column(matrices: np.ndarray) -> pa.Array:
    """(N, r, c) float64 -> list<float64> of r * c values per row, row-major."""
    flat = np.ascontiguousarray(matrices, dtype=np.float64).reshape(len(matrices), -1)
    return pa.ListArray.from_arrays(_offsets([flat.shape[1]] * len(flat)), pa.array(flat.ravel()))


def _lanes_column(frames: Sequence[FrameRecord]) -> pa.Array:
    """The lanes of every frame as one nested Arrow array, built from flat numpy buffers."""
    lanes = [lane for frame in frames for lane in frame.lanes]
    points = [np.asarray(lane.points, dtype=np.float32).reshape(-1, 3) for lane in lanes]
    visibility = [np.asarray(lane.visibility, dtype=np.float32).reshape(-1) for lane in lanes]
    for lane, p, v in zip(lanes, points, visibility):
        if len(p) != len(v):
            raise ValueError(f"lane {lane.track_id}: {len(p)} points but {len(v)} visibility values")
    points_per_lane = [len(p) for p in points]
    xyz = np.concatenate(points).ravel() if lanes else np.zeros(0, np.float32)
    vis = np.concatenate(visibility) if lanes else np.zeros(0, np.float32)
    point_lists = pa.ListArray.from_arrays(_offsets([3] * sum(points_per_lane)), pa.array(xyz))
    structs = pa.StructArray.from_arrays(
        [
            pa.array([lane.track_id for lane in lanes], pa.int64()),
            pa.array([lane.category for lane in lanes], pa.int32()),
            pa.ListArray.from_arrays(_offsets(points_per_lane), point_lists),
            pa.ListArray.from_arrays(_offsets(points_per_lane), pa.array(vis)),
        ],
        fields=list(LANE_TYPE),
    )
    return pa.ListArray.from_arrays(_offsets([len(frame.lanes) for frame in frames]), structs)


def _frames_to_table(frames: Sequence[FrameRecord]) -> pa.Table:
    columns = [
        pa.array([f.timestamp_ns for f in frames], pa.int64()),
        pa.array([f.image for f in frames], pa.binary()),
        pa.array([f.image_encoding for f in frames], pa.string()),
        pa.array([f.width for f in frames], pa.int32()),
        pa.array([f.height for f in frames], pa.int32()),
        _matrix_column(np.stack([np.asarray(f.K).reshape(3, 3) for f in frames])),
        _matrix_column(np.stack([np.asarray(f.T_lane_cam).reshape(4, 4) for f in frames])),
        _matrix_column(np.stack([np.asarray(f.T_world_lane).reshape(4, 4) for f in frames])),
        pa.array([bool(f.labeled) for f in frames], pa.bool_()),
        _lanes_column(frames),
        pa.array([sorted(f.tags.items()) for f in frames], CLIP_SCHEMA.field("tags").type),
    ]
    return pa.Table.from_arrays(columns, schema=CLIP_SCHEMA)


def _flat(column: pa.ChunkedArray, dtype: type) -> np.ndarray:
    """The values of a list column, concatenated: (sum of lengths,)."""
    return np.array(pc.list_flatten(column).to_numpy(), dtype=dtype)  # a writable copy


def frames_from_table(table: pa.Table) -> list[FrameRecord]:
    """Rows of a clip table (any slice of one) -> FrameRecords."""
    n = table.num_rows
    K = _flat(table["K"], np.float64).reshape(n, 3, 3)
    T_lane_cam = _flat(table["T_lane_cam"], np.float64).reshape(n, 4, 4)
    T_world_lane = _flat(table["T_world_lane"], np.float64).reshape(n, 4, 4)
    lanes = _lanes_from_column(table["lanes"].combine_chunks())
    return [
        FrameRecord(
            timestamp_ns=timestamp_ns,
            image=image,
            image_encoding=encoding,
            width=width,
            height=height,
            K=K[i],
            T_lane_cam=T_lane_cam[i],
            T_world_lane=T_world_lane[i],
            labeled=labeled,
            lanes=lanes[i],
            tags=dict(tags),
        )
        for i, (timestamp_ns, image, encoding, width, height, labeled, tags) in enumerate(zip(
            *(table[name].to_pylist() for name in
              ("timestamp_ns", "image", "image_encoding", "width", "height", "labeled", "tags"))))
    ]


def _lanes_from_column(column: pa.ListArray) -> list[list[LaneRecord]]:
    """The lanes column -> per frame, its LaneRecords (numpy views into one flat buffer)."""
    lanes_per_frame = pc.list_value_length(column).to_numpy()
    structs = pc.list_flatten(column)
    points = pc.struct_field(structs, "points")
    points_per_lane = pc.list_value_length(points).to_numpy()
    xyz = np.array(pc.list_flatten(pc.list_flatten(points)).to_numpy()).reshape(-1, 3)  # writable copies
    visibility = np.array(pc.list_flatten(pc.struct_field(structs, "visibility")).to_numpy())
    split_at = np.cumsum(points_per_lane)[:-1]
    lanes = [
        LaneRecord(int(track_id), int(category), p, v)
        for track_id, category, p, v in zip(
            pc.struct_field(structs, "track_id").to_pylist(),
            pc.struct_field(structs, "category").to_pylist(),
            np.split(xyz, split_at),
            np.split(visibility, split_at),
        )
    ]
    starts = np.concatenate([[0], np.cumsum(lanes_per_frame)])
    return [lanes[starts[i]:starts[i + 1]] for i in range(len(lanes_per_frame))]


# --- reading a store -------------------------------------------------------------------------

class ClipStore:
    """A clip store opened for reading: its manifest, and windows of frames of its clips.

    Holds no open file between calls, so it is safe to share with forked or spawned workers.
    """

    def __init__(self, root: str | Path) -> None:
        self.root = Path(root)
        self.manifest = read_manifest(self.root)
        self._clips = {clip.clip_id: clip for clip in self.manifest.clips}

    @property
    def clips(self) -> list[ClipEntry]:
        return self.manifest.clips

    def clips_in(self, split: str) -> list[ClipEntry]:
        """The clips of ``split`` (train | val | test), in manifest order."""
        if split not in SPLITS:
            raise ValueError(f"unknown split {split!r}; one of {', '.join(SPLITS)}")
        return [clip for clip in self.manifest.clips if clip.split == split]

    def clip(self, clip_id: str) -> ClipEntry:
        try:
            return self._clips[clip_id]
        except KeyError:
            raise KeyError(f"{self.root}: no clip {clip_id!r} in the manifest") from None

    def clip_path(self, clip_id: str) -> Path:
        return clip_path(self.root, self.clip(clip_id).clip_id)

    def read_frames(self, clip_id: str, start: int = 0, stop: int | None = None) -> list[FrameRecord]:
        """Frames ``start`` to ``stop - 1`` of a clip, in time order; one file open, only the row groups needed."""
        num_frames = self.clip(clip_id).num_frames
        stop = num_frames if stop is None else stop
        if not 0 <= start < stop <= num_frames:
            raise IndexError(f"clip {clip_id!r} has {num_frames} frames; cannot read [{start}, {stop})")
        with open(self.clip_path(clip_id), "rb") as handle:
            parquet = pq.ParquetFile(handle)
            ends = np.cumsum([parquet.metadata.row_group(i).num_rows for i in range(parquet.num_row_groups)])
            first = int(np.searchsorted(ends, start, side="right"))
            last = int(np.searchsorted(ends, stop - 1, side="right"))
            table = parquet.read_row_groups(list(range(first, last + 1)))
        offset = start - (int(ends[first - 1]) if first > 0 else 0)
        return frames_from_table(table.slice(offset, stop - start))

    def read_labels(self, clip_id: str) -> list[tuple[bool, list[LaneRecord]]]:
        """Every frame's ``labeled`` flag and lanes, in time order, reading those two columns
        alone (no images): what statistics over the labels of many frames need."""
        table = pq.read_table(self.clip_path(clip_id), columns=["labeled", "lanes"])
        lanes = _lanes_from_column(table["lanes"].combine_chunks())
        return list(zip(table["labeled"].to_pylist(), lanes))
