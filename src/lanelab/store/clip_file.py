"""Clip files: frames -> Parquet (:data:`~lanelab.store.schema.CLIP_SCHEMA`) and back.

The only code that knows the clip file's columns by name. Every write is atomic
(:func:`lanelab.atomic_file.atomic_output`) and gives each Parquet page a CRC checksum; a
read opens the file once, reads only the row groups or columns it needs and verifies their
checksums, so a damaged file raises :class:`ClipFileError` naming it instead of giving
wrong values.
"""

from __future__ import annotations

import contextlib
from pathlib import Path
from typing import Iterable, Iterator, Sequence

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

from lanelab.atomic_file import atomic_output
from lanelab.lanes import Lane
from lanelab.store.records import FrameRecord
from lanelab.store.schema import (
    CLIP_SCHEMA,
    DICTIONARY_COLUMNS,
    LANE_TYPE,
    ROW_GROUP_FRAMES,
    STATISTICS_COLUMNS,
    ZSTD_LEVEL,
    clip_path,
)


class ClipFileError(ValueError):
    """A clip file that cannot be read: damaged (a page checksum or its structure) or unreadable, or
    whose data a writer refuses to follow (a frame's file_path leading out of its folder); names the file."""


@contextlib.contextmanager
def _reading(path: Path) -> Iterator[None]:
    """Turn pyarrow's errors while reading ``path`` into a :class:`ClipFileError` naming it."""
    try:
        yield
    except FileNotFoundError:  # the manifest lists it: a re-ingest writes it again (integrity.clip_fault)
        raise ClipFileError(f"{path}: clip file missing (the store's manifest lists clip {path.stem!r}); re-ingest "
                            f"the store (lanelab-ingest or lanelab-openlane with output={path.parent.parent}) to "
                            "write it again") from None
    except (OSError, pa.ArrowException) as err:
        raise ClipFileError(f"{path}: damaged clip file ({type(err).__name__}: {err})") from None


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
                              write_statistics=STATISTICS_COLUMNS, use_dictionary=DICTIONARY_COLUMNS,
                              write_page_checksum=True) as writer:
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


def _frames_from_table(table: pa.Table) -> list[FrameRecord]:
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


def _lanes_from_column(column: pa.ListArray) -> list[list[Lane]]:
    """The lanes column -> per frame, its Lanes (numpy views into one flat buffer)."""
    lanes_per_frame = pc.list_value_length(column).to_numpy()
    structs = pc.list_flatten(column)
    points = pc.struct_field(structs, "points")
    points_per_lane = pc.list_value_length(points).to_numpy()
    xyz = np.array(pc.list_flatten(pc.list_flatten(points)).to_numpy()).reshape(-1, 3)  # writable copies
    visibility = np.array(pc.list_flatten(pc.struct_field(structs, "visibility")).to_numpy())
    split_at = np.cumsum(points_per_lane)[:-1]
    lanes = [
        Lane(p, v, int(category), track_id=int(track_id))
        for track_id, category, p, v in zip(
            pc.struct_field(structs, "track_id").to_pylist(),
            pc.struct_field(structs, "category").to_pylist(),
            np.split(xyz, split_at),
            np.split(visibility, split_at),
        )
    ]
    starts = np.concatenate([[0], np.cumsum(lanes_per_frame)])
    return [lanes[starts[i]:starts[i + 1]] for i in range(len(lanes_per_frame))]


def read_window(path: Path, start: int, stop: int) -> list[FrameRecord]:
    """Frames ``start`` to ``stop - 1`` of the clip file at ``path``; one file open, only the row groups needed."""
    with _reading(path), open(path, "rb") as handle:
        parquet = pq.ParquetFile(handle, page_checksum_verification=True)
        ends = np.cumsum([parquet.metadata.row_group(i).num_rows for i in range(parquet.num_row_groups)])
        first = int(np.searchsorted(ends, start, side="right"))
        last = int(np.searchsorted(ends, stop - 1, side="right"))
        table = parquet.read_row_groups(list(range(first, last + 1)))
    offset = start - (int(ends[first - 1]) if first > 0 else 0)
    return _frames_from_table(table.slice(offset, stop - start))


def read_labels(path: Path) -> list[tuple[bool, list[Lane]]]:
    """Every frame's ``labeled`` flag and lanes, in time order, from those two columns alone."""
    with _reading(path):
        table = pq.read_table(path, columns=["labeled", "lanes"], page_checksum_verification=True)
    lanes = _lanes_from_column(table["lanes"].combine_chunks())
    return list(zip(table["labeled"].to_pylist(), lanes))


def read_timeline(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Every frame's ``timestamp_ns`` (N,) int64 and ``labeled`` flag (N,) bool, from those two columns alone."""
    with _reading(path):
        table = pq.read_table(path, columns=["labeled", "timestamp_ns"], page_checksum_verification=True)
    return table["timestamp_ns"].to_numpy(), table["labeled"].to_numpy()


def read_tags(path: Path) -> list[tuple[int, dict[str, str]]]:
    """Every frame's ``timestamp_ns`` and tags, in time order, from those two columns alone."""
    with _reading(path):
        table = pq.read_table(path, columns=["timestamp_ns", "tags"], page_checksum_verification=True).to_pydict()
    return [(timestamp, dict(tags or [])) for timestamp, tags in zip(table["timestamp_ns"], table["tags"])]


def check_readable(path: Path) -> None:
    """Read every page of the clip file at ``path``, verifying its checksums; :class:`ClipFileError` if damaged."""
    with _reading(path):
        pq.read_table(path, page_checksum_verification=True)
