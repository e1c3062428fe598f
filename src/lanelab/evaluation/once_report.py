"""The ONCE-3DLanes report: the metric's row at every score threshold, and the best row.

Published ONCE-3DLanes numbers (the benchmark's paper, PersFormer, LATR, SparseLaneSTP's Table 6)
are the row of highest F1 over the score thresholds 0.10, 0.15, ..., 0.95
(:func:`lanelab.metrics.once.best`); the whole table shows how the numbers move with the threshold.
``report.json`` holds ``metric``, ``inputs``, ``best`` and ``thresholds`` (NaN written as null:
no prediction above a threshold), ``report.md`` the table with the best row marked.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from lanelab.evaluation.report import REPORT_JSON, REPORT_MARKDOWN, write_texts
from lanelab.metrics.once import best

Row = Mapping[str, float | int]


def once_report(rows: Sequence[Row], inputs: Mapping[str, str]) -> dict[str, Any]:
    """The report of :func:`lanelab.metrics.once.summarize_once` rows; inputs: name -> path scored."""
    return {"metric": "ONCE-3DLanes", "inputs": dict(inputs), "best": _finite(best(rows)),
            "thresholds": [_finite(row) for row in rows]}  # fmt: skip


def once_markdown(report: Mapping[str, Any]) -> str:
    """The report as a Markdown table, one row per score threshold, the best in bold."""
    chosen = report["best"]["score_threshold"]
    lines = [
        "# ONCE-3DLanes",
        "",
        *(f"- {name}: `{path}`" for name, path in report["inputs"].items()),
        "",
        "| score > | F1 (%) | precision (%) | recall (%) | CD (m) | TP | predicted | GT |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for row in report["thresholds"]:
        cells = [f"{row['score_threshold']:.2f}", _percent(row["f1"]), _percent(row["precision"]),
                 _percent(row["recall"]), _number(row["cd"], 3), str(row["tp"]), str(row["pred_lanes"]),
                 str(row["gt_lanes"])]  # fmt: skip
        if row["score_threshold"] == chosen:
            cells = [f"**{cell}**" for cell in cells]
        lines.append("| " + " | ".join(cells) + " |")
    b = report["best"]
    lines += ["", f"Best (the published row): score > {b['score_threshold']:.2f}: F1 {_percent(b['f1'])} %, "
              f"precision {_percent(b['precision'])} %, recall {_percent(b['recall'])} %, CD {_number(b['cd'], 3)} m "
              f"over {b['num_frames']} frames", ""]  # fmt: skip
    return "\n".join(lines)


def write_once_report(report: Mapping[str, Any], out_dir: str | os.PathLike[str]) -> list[Path]:
    """Write ``report.json`` and ``report.md`` into out_dir (each atomically); their paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    texts = {out / REPORT_JSON: json.dumps(report, indent=1, allow_nan=False) + "\n",
             out / REPORT_MARKDOWN: once_markdown(report)}  # fmt: skip
    return write_texts(texts)


def _finite(row: Row) -> dict[str, float | int | None]:
    return {key: None if isinstance(value, float) and math.isnan(value) else value for key, value in row.items()}


def _percent(value: float | None) -> str:
    return "-" if value is None else f"{100 * value:.2f}"


def _number(value: float | None, digits: int) -> str:
    return "-" if value is None else f"{value:.{digits}f}"
