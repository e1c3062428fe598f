"""Cutting a log's frames into clips, naming them and drawing their splits.

- ``clips.target_fps`` (optional): a frame is kept once 3/4 of the target period has passed
  since the last kept one, so a jittery source still gives the target rate;
- a clip ends wherever consecutive frames are more than ``clips.gap_s`` apart;
- a longer run than ``clips.max_length_s`` is cut into the fewest equal parts that fit;
- the split (train / val / test, by ``split.*`` ratios) is drawn from a hash of the log's
  name (``split.by=log``) or of the clip's place in it (``split.by=clip``), never per
  frame: re-ingesting gives the same splits. Few clips can all draw val or test; then one of
  them (with ``split.by=log``, its log's clips) goes to train (:func:`clips_for_train`),
  chosen from the clips alone, so that the same logs give the same store.
"""

from __future__ import annotations

import hashlib
import math
import re

import numpy as np

from data_ingest.ingest.config import SplitConfig
from lanelab.store import ClipEntry

KEEP_AFTER = 0.75  # of the target period, for target_fps


def log_name(path_stem: str) -> str:
    """A log's name in clip ids: its file stem with anything but [A-Za-z0-9._-] replaced by "_"."""
    return re.sub(r"[^A-Za-z0-9._-]+", "_", path_stem)


def subsample(stamps: np.ndarray, target_fps: float | None) -> np.ndarray:
    """Which frames of sorted ``stamps`` (N,) int64 ns to keep for ``target_fps`` -> (N,) bool."""
    keep = np.ones(len(stamps), dtype=bool)
    if target_fps is None:
        return keep
    min_step = KEEP_AFTER * 1e9 / target_fps
    last = None
    for i, stamp in enumerate(stamps):
        keep[i] = last is None or stamp - last >= min_step
        if keep[i]:
            last = stamp
    return keep


def cut(stamps: np.ndarray, gap_s: float, max_length_s: float) -> list[slice]:
    """Sorted ``stamps`` (N,) int64 ns -> slices of consecutive frames, one per clip, in time order."""
    breaks = np.flatnonzero(np.diff(stamps) > gap_s * 1e9) + 1
    clips = []
    for start, stop in zip(np.concatenate([[0], breaks]), np.concatenate([breaks, [len(stamps)]])):
        run = stamps[start:stop]
        parts = max(1, math.ceil((run[-1] - run[0]) / (max_length_s * 1e9)))
        # Frame k of the run goes to part floor(parts * elapsed / duration); the last frame to the last part.
        part = np.minimum((parts * (run - run[0])) // max(run[-1] - run[0], 1), parts - 1)
        bounds = np.concatenate([[0], np.flatnonzero(np.diff(part)) + 1, [len(run)]])
        clips += [slice(int(start + a), int(start + b)) for a, b in zip(bounds[:-1], bounds[1:])]
    return clips


def draw_split(key: str, split: SplitConfig) -> str:
    """train, val or test for ``key``, with probabilities ``split.train/val/test``, fixed by ``split.seed``."""
    digest = hashlib.sha256(f"{split.seed}/{key}".encode()).digest()
    u = int.from_bytes(digest[:8], "big") / 2**64
    return "train" if u < split.train else "val" if u < split.train + split.val else "test"


def clips_for_train(clips: list[ClipEntry], split: SplitConfig) -> list[ClipEntry]:
    """The clips to move into train when a store that should have a train split has none, and
    two clips or more (one stays for evaluation): the first by id of the fuller of test and val
    (test on a tie: validation is what training needs) and, with ``split.by=log``, the other
    clips of its log (a log stays in one split). None when nothing needs to move."""
    if split.train == 0 or len(clips) < 2 or any(clip.split == "train" for clip in clips):
        return []
    by_split = {name: sorted((c for c in clips if c.split == name), key=lambda c: c.clip_id) for name in ("test", "val")}
    first = by_split[max(("test", "val"), key=lambda name: len(by_split[name]))][0]
    return [clip for clip in clips if clip.source == first.source] if split.by == "log" else [first]


def split_key(name: str, index: int, split: SplitConfig) -> str:
    """What the split of clip ``index`` of log ``name`` is drawn for: the log or the clip."""
    return name if split.by == "log" else f"{name}/{index}"
