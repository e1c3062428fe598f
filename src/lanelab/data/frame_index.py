"""Which frames a sample is made of: a global numbering of the frames of a split, and sample keys.

A :class:`FrameIndex` numbers the frames of a list of clips 0..N-1, clip after clip, each clip in
time order. Samplers speak in these numbers and hand the dataset :class:`SampleKey` objects; the
dataset turns a key into a window of frames. Neither side needs to know the other's rules.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple, Sequence

import numpy as np

from lanelab.store import ClipStore


class SampleKey(NamedTuple):
    """What a sampler asks the dataset for: the window of frames that ends at ``frame``.

    frame: global index (in a :class:`FrameIndex`) of the current frame.
    offsets: how many frames back each frame of the window lies, oldest first; the last is 0.
        A window reaching back past its clip's first frame is padded there (see the dataset).
    reset: the model's memory of earlier samples must be cleared before this one.
    padding: the sample repeats another only to keep ranks and streams the same length;
        metrics must skip it.
    flip: mirror the sample left to right (training augmentation; the dataset mirrors the
        images, cameras, poses and lanes alike).
    """

    frame: int
    offsets: tuple[int, ...]
    reset: bool
    padding: bool = False
    flip: bool = False


def consecutive_offsets(num_frames: int) -> tuple[int, ...]:
    """Offsets of a window of ``num_frames`` consecutive frames: (F - 1, ..., 1, 0)."""
    if num_frames < 1:
        raise ValueError(f"a window needs at least one frame, got num_frames={num_frames}")
    return tuple(range(num_frames - 1, -1, -1))


@dataclass(frozen=True)
class FrameIndex:
    """Frames of clips numbered globally: clip c holds frames ``starts[c]`` to ``starts[c + 1] - 1``.

    clip_ids: (C,) the clips, in the order they are numbered.
    starts: (C + 1,) int64, cumulative frame counts (starts[0] = 0, starts[C] = N).
    labeled: (N,) bool, whether a frame has lane labels.
    timestamp_ns: (N,) int64 sensor time of each frame.
    """

    clip_ids: tuple[str, ...]
    starts: np.ndarray
    labeled: np.ndarray
    timestamp_ns: np.ndarray

    @classmethod
    def from_clips(cls, clips: list[tuple[str, np.ndarray, np.ndarray]]) -> FrameIndex:
        """Build from (clip_id, labeled (n,) bool, timestamp_ns (n,) int64) per clip, in order."""
        if not clips:
            raise ValueError("a frame index needs at least one clip")
        if any(len(labeled) == 0 for _, labeled, _ in clips):
            raise ValueError("a clip without frames cannot be indexed")
        return cls(
            clip_ids=tuple(clip_id for clip_id, _, _ in clips),
            starts=np.cumsum([0] + [len(labeled) for _, labeled, _ in clips], dtype=np.int64),
            labeled=np.concatenate([np.asarray(labeled, bool) for _, labeled, _ in clips]),
            timestamp_ns=np.concatenate([np.asarray(t, np.int64) for _, _, t in clips]),
        )

    @classmethod
    def from_store(cls, store: ClipStore, clip_ids: Sequence[str]) -> FrameIndex:
        """Index these clips of a store, reading only their small columns."""
        timelines = [store.read_timeline(c) for c in clip_ids]
        return cls.from_clips([(c, labeled, stamps) for c, (stamps, labeled) in zip(clip_ids, timelines)])

    def __len__(self) -> int:
        return int(self.starts[-1])

    @property
    def num_clips(self) -> int:
        return len(self.clip_ids)

    @property
    def clip_lengths(self) -> np.ndarray:
        """(C,) int64 frames per clip."""
        return np.diff(self.starts)

    def clip_of(self, frames: np.ndarray | int) -> np.ndarray:
        """Clip number of global frame indices (any shape)."""
        return np.searchsorted(self.starts, frames, side="right") - 1

    def locate(self, frame: int) -> tuple[int, int]:
        """(clip number, position within the clip) of a global frame index."""
        if not 0 <= frame < len(self):
            raise IndexError(f"frame {frame} is outside 0..{len(self) - 1}")
        clip = int(self.clip_of(frame))
        return clip, frame - int(self.starts[clip])

    def is_clip_start(self, frames: np.ndarray | int) -> np.ndarray:
        """Whether global frame indices (any shape) are the first frame of their clip."""
        return np.isin(frames, self.starts[:-1])
