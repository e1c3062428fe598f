"""``lanelab-sweep-report``: a Hydra multirun of ``lanelab-train`` as the papers' ablation tables.

    lanelab-sweep-report runs/<task_name>/multirun/<time> [--out DIR]

Reads every job folder of the multirun (``<job>/.hydra/overrides.yaml`` and the
``metrics.json`` that ``lanelab-train`` writes), finds the overrides whose values differ
between jobs (the swept keys), and writes into the multirun folder (or ``--out``):

- ``sweep_report.md``: one row per job, the swept values, F1, precision, recall and the x / z
  errors per range (test metrics where the jobs tested, else the last validation's), as in
  SparseLaneSTP's Tables 2 and 3;
- ``sweep_report.csv``: the same numbers, unrounded (fractions in [0, 1], errors in metres);
- ``sweep_f1.png``: F1 against the swept value, each point labelled with its F1 (matplotlib).

A sweep of a paper's ablation (``sweep=contributions``, ``attention``, ``memory_length`` or one of
Bi²Lane's, :mod:`lanelab.experiment.paper_tables`) also gets the paper's table in the report: its
rows in the paper's order, our numbers beside the paper's, each the mean ± sample standard
deviation over the jobs that ran the row (a multirun with ``seed=1,2,3`` gives three per row).

When the jobs ran their evaluation (``evaluation.enabled=true``), ``metrics.json`` also holds
the blind prior's scores (``blind_prior/<metric>``: the training split's mean lane layout,
straight and flat, no image, scored on the evaluated split; :mod:`lanelab.evaluation.blind_prior`).
If the jobs share a training store (``data.store`` of ``<job>/.hydra/config.yaml``) and so
the same prior, the Markdown table ends with a "blind prior" row and the plot draws its F1 as
a dashed line: the score a model must beat to have learnt anything from the images. A line
under the table says which split the prior was scored on, or why there is no such row. The
CSV holds the jobs alone (the prior's unrounded numbers are in each job's ``metrics.json``).

Jobs without ``metrics.json`` (failed or still running), or whose ``metrics.json`` or
``overrides.yaml`` cannot be read, are named and left out; jobs that never validated (their
``trainer.max_steps`` ended them within the first epoch) are named, with how to get validation
(``trainer.val_check_interval``), on stderr and in the report. So is a sweep whose every job
scored F1 0 (the smoke-test preset ``experiment=tiny``, or too few steps), with the recipe
that learns (``experiment=demo`` on the same store).
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import statistics
import sys
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import yaml

from lanelab.atomic_file import atomic_output
from lanelab.experiment import BLIND_PRIOR_PREFIX, METRICS_JSON
from lanelab.experiment.paper_tables import PAPER_TABLES, PaperRow
from lanelab.metrics.openlane import DETECTION_SCORES
from lanelab.metrics.scenarios import markdown_table

if TYPE_CHECKING:
    from matplotlib.figure import Figure

REPORT_MD, REPORT_CSV, PLOT_PNG = "sweep_report.md", "sweep_report.csv", "sweep_f1.png"
BLIND_PRIOR_ROW = "blind prior"  # the reference row's label (lanelab.evaluation.blind_prior.NAME)


@dataclass(frozen=True)
class Job:
    """One run of the sweep: its folder, overrides (key -> value as written) and metrics."""

    folder: Path
    overrides: dict[str, str]
    metrics: dict[str, float | None]

    def config_value(self, key: str) -> object:
        """A dotted key of the job's composed config (``.hydra/config.yaml``); None if absent."""
        path = self.folder / ".hydra" / "config.yaml"
        node: object = yaml.safe_load(path.read_text()) if path.is_file() else None
        for part in key.split("."):
            node = node.get(part) if isinstance(node, dict) else None
        return node


def read_jobs(multirun: Path) -> tuple[list[Job], list[Path]]:
    """The finished jobs of a multirun folder, in job order, and the folders without metrics."""
    jobs, unfinished = [], []
    folders = sorted((p.parent.parent for p in multirun.glob("*/.hydra/overrides.yaml")), key=_job_order)
    for folder in folders:
        if not (folder / METRICS_JSON).is_file():
            unfinished.append(folder)
            continue
        try:
            lines = yaml.safe_load((folder / ".hydra" / "overrides.yaml").read_text()) or []
            overrides = dict(line.lstrip("+~").split("=", 1) for line in lines)
        except (OSError, UnicodeDecodeError, yaml.YAMLError, AttributeError, TypeError, ValueError) as err:
            _leave_out(folder / ".hydra" / "overrides.yaml", f"not a list of overrides ({err})")
            continue
        try:
            metrics = json.loads((folder / METRICS_JSON).read_text())
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as err:
            _leave_out(folder / METRICS_JSON, f"cannot be read ({err})")
            continue
        jobs.append(Job(folder, overrides, metrics))
    return jobs, unfinished


def _leave_out(path: Path, problem: str) -> None:
    print(f"lanelab-sweep-report: {path}: {problem}; its job is left out", file=sys.stderr)


def never_validated(jobs: list[Job]) -> str | None:
    """A line naming the jobs whose metrics hold no validation or test metric, and how to get
    them; None when every job has some."""
    silent = [job.folder.name for job in jobs if not any(key.startswith(("val/", "test/")) for key in job.metrics)]
    if not silent:
        return None
    return (f"{len(silent)} of {len(jobs)} jobs never validated ({', '.join(silent)}): their {METRICS_JSON} holds "
            "no val/ or test/ metric. Validation runs at the end of each epoch, so a job whose trainer.max_steps "
            "ends it within its first epoch has none: validate every N steps with trainer.val_check_interval=N "
            "(N <= max_steps), or test after fitting with test=true.")


def nothing_learnt(jobs: list[Job]) -> str | None:
    """A line for a sweep whose every job scored F1 0 (found no lane) in the metrics the report
    shows: why (the smoke-test preset experiment=tiny, or too few steps) and what to run
    instead; None when a job scored above 0 or none has an F1."""
    scores = [float(score) for job in jobs if (score := job.metrics.get(_stage(jobs) + "f1")) is not None]
    if not any(math.isfinite(score) for score in scores) or any(score > 0 for score in scores):
        return None
    steps = [float(job.metrics["train/steps"]) for job in jobs if job.metrics.get("train/steps") is not None]
    if {job.overrides.get("experiment") for job in jobs} == {"tiny"}:
        why = "experiment=tiny is a smoke test: it checks that a run trains, validates and reports, not that it learns"
    else:
        most = f" (at most {max(steps):.0f})" if steps else ""
        why = f"the jobs trained too few steps to learn{most}, or their preset is a smoke test"
    return (f"every job's F1 is 0: no job found a lane. {why}. For a sweep that learns, train the demo's recipe "
            "on your store: lanelab-train --multirun experiment=demo data.store=STORE sweep=... "
            "(1,500 steps a job; check that it beats the blind prior with evaluation.enabled=true).")


def swept_keys(jobs: list[Job]) -> list[str]:
    """Override keys whose value differs between jobs, in the order of the first job."""
    keys = list(dict.fromkeys(key for job in jobs for key in job.overrides))
    return [key for key in keys if len({job.overrides.get(key) for job in jobs}) > 1]


def table_rows(jobs: list[Job], keys: list[str]) -> tuple[list[dict[str, object]], list[str]]:
    """One row per job (swept values, then the metrics without their stage prefix) and the
    metric columns: test metrics where any job has them, else validation metrics."""
    stage = _stage(jobs)
    names = sorted({key[len(stage):] for job in jobs for key in job.metrics if key.startswith(stage)})
    errors = [name for name in names if name.startswith(("x_error_", "z_error_"))]
    columns = [name for name in DETECTION_SCORES if name in names] + errors + (["vis_iou"] if "vis_iou" in names else [])
    rows = []
    for job in jobs:
        row: dict[str, object] = {key: job.overrides.get(key, "") for key in keys}
        for name in columns:
            value = job.metrics.get(stage + name)
            row[name] = float("nan") if value is None else float(value)
        rows.append(row)
    if len(keys) == 1 and all(_is_number(str(row[keys[0]])) for row in rows):
        rows.sort(key=lambda row: float(str(row[keys[0]])))
    return rows, columns


def _stage(jobs: list[Job]) -> str:
    """The metrics a report shows: test metrics where any job has them, else validation's."""
    return "test/" if any(key.startswith("test/") for job in jobs for key in job.metrics) else "val/"


def paper_section(jobs: list[Job]) -> str | None:
    """The sweep as its paper's table (the jobs' common ``sweep`` override names it), in Markdown:
    per row of the paper, in its order, the jobs that ran it, our numbers (mean ± sample std over
    those jobs) and the paper's. Rows the sweep did not run show "–"; values the paper has no row
    for come last. None when the sweep is no paper's."""
    names = {job.overrides.get("sweep") for job in jobs}
    table = PAPER_TABLES.get(names.pop()) if len(names) == 1 else None
    if table is None:
        return None
    ran = defaultdict(list)
    for job in jobs:
        ran[str(job.overrides.get(table.key.lstrip("+~"), "")).lower()].append(job)  # as read_jobs keys them
    known = {row.value for row in table.rows}
    rows = [*table.rows, *(PaperRow(value, value, {}) for value in ran if value not in known)]
    stage = _stage(jobs)
    header = ["row", table.key, "jobs"] + [f"{_metric_label(name)} {who}" for name in table.columns for who in ("ours", "paper")]
    lines = ["| " + " | ".join(header) + " |", "|---|---|" + "---:|" * (len(header) - 2)]
    for row in rows:
        cells = [row.label, row.value, str(len(ran[row.value]))]
        for name in table.columns:
            ours = [float(job.metrics[stage + name]) for job in ran[row.value] if job.metrics.get(stage + name) is not None]
            cells += [_spread(ours, 100.0 if name == "f1" else 1.0), _paper_number(row.numbers.get(name), name)]
        lines.append("| " + " | ".join(cells) + " |")
    where = "test" if stage == "test/" else "validation"
    return (f"## As in the paper: {table.title}\n\n" + "\n".join(lines) + "\n\n"
            f"Ours: {where} metrics of this sweep's jobs, mean ± sample standard deviation over the jobs of a row "
            "(seeds). The paper's: OpenLane, as published.\n")


def _metric_label(name: str) -> str:
    return "F1 (%)" if name == "f1" else f"{name[0]} err. {name[8:]} (m)"


def _spread(values: list[float], scale: float) -> str:
    """Mean ± sample std of values (times scale), one decimal for percent, three for metres."""
    if not values:
        return "–"
    digits = 1 if scale == 100.0 else 3
    mean = f"{scale * statistics.fmean(values):.{digits}f}"
    return mean if len(values) == 1 else f"{mean} ± {scale * statistics.stdev(values):.{digits}f}"


def _paper_number(value: float | None, name: str) -> str:
    return "–" if value is None else f"{value:.1f}" if name == "f1" else f"{value:.3f}"


def blind_prior_row(jobs: list[Job], keys: list[str], columns: list[str]) -> tuple[dict[str, object] | None, str]:
    """The blind prior's table row (its label in the first key's column), when the jobs
    share a training store and their metrics.json hold the same blind prior, and the line
    that says where it was scored, or why there is no row."""
    with_prior = [job for job in jobs if any(key.startswith(BLIND_PRIOR_PREFIX) for key in job.metrics)]
    if not with_prior:
        return None, (f"No {BLIND_PRIOR_ROW} row: the jobs' {METRICS_JSON} hold none "
                      "(run them with evaluation.enabled=true to score it).")  # fmt: skip
    stores = {str(job.config_value("data.store")) for job in jobs}
    if len(stores) > 1:
        return None, f"No {BLIND_PRIOR_ROW} row: the jobs train on different stores ({', '.join(sorted(stores))})."
    values = [{name: job.metrics.get(BLIND_PRIOR_PREFIX + name) for name in columns} for job in with_prior]
    if any(other != values[0] for other in values[1:]):
        return None, (f"No {BLIND_PRIOR_ROW} row: the jobs scored different blind priors "
                      "(different evaluated splits or metric settings); see each job's eval/report.md.")  # fmt: skip
    row: dict[str, object] = {key: "" for key in keys}
    row[keys[0]] = BLIND_PRIOR_ROW
    row.update({name: float("nan") if value is None else float(value) for name, value in values[0].items()})
    split = with_prior[0].config_value("data.splits.predict")
    note = (f"{BLIND_PRIOR_ROW}: the mean lane layout of the train split of {stores.pop()}, straight and flat, "
            f"predicted without looking at the images, scored on the {split} split by the jobs' evaluation.")
    if not any(key.startswith("test/") for job in jobs for key in job.metrics):  # table_rows shows val/ then
        note += f" The jobs' rows are validation metrics (the {with_prior[0].config_value('data.splits.val')} split)."
    return row, note


def write_report(multirun: Path, out: Path) -> list[Path]:
    """Write the table, the CSV and the plot for a multirun folder; their paths."""
    jobs, unfinished = read_jobs(multirun)
    for folder in unfinished:
        print(f"lanelab-sweep-report: {folder} has no {METRICS_JSON} (failed or unfinished); left out", file=sys.stderr)
    if not jobs:
        raise FileNotFoundError(f"{multirun}: no finished lanelab-train job (<job>/.hydra and {METRICS_JSON})")
    warnings = [warning for warning in (never_validated(jobs), nothing_learnt(jobs)) if warning is not None]
    keys = swept_keys(jobs) or ["job"]
    if keys == ["job"]:
        jobs = [Job(job.folder, {"job": job.folder.name}, job.metrics) for job in jobs]
    rows, columns = table_rows(jobs, keys)
    prior, note = blind_prior_row(jobs, keys, columns)
    for warning in warnings:
        print(f"lanelab-sweep-report: warning: {warning}", file=sys.stderr)
        note = f"{warning}\n\n{note}"
    out.mkdir(parents=True, exist_ok=True)

    markdown = f"# Sweep {multirun}\n\n" + markdown_table(rows + ([prior] if prior else []), [*keys, *columns])
    markdown += f"\n{note}\n"
    paper = paper_section(jobs)
    if paper is not None:
        markdown += f"\n{paper}"
    with atomic_output(out / REPORT_MD) as tmp:
        tmp.write_text(markdown)
    with atomic_output(out / REPORT_CSV) as tmp, tmp.open("w", newline="") as f:
        writer = csv.DictWriter(f, [*keys, *columns])
        writer.writeheader()
        writer.writerows(rows)
    labels = [", ".join(str(row[key]) for key in keys) for row in rows]
    f1 = [100 * float(row["f1"]) for row in rows] if "f1" in columns else [float("nan")] * len(rows)
    prior_f1 = 100 * float(prior["f1"]) if prior is not None and "f1" in columns else None
    plot_f1(out / PLOT_PNG, " / ".join(keys), labels, f1, prior_f1)
    print(markdown)
    return [out / REPORT_MD, out / REPORT_CSV, out / PLOT_PNG]


def plot_f1(path: Path, x_name: str, labels: list[str], f1: list[float], prior_f1: float | None = None) -> None:
    """Write :func:`f1_figure` as a PNG."""
    import matplotlib.pyplot as plt

    figure = f1_figure(x_name, labels, f1, prior_f1)
    with atomic_output(path) as tmp:
        figure.savefig(tmp, format="png")
    plt.close(figure)


def f1_figure(x_name: str, labels: list[str], f1: list[float], prior_f1: float | None = None) -> Figure:
    """F1 (%) against the swept values (labels, one per job): a line over numbers, points over
    names, each point labelled with its F1; the blind prior's F1 (%), if given, as a dashed
    horizontal line. A titled matplotlib figure with named axes."""
    import matplotlib

    matplotlib.use("Agg")  # files only, no display
    import matplotlib.pyplot as plt

    numeric = all(_is_number(label) for label in labels)
    x = [float(label) for label in labels] if numeric else list(range(len(labels)))
    figure, axes = plt.subplots(figsize=(6, 4), dpi=100)
    axes.plot(x, f1, "o-" if numeric else "o", color="tab:blue", label="jobs")
    for xv, value in zip(x, f1):
        if math.isfinite(value):
            axes.annotate(f"{value:.1f}", (xv, value), textcoords="offset points", xytext=(0, 7), ha="center",
                          fontsize=9)  # fmt: skip
    if prior_f1 is not None and math.isfinite(prior_f1):
        axes.axhline(prior_f1, color="grey", linestyle="--", label=f"{BLIND_PRIOR_ROW} ({prior_f1:.1f})")
        axes.legend(loc="best", fontsize=9)
    axes.set_xticks(x, labels)
    axes.margins(y=0.15)  # room for the value labels
    axes.set(xlabel=x_name, ylabel="F1 (%)", title=f"Sweep: F1 against {x_name}")
    axes.grid(alpha=0.3)
    figure.tight_layout()
    return figure


def _job_order(folder: Path) -> tuple[int, str]:
    return (int(folder.name), "") if folder.name.isdigit() else (sys.maxsize, folder.name)


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="lanelab-sweep-report", description=__doc__.split("\n\n")[0])
    parser.add_argument("multirun", type=Path, help="a multirun folder of lanelab-train (hydra.sweep.dir)")
    parser.add_argument("--out", type=Path, default=None, help="where the report goes (default: the multirun folder)")
    args = parser.parse_args(argv)
    try:
        written = write_report(args.multirun, args.out or args.multirun)
    except FileNotFoundError as err:
        print(f"lanelab-sweep-report: {err}", file=sys.stderr)
        sys.exit(1)
    print("wrote " + ", ".join(str(path) for path in written))


if __name__ == "__main__":
    main()
