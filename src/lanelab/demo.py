"""``lanelab-demo``: the main job end to end on the embedded default, synthetic drives.

    lanelab-demo [key=value ...]        # Hydra overrides of experiment=demo, e.g. demo.out=DIR trainer.max_steps=300
    lanelab-demo experiment=demo_bi2lane  # the same for Bi²Lane and its single-frame baseline
    lanelab-demo --help

1. ``lanelab-synth`` writes the training drives and the held-out drives (fog, dense traffic);
2. ``lanelab-ingest`` turns them into two clip stores: train / val, and the held-out test;
3. every model of ``demo.models`` (the temporal SparseLaneSTP and its single-frame baseline)
   is trained alike on the first (:func:`lanelab.experiment.train.train`), for the same number
   of steps: ``trainer.max_steps``, or the steps the first model reached when the wall-clock
   cap ``trainer.max_time`` stopped it sooner (the later models then run exactly as many,
   without the cap);
4. and evaluated on the second from its best checkpoint, as ``lanelab-eval checkpoint=...
   store=...`` does (:func:`lanelab.experiment.evaluate.evaluate_checkpoint`): report,
   prediction files and pictures per model;
5. the comparison (F1 over all held-out frames and per scenario, x / z errors) is printed
   and written to ``<demo.out>/comparison.md``, with a "blind prior" row: the training
   store's mean lane layout predicted for every frame without looking at the images
   (:mod:`lanelab.evaluation.blind_prior`), scored on the same held-out ground truth. A model
   has learnt something from the camera only where it beats that row. Below it, where each
   model's F1 goes: the points it would gain with one kind of error fixed by the ground truth
   (:mod:`lanelab.metrics.error_budget`). Above it, a "Note:" line whenever a model stopped
   before ``trainer.max_steps``: the steps each got.

Everything it runs is configured in ``conf/experiment/demo.yaml``; any key of it or of
``lanelab-train``'s config can be overridden. The drive-log tools run as their own commands
(lanelab does not import ``data_ingest``). A bad option stops it before anything is written,
in one line (exit status 2); a tool that fails, with the tool's name (exit status 1).
"""

from __future__ import annotations

import logging
import shutil
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

from omegaconf import DictConfig

from lanelab.atomic_file import atomic_output
from lanelab.evaluation.blind_prior import NAME as BLIND_PRIOR_NAME
from lanelab.evaluation.report import ERROR_BUDGET_KEY
from lanelab.evaluation.report import REFERENCE_KEY as BLIND_PRIOR
from lanelab.experiment.config import load_train_config
from lanelab.experiment.evaluate import evaluate_checkpoint
from lanelab.experiment.train import run_errors_exit, train
from lanelab.lightning.console import ignore_known_warnings, route_lightning_logs
from lanelab.metrics.error_budget import gains_table

COMPARISON_MD = "comparison.md"


def main(argv: list[str] | None = None) -> None:
    arguments = sys.argv[1:] if argv is None else argv
    if {"-h", "--help"} & set(arguments):
        print(__doc__.strip())
        return
    logging.basicConfig(level=logging.INFO, format="%(message)s", stream=sys.stdout)
    logging.captureWarnings(True)
    route_lightning_logs()
    ignore_known_warnings()
    with run_errors_exit("lanelab-demo"):
        demo(arguments)


def demo(arguments: list[str]) -> None:
    """Run the demo with these overrides of experiment=demo, or of the preset they name (see the module)."""
    overrides = arguments if any(a.startswith("experiment=") for a in arguments) else ["experiment=demo", *arguments]
    base = load_train_config([*overrides, "paths.output_dir=."])
    demo = base.demo
    out = Path(demo.out)
    start = time.monotonic()

    train_store, test_store = prepare_stores(demo, out, start)

    reports: dict[str, dict[str, Any]] = {}
    steps: dict[str, int] = {}
    for model in demo.models:
        run = out / model
        _step(start, f"training {model}")
        fit = train(load_train_config([*overrides, *same_steps(steps), f"model={model}",
                                       f"data.store={train_store}", f"paths.output_dir={run / 'train'}"]))  # fmt: skip
        steps[model] = int(fit["train/steps"])
        _step(start, f"evaluating {model} on the held-out drives (lanelab-eval checkpoint=... store=...)")
        reports[model] = evaluate_checkpoint(best_checkpoint(run / "train"), test_store, run / "heldout",
                                             **heldout_options(base))  # fmt: skip

    table = short_training_note(steps, base.trainer) + comparison(reports, steps, demo) + budget_comparison(reports)
    with atomic_output(out / COMPARISON_MD) as tmp:
        tmp.write_text(f"# lanelab-demo: held-out drives\n\n{table}")
    print(f"\nHeld-out drives ({', '.join(demo.test_logs)}), {_minutes(start)} in all:\n\n{table}")
    for model in demo.models:
        print(f"{model}: report and pictures in {out / model / 'heldout'}")


def prepare_stores(demo: DictConfig, out: Path, start: float) -> tuple[Path, Path]:
    """Synthesize the demo's training and held-out drives under ``out/logs`` and ingest them
    into ``out/clips_train`` (train / val) and ``out/clips_test``; the two stores' paths.
    With ``demo.train_store``, that store is trained on and no training drive is made.
    ``start``: the monotonic time the progress lines count from."""
    _step(start, "synthesizing drive logs")
    if not demo.train_store:
        _tool("lanelab-synth", f"output_dir={out / 'logs' / 'train'}", *demo.synth, *demo.train_logs)
    for name, options in demo.test_logs.items():
        _tool("lanelab-synth", f"output_dir={out / 'logs' / 'test' / name}", *demo.synth, *options)
    _step(start, "ingesting them into clip stores")
    train_store, test_store = Path(demo.train_store or out / "clips_train"), out / "clips_test"
    if not demo.train_store:
        _tool("lanelab-ingest", f"input={out / 'logs' / 'train'}", f"output={train_store}", *demo.ingest_train)
    _tool("lanelab-ingest", f"input={out / 'logs' / 'test'}", f"output={test_store}", *demo.ingest_test)
    return train_store, test_store


def same_steps(steps: dict[str, int]) -> list[str]:
    """The trainer overrides of a model trained after those of ``steps`` (model -> steps
    reached, in training order): exactly the first one's steps, without the wall-clock cap
    (a cap hit again would cut this model at another step: the rows would not compare alike).
    Nothing for the first model: it trains as configured."""
    if not steps:
        return []
    return [f"trainer.max_steps={next(iter(steps.values()))}", "trainer.max_time=null"]


def short_training_note(steps: dict[str, int], trainer: DictConfig) -> str:
    """The line above the comparison when a model stopped before ``trainer.max_steps`` (its
    wall-clock cap ``trainer.max_time`` reached on a slow or busy machine, or ``max_epochs``):
    at which steps, and whether the models still trained alike; "" when every model ran them all."""
    short = {model: n for model, n in steps.items() if n < trainer.max_steps}
    if not short:
        return ""
    counts = set(steps.values())
    alike = (f"every model trained the same {counts.pop()} steps, so the rows compare alike, but they are "
             "not the full recipe's numbers" if len(counts) == 1 else
             "the models trained different numbers of steps, so the rows do not compare alike")  # fmt: skip
    return (f"Note: training stopped before trainer.max_steps={trainer.max_steps} (trainer.max_time="
            f"{trainer.max_time} or trainer.max_epochs={trainer.max_epochs} came first): "
            f"{', '.join(f'{model} at step {n}' for model, n in short.items())}; {alike}. On an idle machine, "
            "or with a longer trainer.max_time, every model runs them all.\n\n")


def comparison(reports: dict[str, dict[str, Any]], steps: dict[str, int], demo: DictConfig) -> str:
    """A Markdown table: one row per model, its training steps, F1 over all held-out frames
    and per scenario column of demo.columns, and the x / z errors (percent and metres); then
    the blind prior's row (no training steps), from the reports' ``blind_prior`` (every
    model's report scores the same prior on the same frames; the first one's is shown), or a
    line saying why there is none."""
    errors = [key for key in next(iter(reports.values()))["overall"] if key.startswith(("x_error_", "z_error_"))]
    header = ["model", "steps", "F1 all (%)", *[f"F1 {label} (%)" for label in demo.columns], *[f"{e} (m)" for e in errors]]
    lines = ["| " + " | ".join(header) + " |", "|---|" + "---:|" * (len(header) - 1)]
    rows = [(model, str(steps[model]), report) for model, report in reports.items()]
    prior = next((report[BLIND_PRIOR] for report in reports.values() if BLIND_PRIOR in report), None)
    if prior is not None and "overall" in prior:
        rows.append((BLIND_PRIOR_NAME, "–", prior))
    for name, model_steps, report in rows:
        f1 = [report["overall"]["f1"], *[_scenario_f1(report, group, scenario) for group, scenario in demo.columns.values()]]
        cells = [name, model_steps, *[_number(v, 100, 1) for v in f1],
                 *[_number(report["overall"].get(e), 1, 3) for e in errors]]  # fmt: skip
        lines.append("| " + " | ".join(cells) + " |")
    table = "\n".join(lines) + "\n"
    if prior is None:
        return table
    if "overall" not in prior:
        return table + f"\n{prior['description']}\n"
    return table + (f"\n{BLIND_PRIOR_NAME}: the mean lane layout of {prior['store']} ({prior['split']} split), "
                    "straight and flat, predicted for every frame without looking at the images.\n")  # fmt: skip


def budget_comparison(reports: dict[str, dict[str, Any]]) -> str:
    """Where each model's F1 goes, beside the blind prior's (their reports' error budgets,
    :mod:`lanelab.metrics.error_budget`); "" when the reports have none."""
    budgets = {model: [report[ERROR_BUDGET_KEY]] for model, report in reports.items() if ERROR_BUDGET_KEY in report}
    if not budgets:
        return ""
    priors = [report[BLIND_PRIOR][ERROR_BUDGET_KEY] for report in reports.values()
              if ERROR_BUDGET_KEY in report.get(BLIND_PRIOR, {})]  # fmt: skip
    if priors:  # every report scores the same prior on the same frames
        budgets[BLIND_PRIOR_NAME] = priors[:1]
    return ("\nWhere the F1 goes: the points each model would gain with one kind of error fixed by the ground truth "
            f"(lanelab.metrics.error_budget):\n\n{gains_table(budgets)}")


def _scenario_f1(report: dict[str, Any], group: str, scenario: str) -> float | None:
    rows = [row for row in report["scenarios"] if row["group"] == group and row["scenario"] == scenario]
    return rows[0]["f1"] if rows else None


def _number(value: float | None, scale: float, digits: int) -> str:
    return "–" if value is None else f"{scale * value:.{digits}f}"  # None: no pair had a value


def heldout_options(cfg: DictConfig) -> dict[str, Any]:
    """evaluate_checkpoint's options from a demo run's config: its predict split (the held-out
    store is all test split), its trainer's accelerator, its evaluation's pictures, blind prior
    and error budget."""
    evaluation = cfg.evaluation
    return {
        "split": cfg.data.splits.predict, "accelerator": cfg.trainer.accelerator,
        "num_pictures": evaluation.num_pictures, "picture_height": evaluation.picture_height,
        "blind_prior": evaluation.blind_prior, "prior_store": evaluation.prior_store,
        "error_budget": evaluation.error_budget,
    }  # fmt: skip


def best_checkpoint(run: Path) -> Path:
    """The run's best checkpoint (the callback keeps one per run; of a folder trained into
    again, the newest), else its last."""
    best = sorted((run / "checkpoints").glob("epoch*.ckpt"), key=lambda path: path.stat().st_mtime)
    return best[-1] if best else run / "checkpoints" / "last.ckpt"


def _tool(name: str, *overrides: str) -> None:
    """Run a lanelab command (installed beside this Python, or on the PATH); stop if it fails."""
    beside = Path(sys.executable).with_name(name)
    command = str(beside) if beside.exists() else shutil.which(name)
    if command is None:
        sys.exit(f"lanelab-demo: {name} is not installed (pip install -e .)")
    if subprocess.run([command, *overrides], check=False).returncode != 0:
        sys.exit(f"lanelab-demo: {name} failed")


def _step(start: float, what: str) -> None:
    print(f"\n== lanelab-demo [{_minutes(start)}]: {what}", flush=True)


def _minutes(start: float) -> str:
    seconds = time.monotonic() - start
    return f"{int(seconds // 60)} min {seconds % 60:04.1f} s"


if __name__ == "__main__":
    main()
