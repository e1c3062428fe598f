"""A log's frames, ready to use: read (:mod:`scan`), completed (:mod:`assemble`) and thinned to
``clips.target_fps`` (:func:`~data_ingest.ingest.clips.subsample`). What lanelab-ingest cuts
into clips and lanelab-predict runs a model over, read the same way by both."""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from data_ingest.ingest.assemble import PlannedFrame, assemble
from data_ingest.ingest.clips import subsample
from data_ingest.ingest.config import LogReading
from data_ingest.ingest.errors import LogError
from data_ingest.ingest.mcap_reader import ReadReport
from data_ingest.ingest.scan import LogContents, scan_log
from data_ingest.ingest.spill import Spill


@dataclass
class LogFrames:
    """The usable frames of a log in time order (image bytes in the spill), the frames
    dropped by reason, and the log's problems that did not drop a frame, one line each."""

    frames: list[PlannedFrame] = field(default_factory=list)
    dropped: Counter = field(default_factory=Counter)
    warnings: list[str] = field(default_factory=list)

    def unusable(self, path: Path) -> LogError:
        """The error of a log without a usable frame, with the reasons its frames were dropped."""
        reasons = "; ".join(f"{n} x {reason}" for reason, n in self.dropped.most_common())
        return LogError(f"{path}: no usable frame" + (f" ({reasons})" if reasons else " (no images)"))


# Labels made anew from a log's frames and contents (auto-labeling): frames, contents and the
# warnings list to add to -> the frames with their new labels.
Relabel = Callable[[list[PlannedFrame], LogContents, list[str]], list[PlannedFrame]]


def read_frames(path: Path, cfg: LogReading, spill: Spill, report: ReadReport,
                progress: Callable[[int], None] | None = None, relabel: Relabel | None = None) -> LogFrames:
    """Read the log at ``path`` into frames; ``progress(n)`` gets the bytes read since its last call.
    relabel, if given, replaces the frames' labels before they are thinned (its log's 2D
    detections and occluder masks are read for it).

    Raises :class:`LogError` for a log that cannot be used at all (not MCAP, a required topic
    missing, an unknown schema, a TF tree that never connects world, ego and camera).
    """
    contents = scan_log(path, cfg, spill, report, progress, detections=relabel is not None)
    warnings = [f"{n} message(s) skipped on {reason}" for reason, n in sorted(contents.bad_messages.items())]
    assembled = assemble(path, contents, cfg)
    frames, dropped = assembled.frames, assembled.dropped
    warnings += assembled.notes
    if relabel is not None and frames:
        frames = relabel(frames, contents, warnings)
    keep = subsample(np.array([f.record.timestamp_ns for f in frames], dtype=np.int64), cfg.clips.target_fps)
    if not keep.all():
        dropped[f"left out for clips.target_fps={cfg.clips.target_fps}"] += int((~keep).sum())
        frames = [frame for frame, kept in zip(frames, keep) if kept]
    return LogFrames(frames, dropped, warnings)
