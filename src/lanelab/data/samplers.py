"""Temporal samplers: which windows of frames every rank loads at every step.

Both samplers yield this rank's :class:`SampleKey` step by step, ``batch_size`` keys per step,
for ``DataLoader(dataset, sampler=..., batch_size=batch_size)`` to batch (slot b of every batch
is the same stream when streaming). They are per-sample samplers rather than batch samplers
because Lightning calls ``set_epoch`` only on ``loader.sampler`` (or a batch sampler's
``.sampler``) and, to predict, rebuilds the batch sampler around ``loader.sampler``. Rules:

- Distributed: ``rank`` / ``world_size`` are given or read from ``torch.distributed`` (else 0 / 1).
  Every rank gets the same number of full batches, so collectives never wait on a rank that ran
  out of data; the shortfall is made up of padding samples (``SampleKey.padding``) that repeat
  real ones and that metrics skip.
- Deterministic: the order depends only on (seed, epoch); call ``set_epoch`` before each epoch
  (Lightning does). Every rank computes the same global plan and takes its share of it.
- Fixed epoch length: ``num_steps`` (and ``len(sampler) = num_steps * batch_size``) is the same
  for every epoch and every rank (Lightning computes the validation interval once).

Use them with ``Trainer(use_distributed_sampler=False)``: Lightning must not shard them again.
"""

from __future__ import annotations

import heapq
import math
from typing import Iterator

import numpy as np
import torch.distributed as dist
from torch.utils.data import Sampler

from lanelab.data.frame_index import FrameIndex, SampleKey, consecutive_offsets


def resolve_rank(rank: int | None = None, world_size: int | None = None) -> tuple[int, int]:
    """(rank, world_size): the given values, else torch.distributed's, else (0, 1)."""
    initialized = dist.is_available() and dist.is_initialized()
    if world_size is None:
        world_size = dist.get_world_size() if initialized else 1
    if rank is None:
        rank = dist.get_rank() if initialized else 0
    if not 0 <= rank < world_size:
        raise ValueError(f"rank {rank} is outside 0..{world_size - 1}")
    return rank, world_size


class _TemporalSampler(Sampler[SampleKey]):
    """What both samplers share: the index, this rank's place, the (seed, epoch) generator, and
    yielding the steps of :meth:`_steps` one key after another. Subclasses set ``num_steps``."""

    num_steps: int

    def __init__(
        self,
        index: FrameIndex,
        batch_size: int,
        num_frames: int,
        seed: int,
        rank: int | None,
        world_size: int | None,
        flip: bool,
    ) -> None:
        if batch_size < 1 or num_frames < 1:
            raise ValueError(f"batch_size and num_frames must be >= 1, got {batch_size} and {num_frames}")
        self.index = index
        self.batch_size = batch_size
        self.num_frames = num_frames
        self.seed = seed
        self.rank, self.world_size = resolve_rank(rank, world_size)
        self.flip = flip
        self.epoch = 0

    def set_epoch(self, epoch: int) -> None:
        self.epoch = epoch

    def __len__(self) -> int:
        return self.num_steps * self.batch_size

    def __iter__(self) -> Iterator[SampleKey]:
        for step in self._steps():
            yield from step

    def _steps(self) -> Iterator[list[SampleKey]]:
        """This rank's batches of the current epoch, ``num_steps`` lists of ``batch_size`` keys."""
        raise NotImplementedError

    def _rng(self, *key: int) -> np.random.Generator:
        return np.random.default_rng([self.seed, *key])


class WindowSampler(_TemporalSampler):
    """Random windows: every target frame is the current frame of exactly one sample per epoch.

    Targets are the labeled frames (``targets="labeled"``) or all frames (``"all"``). A sample
    is the target plus ``num_frames - 1`` past frames chosen from a window of ``window`` past
    frames, thinned to every ``stride``-th (candidates: stride, 2 stride, ... <= window frames
    back; window None: (num_frames - 1) * stride):

    - ``history="nearest"``: the nearest candidates. Bi²Lane (Sec. IV-A.2) uses "a time window
      of 5 and ... the 3 nearest frames to the current frame as historical frames", in training
      and testing: num_frames=4, window=5. Anchor3DLane-T, whose pipeline Bi²Lane builds on,
      tests with a stride (its ``prev_step``).
    - ``history="random"``: distinct candidates drawn at random per sample and epoch, as
      Anchor3DLane-T trains (``prev_num`` of the last ``prev_range`` frames).

    Past frames before the clip's first frame are padded by the dataset (the first frame
    repeated, masked invalid). Per epoch the targets are shuffled (``shuffle``), cycled to fill
    ``ceil(targets / (world_size * batch_size))`` steps of full batches on every rank (the
    repeats are padding samples), and dealt out batch by batch: step i, rank r gets samples
    ``[(i * world_size + r) * batch_size, ... + batch_size)``. Windows are independent, so
    every sample has ``reset=True``.
    """

    def __init__(
        self,
        index: FrameIndex,
        batch_size: int,
        num_frames: int,
        *,
        history: str,
        window: int | None,
        stride: int,
        targets: str,
        shuffle: bool,
        seed: int,
        rank: int | None,
        world_size: int | None,
        flip: bool,
    ) -> None:
        super().__init__(index, batch_size, num_frames, seed, rank, world_size, flip)
        if history not in ("nearest", "random"):
            raise ValueError(f"history must be 'nearest' or 'random', got {history!r}")
        if targets not in ("labeled", "all"):
            raise ValueError(f"targets must be 'labeled' or 'all', got {targets!r}")
        if stride < 1:
            raise ValueError(f"stride must be >= 1, got {stride}")
        num_past = num_frames - 1
        window = num_past * stride if window is None else window
        self.candidates = np.arange(stride, window + 1, stride)
        if len(self.candidates) < num_past:
            raise ValueError(
                f"a window of {window} frames with stride {stride} has {len(self.candidates)} "
                f"past frames to choose from; num_frames={num_frames} needs {num_past}"
            )
        self.history = history
        self.shuffle = shuffle
        self.targets = np.flatnonzero(index.labeled) if targets == "labeled" else np.arange(len(index))
        if len(self.targets) == 0:
            raise ValueError(f"no {targets} frames to sample from")
        self.num_steps = math.ceil(len(self.targets) / (self.world_size * batch_size))

    def _past_offsets(self, rng: np.random.Generator, num_samples: int) -> np.ndarray:
        """(num_samples, num_frames - 1) past-frame offsets, oldest first."""
        num_past = self.num_frames - 1
        if self.history == "nearest":
            chosen = np.broadcast_to(self.candidates[:num_past], (num_samples, num_past))
        else:
            ranks = rng.random((num_samples, len(self.candidates))).argsort(axis=1)
            chosen = self.candidates[ranks[:, :num_past]]
        return -np.sort(-chosen, axis=1)

    def _steps(self) -> Iterator[list[SampleKey]]:
        rng = self._rng(self.epoch)
        order = rng.permutation(self.targets) if self.shuffle else self.targets
        total = self.num_steps * self.world_size * self.batch_size
        frames = order[np.arange(total) % len(order)]
        padding = np.arange(total) >= len(order)
        offsets = np.concatenate([self._past_offsets(rng, total), np.zeros((total, 1), int)], axis=1)
        flips = (rng.random(total) < 0.5) & self.flip

        mine = np.arange(total).reshape(self.num_steps, self.world_size, self.batch_size)[:, self.rank]
        for step in mine:
            yield [SampleKey(int(frames[i]), tuple(map(int, offsets[i])), True, bool(padding[i]), bool(flips[i]))
                   for i in step]  # fmt: skip


class StreamSampler(_TemporalSampler):
    """StreamPETR-style streaming: ``batch_size`` parallel streams per rank, one frame per step.

    Each stream walks its clips in temporal order; a batch holds the next frame of each of this
    rank's streams. ``SampleKey.reset`` marks where a model's memory must be cleared: the first
    frame of a stream's clip (or clip piece), and the first step of every epoch. With
    ``num_frames > 1`` each step is the window of consecutive frames ending at the stream's frame.

    A *pass* visits every frame of the index exactly once, spread over the
    S = world_size * batch_size streams of all ranks (rank r owns streams r*B .. r*B + B - 1),
    clips in an order shuffled per pass (``shuffle``):

    - ``split_clips=True`` (training): the clips, one after another, are cut into S contiguous
      pieces whose lengths differ by at most one (StreamPETR likewise splits scenes into
      sub-sequences). Perfectly balanced: a pass has ``ceil(N / S)`` steps, at most S - 1
      padding samples, and a memory reset where a cut falls inside a clip.
    - ``split_clips=False`` (evaluation): whole clips go to streams, longest first, each to the
      stream with the fewest frames so far, so every clip is seen from its first frame as in
      deployment. A pass has as many steps as the longest stream; that number depends on the
      clip lengths only, not on the shuffle, so it is the same every pass.

    Streams shorter than the pass repeat their last frame as padding (``SampleKey.padding``).
    An epoch is ``steps_per_epoch`` steps (None: one pass) of an endless walk through pass
    after pass (pass p shuffled with (seed, p)): with None, epoch e is pass e; shorter or
    longer epochs continue where the previous one stopped, so every frame is still visited once
    per pass.
    """

    def __init__(
        self,
        index: FrameIndex,
        batch_size: int,
        num_frames: int,
        *,
        steps_per_epoch: int | None,
        split_clips: bool,
        shuffle: bool,
        seed: int,
        rank: int | None,
        world_size: int | None,
        flip: bool,
    ) -> None:
        super().__init__(index, batch_size, num_frames, seed, rank, world_size, flip)
        self.offsets = consecutive_offsets(num_frames)
        self.split_clips = split_clips
        self.shuffle = shuffle
        self.num_streams = self.world_size * batch_size
        self.pass_length = max(sum(stop - start for start, stop in s) for s in self._streams(0))
        if steps_per_epoch is not None and steps_per_epoch < 1:
            raise ValueError(f"steps_per_epoch must be >= 1, got {steps_per_epoch}")
        self.num_steps = steps_per_epoch or self.pass_length

    def _streams(self, pass_number: int) -> list[list[tuple[int, int]]]:
        """Per stream, its (start, stop) global frame ranges in walking order, for one pass."""
        rng = self._rng(pass_number)
        starts, lengths = self.index.starts[:-1], self.index.clip_lengths
        order = rng.permutation(self.index.num_clips) if self.shuffle else np.arange(self.index.num_clips)
        if self.split_clips:
            return _cut(starts[order], lengths[order], self.num_streams)
        order = order[np.argsort(-lengths[order], kind="stable")]
        streams = _longest_first(starts[order], lengths[order], self.num_streams)
        return [[s[i] for i in rng.permutation(len(s))] if self.shuffle else s for s in streams]

    def _pass(self, pass_number: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """frames, reset, padding, flip: (S, pass_length) int64 / bool / bool / bool for one pass.
        A clip piece is mirrored as a whole (flip), so the memory never mixes both sides."""
        shape = (self.num_streams, self.pass_length)
        frames = np.zeros(shape, np.int64)
        reset = np.zeros(shape, bool)
        padding = np.ones(shape, bool)
        flip = np.zeros(shape, bool)
        flip_rng = self._rng(pass_number, 1)
        for s, ranges in enumerate(self._streams(pass_number)):
            lengths = [stop - start for start, stop in ranges]
            walk = np.concatenate([np.arange(start, stop) for start, stop in ranges] or [np.zeros(1, int)])
            steps = np.minimum(np.arange(self.pass_length), len(walk) - 1)
            frames[s] = walk[steps]
            reset[s, np.cumsum([0] + lengths[:-1])] = True
            padding[s, : sum(lengths)] = False
            pieces = np.repeat((flip_rng.random(len(lengths)) < 0.5) & self.flip, lengths)
            flip[s] = pieces[steps] if len(pieces) else False
        return frames, reset, padding, flip

    def _steps(self) -> Iterator[list[SampleKey]]:
        start = self.epoch * self.num_steps
        first_pass, last_pass = start // self.pass_length, (start + self.num_steps - 1) // self.pass_length
        begin = start - first_pass * self.pass_length
        mine = slice(self.rank * self.batch_size, (self.rank + 1) * self.batch_size)
        plan = [self._pass(p) for p in range(first_pass, last_pass + 1)]
        frames, reset, padding, flip = (
            np.concatenate(arrays, axis=1)[mine, begin : begin + self.num_steps].T for arrays in zip(*plan)
        )
        reset[0] = True  # memory does not carry over from the previous epoch (validation ran between)
        for f, r, p, m in zip(frames, reset, padding, flip):
            yield [SampleKey(int(fi), self.offsets, bool(ri), bool(pi), bool(mi)) for fi, ri, pi, mi in zip(f, r, p, m)]


def _cut(starts: np.ndarray, lengths: np.ndarray, num_streams: int) -> list[list[tuple[int, int]]]:
    """Cut clips (in this order) into num_streams contiguous pieces, lengths differing by <= 1."""
    total = int(lengths.sum())
    sizes = [total // num_streams + (s < total % num_streams) for s in range(num_streams)]
    clips = iter(zip(starts.tolist(), (starts + lengths).tolist()))
    start, stop = next(clips)
    streams = []
    for size in sizes:
        ranges = []
        while size > 0:
            take = min(size, stop - start)
            ranges.append((start, start + take))
            start, size = start + take, size - take
            if start == stop:
                start, stop = next(clips, (0, 0))
        streams.append(ranges)
    return streams


def _longest_first(starts: np.ndarray, lengths: np.ndarray, num_streams: int) -> list[list[tuple[int, int]]]:
    """Whole clips (in this order) each to the stream with the fewest frames so far (ties: lowest)."""
    streams: list[list[tuple[int, int]]] = [[] for _ in range(num_streams)]
    loads = [(0, s) for s in range(num_streams)]
    for start, length in zip(starts.tolist(), lengths.tolist()):
        load, s = heapq.heappop(loads)
        streams[s].append((start, start + length))
        heapq.heappush(loads, (load + length, s))
    return streams
