"""Temporal samplers: coverage, padding, ordering, reset flags, equal lengths, determinism.

Ranks are simulated by building one sampler per (rank, world_size).
"""

from __future__ import annotations

from collections import Counter

import numpy as np
import pytest

from lanelab.data.frame_index import FrameIndex, SampleKey
from lanelab.data.samplers import StreamSampler, WindowSampler, resolve_rank

CLIP_LENGTHS = [5, 12, 3, 9, 1, 7, 4]  # 41 frames, uneven on purpose (a one-frame clip too)
# The samplers' training settings (conf/sampler/*.yaml has them; window None: as many frames
# back as the sample needs), which a test changes where it says so; one process.
WINDOW = {"history": "nearest", "window": None, "stride": 1, "targets": "labeled", "shuffle": True, "seed": 0,
          "rank": 0, "world_size": 1, "flip": False}  # fmt: skip
STREAM = {"num_frames": 1, "steps_per_epoch": None, "split_clips": True, "shuffle": True, "seed": 0, "rank": 0,
          "world_size": 1, "flip": False}  # fmt: skip


def window_sampler(index: FrameIndex, batch_size: int, num_frames: int, **options) -> WindowSampler:
    return WindowSampler(index, batch_size, num_frames, **{**WINDOW, **options})


def stream_sampler(index: FrameIndex, batch_size: int, **options) -> StreamSampler:
    return StreamSampler(index, batch_size, **{**STREAM, **options})


def make_index(lengths=CLIP_LENGTHS, label_every=2) -> FrameIndex:
    return FrameIndex.from_clips([
        (f"c{c}", np.arange(n) % label_every == 0, c * 10**12 + np.arange(n) * 10**8)
        for c, n in enumerate(lengths)
    ])


def epoch_of(make_sampler, world_size, epoch=0, **kwargs) -> list[list[list[SampleKey]]]:
    """Per rank, the batches of one epoch (the sampler's keys in steps of batch_size)."""
    ranks = []
    for rank in range(world_size):
        sampler = make_sampler(rank=rank, world_size=world_size, **kwargs)
        sampler.set_epoch(epoch)
        keys = list(sampler)
        assert len(keys) == len(sampler) == sampler.num_steps * sampler.batch_size
        ranks.append([keys[i : i + sampler.batch_size] for i in range(0, len(keys), sampler.batch_size)])
    return ranks


def real_frames(ranks) -> Counter:
    return Counter(key.frame for batches in ranks for batch in batches for key in batch if not key.padding)


# --- window --------------------------------------------------------------------------------

@pytest.mark.parametrize("world_size", [1, 2, 3])
@pytest.mark.parametrize("targets", ["labeled", "all"])
def test_window_covers_every_target_once(world_size, targets):
    index, batch_size = make_index(), 4
    ranks = epoch_of(window_sampler, world_size, index=index, batch_size=batch_size, num_frames=3, targets=targets)
    expected = np.flatnonzero(index.labeled) if targets == "labeled" else np.arange(len(index))

    assert real_frames(ranks) == Counter(expected.tolist())
    # Equal steps on every rank, full batches only; the shortfall is padding, fewer than one round.
    assert len({len(batches) for batches in ranks}) == 1
    assert all(len(batch) == batch_size for batches in ranks for batch in batches)
    num_padding = sum(key.padding for batches in ranks for batch in batches for key in batch)
    assert num_padding == len(ranks[0]) * world_size * batch_size - len(expected) < world_size * batch_size
    assert all(key.reset for batches in ranks for batch in batches for key in batch)


def test_window_history_nearest_is_bi2lane():
    # Bi²Lane: a window of 5 past frames, the 3 nearest used.
    sampler = window_sampler(make_index(), 2, 4, history="nearest", window=5)
    assert {key.offsets for key in sampler} == {(3, 2, 1, 0)}
    strided = window_sampler(make_index(), 2, 3, history="nearest", stride=2)
    assert {key.offsets for key in strided} == {(4, 2, 0)}


def test_window_history_random_draws_distinct_past_frames_from_the_window():
    sampler = window_sampler(make_index(), 4, 3, history="random", window=5)
    seen = set()
    for epoch in range(3):
        sampler.set_epoch(epoch)
        for key in sampler:
            *past, current = key.offsets
            assert current == 0 and len(set(past)) == 2 and all(1 <= o <= 5 for o in past)
            assert list(key.offsets) == sorted(key.offsets, reverse=True)  # oldest first
            seen.add(key.offsets)
    assert len(seen) == 10  # every pair of 5 past frames turns up


def test_window_too_small_for_the_frames_is_refused():
    with pytest.raises(ValueError, match="needs 3"):
        window_sampler(make_index(), 2, 4, window=2)


@pytest.mark.parametrize("make_sampler, kwargs", [
    (window_sampler, {"num_frames": 3, "history": "random", "window": 4}),
    (stream_sampler, {}),
])
def test_deterministic_per_seed_and_epoch(make_sampler, kwargs):
    def plan(seed, epoch):
        return epoch_of(make_sampler, 2, epoch, index=make_index(), batch_size=3, seed=seed, **kwargs)

    assert plan(0, 1) == plan(0, 1)
    assert plan(0, 1) != plan(0, 2)
    assert plan(0, 1) != plan(1, 1)


def test_eval_window_keeps_index_order():
    index = make_index()
    ranks = epoch_of(window_sampler, 2, index=index, batch_size=2, num_frames=2, targets="all", shuffle=False)
    interleaved = [key.frame for step in zip(*ranks) for batch in step for key in batch if not key.padding]
    assert interleaved == list(range(len(index)))


# --- stream --------------------------------------------------------------------------------

def check_streams(index: FrameIndex, ranks, whole_clips: bool) -> None:
    """Each stream walks frames in time order; resets exactly where a walk starts or jumps."""
    for batches in ranks:
        for stream in zip(*batches):  # slot b of every step: one stream
            previous = None
            for step, key in enumerate(stream):
                if key.padding:  # repeats the stream's last frame; a stream without frames is all padding
                    assert key.frame == previous.frame if previous else all(k.padding for k in stream)
                    assert not key.reset or step == 0
                    continue
                continues = previous is not None and key.frame == previous.frame + 1
                same_clip = continues and index.clip_of(key.frame) == index.clip_of(previous.frame)
                assert key.reset == (step == 0 or not same_clip)
                if same_clip:
                    assert index.timestamp_ns[key.frame] > index.timestamp_ns[previous.frame]
                if whole_clips:  # every clip is walked from its first frame
                    assert key.reset == bool(index.is_clip_start(key.frame))
                previous = key


@pytest.mark.parametrize("world_size", [1, 2, 3])
@pytest.mark.parametrize("split_clips", [True, False])
def test_stream_covers_every_frame_once_in_order(world_size, split_clips):
    index, batch_size = make_index(), 2
    ranks = epoch_of(stream_sampler, world_size, index=index, batch_size=batch_size, split_clips=split_clips)

    assert real_frames(ranks) == Counter(range(len(index)))
    assert len({len(batches) for batches in ranks}) == 1
    assert all(len(batch) == batch_size for batches in ranks for batch in batches)
    num_streams = world_size * batch_size
    if split_clips:  # perfectly balanced: ceil(N / S) steps
        assert len(ranks[0]) == -(-len(index) // num_streams)
    else:  # longest stream of whole clips
        assert len(ranks[0]) >= max(CLIP_LENGTHS)
    check_streams(index, ranks, whole_clips=not split_clips)


def test_stream_length_is_fixed_across_epochs():
    index = make_index()
    lengths = set()
    for split_clips in (True, False):
        sampler = stream_sampler(index, 2, split_clips=split_clips, world_size=3)
        for epoch in range(4):
            sampler.set_epoch(epoch)
            lengths.add((split_clips, len(list(sampler)), len(sampler)))
    assert len(lengths) == 2 and all(n == m for _, n, m in lengths)


def test_stream_epochs_of_any_length_continue_the_walk():
    # 41 frames over 2 ranks x 2 streams: passes of 11 steps; epochs of 4 steps run through them.
    index, world_size, steps = make_index(), 2, 4
    frames, total_steps = Counter(), 0
    for epoch in range(11):  # 44 steps = 4 passes
        ranks = epoch_of(stream_sampler, world_size, epoch, index=index, batch_size=2, steps_per_epoch=steps)
        assert all(len(batches) == steps for batches in ranks)
        assert all(key.reset for batches in ranks for key in batches[0])  # memory reset per epoch
        frames += real_frames(ranks)
        total_steps += steps
    assert frames == Counter({f: 4 for f in range(len(index))})


def test_stream_with_windows_and_more_streams_than_clips():
    index = make_index([3, 2])
    ranks = epoch_of(stream_sampler, 2, index=index, batch_size=2, num_frames=2, split_clips=False, shuffle=False)
    assert real_frames(ranks) == Counter(range(5))
    assert all(key.offsets == (1, 0) for batches in ranks for batch in batches for key in batch)
    check_streams(index, ranks, whole_clips=True)


# --- ranks ---------------------------------------------------------------------------------

def test_rank_defaults_without_torch_distributed():
    assert resolve_rank() == (0, 1)
    assert resolve_rank(2, 3) == (2, 3)
    with pytest.raises(ValueError, match="outside"):
        resolve_rank(3, 3)


def test_flips_are_drawn_per_window_and_per_stream_piece():
    """With flip=True about half the windows are mirrored; a stream mirrors each clip piece as a
    whole (the memory never sees both sides of one drive), and only where a piece starts does the
    choice change. Without it nothing is mirrored."""
    index = make_index(CLIP_LENGTHS * 20)
    (windows,) = epoch_of(window_sampler, 1, index=index, batch_size=4, num_frames=2, flip=True)
    flips = [key.flip for batch in windows for key in batch]
    assert 0.35 < np.mean(flips) < 0.65
    (steps,) = epoch_of(stream_sampler, 1, index=index, batch_size=4, flip=True)
    streams = list(zip(*steps))
    changes = [(b.flip != a.flip) for stream in streams for a, b in zip(stream, stream[1:]) if not b.padding]
    starts = [b.reset for stream in streams for a, b in zip(stream, stream[1:]) if not b.padding]
    assert any(changes) and all(start for change, start in zip(changes, starts) if change)
    (plain,) = epoch_of(stream_sampler, 1, index=index, batch_size=4)
    assert not any(key.flip for batch in plain for key in batch)
