"""Few clips and empty splits: one clip goes to train where the others leave it empty, and the
ingest summary names a split without clips."""

from __future__ import annotations

import pytest

from data_ingest.ingest.clips import clips_for_train
from data_ingest.ingest.config import SplitConfig
from data_ingest.ingest.summary import print_summary
from lanelab.store import ClipEntry, Manifest


def split_config(by: str = "clip", train: float = 0.8, val: float = 0.1, test: float = 0.1) -> SplitConfig:
    return SplitConfig(by=by, seed=0, train=train, val=val, test=test)


def clip(clip_id: str, split: str, source: str = "") -> ClipEntry:
    return ClipEntry(clip_id, source or clip_id.split("_")[0], split, 10, 0, 900_000_000)


@pytest.mark.parametrize(
    ("splits", "moved"),
    [
        ({"a_0": "val", "b_0": "val"}, ["a_0"]),  # both drew val: the first goes to train
        ({"a_0": "val", "b_0": "test"}, ["b_0"]),  # a tie: test gives one up, val is what training needs
        ({"a_0": "test", "b_0": "test", "c_0": "val"}, ["a_0"]),
        ({"a_0": "train", "b_0": "val"}, []),  # train has a clip
        ({"a_0": "val"}, []),  # one clip: it stays for evaluation
    ],
)
def test_a_clip_moves_to_an_empty_train_split_where_it_can(splits: dict[str, str], moved: list[str]) -> None:
    clips = [clip(clip_id, split) for clip_id, split in splits.items()]
    assert [c.clip_id for c in clips_for_train(clips, split_config())] == moved


def test_split_by_log_moves_a_whole_log_and_a_store_without_train_share_moves_nothing() -> None:
    clips = [clip("a_0", "val", "a"), clip("a_1", "val", "a"), clip("b_0", "val", "b")]
    assert [c.clip_id for c in clips_for_train(clips, split_config("log"))] == ["a_0", "a_1"]
    assert clips_for_train(clips, split_config("log", 0.0, 0.0, 1.0)) == []


def test_the_summary_warns_of_an_empty_split_and_names_a_moved_clip(capsys: pytest.CaptureFixture[str]) -> None:
    manifest = Manifest(clips=[clip("a_0", "train"), clip("b_0", "val")])
    print_summary([], manifest, 1.0, split_config(), moved=[clip("a_0", "test")])
    out = capsys.readouterr().out
    assert "note: no clip drew the train split; moved there from test: a_0" in out
    assert "warning: no clip in split test: lanelab-train needs train and val clips" in out and "split.by=clip" in out
    print_summary([], manifest, 1.0, split_config("clip", 0.5, 0.5, 0.0))
    assert "warning" not in capsys.readouterr().out  # no share for test: nothing missing
