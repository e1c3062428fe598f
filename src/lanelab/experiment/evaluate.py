"""The evaluation report of a trained model on a clip-store split: prediction files, the
papers' tables (overall and per scenario tag) and pictures.

The model predicts ``data.splits.predict`` (``Trainer.predict`` with
:class:`~lanelab.lightning.OpenLaneWriter`, which also writes the ground truth and the test
list, so the numbers come from the same files any OpenLane tool reads, and it works under
DDP). Then, on rank zero, the pieces of ``lanelab-eval`` score the files
(:func:`~lanelab.metrics.openlane.evaluate_frames` with the model's metric settings), group
the frames by the store's scenario tags (weather, occlusion, curvature, ...;
:func:`~lanelab.metrics.scenarios.tag_scenarios`), write ``report.md`` / ``report.json`` and
draw ``pictures.png`` on the store's camera images. Beside the model, the report shows the
blind prior (:mod:`lanelab.evaluation.blind_prior`: the training split's mean lane layout,
no image) scored on the same ground-truth files, unless ``blind_prior`` is false. Layout of
``out``::

    predictions/  ground_truth/  test_list.txt  report.md  report.json  pictures.png

:func:`evaluate_checkpoint` does the same from a checkpoint file alone (``lanelab-eval
checkpoint=... store=...``): lanelab-train writes the run's resolved config into every
checkpoint (:mod:`lanelab.experiment.build`), so the model, its metric settings and the data
pipeline are rebuilt as trained; its blind prior comes from the store the checkpoint was
trained on.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Sequence
from pathlib import Path

import cv2
import lightning.pytorch as pl
import numpy as np
from lightning.pytorch.loggers import Logger, WandbLogger
from omegaconf import DictConfig, OmegaConf

from lanelab.config_checks import check_writable_folder
from lanelab.data.datamodule import ClipDataModule
from lanelab.evaluation.blind_prior import blind_prior_reference
from lanelab.evaluation.once_report import once_markdown, once_report, write_once_report
from lanelab.evaluation.pictures import PictureFrame, draw_pictures, pick_frames, read_openlane_frame, write_png
from lanelab.evaluation.report import (
    PICTURES_PNG,
    REPORT_JSON,
    REPORT_MARKDOWN,
    Report,
    build_report,
    to_text,
    write_report,
)
from lanelab.experiment.build import CONFIG_KEY, build_run, read_checkpoint
from lanelab.experiment.checkpoints import check_weights_fit
from lanelab.experiment.config import validate
from lanelab.lightning import OpenLaneWriter
from lanelab.lightning.once_writer import OnceWriter
from lanelab.lightning.openlane_writer import GROUND_TRUTH, PREDICTIONS, TEST_LIST
from lanelab.lightning.pictures import log_pictures_to, takes_images
from lanelab.metrics.error_budget import evaluate_with_budget
from lanelab.metrics.once import evaluate_once
from lanelab.metrics.scenarios import OPENLANE_TAG_GROUPS, SCENARIO_GROUPS, tag_scenarios
from lanelab.openlane.file_paths import FILE_PATH_TAG, frame_id, store_file_path
from lanelab.store import ClipStore
from lanelab.store.image_codec import decode_image


@dataclasses.dataclass(frozen=True)
class StoreFrame:
    """Where an evaluated frame lies in its store, and its scenario tags."""

    clip_id: str
    timestamp_ns: int
    tags: dict[str, str]


def evaluate(
    trainer: pl.Trainer,
    module: pl.LightningModule,
    datamodule: ClipDataModule,
    ckpt_path: str | None,
    options: DictConfig,
) -> Report | None:
    """Predict, score, write the report and pictures under options.out (see the module).

    ckpt_path: the weights (None: those in memory). options: ``out``, ``num_pictures``,
    ``picture_height``, ``blind_prior``, ``prior_store``, ``error_budget`` (conf/train.yaml
    ``evaluation``).
    The blind prior comes from the train split of ``prior_store``, else (null, or no prior
    there) of the datamodule's store. Returns the report on rank zero.
    """
    out = Path(options.out)
    if options.get("format", "openlane") == "once":
        return _evaluate_once(trainer, module, datamodule, ckpt_path, out)
    _predict_into(OpenLaneWriter(out, ground_truth=datamodule.store), trainer, module, datamodule, ckpt_path)
    if not trainer.is_global_zero:
        return None

    with_budget = options.get("error_budget", False)
    results, budget = evaluate_with_budget(out / GROUND_TRUTH, out / PREDICTIONS, out / TEST_LIST,
                                           module.metric_config, with_budget)  # fmt: skip
    store = ClipStore(datamodule.store)
    frames = store_frames(store, datamodule.splits["predict"])
    tags = {frame: frames[frame].tags for frame, _ in results}
    from_openlane = any(FILE_PATH_TAG in frame_tags for frame_tags in tags.values())
    scenarios = tag_scenarios(tags, OPENLANE_TAG_GROUPS if from_openlane else SCENARIO_GROUPS)
    reference = None
    if options.get("blind_prior", True):
        stores = [store for store in (options.get("prior_store"), datamodule.store) if store]
        reference = blind_prior_reference(stores, out / GROUND_TRUTH, out / TEST_LIST, module.metric_config, scenarios,
                                          error_budget=with_budget)  # fmt: skip
    inputs = {"store": str(datamodule.store), "out": str(out)}
    report = build_report(results, module.metric_config, scenarios, inputs, "model", reference, budget)
    print(to_text(report))
    written = write_report(report, out)

    chosen = [results[i][0] for i in pick_frames(len(results), options.num_pictures)]
    if chosen:
        pictures = [_picture_frame(store, out, frame, frames[frame]) for frame in chosen]
        y_range = (0.0, float(module.metric_config.y_range[1]))
        written.append(write_png(out / PICTURES_PNG, draw_pictures(pictures, options.picture_height, y_range)))
    print("wrote " + ", ".join(str(path) for path in written))
    return report


def evaluate_checkpoint(
    checkpoint: str | Path,
    store: str | Path,
    out: str | Path,
    *,
    split: str,
    accelerator: str,
    num_pictures: int,
    picture_height: int,
    blind_prior: bool,
    prior_store: str | Path | None,
    error_budget: bool = False,
    format: str = "openlane",
    without_ego_motion: str | None = None,
) -> dict:
    """Score a lanelab-train checkpoint on one split of a clip store, on one device of the
    accelerator ("cpu", "gpu", "auto"): the predictions, report and pictures (num_pictures
    rows of picture_height pixels) of :func:`evaluate` under ``out``. Returns report.json's
    content. Raises ConfigError naming the checkpoint when it cannot be read, holds no lanelab run
    config or weights of another model than its config's, and naming ``out`` when it cannot be
    written (before anything is predicted).

    The blind prior (unless blind_prior is False) comes from the train split of prior_store,
    or where that is None from the store the checkpoint was trained on (its run config's
    ``data.store``), else from the evaluated store's own train split; the report says why when
    neither has one. error_budget: the report also shows where the F1 goes
    (:mod:`lanelab.metrics.error_budget`). format: "openlane", or "once" for ONCE-3DLanes files
    and metric (:func:`_evaluate_once`). without_ego_motion: refuse | single_frame for clips without
    ego motion (:mod:`lanelab.experiment.ego_motion`), None: as the run config says.
    """
    content = read_checkpoint(checkpoint)
    check_writable_folder("out", out)  # before the store is read and the model built
    cfg = OmegaConf.create(content[CONFIG_KEY])
    trained_on = OmegaConf.select(cfg, "data.store")
    cfg.merge_with({
        "train": False, "test": False, "ckpt_path": str(checkpoint), "logger": None,
        "data": {"store": str(store), "splits": {"predict": split}},
        "paths": {"output_dir": str(out)},
        "evaluation": {"enabled": True, "out": str(out), "num_pictures": num_pictures, "picture_height": picture_height,
                       "blind_prior": blind_prior, "error_budget": error_budget, "format": format,
                       "prior_store": None if prior_store is None and trained_on is None else str(prior_store or trained_on)},
        "trainer": {"accelerator": accelerator, "devices": 1, "num_nodes": 1, "strategy": "auto"},
    })  # fmt: skip
    if without_ego_motion is not None:
        cfg.without_ego_motion = without_ego_motion
    run = build_run(validate(cfg))
    check_weights_fit(run.module, content["state_dict"], "checkpoint", checkpoint, "its run config's")
    del content  # the file's tensors, mapped: Lightning loads them again
    evaluate(run.trainer, run.module, run.datamodule, cfg.ckpt_path, cfg.evaluation)
    return json.loads((Path(out) / REPORT_JSON).read_text())


def _evaluate_once(
    trainer: pl.Trainer, module: pl.LightningModule, datamodule: ClipDataModule, ckpt_path: str | None, out: Path
) -> None:
    """Predict into ONCE-3DLanes files (:class:`~lanelab.lightning.once_writer.OnceWriter`), score them
    with the ONCE metric on rank zero, print the table and write ``report.json`` / ``report.md``. No
    blind prior, scenarios or pictures: those belong to the OpenLane report."""
    _predict_into(OnceWriter(out, ground_truth=datamodule.store), trainer, module, datamodule, ckpt_path)
    if trainer.is_global_zero:
        report = once_report(evaluate_once(out / GROUND_TRUTH, out / PREDICTIONS), {"store": str(datamodule.store),
                                                                                   "out": str(out)})
        print(once_markdown(report))
        print("wrote " + ", ".join(str(path) for path in write_once_report(report, out)))


def _predict_into(
    writer: pl.Callback, trainer: pl.Trainer, module: pl.LightningModule, datamodule: ClipDataModule,
    ckpt_path: str | None,
) -> None:
    """Predict the datamodule's predict split with ``writer`` (which writes the files) among the
    trainer's callbacks for this run only: the trainer may go on to fit or predict without it."""
    trainer.callbacks.append(writer)
    try:
        trainer.predict(module, datamodule=datamodule, ckpt_path=ckpt_path, return_predictions=False)
    finally:
        trainer.callbacks.remove(writer)


def store_frames(store: ClipStore, split: str) -> dict[str, StoreFrame]:
    """Frame id (as the test list names it: :func:`~lanelab.openlane.file_paths.frame_id` of the
    frame's ``file_path``) -> the frame of the split's clips, read from their ``tags`` column alone."""
    frames = {}
    for clip in store.clips_in(split):
        for timestamp, tags in store.read_tags(clip.clip_id):
            frames[frame_id(store_file_path(clip.clip_id, timestamp, tags))] = StoreFrame(clip.clip_id, timestamp, tags)
    return frames


def log_evaluation(loggers: Sequence[Logger], report: Report, out: Path, step: int) -> None:
    """The evaluation report to the run's loggers: its overall numbers as ``eval/<metric>``; to
    those that take images (W&B, TensorBoard, MLflow) ``<out>/pictures.png`` as ``eval/pictures``; to W&B
    also ``report.md`` as a text panel (``eval/report``). The files stay in ``out`` for the others."""
    numbers = {f"eval/{name}": float(value) for name, value in report.overall.items() if value is not None}
    picture = cv2.imread(str(out / PICTURES_PNG), cv2.IMREAD_COLOR)
    for logger in loggers:
        logger.log_metrics(numbers, step=step)
        if isinstance(logger, WandbLogger):
            logger.log_text(key="eval/report", columns=["report.md"], data=[[(out / REPORT_MARKDOWN).read_text()]])
    with_images = [logger for logger in loggers if takes_images(logger)]
    if picture is not None and with_images:
        log_pictures_to(with_images, "eval/pictures", [picture[..., ::-1].copy()], step, out)


def _picture_frame(store: ClipStore, out: Path, frame: str, where: StoreFrame) -> PictureFrame:
    """The evaluated frame's lanes from the files, drawn on the store's camera image (with its
    own K and T_lane_cam, as the ground-truth files hold them)."""
    picture = read_openlane_frame(out / GROUND_TRUTH, out / PREDICTIONS, frame, None)
    records = store.read_frames(where.clip_id)
    record = next(r for r in records if r.timestamp_ns == where.timestamp_ns)
    image = np.ascontiguousarray(decode_image(record)[..., ::-1])  # RGB -> BGR
    title = f"{where.clip_id} {(where.timestamp_ns - records[0].timestamp_ns) / 1e9:.1f} s"  # time into the clip
    return dataclasses.replace(picture, title=title, image=image, K=record.K, T_lane_cam=record.T_lane_cam)
