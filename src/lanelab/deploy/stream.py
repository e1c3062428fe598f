"""A trained detector run over one stream of frames, as a deployed model runs: one ``step``
per frame, its memory carried from frame to frame and emptied where a clip starts (the first
frame, and after a gap; lanelab-predict cuts logs as the ingestor cuts clips)."""

from __future__ import annotations

import torch

from lanelab.deploy.trained import TrainedDetector
from lanelab.lanes import Lane
from lanelab.store import FrameRecord


class LaneStream:
    """Calls of ``stream(record, reset)`` predict the lanes of consecutive frames of one camera."""

    def __init__(self, detector: TrainedDetector) -> None:
        self.detector = detector
        self._started = False

    @torch.inference_mode()
    def __call__(self, record: FrameRecord, reset: bool) -> list[Lane]:
        """The lanes of the frame (lane frame, sampled at the detector's y grid, every sample
        with its visibility; each with its category and score), after emptying the memory when
        ``reset`` (forced on the first call)."""
        detector = self.detector
        reset = reset or not self._started
        self._started = True
        frame = detector.model_input(record)
        frame["reset"] = torch.tensor([reset], device=detector.device)
        outputs = detector.net.step(frame)
        return detector.module.predictions(outputs, detector.y).lanes(0, visible_only=False)
