"""How good the auto-labels are, where a log also has true 3D lanes: the OpenLane metric with
SparseLaneSTP's long-range extension (§5.1: x / z errors over 0-40, 40-100, 100-150 and
150-200 m, F1, Vis-IoU; :meth:`lanelab.metrics.openlane.OpenLaneConfig.long_range`), the
true lanes as ground truth and the auto-labels as predictions, with their visibility.

The report is lanelab's evaluation report (:mod:`lanelab.evaluation.report`): overall, and
per scenario tag of the logs (weather, curvature, occlusion, ...); its pictures are those
of ``lanelab-eval`` (:mod:`lanelab.evaluation.pictures`): true lanes and auto-labels over the
camera image and from above, out to 200 m.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

import numpy as np

from lanelab.evaluation.pictures import PictureFrame, draw_pictures, pick_frames, write_png
from lanelab.evaluation.report import PICTURES_PNG, Report, build_report, to_text, write_report
from lanelab.lanes import Lane
from lanelab.metrics.openlane import FrameResult, OpenLaneConfig, evaluate_frame
from lanelab.metrics.scenarios import SCENARIO_GROUPS, tag_scenarios

REPORT_NAME = "auto-labels"
TOP_VIEW_Y_RANGE = (0.0, 200.0)
PICTURE_HEIGHT = 300


@dataclass
class Quality:
    """The scored frames of some logs: (frame id, result), each frame's tags, pictures to draw."""

    results: list[tuple[str, FrameResult]] = field(default_factory=list)
    tags: dict[str, dict[str, str]] = field(default_factory=dict)
    pictures: list[PictureFrame] = field(default_factory=list)

    def extend(self, other: Quality) -> None:
        self.results += other.results
        self.tags.update(other.tags)
        self.pictures += other.pictures

    def add_picture(self, title: str, image: np.ndarray, K: np.ndarray, T_lane_cam: np.ndarray,
                    truth: Sequence[Lane], labels: Sequence[Lane]) -> None:
        """A frame to draw: its image (H, W, 3) BGR and camera, its true lanes and auto-labels."""
        self.pictures.append(PictureFrame(title, image, K, T_lane_cam, list(truth), list(labels)))


def spread(count: int, wanted: int) -> list[int]:
    """Indices of ``wanted`` of ``count`` frames spread evenly over them, as the pictures pick them."""
    return pick_frames(count, wanted)


def metric_config() -> OpenLaneConfig:
    """The metric of the report: OpenLane with the long-range extension."""
    return OpenLaneConfig.long_range()


def score_frame(truth: Sequence[Lane], labels: Sequence[Lane], config: OpenLaneConfig) -> FrameResult:
    """One frame's auto-labels scored against its true lanes (both in its lane frame)."""
    return evaluate_frame([lane.points for lane in truth], [lane.visibility for lane in truth],
                          [lane.category for lane in truth], [lane.points for lane in labels],
                          [lane.category for lane in labels], config, [lane.visibility for lane in labels])


def quality_report(quality: Quality, inputs: dict[str, str]) -> Report:
    """The report of the scored frames, overall and per scenario tag."""
    return build_report(quality.results, metric_config(), tag_scenarios(quality.tags, SCENARIO_GROUPS), inputs,
                        name=REPORT_NAME)


def write_quality(quality: Quality, inputs: dict[str, str], out_dir: str | os.PathLike[str],
                  num_pictures: int) -> tuple[Report, list[Path]]:
    """Write report.md, report.json and pictures.png (``num_pictures`` frames spread over the
    scored ones) into out_dir; the report and the files written."""
    report = quality_report(quality, inputs)
    written = write_report(report, out_dir)
    chosen = [quality.pictures[i] for i in pick_frames(len(quality.pictures), num_pictures)]
    if chosen:
        written.append(write_png(Path(out_dir) / PICTURES_PNG, draw_pictures(chosen, PICTURE_HEIGHT, TOP_VIEW_Y_RANGE)))
    return report, written



def report_text(report: Report) -> str:
    """The report for a terminal (lanelab-eval's tables)."""
    return to_text(report)
