"""Issue 37, cases 3 and 5: /tf that cannot place a frame. A sensor clock that jumps back (every
stamp after 1 s moved back 0.5 s, /tf too) makes the times it claims twice ambiguous: their
frames are dropped, the others keep their true poses. A hole in /tf longer than
``tolerances.max_tf_gap_s`` is never bridged: the frames in it are dropped and counted."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Any, Callable

import numpy as np
from ingest_helpers import START_NS, ingest_into, read_log, write_log

from lanelab.store import ClipStore

AMBIGUOUS = ("no ego pose: TF odom -> base_link is ambiguous at the image time (its stamps go back in time, "
             "or disagree at one stamp)")
REPEATED = "repeated image timestamp (the first image kept)"
ACROSS_GAP = ("no ego pose: TF odom -> base_link would be interpolated across a gap between samples longer than "
              "tolerances.max_tf_gap_s=0.5")


def stamp_ns(stamp: dict[str, int]) -> int:
    return stamp["sec"] * 1_000_000_000 + stamp["nsec"]


def restamped(value: Any, shift: Callable[[int], int]) -> Any:
    """A Foxglove JSON message with every ``timestamp`` t replaced by shift(t)."""
    if isinstance(value, dict):
        value = {key: restamped(item, shift) for key, item in value.items()}
        if isinstance(value.get("timestamp"), dict) and "sec" in value["timestamp"]:
            t = shift(stamp_ns(value["timestamp"]))
            value["timestamp"] = {"sec": t // 1_000_000_000, "nsec": t % 1_000_000_000}
        return value
    return [restamped(item, shift) for item in value] if isinstance(value, list) else value


def poses(store: Path) -> dict[int, np.ndarray]:
    clips = ClipStore(store)
    return {f.timestamp_ns: f.T_world_lane for clip in clips.clips for f in clips.read_frames(clip.clip_id)}


def test_a_clock_that_jumps_back_drops_the_frames_it_makes_ambiguous(tmp_path, synth_log):
    log = synth_log("foxglove-json")
    jump, back = START_NS + 1_000_000_000, 500_000_000

    def shift(t: int) -> int:
        return t - back if t > jump else t

    messages = [dataclasses.replace(m, data=json.dumps(restamped(json.loads(m.data), shift)).encode())
                for m in read_log(log)]
    (result,) = ingest_into(tmp_path / "jumped", write_log(tmp_path / "jumped.mcap", messages))

    # Images 0-1.0 s, then 1.1-1.9 s stamped 0.6-1.4 s: 0.6-1.0 s is claimed twice.
    assert result.status == "ingested" and result.num_frames == 10
    assert result.dropped == {REPEATED: 5, AMBIGUOUS: 5}
    assert any(w.startswith("TF odom -> base_link: 24 sample(s) stamped before one received earlier and off the "
                            "others' path (largest step back 0.480 s, at ") and "the clock jumped back?" in w
               for w in result.warnings)
    ingest_into(tmp_path / "true", log)
    truth, kept = poses(tmp_path / "true"), poses(tmp_path / "jumped")
    assert sorted(kept) == [START_NS + k * 100_000_000 for k in [*range(6), *range(11, 15)]]
    for stamp, pose in kept.items():  # every kept frame has its true pose (after the jump: its true time's)
        np.testing.assert_allclose(pose, truth[stamp + (back if stamp > START_NS + 500_000_000 else 0)], atol=1e-6)


def test_a_hole_in_tf_longer_than_the_tolerance_drops_its_frames(tmp_path, synth_log):
    log = synth_log("foxglove-json")
    hole = (START_NS + 500_000_000, START_NS + 1_500_000_000)
    messages = [m for m in read_log(log)
                if not (m.topic == "/tf" and hole[0] < stamp_ns(json.loads(m.data)["transforms"][0]["timestamp"])
                        < hole[1])]
    holed = write_log(tmp_path / "holed.mcap", messages)
    (result,) = ingest_into(tmp_path / "store", holed)
    assert result.status == "ingested" and result.num_frames == 11  # 0.6-1.4 s would be interpolated across 1 s
    assert result.dropped == {ACROSS_GAP: 9}
    assert sorted(poses(tmp_path / "store")) == [START_NS + k * 100_000_000 for k in [*range(6), *range(15, 20)]]

    (result,) = ingest_into(tmp_path / "bridged", holed, "tolerances.max_tf_gap_s=null")  # as before: bridged
    assert result.status == "ingested" and result.num_frames == 20 and not result.dropped
