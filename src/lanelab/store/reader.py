"""Reading a clip store: its manifest, and windows of frames or single columns of its clips."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from lanelab.lanes import Lane
from lanelab.store import clip_file
from lanelab.store.manifest import ClipEntry, read_manifest
from lanelab.store.records import FrameRecord
from lanelab.store.schema import SPLITS, clip_path


class DataError(ValueError):
    """A store cannot give what was asked of it: a split without clips, or samples its clips cannot
    give; the message names the store and the split and says what to change."""


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

    def split_counts(self) -> str:
        """How many clips each split has: "train 0, val 2, test 0"."""
        return ", ".join(f"{split} {len(self.clips_in(split))}" for split in SPLITS)

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
        return clip_file.read_window(self.clip_path(clip_id), start, stop)

    def read_labels(self, clip_id: str) -> list[tuple[bool, list[Lane]]]:
        """Every frame's ``labeled`` flag and lanes, in time order, reading those two columns
        alone (no images): what statistics over the labels of many frames need."""
        return clip_file.read_labels(self.clip_path(clip_id))

    def read_timeline(self, clip_id: str) -> tuple[np.ndarray, np.ndarray]:
        """Every frame's ``timestamp_ns`` (N,) int64 and ``labeled`` flag (N,) bool, in time
        order, reading those two columns alone: what indexing the frames of many clips needs."""
        return clip_file.read_timeline(self.clip_path(clip_id))

    def read_tags(self, clip_id: str) -> list[tuple[int, dict[str, str]]]:
        """Every frame's ``timestamp_ns`` and scenario tags, in time order, reading those two
        columns alone."""
        return clip_file.read_tags(self.clip_path(clip_id))
