"""Where a frame's ONCE-3DLanes files lie: ``<sequence>/cam01/<stamp>.json`` below a split folder.

The official evaluator pairs a prediction with the label at the same relative path. A frame of a
store made by ``lanelab-once`` keeps its label's relative path in the :data:`LABEL_PATH_TAG` tag,
so that predictions line up with the release; any other store's frame is named
``<clip_id>/cam01/<timestamp_ns>.json``. The path is data: :func:`json_file` keeps it inside its
folder (:func:`lanelab.data_paths.path_inside`).
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path

from lanelab.data_paths import path_inside

LABEL_PATH_TAG = "once.label_path"  # "<sequence>/cam01/<stamp>.json": the frame's label, relative to its split folder
CAMERA = "cam01"  # the front camera, the only one ONCE-3DLanes labels


def label_path(sequence: str, stamp: str) -> str:
    """The relative path of the label of frame ``stamp`` (its file name without .json) of ``sequence``."""
    return f"{sequence}/{CAMERA}/{stamp}.json"


def store_label_path(clip_id: str, timestamp_ns: int, tags: Mapping[str, str]) -> str:
    """The relative path under which a clip-store frame's ONCE files are written: its
    :data:`LABEL_PATH_TAG` tag, else ``<clip_id>/cam01/<timestamp_ns>.json``."""
    return tags.get(LABEL_PATH_TAG) or label_path(clip_id, str(timestamp_ns))


def json_file(directory: str | os.PathLike[str], relative: str) -> Path:
    """``directory / relative``; UnsafePathError when that is not inside directory."""
    return path_inside(directory, relative, f"ONCE label path {relative!r}")
