"""Pictures of predictions for the training logs: the camera image with the predicted lanes,
beside top views of the ground truth and of the predictions (lanelab.viz draws all three).

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
from lanelab.viz import draw_lanes_on_image, draw_top_view


def prediction_picture(
    image: Tensor,
    K: Tensor,
    T_lane_cam: Tensor,
    predictions: Sequence[Lane],
    ground_truth: Sequence[Lane],
    x_range: tuple[float, float],
    y_range: tuple[float, float],
    height: int,
) -> np.ndarray:
    """One frame's picture (height, W, 3) RGB uint8.

    image (3, H, W) as the model saw it (normalised: shown stretched to its own min..max,
    enlarged or shrunk to height pixels); K (3, 3) of that image; T_lane_cam (4, 4); lanes in
    the lane frame; x_range, y_range: the lane-frame region of the top views (metres).
    """
    rgb = image.detach().float().cpu().permute(1, 2, 0).numpy()
    rgb = (255 * (rgb - rgb.min()) / max(float(rgb.max() - rgb.min()), 1e-6)).astype(np.uint8)
    scale = height / rgb.shape[0]
    bgr = cv2.resize(rgb[..., ::-1], (round(rgb.shape[1] * scale), height), interpolation=cv2.INTER_LINEAR)
    K_scaled = K.detach().double().cpu().numpy() * np.array([[scale], [scale], [1.0]])
    camera = draw_lanes_on_image(bgr, predictions, K_scaled, T_lane_cam.detach().double().cpu().numpy())
    size = (height, height // 2)
    top_gt = draw_top_view(ground_truth, size, x_range, y_range, title="ground truth")
    top_pred = draw_top_view(predictions, size, x_range, y_range, title="prediction")
    return np.concatenate([camera, top_gt, top_pred], axis=1)[..., ::-1].copy()


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
