"""Pictures of predictions for the training logs: for each drawn frame, ground truth and
prediction over the camera image the model saw and from above, under the frame's name and the
training step, with a legend (:func:`lanelab.viz.panels.comparison_row`).

They go to each logger that takes images (W&B, TensorBoard, MLflow), else into PNG files under
the logger's log directory (CSV) or the run folder (no logger).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import cv2
import lightning.pytorch as pl
import numpy as np
from lightning.pytorch.loggers import Logger, MLFlowLogger, TensorBoardLogger
from torch import Tensor

from lanelab.atomic_file import atomic_output
from lanelab.lanes import Lane
from lanelab.viz.panels import categories_of, comparison_row, stack_rows


def prediction_picture(
    image: Tensor,
    K: Tensor,
    T_lane_cam: Tensor,
    predictions: Sequence[Lane],
    ground_truth: Sequence[Lane],
    x_range: tuple[float, float],
    y_range: tuple[float, float],
    height: int,
    title: str,
) -> np.ndarray:
    """One frame's picture (H, W, 3) RGB uint8: its row of panels (height pixels each) under
    title, over a legend.

    image (3, H, W) as the model saw it (normalised: shown stretched to its own min..max,
    enlarged or shrunk to height pixels); K (3, 3) of that image; T_lane_cam (4, 4); lanes in
    the lane frame; x_range, y_range: the lane-frame region of the top view (metres).
    """
    rgb = image.detach().float().cpu().permute(1, 2, 0).numpy()
    rgb = (255 * (rgb - rgb.min()) / max(float(rgb.max() - rgb.min()), 1e-6)).astype(np.uint8)
    K, T_lane_cam = (matrix.detach().double().cpu().numpy() for matrix in (K, T_lane_cam))
    row = comparison_row(np.ascontiguousarray(rgb[..., ::-1]), K, T_lane_cam, ground_truth, predictions, height,
                         x_range, y_range, title)  # fmt: skip
    return stack_rows([row], categories_of(ground_truth, predictions), height)[..., ::-1].copy()


def log_pictures(trainer: pl.Trainer, key: str, pictures: Sequence[np.ndarray]) -> None:
    """Log RGB pictures under key at the current step to each of the trainer's loggers
    (:func:`log_pictures_to`)."""
    log_pictures_to(trainer.loggers, key, pictures, trainer.global_step, Path(trainer.default_root_dir))


def log_pictures_to(loggers: Sequence[Logger], key: str, pictures: Sequence[np.ndarray], step: int,
                    folder: Path) -> None:
    """RGB pictures (H, W, 3) uint8 to each logger that takes images (W&B's ``log_image``,
    TensorBoard's ``add_image``, MLflow's artifacts); for each other logger (CSV), and without
    any, PNG files ``<its log_dir, else folder>/pictures/<key>_step<step>_<i>.png``."""
    folders = []
    for logger in loggers:
        if hasattr(logger, "log_image"):
            logger.log_image(key=key, images=list(pictures), step=step)
        elif isinstance(logger, TensorBoardLogger):
            for i, picture in enumerate(pictures):
                logger.experiment.add_image(f"{key}/{i}", picture, step, dataformats="HWC")
        elif isinstance(logger, MLFlowLogger):
            for i, picture in enumerate(pictures):
                logger.experiment.log_image(logger.run_id, picture, f"{key}/step{step:07d}_{i}.png")
        else:
            folders.append(Path(getattr(logger, "log_dir", None) or folder))
    for directory in dict.fromkeys(folders if loggers else [folder]):
        _write_pngs(directory / "pictures", key, pictures, step)


def _write_pngs(directory: Path, key: str, pictures: Sequence[np.ndarray], step: int) -> None:
    directory.mkdir(parents=True, exist_ok=True)
    for i, picture in enumerate(pictures):
        ok, png = cv2.imencode(".png", picture[..., ::-1])
        assert ok, "PNG encoding of a uint8 picture cannot fail"
        with atomic_output(directory / f"{key.replace('/', '_')}_step{step:07d}_{i}.png") as tmp:
            tmp.write_bytes(png.tobytes())


def takes_images(logger: Logger) -> bool:
    """Whether :func:`log_pictures_to` gives the logger the pictures themselves (not PNG files)."""
    return hasattr(logger, "log_image") or isinstance(logger, (TensorBoardLogger, MLFlowLogger))
