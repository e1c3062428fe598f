"""The clip store's format, version 1 (DESIGN.md, "Clip store contract"): defined here, once.

A store is a directory that pyarrow, DuckDB or Spark read without lanelab::

    <store>/manifest.json            format, version, source logs (sha256), clips (splits, file sha256)
    <store>/clips/<clip_id>.parquet  one row per frame, in time order (:data:`CLIP_SCHEMA`)

Clip files are written in row groups of :data:`ROW_GROUP_FRAMES` frames, so reading a
window of frames opens one file and reads only the row groups that hold the window.
"""

from __future__ import annotations

from pathlib import Path

import pyarrow as pa

FORMAT_NAME = "lanelab-clips"
FORMAT_VERSION = 1
MANIFEST_NAME = "manifest.json"
CLIPS_DIR = "clips"
CLIP_SUFFIX = ".parquet"
ROW_GROUP_FRAMES = 8  # a window of F frames touches at most ceil(F / 8) + 1 row groups
SPLITS = ("train", "val", "test")
# Parquet dictionary-encodes only these repetitive strings (trying it on image bytes costs a
# third of the writing time for nothing); statistics are kept for timestamps only.
DICTIONARY_COLUMNS = ["image_encoding", "tags.key_value.key", "tags.key_value.value"]
STATISTICS_COLUMNS = ["timestamp_ns"]
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


def manifest_path(store_dir: str | Path) -> Path:
    """``<store_dir>/manifest.json``."""
    return Path(store_dir) / MANIFEST_NAME


def clip_path(store_dir: str | Path, clip_id: str) -> Path:
    """``<store_dir>/clips/<clip_id>.parquet``."""
    return Path(store_dir) / CLIPS_DIR / f"{clip_id}{CLIP_SUFFIX}"
