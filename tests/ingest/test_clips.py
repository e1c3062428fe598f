"""Cutting frames into clips, target frame rates and split draws."""

from __future__ import annotations

from collections import Counter

import numpy as np

from data_ingest.ingest.clips import cut, draw_split, log_name, split_key, subsample
from data_ingest.ingest.config import SplitConfig

MS = 1_000_000


def test_cut_at_gaps_and_into_equal_parts_no_longer_than_the_maximum():
    stamps = np.array([0, 100, 200, 900, 1000, *range(2000, 4600, 100)]) * MS
    clips = cut(stamps, gap_s=0.5, max_length_s=1.0)
    lengths = [(stamps[c][-1] - stamps[c][0]) / 1e9 for c in clips]
    assert [c.start for c in clips] == [0, 3, 5, 14, 22] and clips[-1].stop == len(stamps)
    assert max(lengths) <= 1.0 and lengths[2:] == [0.8, 0.7, 0.8]  # 2.5 s cut in 3 parts of 0.83 s


def test_subsample_keeps_the_target_rate_despite_jitter():
    stamps = (np.arange(30) * 1e9 / 30 + np.random.default_rng(0).uniform(-3e6, 3e6, 30)).astype(np.int64)
    keep = subsample(stamps, 10.0)
    assert keep.sum() == 10 and np.all(np.diff(stamps[keep]) > 0.075e9)
    assert subsample(stamps, None).all()


def test_splits_follow_the_ratios_and_never_change():
    split = SplitConfig(by="clip", seed=0, train=0.8, val=0.1, test=0.1)
    draws = Counter(draw_split(split_key("log", i, split), split) for i in range(2000))
    assert abs(draws["train"] / 2000 - 0.8) < 0.03 and abs(draws["val"] / 2000 - 0.1) < 0.02
    assert [draw_split(split_key("log", i, split), split) for i in range(5)] == \
        [draw_split(split_key("log", i, split), split) for i in range(5)]
    by_log = SplitConfig(by="log", seed=0, train=0.5, val=0.5, test=0.0)
    assert len({draw_split(split_key("drive_7", i, by_log), by_log) for i in range(50)}) == 1


def test_log_names_are_safe_in_file_names():
    assert log_name("2026-05-01 run #3") == "2026-05-01_run_3"
