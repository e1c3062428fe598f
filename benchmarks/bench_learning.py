"""Do the detectors learn? Train on the demo's synthetic drives, score on held-out drives.

    python benchmarks/bench_learning.py [--models sparselanestp latr_baseline] [--seeds 0 1 2]
        [--max-steps 1500] [--max-time 00:00:07:00] [--val-every 250] [--out runs/bench_learning]
        [--results] [key=value ...]
    python benchmarks/bench_learning.py --combine A/summary.json B/summary.json [--out DIR] [--results]

Every (model, seed) trains as ``lanelab-demo`` trains it (``experiment=demo``, the extra
``key=value`` arguments as Hydra overrides), validating every ``--val-every`` steps, then its
checkpoint is scored on the demo's held-out drives (fog, dense traffic) with the blind prior
beside it: the training split's mean lane layout, straight and flat, predicted without looking
at the images (:mod:`lanelab.evaluation.blind_prior`). The demo's clip stores are reused where
they exist (``demo.out``), else made as the demo makes them.

Writes to ``--out``: ``curves.png`` (every loss term, validation F1 and x / z errors against
steps, a line per run), ``summary.json`` and ``learning.md`` (held-out scores per seed, mean and
sample standard deviation over seeds, the blind prior, the temporal model's lead). With
``--results`` the Markdown replaces the "Learning" section of ``benchmarks/RESULTS.md`` and the
PNG is copied to ``benchmarks/learning_curves.png``. ``--combine`` joins the summaries of
runs made apart (e.g. one process per model on a machine with spare cores) into one report.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import platform
import shutil
import statistics
import sys
import time
from pathlib import Path

import cv2
import torch

from lanelab.atomic_file import atomic_output
from lanelab.demo import best_checkpoint, heldout_options, prepare_stores
from lanelab.evaluation.report import ERROR_BUDGET_KEY, REFERENCE_KEY
from lanelab.experiment.config import load_train_config
from lanelab.experiment.evaluate import evaluate_checkpoint
from lanelab.experiment.train import train
from lanelab.metrics.error_budget import gains_table
from lanelab.metrics.openlane import DETECTION_SCORES, OpenLaneConfig
from lanelab.viz.charts import chart_grid, line_chart

BENCHMARKS = Path(__file__).resolve().parent
SECTION = "## Learning (`benchmarks/bench_learning.py`)"
ERRORS = tuple(OpenLaneConfig().pair_value_names)  # the official metric's: x / z errors close and far
SCORES = (*DETECTION_SCORES, *ERRORS)
VALIDATION = ("val/f1", *(f"val/{error}" for error in ERRORS))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--models", nargs="+", default=["sparselanestp", "latr_baseline"])
    parser.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    parser.add_argument("--max-steps", type=int, default=1500)
    parser.add_argument("--max-time", default="00:00:07:00", help="wall-clock cap per run, DD:HH:MM:SS")
    parser.add_argument("--val-every", type=int, default=250, help="validate every N training steps")
    parser.add_argument("--out", type=Path, default=Path("runs/bench_learning"))
    parser.add_argument("--results", action="store_true", help="write the section into benchmarks/RESULTS.md")
    parser.add_argument("--combine", nargs="+", type=Path, help="report on these summary.json files, train nothing")
    args, overrides = parser.parse_known_args()
    if args.combine:
        parts = [json.loads(path.read_text()) for path in args.combine]
        runs = {label: run for part in parts for label, run in part["runs"].items()}
        models = list(dict.fromkeys(run["model"] for run in runs.values()))
        command = " && ".join(part["command"] for part in parts)
        write_outputs({"command": command, "machine": parts[0]["machine"], "runs": runs}, models, args)
        return
    start = time.monotonic()

    # With the first model, so that overrides of its own keys (model.criterion...) compose.
    base = load_train_config(["experiment=demo", f"model={args.models[0]}", *overrides, "paths.output_dir=."])
    stores = Path(base.demo.out) / "clips_train", Path(base.demo.out) / "clips_test"
    if not all((store / "manifest.json").exists() for store in stores):
        stores = prepare_stores(base.demo, Path(base.demo.out), start)

    runs = {}
    for model in args.models:
        for seed in args.seeds:
            print(f"== {model}, seed {seed} [{time.monotonic() - start:.0f} s]", flush=True)
            runs[f"{model} s{seed}"] = run_one(model, seed, stores, args, overrides)
    write_outputs({"command": command_line(), "machine": machine(), "runs": runs}, args.models, args)


def write_outputs(summary: dict, models: list[str], args: argparse.Namespace) -> None:
    """summary.json, curves.png and learning.md in --out; with --results, RESULTS.md too."""
    runs = summary["runs"]
    args.out.mkdir(parents=True, exist_ok=True)
    with atomic_output(args.out / "summary.json") as tmp:
        tmp.write_text(json.dumps(summary, indent=1))
    write_png(args.out / "curves.png", runs)
    markdown = report(summary, models, "learning_curves.png" if args.results else "curves.png")
    with atomic_output(args.out / "learning.md") as tmp:
        tmp.write_text(markdown)
    print("\n" + markdown)
    if args.results:
        shutil.copyfile(args.out / "curves.png", BENCHMARKS / "learning_curves.png")
        results = BENCHMARKS / "RESULTS.md"
        results.write_text(replace_section(results.read_text(), markdown))
        print(f"written into {results}")


def run_one(model: str, seed: int, stores: tuple[Path, Path], args: argparse.Namespace, overrides: list[str]) -> dict:
    """Train one model with one seed, read its curves, score its checkpoint on the held-out store."""
    run = args.out / model / f"seed{seed}"
    began = time.monotonic()
    cfg = load_train_config([
        "experiment=demo", f"model={model}", f"seed={seed}", f"data.store={stores[0]}", f"paths.output_dir={run}",
        f"trainer.max_steps={args.max_steps}", f"trainer.max_time={args.max_time}", "trainer.max_epochs=-1",
        f"trainer.val_check_interval={args.val_every}", "trainer.check_val_every_n_epoch=null", *overrides,
    ])  # fmt: skip
    fit = train(cfg)
    seconds = time.monotonic() - began
    report = evaluate_checkpoint(best_checkpoint(run), stores[1], run / "heldout", **heldout_options(cfg))
    curves = read_curves(run / "csv" / "metrics.csv")
    prior = report.get(REFERENCE_KEY, {}).get("overall")
    return {
        "model": model, "seed": seed, "seconds": seconds,
        "steps": int(fit["train/steps"]),
        "heldout": {key: report["overall"].get(key) for key in SCORES},
        "blind_prior": None if prior is None else {key: prior.get(key) for key in SCORES},
        "budget": report.get(ERROR_BUDGET_KEY),
        "prior_budget": report.get(REFERENCE_KEY, {}).get(ERROR_BUDGET_KEY),
        "curves": curves,
    }  # fmt: skip


def read_curves(path: Path) -> dict[str, tuple[list[int], list[float]]]:
    """metrics.csv of the CSV logger -> {column: (steps, values)} for the loss terms and the
    validation metrics (each row holds what was logged at its step; empty cells skipped)."""
    curves: dict[str, tuple[list[int], list[float]]] = {}
    with path.open() as f:
        for row in csv.DictReader(f):
            for key, value in row.items():
                if value and (key.startswith("train/loss") or key in VALIDATION):
                    steps, values = curves.setdefault(key, ([], []))
                    steps.append(int(row["step"]))
                    values.append(float(value))
    return curves


def write_png(path: Path, runs: dict[str, dict]) -> None:
    """One panel per loss term and per validation metric, a line per run."""
    keys = sorted({key for run in runs.values() for key in run["curves"] if key.startswith("train/")})
    panels = []
    for key in [*keys, *VALIDATION]:
        series = {label: tuple(run["curves"][key]) for label, run in runs.items() if key in run["curves"]}
        reference = None
        if key == "val/f1":
            priors = [run["blind_prior"]["f1"] for run in runs.values() if run["blind_prior"]]
            reference = ("blind prior (held-out)", priors[0]) if priors else None
        panels.append(line_chart(key, series, reference=reference))
    with atomic_output(path) as tmp:
        ok, png = cv2.imencode(".png", cv2.cvtColor(chart_grid(panels, columns=4), cv2.COLOR_RGB2BGR))
        assert ok, "PNG encoding of a uint8 picture cannot fail"
        tmp.write_bytes(png.tobytes())


def report(summary: dict, models: list[str], png: str) -> str:
    """The Markdown section: held-out scores per run, mean ± std per model, the blind prior,
    the temporal model's lead over the baseline."""
    runs = list(summary["runs"].values())
    header = "| model | seed | steps | minutes | F1 (%) | precision (%) | recall (%) | x close (m) | x far (m) | z close (m) | z far (m) |"
    lines = [SECTION, "", f"`{summary['command']}` on {summary['machine']}.", "", header, "|---|---:|" + "---:|" * 9]
    for run in runs:
        lines.append(_row(run["model"], str(run["seed"]), str(run["steps"]), f"{run['seconds'] / 60:.1f}", run["heldout"]))
    means = {}
    for model in models:
        mine = [run["heldout"] for run in runs if run["model"] == model]
        means[model] = {key: _mean_std([r[key] for r in mine]) for key in SCORES}
        lines.append(_row(f"**{model}**", "mean ± std", "", "", means[model]))
    prior = next((run["blind_prior"] for run in runs if run["blind_prior"]), None)
    if prior:
        lines.append(_row("blind prior", "–", "–", "–", prior))
    lines += ["", "Held-out drives: the demo's fog and dense-traffic drives, never trained on. The blind prior is "
              "the training split's mean lane layout, straight and flat, predicted without the images."]  # fmt: skip
    if len(models) >= 2 and all(len(means[m]) for m in models[:2]):
        (lead_mean, lead_std), names = _lead(means[models[0]]["f1"], means[models[1]]["f1"]), models[:2]
        lines.append(f"{names[0]} leads {names[1]} by {100 * lead_mean:+.1f} ± {100 * lead_std:.1f} F1 points "
                     "(difference of the seed means ± the standard deviation of that difference).")  # fmt: skip
    lines += budget_lines(runs, models)
    lines += ["", f"![learning curves]({png})", ""]
    return "\n".join(lines)


def budget_lines(runs: list[dict], models: list[str]) -> list[str]:
    """Where the held-out F1 goes (lanelab.metrics.error_budget), per model over its seeds; []
    without budgets."""
    budgets = {model: [run["budget"] for run in runs if run["model"] == model and run.get("budget")] for model in models}
    budgets = {model: mine for model, mine in budgets.items() if mine}
    if not budgets:
        return []
    prior = next((run["prior_budget"] for run in runs if run.get("prior_budget")), None)
    if prior is not None:
        budgets["blind prior"] = [prior]
    return ["", "Where the held-out F1 goes: the points each model would gain with one kind of error fixed by the "
            "ground truth (`lanelab.metrics.error_budget`; mean ± std over seeds).", "", gains_table(budgets)]


def replace_section(text: str, section: str) -> str:
    """RESULTS.md with its Learning section replaced by ``section`` (appended if absent)."""
    start = text.find(SECTION)
    if start < 0:
        return text.rstrip("\n") + "\n\n" + section
    end = text.find("\n## ", start + len(SECTION))
    return text[:start] + section.rstrip("\n") + "\n" + ("" if end < 0 else text[end:])


def _mean_std(values: list[float | None]) -> tuple[float, float]:
    finite = [v for v in values if v is not None and math.isfinite(v)]
    if not finite:
        return math.nan, math.nan
    return statistics.fmean(finite), statistics.stdev(finite) if len(finite) > 1 else 0.0


def _lead(a: tuple[float, float], b: tuple[float, float]) -> tuple[float, float]:
    return a[0] - b[0], math.hypot(a[1], b[1])


def _row(name: str, seed: str, steps: str, minutes: str, scores: dict) -> str:
    cells = []
    for key in SCORES:
        value = scores.get(key)
        scale, digits = (100, 1) if key in DETECTION_SCORES else (1, 3)
        if isinstance(value, tuple):
            cells.append("–" if math.isnan(value[0]) else f"{scale * value[0]:.{digits}f} ± {scale * value[1]:.{digits}f}")
        else:
            cells.append("–" if value is None or not math.isfinite(value) else f"{scale * value:.{digits}f}")
    return "| " + " | ".join([name, seed, steps, minutes, *cells]) + " |"


def command_line() -> str:
    return "python " + " ".join(["benchmarks/bench_learning.py", *sys.argv[1:]])


def machine() -> str:
    return (f"{platform.machine()} CPU, {os.cpu_count()} cores ({platform.processor() or platform.platform()}), "
            f"torch {torch.__version__}")  # fmt: skip


if __name__ == "__main__":
    main()
