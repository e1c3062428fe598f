"""The evaluation report: the OpenLane metric over all frames and per scenario, in the shape
of the papers' tables, as printed text, Markdown and JSON.

Three tables:

1. **Overall**: frames, F1, precision, recall, category accuracy, x and z errors per range
   and, with the long-range extension, Vis-IoU (the columns of SparseLaneSTP's Tables 1
   and 5 and Bi²Lane's Table I). With extra ranges the errors are labelled by their y
   range (0-40, 40-100, 100-150, 150-200 m) as in SparseLaneSTP's Table 5; otherwise
   "close" and "far" as the official evaluator names them.
2. **Scenario F1**, one row per scenario group: All, each scenario, and Mean, the
   unweighted mean over the scenarios (SparseLaneSTP's Table 4, Bi²Lane's Table II).
3. **Per scenario**: every metric of each scenario.

A report may also carry an **error budget** (:mod:`lanelab.metrics.error_budget`): the F1 with each
kind of error fixed by the ground truth, one at a time (near and far positions, extents, missed
and false lanes), a table of its own and ``error_budget`` in the JSON.

A report may carry a **reference** scored on the same frames and ground truth: the blind prior
(:mod:`lanelab.evaluation.blind_prior`, a prediction that looks at no image). It gets a row
in the first two tables, beside the evaluated predictions, and a section of its own (what it
is, where it comes from, or why it could not be computed); the JSON holds it under
``blind_prior``.

Fractions are printed in percent, errors in metres; the JSON keeps the metric's own keys
and units (fractions in [0, 1]) and writes a value no pair had (NaN) as null.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Mapping, Sequence

from lanelab.atomic_file import atomic_output
from lanelab.metrics.error_budget import budget_table, gains_table
from lanelab.metrics.openlane import RATE_KEYS, FrameResult, OpenLaneConfig, summarize
from lanelab.metrics.scenarios import Scenario, markdown_table, mean_f1, scenario_rows

REPORT_JSON = "report.json"
REPORT_MARKDOWN = "report.md"
PICTURES_PNG = "pictures.png"  # the pictures beside the report (lanelab.evaluation.pictures)
REFERENCE_KEY = "blind_prior"  # report.json's key of the reference (lanelab.evaluation.blind_prior)
ERROR_BUDGET_KEY = "error_budget"  # report.json's key of the error budget (lanelab.metrics.error_budget)


@dataclass(frozen=True)
class Reference:
    """A reference prediction scored on the report's frames (the blind prior).

    name: its row label. description: one line, what it is and where it comes from, or why
    it could not be computed. overall / scenarios: as in :class:`Report`; overall is None
    when it could not be computed. details: JSON-ready facts about it (its lanes, its
    source). details_table: a Markdown table of them ("" for none).
    """

    name: str
    description: str
    overall: dict[str, float | int] | None
    scenarios: list[dict[str, str | int | float]]
    details: dict[str, Any]
    details_table: str = ""


@dataclass(frozen=True)
class Report:
    """What an evaluation found.

    overall: :func:`~lanelab.metrics.openlane.summarize` over every frame. scenarios: one
    :func:`~lanelab.metrics.scenarios.scenario_rows` row per scenario (group, scenario and
    the same keys). inputs: where the numbers come from (name -> path), for the header.
    name: the row label of the evaluated predictions beside a reference ("model", ...).
    reference: the blind prior on the same frames, or None (not asked for). error_budget: an
    :func:`~lanelab.metrics.error_budget.error_budget` of the predictions, or None.
    """

    config: OpenLaneConfig
    overall: dict[str, float | int]
    scenarios: list[dict[str, str | int | float]]
    inputs: dict[str, str]
    name: str = "predictions"
    reference: Reference | None = None
    error_budget: dict[str, dict[str, float | int]] | None = None


def build_report(
    results: Sequence[tuple[str, FrameResult]],
    config: OpenLaneConfig,
    scenarios: Sequence[Scenario] = (),
    inputs: Mapping[str, str] | None = None,
    name: str = "predictions",
    reference: Reference | None = None,
    error_budget: Mapping[str, Mapping[str, float | int]] | None = None,
) -> Report:
    """The report of frame results ((frame id, result), as evaluate_frames returns them),
    with a reference scored on the same frames if given (:func:`build_reference`) and the
    predictions' error budget if given."""
    overall = summarize(result for _, result in results)
    budget = None if error_budget is None else {fix: dict(scores) for fix, scores in error_budget.items()}
    return Report(config, overall, scenario_rows(dict(results), scenarios), dict(inputs or {}), name, reference, budget)


def build_reference(
    name: str,
    description: str,
    results: Sequence[tuple[str, FrameResult]] | None,
    scenarios: Sequence[Scenario] = (),
    details: Mapping[str, Any] | None = None,
    details_table: str = "",
) -> Reference:
    """A reference from its frame results on the report's frames, scored and grouped as the
    report's own (results None: it could not be computed, description says why)."""
    if results is None:
        return Reference(name, description, None, [], dict(details or {}), details_table)
    overall = summarize(result for _, result in results)
    return Reference(name, description, overall, scenario_rows(dict(results), scenarios), dict(details or {}),
                     details_table)  # fmt: skip


def to_markdown(report: Report) -> str:
    """The report as a Markdown document: a header, then the tables under ## titles."""
    parts = ["# Evaluation report", "", *[f"- {line}" for line in _header(report)], ""]
    for title, table in _tables(report):
        parts += [f"## {title}", "", table]
    section = _reference_section(report)
    if section is not None:
        title, description, table = section
        parts += [f"## {title}", "", description, ""] + ([table] if table else [])
    return "\n".join(parts)


def to_text(report: Report) -> str:
    """The report for a terminal: the same tables with aligned columns."""
    parts = [*_header(report), ""]
    for title, table in _tables(report):
        parts += [title, "-" * len(title), _aligned(table), ""]
    section = _reference_section(report)
    if section is not None:
        title, description, table = section
        parts += [title, "-" * len(title), description] + ([_aligned(table)] if table else []) + [""]
    return "\n".join(parts)


def to_json(report: Report) -> dict[str, Any]:
    """The report as JSON-ready data: metric options, inputs, overall, scenarios, and each
    group's mean scenario F1. NaN becomes None."""
    data = {
        "metric": asdict(report.config),
        "inputs": report.inputs,
        "overall": report.overall,
        "scenarios": report.scenarios,
        "mean_scenario_f1": {group: mean_f1(rows) for group, rows in _groups(report.scenarios).items()},
    }
    if report.error_budget is not None:
        data[ERROR_BUDGET_KEY] = report.error_budget
    reference = report.reference
    if reference is not None:
        data[REFERENCE_KEY] = {"name": reference.name, "description": reference.description, **reference.details}
        if reference.overall is not None:
            data[REFERENCE_KEY].update({
                "overall": reference.overall,
                "scenarios": reference.scenarios,
                "mean_scenario_f1": {group: mean_f1(rows) for group, rows in _groups(reference.scenarios).items()},
            })  # fmt: skip
    return _without_nan(data)


def write_report(report: Report, out_dir: str | os.PathLike[str]) -> list[Path]:
    """Write ``report.json`` and ``report.md`` into out_dir (each atomically); their paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    texts = {
        out / REPORT_JSON: json.dumps(to_json(report), indent=1, allow_nan=False) + "\n",
        out / REPORT_MARKDOWN: to_markdown(report),
    }
    return write_texts(texts)


def write_texts(texts: dict[Path, str]) -> list[Path]:
    """Write each text to its path atomically (UTF-8); the paths."""
    for path, text in texts.items():
        with atomic_output(path) as tmp:
            tmp.write_text(text, encoding="utf-8")
    return list(texts)


def _header(report: Report) -> list[str]:
    config = report.config
    extensions = [f"errors to {config.y_samples[-1]:g} m"] if config.extra_ranges else []
    extensions += ["Vis-IoU"] if config.vis_iou else []
    metric = "OpenLane, official protocol"
    if extensions:
        metric += " + " + " and ".join(extensions) + " (SparseLaneSTP §5.1)"
    lines = [f"metric: {metric}", f"frames: {report.overall['num_frames']}"]
    return lines + [f"{name}: {path}" for name, path in report.inputs.items()]


def _tables(report: Report) -> list[tuple[str, str]]:
    """(title, Markdown table) of each table of the report. With a scored reference, the
    overall and scenario-F1 tables get a first column naming the row (the predictions, the
    reference)."""
    names = _display_names(report.config)
    metrics = [*RATE_KEYS, *[names.get(n, n) for n in report.config.pair_value_names]]
    reference = report.reference
    scored = reference is not None and reference.overall is not None
    if scored:
        rows = [{"predictions": report.name, **_renamed(report.overall, names)},
                {"predictions": reference.name, **_renamed(reference.overall, names)}]  # fmt: skip
        tables = [("Overall", markdown_table(rows, ["predictions", "num_frames", *metrics]))]
    else:
        tables = [("Overall", markdown_table([_renamed(report.overall, names)], ["num_frames", *metrics]))]
    reference_groups = _groups(reference.scenarios) if scored else {}
    for group, rows in _groups(report.scenarios).items():
        if scored:
            labelled = [(report.name, report.overall["f1"], rows),
                        (reference.name, reference.overall["f1"], reference_groups.get(group, []))]  # fmt: skip
            tables.append((f"{group} scenarios: F1 (%)", _f1_rows(labelled)))
        else:
            tables.append((f"{group} scenarios: F1 (%)", _f1_row(report.overall["f1"], rows)))
    if report.scenarios:
        rows = [_renamed(row, names) for row in report.scenarios]
        tables.append(("Per scenario", markdown_table(rows, ["group", "scenario", "num_frames", *metrics])))
    if report.error_budget is not None:
        title = "Where the F1 goes: each kind of error fixed with the ground truth"
        tables.append((title, budget_table(report.error_budget)))
        if scored and ERROR_BUDGET_KEY in reference.details:
            budgets = {report.name: [report.error_budget], reference.name: [reference.details[ERROR_BUDGET_KEY]]}
            title = f"Where the F1 goes, beside the {reference.name}: points gained by each fix"
            tables.append((title, gains_table(budgets)))
    return tables


def _reference_section(report: Report) -> tuple[str, str, str] | None:
    """(title, description, Markdown table or "") of the report's reference, if it has one."""
    reference = report.reference
    if reference is None:
        return None
    return reference.name[:1].upper() + reference.name[1:], reference.description, reference.details_table


def _display_names(config: OpenLaneConfig) -> dict[str, str]:
    """Metric key -> table key: with extra ranges, close / far are named by their y range."""
    if not config.extra_ranges:
        return {}
    ranges = {"close": f"0_{config.close_range:g}", "far": f"{config.close_range:g}_{config.extra_ranges[0]:g}"}
    return {f"{axis}_error_{name}": f"{axis}_error_{span}" for axis in "xz" for name, span in ranges.items()}


def _renamed(row: Mapping[str, Any], names: Mapping[str, str]) -> dict[str, Any]:
    return {names.get(key, key): value for key, value in row.items()}


def _groups(scenarios: Sequence[dict[str, str | int | float]]) -> dict[str, list[dict[str, str | int | float]]]:
    """Scenario rows by group, groups in order of appearance."""
    groups: dict[str, list[dict[str, str | int | float]]] = {}
    for row in scenarios:
        groups.setdefault(str(row["group"]), []).append(row)
    return groups


def _f1_row(all_f1: float, rows: Sequence[Mapping[str, Any]]) -> str:
    """A one-row Markdown table: All | each scenario | Mean, F1 in percent."""
    header = ["All", *[str(row["scenario"]) for row in rows], "Mean"]
    values = [all_f1, *[float(row["f1"]) for row in rows], mean_f1(rows)]
    cells = ["–" if math.isnan(v) else f"{100 * v:.1f}" for v in values]
    return "\n".join([
        "| " + " | ".join(header) + " |",
        "|" + "|".join(["---:"] * len(header)) + "|",
        "| " + " | ".join(cells) + " |",
    ]) + "\n"


def _f1_rows(rows: Sequence[tuple[str, float, Sequence[Mapping[str, Any]]]]) -> str:
    """A Markdown table: a column naming each row, then All | each scenario | Mean, F1 in
    percent; rows are (name, F1 over all frames, scenario rows), the first row's scenarios
    name the columns."""
    scenarios = [str(row["scenario"]) for row in rows[0][2]]
    header = ["Predictions", "All", *scenarios, "Mean"]
    lines = ["| " + " | ".join(header) + " |", "|---|" + "|".join(["---:"] * (len(header) - 1)) + "|"]
    for name, all_f1, scenario_rows_ in rows:
        by_name = {str(row["scenario"]): float(row["f1"]) for row in scenario_rows_}
        values = [all_f1, *[by_name.get(s, math.nan) for s in scenarios], mean_f1(scenario_rows_)]
        lines.append("| " + " | ".join([name, *["–" if math.isnan(v) else f"{100 * v:.1f}" for v in values]]) + " |")
    return "\n".join(lines) + "\n"


def _aligned(markdown: str) -> str:
    """A Markdown table as padded columns, aligned as its |---| line says."""
    lines = [[cell.strip() for cell in line.strip().strip("|").split("|")]
             for line in markdown.strip().splitlines()]
    right = [cell.endswith(":") for cell in lines[1]]
    rows = [lines[0], *lines[2:]]
    widths = [max(len(row[i]) for row in rows) for i in range(len(right))]
    return "\n".join(
        "  ".join(cell.rjust(w) if r else cell.ljust(w) for cell, w, r in zip(row, widths, right)).rstrip()
        for row in rows
    )


def _without_nan(value: Any) -> Any:
    if isinstance(value, float) and math.isnan(value):
        return None
    if isinstance(value, dict):
        return {key: _without_nan(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [_without_nan(item) for item in value]
    return value
