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
from lanelab.metrics.openlane import FrameResult, OpenLaneConfig, summarize
from lanelab.metrics.scenarios import Scenario, markdown_table, mean_f1, scenario_rows

REPORT_JSON = "report.json"
REPORT_MARKDOWN = "report.md"
PICTURES_PNG = "pictures.png"  # the pictures beside the report (lanelab.evaluation.pictures)
_SCORES = ("f1", "precision", "recall", "category_accuracy")


@dataclass(frozen=True)
class Report:
    """What an evaluation found.

    overall: :func:`~lanelab.metrics.openlane.summarize` over every frame. scenarios: one
    :func:`~lanelab.metrics.scenarios.scenario_rows` row per scenario (group, scenario and
    the same keys). inputs: where the numbers come from (name -> path), for the header.
    """

    config: OpenLaneConfig
    overall: dict[str, float | int]
    scenarios: list[dict[str, str | int | float]]
    inputs: dict[str, str]


def build_report(
    results: Sequence[tuple[str, FrameResult]],
    config: OpenLaneConfig,
    scenarios: Sequence[Scenario] = (),
    inputs: Mapping[str, str] | None = None,
) -> Report:
    """The report of frame results ((frame id, result), as evaluate_frames returns them)."""
    overall = summarize(result for _, result in results)
    return Report(config, overall, scenario_rows(dict(results), scenarios), dict(inputs or {}))


def to_markdown(report: Report) -> str:
    """The report as a Markdown document: a header, then the tables under ## titles."""
    parts = ["# Evaluation report", "", *[f"- {line}" for line in _header(report)], ""]
    for title, table in _tables(report):
        parts += [f"## {title}", "", table]
    return "\n".join(parts)


def to_text(report: Report) -> str:
    """The report for a terminal: the same tables with aligned columns."""
    parts = [*_header(report), ""]
    for title, table in _tables(report):
        parts += [title, "-" * len(title), _aligned(table), ""]
    return "\n".join(parts)


def to_json(report: Report) -> dict[str, Any]:
    """The report as JSON-ready data: metric options, inputs, overall, scenarios, and each
    group's mean scenario F1. NaN becomes None."""
    return _without_nan({
        "metric": asdict(report.config),
        "inputs": report.inputs,
        "overall": report.overall,
        "scenarios": report.scenarios,
        "mean_scenario_f1": {group: mean_f1(rows) for group, rows in _groups(report).items()},
    })


def write_report(report: Report, out_dir: str | os.PathLike[str]) -> list[Path]:
    """Write ``report.json`` and ``report.md`` into out_dir (each atomically); their paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    texts = {
        out / REPORT_JSON: json.dumps(to_json(report), indent=1, allow_nan=False) + "\n",
        out / REPORT_MARKDOWN: to_markdown(report),
    }
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
    """(title, Markdown table) of each table of the report."""
    names = _display_names(report.config)
    metrics = [*_SCORES, *[names.get(n, n) for n in report.config.pair_value_names]]
    overall = _renamed(report.overall, names)
    tables = [("Overall", markdown_table([overall], ["num_frames", *metrics]))]
    for group, rows in _groups(report).items():
        tables.append((f"{group} scenarios: F1 (%)", _f1_row(report.overall["f1"], rows)))
    if report.scenarios:
        rows = [_renamed(row, names) for row in report.scenarios]
        tables.append(("Per scenario", markdown_table(rows, ["group", "scenario", "num_frames", *metrics])))
    return tables


def _display_names(config: OpenLaneConfig) -> dict[str, str]:
    """Metric key -> table key: with extra ranges, close / far are named by their y range."""
    if not config.extra_ranges:
        return {}
    ranges = {"close": f"0_{config.close_range:g}", "far": f"{config.close_range:g}_{config.extra_ranges[0]:g}"}
    return {f"{axis}_error_{name}": f"{axis}_error_{span}" for axis in "xz" for name, span in ranges.items()}


def _renamed(row: Mapping[str, Any], names: Mapping[str, str]) -> dict[str, Any]:
    return {names.get(key, key): value for key, value in row.items()}


def _groups(report: Report) -> dict[str, list[dict[str, str | int | float]]]:
    """Scenario rows by group, groups in order of appearance."""
    groups: dict[str, list[dict[str, str | int | float]]] = {}
    for row in report.scenarios:
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
