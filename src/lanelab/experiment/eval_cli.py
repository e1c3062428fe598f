"""``lanelab-eval``: the OpenLane metric over prediction files, or over a trained model on a
clip store, printed and written as the papers' tables, with pictures of a few frames.

    lanelab-eval gt=DIR pred=DIR test_list=FILE out=DIR [long_range=true] [scenario_lists=DIR] [images=DIR] [prior_store=DIR]
    lanelab-eval checkpoint=FILE store=DIR [split=test] out=DIR [accelerator=cpu] [blind_prior=false] [prior_store=DIR]
    lanelab-eval format=once gt=DIR pred=DIR out=DIR | format=once checkpoint=FILE store=DIR out=DIR: ONCE-3DLanes
    either with [error_budget=true]: a table of where the F1 goes (lanelab.metrics.error_budget)

Options are Hydra overrides of ``conf/eval.yaml``. Writes ``<out>/report.json``,
``<out>/report.md`` and ``<out>/pictures.png``; a checkpoint's predictions, with the store's
ground truth as OpenLane JSON, go to ``<out>/predictions`` and ``<out>/ground_truth``
(:func:`lanelab.experiment.evaluate.evaluate_checkpoint`: the model, its metric settings and
the data pipeline are rebuilt from the run config inside the checkpoint; scenarios come from
the store's tags). Beside the scores, the report shows the blind prior's, scored on the same
frames (:mod:`lanelab.evaluation.blind_prior`): from the train split of ``prior_store``, for
a checkpoint by default the store it was trained on; for prediction files only when
``prior_store`` is given. Exits with status 1 on a malformed or missing input file, NaN or
infinity in a prediction or ground-truth file included, on a damaged or missing clip file and on a
checkpoint whose weights hold NaN or inf (the message names the file), and 2 on a bad option or
a store that cannot give the split (none there, an unreadable manifest, a split without clips):
a checkpoint that cannot be read or whose weights are another model's than its run config's, an
``out`` that cannot be written (checked before anything is predicted or scored).
"""

from __future__ import annotations

import sys
from pathlib import Path

import hydra
from omegaconf import DictConfig

from lanelab.config_checks import (
    BAD_OPTION_STATUS,
    bad_options_exit,
    check_writable_folder,
    options_or_exit,
    register_schema,
    run_hydra_tool,
)
from lanelab.evaluation.config import SCHEMA_NAME, EvalConfig, validate
from lanelab.evaluation.report import PICTURES_PNG, REPORT_JSON, REPORT_MARKDOWN
from lanelab.finite import NonFiniteError
from lanelab.json_files import LaneFileError
from lanelab.metrics.error_budget import evaluate_with_budget
from lanelab.metrics.openlane import FrameResult, OpenLaneConfig
from lanelab.data.worker_errors import error_message
from lanelab.store import ClipFileError, DataError, ManifestError

register_schema(SCHEMA_NAME, EvalConfig)


def evaluate_prediction_files(
    cfg: EvalConfig, config: OpenLaneConfig
) -> tuple[list[tuple[str, FrameResult]], dict[str, dict[str, float | int]] | None]:
    """(frame id, result) of every frame of the test list, scored from the files, and their
    error budget if asked for (the files read once)."""
    results, budget = evaluate_with_budget(cfg.gt, cfg.pred, cfg.test_list, config, cfg.error_budget)
    if not results:
        raise LaneFileError(cfg.test_list, "the test list names no frame")
    return results, budget


def evaluate_once_files(cfg: EvalConfig) -> list[Path]:
    """Score ONCE-3DLanes prediction files against labels, print the table, write the report; its paths."""
    from lanelab.evaluation.once_report import once_markdown, once_report, write_once_report
    from lanelab.metrics.once import evaluate_once

    rows = evaluate_once(cfg.gt, cfg.pred)
    if not rows[0]["num_frames"]:
        raise LaneFileError(cfg.gt, "no ONCE-3DLanes label (<sequence>/cam01/<stamp>.json) under this folder")
    report = once_report(rows, {"gt": cfg.gt, "pred": cfg.pred})
    print(once_markdown(report))
    written = write_once_report(report, cfg.out)
    print("wrote " + ", ".join(str(path) for path in written))
    return written


def run(cfg: EvalConfig) -> list[Path]:
    """Evaluate, print the tables, write the report and the pictures; the paths written
    (prediction files, or a checkpoint on a store).

    Raises LaneFileError (naming the file) for a malformed or missing input, NonFiniteError
    (naming the checkpoint) for a checkpoint of NaN or inf weights.
    """
    # Heavy imports (torch, via the pictures) only once the options are good.
    from lanelab.evaluation.blind_prior import blind_prior_reference
    from lanelab.evaluation.pictures import (
        draw_pictures,
        pick_frames,
        read_openlane_frame,
        write_png,
    )
    from lanelab.evaluation.report import build_report, to_text, write_report
    from lanelab.metrics.scenarios import scenarios_of
    from lanelab.openlane.lists import read_scenario_lists

    if cfg.checkpoint is not None:
        from lanelab.experiment.evaluate import evaluate_checkpoint  # torch and Lightning only here: files need neither
        from lanelab.lightning.console import ignore_known_warnings, route_lightning_logs

        route_lightning_logs()  # Lightning, imported now, would print each line twice
        ignore_known_warnings()

        options = {"split": cfg.split, "accelerator": cfg.accelerator, "num_pictures": cfg.pictures.num_frames,
                   "picture_height": cfg.pictures.height, "blind_prior": cfg.blind_prior,
                   "prior_store": cfg.prior_store, "error_budget": cfg.error_budget, "format": cfg.format,
                   "without_ego_motion": cfg.without_ego_motion}  # fmt: skip
        evaluate_checkpoint(cfg.checkpoint, cfg.store, cfg.out, **options)
        written = [Path(cfg.out) / name for name in (REPORT_JSON, REPORT_MARKDOWN, PICTURES_PNG)]
        return [path for path in written if path.exists()]  # no pictures when num_frames=0
    check_writable_folder("out", cfg.out)  # before the scoring, which takes long on a large test list
    if cfg.format == "once":
        return evaluate_once_files(cfg)
    config = OpenLaneConfig.long_range() if cfg.long_range else OpenLaneConfig()
    results, budget = evaluate_prediction_files(cfg, config)
    scenarios = []
    if cfg.scenario_lists is not None:
        scenarios = scenarios_of(read_scenario_lists(cfg.scenario_lists), (name for name, _ in results))
    inputs = {"gt": cfg.gt, "pred": cfg.pred, "test list": cfg.test_list}
    reference = None
    if cfg.blind_prior and cfg.prior_store is not None:
        reference = blind_prior_reference([cfg.prior_store], cfg.gt, cfg.test_list, config, scenarios,
                                          error_budget=cfg.error_budget)  # fmt: skip
    report = build_report(results, config, scenarios, inputs, reference=reference, error_budget=budget)
    print(to_text(report))
    written = write_report(report, cfg.out)

    chosen = pick_frames(len(results), cfg.pictures.num_frames)
    if chosen:
        frames = [read_openlane_frame(cfg.gt, cfg.pred, results[i][0], cfg.images) for i in chosen]
        picture = draw_pictures(frames, cfg.pictures.height, (0.0, float(config.y_range[1])))
        written.append(write_png(Path(cfg.out) / PICTURES_PNG, picture))
    print("wrote " + ", ".join(str(path) for path in written))
    return written


@hydra.main(version_base="1.3", config_path="pkg://lanelab.conf", config_name="eval")
def _run(cfg: DictConfig) -> None:
    options = options_or_exit("lanelab-eval", cfg, EvalConfig, validate)
    try:
        with bad_options_exit("lanelab-eval"):  # a ConfigError of run (a checkpoint, out) in the job: else Hydra logs a line first
            run(options)
    except (ManifestError, DataError) as err:  # a store that cannot give the split, checked before the model is built
        print(f"lanelab-eval: {err}", file=sys.stderr)
        sys.exit(BAD_OPTION_STATUS)
    except (LaneFileError, NonFiniteError, ClipFileError) as err:
        print(f"lanelab-eval: {error_message(err)}", file=sys.stderr)
        sys.exit(1)


def main() -> None:
    run_hydra_tool("lanelab-eval", _run)


if __name__ == "__main__":
    main()
