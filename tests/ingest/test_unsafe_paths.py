"""Issue 37, case 1: a path a log names (the ``openlane.file_path`` tag) never decides where a
file is written. The ingestor refuses the frames whose tag is absolute or climbs out of its
folder, names the value and the frames, and keeps the others; nothing appears outside."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

from ingest_helpers import START_NS, ingest_into, read_log, write_log

from lanelab.openlane.file_paths import FILE_PATH_TAG
from lanelab.store import ClipStore

TAGS = "/tags"
REASON = f"tag {FILE_PATH_TAG} on {TAGS} is absolute or leads out of its folder"


def with_file_paths(log: Path, out: Path, file_paths: dict[int, str]) -> Path:
    """The log with the tags message of frame k (its k-th on /tags) given file_paths[k]."""
    messages, k = [], 0
    for m in read_log(log):
        if m.topic == TAGS:
            if k in file_paths:
                tags = json.loads(m.data)
                tags["tags"][FILE_PATH_TAG] = file_paths[k]
                m = dataclasses.replace(m, data=json.dumps(tags).encode())
            k += 1
        messages.append(m)
    return write_log(out, messages)


def test_tags_naming_paths_outside_the_folder_refuse_their_frames(tmp_path, synth_log):
    outside = tmp_path / "outside"
    relative = "../" * (len(tmp_path.parts) + 2) + f"{outside.relative_to('/')}/rel.jpg"
    absolute = str(outside / "abs.jpg")
    log = with_file_paths(synth_log("foxglove-json"), tmp_path / "paths.mcap",
                          {3: relative, 5: "segment-1/5.jpg", 7: absolute})
    (result,) = ingest_into(tmp_path / "store", log)

    assert result.status == "ingested" and result.num_frames == 18
    assert result.dropped == {REASON: 2}
    for value, problem, stamp in [(relative, "climbs out of its folder ('..')", 3), (absolute, "is absolute", 7)]:
        assert any(f"tag {FILE_PATH_TAG} {value!r} {problem}: the 1 frame(s) it names (at "
                   f"{(START_NS + stamp * 100_000_000) / 1e9:.3f} s) are refused" in w for w in result.warnings)
    store = ClipStore(tmp_path / "store")
    stored = [tags.get(FILE_PATH_TAG) for clip in store.clips for _, tags in store.read_tags(clip.clip_id)]
    assert stored.count("segment-1/5.jpg") == 1 and relative not in stored and absolute not in stored
    assert not outside.exists()
