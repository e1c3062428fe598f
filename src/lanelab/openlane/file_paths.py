"""OpenLane ``file_path`` conventions: which frame a file names, and where its JSON lies.

Every OpenLane JSON file names its frame by ``file_path``, the frame's image path
("<folders>/<name>.jpg"); the frame's ground-truth and prediction files lie at that path with
.json under their folders (:func:`json_path`), where test lists point.

- A clip-store frame is named "<clip_id>/<timestamp_ns>.jpg" (:func:`frame_path`).
- A frame of a store made from OpenLane (``lanelab-openlane``) keeps the ground truth's own
  ``file_path`` in its :data:`FILE_PATH_TAG` tag (:func:`file_path_of`), so that predictions
  written under it pair with the official files (and ``images=`` finds its image).

:func:`store_file_path` picks between the two for any store's frame. A ``file_path`` is data:
:func:`json_path` refuses one that is absolute or leads out of its folder
(:func:`lanelab.data_paths.path_inside`), so no frame decides where a file is written.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path, PurePosixPath
from typing import TYPE_CHECKING

from lanelab.data_paths import path_inside

if TYPE_CHECKING:
    from lanelab.store import FrameRecord

FILE_PATH_TAG = "openlane.file_path"  # the frame tag that holds an OpenLane store frame's file_path


def frame_path(clip_id: str, timestamp_ns: int) -> str:
    """A frame's OpenLane ``file_path``: an image path, whose JSON files end in .json instead."""
    return f"{clip_id}/{timestamp_ns}.jpg"


def file_path_of(frame: FrameRecord) -> str:
    """The OpenLane ``file_path`` of a frame of an OpenLane store (its ``openlane.file_path`` tag)."""
    try:
        return frame.tags[FILE_PATH_TAG]
    except KeyError:
        raise KeyError(f"frame at {frame.timestamp_ns} ns has no {FILE_PATH_TAG!r} tag: "
                       "not from a store made by lanelab-openlane") from None


def store_file_path(clip_id: str, timestamp_ns: int, tags: Mapping[str, str]) -> str:
    """The ``file_path`` under which a clip-store frame's OpenLane files are written: its
    :data:`FILE_PATH_TAG` tag (a frame of an OpenLane store), else :func:`frame_path`."""
    return tags.get(FILE_PATH_TAG) or frame_path(clip_id, timestamp_ns)


def frame_id(file_path: str) -> str:
    """The name of the frame with this ``file_path`` in a test list as read
    (:func:`lanelab.openlane.lists.read_test_list`) and in scores: its JSON path, relative."""
    return PurePosixPath(file_path).with_suffix(".json").as_posix()


def json_path(directory: str | os.PathLike[str], file_path: str) -> Path:
    """Where the JSON file (ground truth or prediction) of the frame with this ``file_path``
    lies under directory. Raises UnsafePathError when that is not inside directory."""
    return path_inside(directory, frame_id(file_path), f"file_path {file_path!r}")
