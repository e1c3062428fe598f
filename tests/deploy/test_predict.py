"""lanelab-predict on synthetic drive logs, its output read back with plain MCAP readers and the
Foxglove schemas: every message decodes, the 3D lines lie where the OpenLane prediction files
of the same model on the ingested log put the lanes, the image annotations lie inside the image
on the lines' projections, stamps are the images' sensor times, and a predicted log is ingested
again as labels."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
import torch
from foxglove_schemas_protobuf.CompressedImage_pb2 import CompressedImage
from foxglove_schemas_protobuf.ImageAnnotations_pb2 import ImageAnnotations
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from ingest_helpers import START_NS, ingest_into, read_log, write_log
from mcap_output import Record, as_foxglove, read_mcap

from lanelab.experiment.evaluate import evaluate_checkpoint
from lanelab.geometry import base_link_to_lane, project_lane_points
from lanelab.store import ClipStore
from lanelab.viz import CATEGORY_COLORS, GT_COLOR
from lanelab.viz.lanes import VISIBLE
from log_predict.cli import run
from log_predict.config import load_predict_config

ROOT = Path(__file__).resolve().parents[2]
IMAGE, CALIBRATION = "/camera/front/image", "/camera/front/camera_info"
LANES, SCENE, ANNOTATIONS = "/lanes/predicted", "/lanes/predicted/scene", "/lanes/predicted/annotations"
GROUND_TRUTH, LABELS = "/lanes/ground_truth/scene", "/lanes"
WRITTEN = (LANES, SCENE, ANNOTATIONS, GROUND_TRUTH)
GAP = (START_NS + 800_000_000, START_NS + 1_300_000_000)  # ns: the images of this span are cut out, a 0.7 s gap


def image_stamp(record: Record) -> int:
    """Sensor time of an image message of any encoding."""
    message = record.decoded
    if isinstance(message, dict):
        return message["timestamp"]["sec"] * 10**9 + message["timestamp"]["nsec"]
    if hasattr(message, "header"):
        return message.header.stamp.sec * 10**9 + message.header.stamp.nanosec
    return message.timestamp.seconds * 10**9 + message.timestamp.nanos


def stamp(message: Any) -> int:
    return message.timestamp.seconds * 10**9 + message.timestamp.nanos


def predict(checkpoint: Path, log: Path, out: Path, *more: str) -> int:
    return run(load_predict_config([f"checkpoint={checkpoint}", f"input={log}", f"output={out}", "accelerator=cpu",
                                    *more]))


@pytest.fixture(scope="module")
def gap_log(synth_log, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The Foxglove protobuf log without its images of GAP: two clips for the ingestor."""
    messages = read_log(synth_log("foxglove-protobuf"))
    kept = [m for m in messages
            if m.topic != IMAGE or not GAP[0] <= stamp(CompressedImage.FromString(m.data)) <= GAP[1]]  # fmt: skip
    assert len(messages) - len(kept) == 6
    return write_log(tmp_path_factory.mktemp("gap") / "gap_drive.mcap", kept)


@pytest.fixture(scope="module")
def predicted(checkpoint: Path, gap_log: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("predicted")
    assert predict(checkpoint, gap_log, out, "preview_frames=2") == 0
    return out


@pytest.mark.slow
def test_lines_lie_where_the_openlane_predictions_of_the_ingested_log_are(
    checkpoint: Path, gap_log: Path, predicted: Path, tmp_path: Path
) -> None:
    # The same model on the same log, ingested and evaluated by streaming its clips (lanelab-eval).
    store = tmp_path / "store"
    ingest_into(store, gap_log, "split.train=0", "split.val=0", "split.test=1")
    evaluate_checkpoint(checkpoint, store, tmp_path / "eval", split="test", accelerator="cpu", num_pictures=0,
                        picture_height=96, blind_prior=False, prior_store=None)  # fmt: skip
    files = {int(p.stem): json.loads(p.read_text()) for p in (tmp_path / "eval" / "predictions").rglob("*.json")}
    records = {r.timestamp_ns: r for clip in ClipStore(store).manifest.clips for r in ClipStore(store).read_frames(clip.clip_id)}
    assert len(ClipStore(store).manifest.clips) == 2 and len(files) == 14  # the gap cuts the log in two clips

    _, messages = read_mcap(predicted / "gap_drive.mcap")
    images = {image_stamp(m): m for m in messages if m.topic == IMAGE}
    scenes = [(m, as_foxglove(m, SceneUpdate)) for m in messages if m.topic == SCENE]
    assert sorted(images) == sorted(files) == sorted(stamp(s.entities[0]) for _, s in scenes)
    total = 0
    for message, scene in scenes:
        (entity,) = scene.entities
        t = stamp(entity)
        assert entity.frame_id == "base_link" and message.log_time == images[t].log_time
        lines = files[t]["lane_lines"]
        assert len(entity.lines) == len(lines)
        for line, expected in zip(entity.lines, lines):
            ego = torch.tensor([[p.x, p.y, p.z] for p in line.points], dtype=torch.float64)
            np.testing.assert_allclose(base_link_to_lane(ego).numpy(), expected["xyz"], atol=1e-4)
            blue, green, red = CATEGORY_COLORS[expected["category"]]
            assert (round(255 * line.color.r), round(255 * line.color.g), round(255 * line.color.b)) == (red, green, blue)
            total += len(expected["xyz"])
    assert total > 0  # the model predicts lanes

    # Image annotations: inside the image, on the projections of the same lines, stamped as the image.
    annotated = 0
    for message in (m for m in messages if m.topic == ANNOTATIONS):
        annotations = as_foxglove(message, ImageAnnotations)
        record = None
        for annotation in annotations.points:
            t = stamp(annotation)
            record = records[t]
            uv = np.array([[p.x, p.y] for p in annotation.points])
            assert ((uv >= 0) & (uv < [record.width, record.height])).all()
            assert annotation.type == annotation.LINE_STRIP and len(uv) >= 2
            annotated += len(uv)
        if record is None:
            continue
        xyz = np.concatenate([line["xyz"] for line in files[record.timestamp_ns]["lane_lines"]])
        projected, _, in_front = project_lane_points(*(torch.tensor(a, dtype=torch.float64)
                                                       for a in (xyz, record.K, record.T_lane_cam)))
        inside = in_front.numpy() & ((projected.numpy() >= 0) & (projected.numpy() < [record.width - 1e-3, record.height - 1e-3])).all(1)
        vertices = np.array([[p.x, p.y] for a in annotations.points for p in a.points])
        distance = np.abs(projected.numpy()[inside][:, None] - vertices[None]).max(-1).min(-1)
        assert (distance < 1e-3).all()  # every projected point inside the image is a vertex (pixels)
    assert annotated > 0


def test_every_message_decodes_and_stamps_are_the_images_sensor_times(gap_log: Path, predicted: Path) -> None:
    profile, messages = read_mcap(predicted / "gap_drive.mcap")
    _, inputs = read_mcap(gap_log)
    topics = {m.topic for m in messages}
    assert topics == {IMAGE, CALIBRATION, "/tf", "/tf_static", *WRITTEN}
    copied = [(m.topic, m.log_time, m.data) for m in inputs if m.topic in (IMAGE, CALIBRATION, "/tf", "/tf_static")]
    assert sorted(copied) == sorted((m.topic, m.log_time, m.data) for m in messages if m.topic not in WRITTEN)
    images = sorted(image_stamp(m) for m in messages if m.topic == IMAGE)
    lanes = [m.decoded for m in messages if m.topic == LANES]
    assert sorted(m["timestamp"]["sec"] * 10**9 + m["timestamp"]["nsec"] for m in lanes) == images
    for label in lanes:
        assert label["frame_id"] == "base_link" and label["lanes"]
        for lane in label["lanes"]:
            assert len(lane["points"]) == len(lane["visibility"]) == 100 and 0 <= lane["score"] <= 1
    annotations = [as_foxglove(m, ImageAnnotations) for m in messages if m.topic == ANNOTATIONS]
    assert sorted(stamp(a) for a in annotations) == images  # each frame's, lanes or none, stamped as its image
    # The picture closes with a legend of its colours: the ground truth's, each predicted category's.
    legend = cv2.imread(str(predicted / "gap_drive.png"))[2 * 240 :]  # under the two rows of preview_frames=2
    categories = {lane["category"] for label in lanes for lane in label["lanes"]}
    assert 0 < legend.shape[0] < 60
    for color in (GT_COLOR, *(CATEGORY_COLORS[c] for c in categories)):
        assert (legend == color).all(-1).any(), color


def test_the_ground_truth_is_written_beside_the_predictions_in_its_own_colour(gap_log: Path, predicted: Path) -> None:
    """Each labelled image gets the visible parts of its label's lanes (the log's /lanes, ego frame)
    on the ground-truth topic, stamped as the image and logged with it, in GT_COLOR."""
    _, inputs = read_mcap(gap_log)
    _, messages = read_mcap(predicted / "gap_drive.mcap")
    labels = {m.decoded["timestamp"]["sec"] * 10**9 + m.decoded["timestamp"]["nsec"]: m.decoded
              for m in inputs if m.topic == LABELS}  # fmt: skip
    images = {image_stamp(m): m.log_time for m in messages if m.topic == IMAGE}
    scenes = [(m.log_time, as_foxglove(m, SceneUpdate)) for m in messages if m.topic == GROUND_TRUTH]
    # The log labels some of its images (a labelled frame every so often), each of those gets its ground truth.
    assert sorted(stamp(scene.entities[0]) for _, scene in scenes) == sorted(set(labels) & set(images))
    assert 0 < len(scenes) < len(images) == 14
    blue, green, red = GT_COLOR
    drawn = 0
    for log_time, scene in scenes:
        (entity,) = scene.entities
        t = stamp(entity)
        assert t > 0 and images[t] == log_time and entity.frame_id == labels[t]["frame_id"] == "base_link"
        expected = []
        for lane in labels[t]["lanes"]:
            visible = np.asarray(lane["visibility"]) > VISIBLE
            if visible.sum() >= 2:
                expected.append(np.asarray(lane["points"])[visible])
        assert len(entity.lines) == len(expected) > 0
        for line, points in zip(entity.lines, expected):
            np.testing.assert_allclose([[p.x, p.y, p.z] for p in line.points], points, atol=1e-4)
            assert (round(255 * line.color.r), round(255 * line.color.g), round(255 * line.color.b)) == (red, green, blue)
            drawn += len(points)
    assert drawn > 0


def test_a_log_without_labels_gets_no_ground_truth_topic(checkpoint: Path, synth_log, tmp_path: Path) -> None:
    log = write_log(tmp_path / "unlabelled.mcap", [m for m in read_log(synth_log("foxglove-protobuf"))
                                                   if m.topic != LABELS])  # fmt: skip
    assert predict(checkpoint, log, tmp_path / "out", "preview_frames=0") == 0
    topics = {m.topic for m in read_mcap(tmp_path / "out" / log.name)[1]}
    assert SCENE in topics and GROUND_TRUTH not in topics


@pytest.mark.slow
@pytest.mark.parametrize("encoding, expected", [
    ("ros2", ("ros2", "jsonschema", "json")),
    ("foxglove-json", ("", "jsonschema", "json")),
])  # fmt: skip
def test_the_encoding_of_the_new_topics_follows_the_log(encoding: str, expected: tuple, checkpoint: Path, synth_log,
                                                        tmp_path: Path) -> None:
    log = synth_log(encoding)
    assert predict(checkpoint, log, tmp_path, "preview_frames=0") == 0
    profile, messages = read_mcap(tmp_path / log.name)
    scene = next(m for m in messages if m.topic == SCENE)
    assert (profile, scene.schema_encoding, scene.message_encoding) == expected
    images = sorted(image_stamp(m) for m in messages if m.topic == IMAGE)
    assert sorted(stamp(as_foxglove(m, SceneUpdate).entities[0]) for m in messages if m.topic == SCENE) == images
    for message in (m for m in messages if m.topic == ANNOTATIONS):
        assert {stamp(a) for a in as_foxglove(message, ImageAnnotations).points} <= set(images)


def test_merge_writes_the_log_and_its_predictions_in_one_file(checkpoint: Path, synth_log, tmp_path: Path) -> None:
    log = synth_log("foxglove-protobuf")
    assert predict(checkpoint, log, tmp_path, "merge=true", "preview_frames=0") == 0
    _, inputs = read_mcap(log)
    _, messages = read_mcap(tmp_path / log.name)
    original = [(m.topic, m.log_time, m.data) for m in messages if m.topic not in WRITTEN]
    assert sorted(original) == sorted((m.topic, m.log_time, m.data) for m in inputs)
    assert len([m for m in messages if m.topic == SCENE]) == len([m for m in inputs if m.topic == IMAGE])


def test_a_predicted_log_is_ingested_again_as_labels(predicted: Path, tmp_path: Path) -> None:
    store = tmp_path / "store"
    (result,) = ingest_into(store, predicted / "gap_drive.mcap", f"topics.lanes={LANES}")
    assert result.status == "ingested" and result.labeled == result.num_frames == 14
    _, messages = read_mcap(predicted / "gap_drive.mcap")
    labels = {m.decoded["timestamp"]["sec"] * 10**9 + m.decoded["timestamp"]["nsec"]: m.decoded["lanes"]
              for m in messages if m.topic == LANES}
    for clip in ClipStore(store).manifest.clips:
        for record in ClipStore(store).read_frames(clip.clip_id):
            lanes = labels[record.timestamp_ns]
            assert [lane.category for lane in record.lanes] == [lane["category"] for lane in lanes]
            for stored, lane in zip(record.lanes, lanes):
                ego = torch.tensor(lane["points"], dtype=torch.float64)
                np.testing.assert_allclose(stored.points, base_link_to_lane(ego).numpy(), atol=1e-4)
                np.testing.assert_allclose(stored.visibility, lane["visibility"], atol=1e-6)


def test_the_memory_starts_empty_at_each_clip_of_the_ingestor(checkpoint: Path, gap_log: Path, tmp_path: Path,
                                                              capsys: pytest.CaptureFixture) -> None:
    assert predict(checkpoint, gap_log, tmp_path, "preview_frames=0") == 0
    assert "14 frames predicted (2 clips" in capsys.readouterr().out
    assert predict(checkpoint, gap_log, tmp_path / "one", "preview_frames=0", "clips.gap_s=1.0") == 0
    assert "14 frames predicted (1 clips" in capsys.readouterr().out
    after_gap = GAP[1] + 100_000_000
    reset, carried = ({stamp(as_foxglove(m, SceneUpdate).entities[0]): as_foxglove(m, SceneUpdate)
                       for m in read_mcap(folder / "gap_drive.mcap")[1] if m.topic == SCENE}[after_gap]
                      for folder in (tmp_path, tmp_path / "one"))  # fmt: skip
    first = [[(p.x, p.y, p.z) for p in line.points] for line in reset.entities[0].lines]
    second = [[(p.x, p.y, p.z) for p in line.points] for line in carried.entities[0].lines]
    assert first != second  # the memory of the frames before the gap changes what the model sees after it


def run_cli(*args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT / "src"), str(ROOT)])}
    return subprocess.run([sys.executable, "-m", "log_predict.cli", *args], capture_output=True, text=True,
                          timeout=300, env=env)  # fmt: skip


def test_a_missing_checkpoint_is_one_line_naming_it(tmp_path: Path, synth_log) -> None:
    missing = tmp_path / "nothing.ckpt"
    result = run_cli(f"checkpoint={missing}", f"input={synth_log('ros2')}", f"output={tmp_path / 'out'}")
    assert result.returncode == 2 and result.stderr.strip().count("\n") == 0 and str(missing) in result.stderr
    assert not (tmp_path / "out").exists()


@pytest.mark.slow
def test_bad_logs_are_one_line_each_naming_the_file_and_the_others_are_predicted(
    checkpoint: Path, synth_log, tmp_path: Path
) -> None:
    logs = tmp_path / "logs"
    logs.mkdir()
    good = synth_log("ros2")
    (logs / good.name).write_bytes(good.read_bytes())
    (logs / "corrupt.mcap").write_bytes(os.urandom(4096))
    write_log(logs / "no_tf.mcap", [m for m in read_log(good) if m.topic != "/tf"])
    out = tmp_path / "out"
    result = run_cli(f"checkpoint={checkpoint}", f"input={logs}", f"output={out}", "accelerator=cpu")
    assert result.returncode == 1
    errors = result.stderr.strip().splitlines()
    assert len(errors) == 2
    assert f"{logs / 'corrupt.mcap'}: not an MCAP file" in errors[0]
    assert f"{logs / 'no_tf.mcap'}: missing required topic /tf" in errors[1]
    assert sorted(p.name for p in out.iterdir()) == [good.with_suffix(".mcap").name, good.with_suffix(".png").name]


def test_a_bi2lane_checkpoint_predicts_a_log_with_its_frame_cache(bi2lane_checkpoint: Path, synth_log,
                                                                  tmp_path: Path) -> None:
    assert predict(bi2lane_checkpoint, synth_log("foxglove-protobuf"), tmp_path) == 0
    (written,) = tmp_path.glob("*.mcap")
    _, messages = read_mcap(written)
    images = sorted(image_stamp(m) for m in messages if m.topic == IMAGE)
    scenes = [as_foxglove(m, SceneUpdate) for m in messages if m.topic == SCENE]
    assert len(images) == 20 and sorted(stamp(scene.entities[0]) for scene in scenes) == images
    assert sum(message.topic == LANES for message in messages) == 20
