"""lanelab-predict's work: each log read as the ingestor reads it, the model streamed over its
frames, the predicted log written beside the others.

For one log (:func:`predict_log`):

1. its frames are read and completed as lanelab-ingest does, with the same options
   (:func:`data_ingest.ingest.frames.read_frames`): a frame that cannot be completed (no pose,
   no calibration, ...) is dropped with the ingestor's reason and gets no prediction;
2. they are cut where the ingestor cuts clips (``clips.gap_s``, ``clips.max_length_s``:
   :func:`data_ingest.ingest.clips.cut`), and the model steps over them in time order, its
   memory emptied at the first frame of each clip (:class:`lanelab.deploy.stream.LaneStream`);
3. the log is read again and ``<output>/<name>.mcap`` written: its messages (every one with
   ``merge=true``, else the image, calibration, /tf and /tf_static topics) copied as they are,
   and after each predicted image its frame's messages (:mod:`log_predict.messages`) logged at
   the image's log time (and, for a frame the log labels, its ground-truth lanes on
   ``predictions.ground_truth``). The file appears only once complete (an interrupted run leaves the
   previous file, or none);
4. ``<output>/<name>.png`` is drawn from the written file (:mod:`log_predict.preview`).

:func:`predict` runs one model over the logs of ``input``, with a progress bar per log (plain lines
where the output is no terminal: :mod:`lanelab.progress`); a log
that cannot be used is reported in one line naming it, and the others go on.
"""

from __future__ import annotations

import dataclasses
import sys
import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from foxglove_schemas_protobuf.ImageAnnotations_pb2 import ImageAnnotations
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from mcap.well_known import MessageEncoding, SchemaEncoding

from data_ingest.contract import IMAGE
from data_ingest.ingest.clips import cut, log_name
from data_ingest.ingest.errors import LogError
from data_ingest.ingest.frames import read_frames
from data_ingest.ingest.ingest import find_logs
from data_ingest.ingest.mcap_reader import ReadReport, read_messages
from data_ingest.ingest.messages import Decoder, MessageError
from data_ingest.ingest.spill import Spill
from lanelab.atomic_file import atomic_output
from lanelab.deploy.stream import LaneStream
from lanelab.deploy.trained import TrainedDetector
from lanelab.evaluation.pictures import pick_frames
from lanelab.progress import Progress
from log_predict.config import PredictConfig
from log_predict.messages import (
    LANES3D_SCHEMA,
    FoxgloveEncoding,
    PredictedFrame,
    ground_truth_scene,
    image_annotations,
    lanes3d,
    scene_update,
    visible_lines,
)
from log_predict.preview import draw_preview
from log_predict.writer import OutputLog


@dataclass
class LogPrediction:
    """What happened to one log: the files written, frames predicted, clips (memory resets),
    lanes predicted, frames dropped by reason, warnings, or the error that stopped it."""

    path: Path
    output: Path | None = None
    preview: Path | None = None
    frames: int = 0
    clips: int = 0
    lanes: int = 0
    dropped: Counter = field(default_factory=Counter)
    warnings: list[str] = field(default_factory=list)
    error: str | None = None


def output_name(path: Path) -> str:
    """The name of a log's predicted file: its file stem, as lanelab-ingest names a log."""
    return log_name(path.stem)


def input_logs(cfg: PredictConfig) -> list[Path]:
    """The logs of ``cfg.input`` (as lanelab-ingest finds them) but those under ``cfg.output``,
    which are predictions of an earlier run. Raises LogError when two share a name, as their
    outputs would."""
    output = Path(cfg.output).resolve()
    logs = [path for path in find_logs(cfg.input) if not path.resolve().is_relative_to(output)]
    names: dict[str, Path] = {}
    for path in logs:
        other = names.setdefault(output_name(path), path)
        if other != path:
            raise LogError(f"{path}: has the same name as {other}, and both would be written to "
                           f"{Path(cfg.output) / (output_name(path) + '.mcap')}; rename one")
    return logs


def predict_log(path: Path, cfg: PredictConfig, detector: TrainedDetector) -> LogPrediction:
    """Predict one log and write its files under ``cfg.output`` (see the module); raises
    LogError naming the log when it cannot be used."""
    result = LogPrediction(path)
    out_dir = Path(cfg.output)
    out_dir.mkdir(parents=True, exist_ok=True)
    report = ReadReport(path.stat().st_size)
    with Spill(out_dir) as spill:
        log = read_frames(path, cfg, spill, report)
        result.dropped, result.warnings = log.dropped, log.warnings
        if not log.frames:
            raise log.unusable(path)
        stamps = np.array([frame.record.timestamp_ns for frame in log.frames], dtype=np.int64)
        starts = {part.start for part in cut(stamps, cfg.clips.gap_s, cfg.clips.max_length_s)}
        stream, predicted = LaneStream(detector), {}
        with Progress(len(log.frames), path.name, "frames") as bar:
            for index, frame in enumerate(log.frames):
                record = dataclasses.replace(frame.record, image=spill.get(frame.image.data))
                lanes = stream(record, reset=index in starts)
                predicted[record.timestamp_ns] = PredictedFrame(record.timestamp_ns, lanes, record.K, record.T_lane_cam,
                                                                record.width, record.height,
                                                                record.lanes if record.labeled else None)
                bar.update(1)
    result.warnings[:0] = report.problems()
    result.frames, result.clips = len(predicted), len(starts)
    result.lanes = sum(len(frame.lanes) for frame in predicted.values())
    result.output = out_dir / f"{output_name(path)}.mcap"
    _write(path, result.output, cfg, report, predicted, detector)
    if cfg.preview_frames:
        stamps = sorted(predicted)
        chosen = [stamps[i] for i in pick_frames(len(stamps), cfg.preview_frames)]
        y_range = (0.0, float(detector.y[-1]))
        result.preview = draw_preview(result.output, cfg, chosen, y_range, out_dir / f"{output_name(path)}.png")
    return result


def _write(path: Path, out: Path, cfg: PredictConfig, report: ReadReport, predicted: dict[int, PredictedFrame],
           detector: TrainedDetector) -> None:
    """Write the predicted log ``out`` from the log at ``path`` (read again) and the predictions by image stamp."""
    copied = set(report.topics) if cfg.merge else set(cfg.copied_topics()) & set(report.topics)
    clash = sorted(copied & set(cfg.written_topics()))
    if clash:
        raise LogError(f"{path}: the log has topic {clash[0]}, which lanelab-predict would write too "
                       f"(merge=true copies every topic); set predictions.* to other names")
    image_schema = report.schemas.get(cfg.topics.image)
    foxglove = FoxgloveEncoding(protobuf=image_schema is not None and image_schema.encoding == SchemaEncoding.Protobuf)
    profile = "ros2" if image_schema is not None and image_schema.encoding == SchemaEncoding.ROS2 else ""
    threshold = detector.module.metric_config.visibility_threshold
    options = cfg.predictions
    lifetime_ns = int(cfg.clips.gap_s * 1e9)  # lanes of the last frame before a gap vanish with it
    decoder, missing = Decoder(), dict(predicted)
    with atomic_output(out) as tmp, open(tmp, "wb") as stream:
        log = OutputLog(stream, profile)
        log.add_channel(options.lanes, LANES3D_SCHEMA, MessageEncoding.JSON)
        log.add_channel(options.scene, foxglove.schema(SceneUpdate), foxglove.message_encoding)
        log.add_channel(options.annotations, foxglove.schema(ImageAnnotations), foxglove.message_encoding)
        if any(frame.labels is not None for frame in predicted.values()):
            log.add_channel(options.ground_truth, foxglove.schema(SceneUpdate), foxglove.message_encoding)
        for message in read_messages(path, copied, ReadReport(report.size)):
            log.copy(message)
            if message.topic != cfg.topics.image:
                continue
            try:
                frame = missing.pop(decoder.decode(message, IMAGE).stamp_ns, None)
            except MessageError:  # an image the first reading dropped too
                continue
            if frame is None:
                continue
            lines = visible_lines(frame.lanes, threshold)
            log.write(options.lanes, message.log_time, lanes3d(frame, cfg.frames.ego))
            log.write(options.scene, message.log_time, foxglove.serialize(
                scene_update(frame, lines, cfg.frames.ego, options.line_width, lifetime_ns)))
            log.write(options.annotations, message.log_time, foxglove.serialize(
                image_annotations(frame, lines, options.annotation_width)))
            if frame.labels is not None:
                log.write(options.ground_truth, message.log_time, foxglove.serialize(
                    ground_truth_scene(frame, cfg.frames.ego, options.line_width, lifetime_ns)))
        log.finish()
    if missing:  # the log changed between the two readings
        raise LogError(f"{path}: {len(missing)} predicted images were not found on a second reading of the log")


def predict(cfg: PredictConfig, detector: TrainedDetector) -> list[LogPrediction]:
    """Predict every log of ``cfg.input``; print a line per log (problems included) and a total.

    Raises LogError when there is no log, or two would be written to the same file.
    """
    logs = input_logs(cfg)
    if not logs:
        raise LogError(f"input={cfg.input}: no MCAP log there (a file, a folder of *.mcap or a glob)")
    start = time.perf_counter()
    results = []
    for path in logs:
        try:
            results.append(predict_log(path, cfg, detector))
        except LogError as err:
            results.append(LogPrediction(path, error=str(err)))
        except Exception as err:  # whatever else a damaged log provokes, the other logs go on
            results.append(LogPrediction(path, error=f"{path}: cannot be predicted: {type(err).__name__}: {err}"))
        _print(results[-1])
    frames = sum(r.frames for r in results)
    failed = sum(r.error is not None for r in results)
    seconds = time.perf_counter() - start
    print(f"lanelab-predict: {len(results) - failed} of {len(results)} logs predicted, {frames} frames in "
          f"{seconds:.1f} s ({frames / max(seconds, 1e-9):.1f} frames/s) on {detector.device}"
          + (f"; {failed} failed" if failed else ""))
    return results


def _print(result: LogPrediction) -> None:
    if result.error is not None:
        print(f"lanelab-predict: {result.error}", file=sys.stderr)
        return
    dropped = sum(result.dropped.values())
    print(f"{result.output}: {result.frames} frames predicted ({result.clips} clips: the memory starts empty at each), "
          f"{result.lanes / max(result.frames, 1):.1f} lanes per frame" + (f", {dropped} frames dropped" if dropped else "")
          + (f"; picture {result.preview}" if result.preview else ""))
    for reason, n in result.dropped.most_common():
        print(f"    dropped {n}: {reason}")
    for warning in result.warnings:
        print(f"    warning: {warning}")
