"""``lanelab-ingest autolabel.enabled=true``: a store of auto-labels, its manifest, the quality
report, and logs that cannot be auto-labeled (named, while the others go on)."""

from __future__ import annotations

import json
import shutil

from ingest_helpers import ingest_into, read_log, write_log

from lanelab.store import ClipStore

# The small test drive is 2 s long: its labels reach some 40 m past its end, not 200 m.
SHORT = ["autolabel.enabled=true", "autolabel.range_m=60", "autolabel.min_reach_m=30", "autolabel.min_travel_m=5",
         "autolabel.min_length_m=5"]


def test_a_store_of_auto_labels_says_so_and_reports_their_quality(tmp_path, synth_log, capsys):
    store = tmp_path / "store"
    (result,) = ingest_into(store, synth_log("foxglove-json"), *SHORT)
    assert result.status == "ingested", result.error
    assert "lines tracked" in result.autolabeled
    options = json.loads((store / "manifest.json").read_text())["options"]
    assert "/lanes2d" in options["autolabel"]["labels_from"] and options["autolabel"]["range_m"] == 60
    clips = ClipStore(store)
    frames = [frame for clip in clips.clips for frame in clips.read_frames(clip.clip_id)]
    labeled = [frame for frame in frames if frame.labeled]
    assert labeled and all(frame.lanes for frame in labeled)
    assert all(lane.track_id >= 0 and lane.points[:, 1].max() <= 60 for frame in labeled for lane in frame.lanes)
    report = store / "autolabel_report"
    assert {path.name for path in report.iterdir()} == {"report.md", "report.json", "pictures.png"}
    overall = json.loads((report / "report.json").read_text())["overall"]
    assert overall["num_frames"] > 0 and "x_error_150_200" in overall and "vis_iou" in overall
    assert "Auto-labels against the true lanes on /lanes" in capsys.readouterr().out


def test_a_log_without_2d_detections_is_named_and_the_others_go_on(tmp_path, synth_log):
    logs = tmp_path / "logs"
    logs.mkdir()
    good = shutil.copy(synth_log("ros2"), logs / "good.mcap")
    bad = write_log(logs / "no_detections.mcap", [m for m in read_log(synth_log("ros2")) if m.topic != "/lanes2d"])
    results = {r.path: r for r in ingest_into(tmp_path / "store", logs, *SHORT)}
    assert results[str(good)].status == "ingested"
    failed = results[str(bad)]
    assert failed.status == "failed" and "\n" not in failed.error
    assert failed.error.startswith(f"{bad}: no 2D lane detections on /lanes2d")


def test_a_trajectory_that_stops_or_jumps_is_named(tmp_path, synth_log):
    log = synth_log("ros2")
    (stops,) = ingest_into(tmp_path / "a", log, *SHORT, "autolabel.min_travel_m=10000")
    assert stops.status == "failed" and stops.error.startswith(f"{log}: the ego trajectory stops")
    (jumps,) = ingest_into(tmp_path / "b", log, *SHORT, "autolabel.max_speed_mps=1")
    assert jumps.status == "failed" and jumps.error.count("\n") == 0
    assert jumps.error.startswith(f"{log}: the ego trajectory jumps") and "autolabel.max_speed_mps=1" in jumps.error
