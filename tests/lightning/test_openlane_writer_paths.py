"""Issue 37, case 1: the OpenLaneWriter (lanelab-eval and lanelab-train's evaluation) writes a
frame's files under its ``file_path`` from the store; one that leads out of the output folder
(a store written before ingest refused such tags) stops it with one line naming the clip file,
the frame and the value, and nothing appears outside."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest
import torch
from tiny_setup import build_store, frame_record

from lanelab.lightning import OpenLaneWriter, PredictionBatch
from lanelab.lightning.predictions import DenseLanes
from lanelab.openlane.file_paths import FILE_PATH_TAG
from lanelab.store import ClipFileError, ClipStore, write_clip


def one_lane_batch(clip_id: str, index: int, file_path: str) -> PredictionBatch:
    y = torch.arange(5.0, 10.0)
    points = torch.stack([torch.zeros(5), y, torch.zeros(5)], -1)[None, None]
    lanes = DenseLanes(points, torch.ones(1, 1, 5), torch.tensor([[2]]), torch.ones(1, 1),
                       torch.ones(1, 1, dtype=torch.bool), 0.5)  # fmt: skip
    return PredictionBatch([file_path], [clip_id], torch.tensor([index]), torch.tensor([True]), lanes)


@pytest.mark.parametrize("kind", ["relative", "absolute"])
def test_a_store_frame_whose_file_path_leads_out_is_refused(tmp_path: Path, kind: str) -> None:
    outside = tmp_path / "outside"
    file_path = {"relative": "../" * (len(tmp_path.parts) + 3) + f"{outside.relative_to('/')}/rel.jpg",
                 "absolute": str(outside / "abs.jpg")}[kind]
    store = build_store(tmp_path / "store", [3])
    frames = [frame_record(0, p) for p in range(3)]
    frames[1] = dataclasses.replace(frames[1], tags={FILE_PATH_TAG: file_path})
    write_clip(store, "clip00", frames)

    writer = OpenLaneWriter(tmp_path / "ev", ground_truth=store)
    writer.write_on_batch_end(None, None, one_lane_batch("clip00", 0, "clip00/0.jpg"), None, None, 0, 0)
    with pytest.raises(ClipFileError) as caught:
        writer.write_on_batch_end(None, None, one_lane_batch("clip00", 1, file_path), None, None, 1, 0)
    assert str(caught.value).startswith(f"{ClipStore(store).clip_path('clip00')}: frame 1: file_path {file_path!r}")
    assert "refused" in str(caught.value) and "\n" not in str(caught.value)
    assert not outside.exists()
    assert (tmp_path / "ev" / "predictions" / "clip00" / "0.json").is_file()  # what was written stays
