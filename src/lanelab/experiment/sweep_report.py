"""``lanelab-sweep-report``: a Hydra multirun of ``lanelab-train`` as the papers' ablation tables.

    lanelab-sweep-report runs/<task_name>/multirun/<time> [--out DIR]

Reads every job folder of the multirun (``<job>/.hydra/overrides.yaml`` and the
``metrics.json`` that ``lanelab-train`` writes), finds the overrides whose values differ
between jobs (the swept keys), and writes into the multirun folder (or ``--out``):

- ``sweep_report.md``: one row per job, the swept values, F1, precision, recall and the x / z
  errors per range (test metrics where the jobs tested, else the last validation's), as in
  SparseLaneSTP's Tables 2 and 3;
- ``sweep_report.csv``: the same numbers, unrounded (fractions in [0, 1], errors in metres);
- ``sweep_f1.png``: F1 against the swept value (matplotlib if installed, else OpenCV).

Jobs without ``metrics.json`` (failed or still running) are listed and left out.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import sys
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import yaml

from lanelab.atomic_file import atomic_output
from lanelab.experiment import METRICS_JSON
from lanelab.metrics.scenarios import markdown_table

REPORT_MD, REPORT_CSV, PLOT_PNG = "sweep_report.md", "sweep_report.csv", "sweep_f1.png"
_SCORES = ("f1", "precision", "recall")


@dataclass(frozen=True)
class Job:
    """One run of the sweep: its folder, overrides (key -> value as written) and metrics."""

    folder: Path
    overrides: dict[str, str]
    metrics: dict[str, float | None]


def read_jobs(multirun: Path) -> tuple[list[Job], list[Path]]:
    """The finished jobs of a multirun folder, in job order, and the folders without metrics."""
    jobs, unfinished = [], []
    folders = sorted((p.parent.parent for p in multirun.glob("*/.hydra/overrides.yaml")), key=_job_order)
    for folder in folders:
        if not (folder / METRICS_JSON).is_file():
            unfinished.append(folder)
            continue
        lines = yaml.safe_load((folder / ".hydra" / "overrides.yaml").read_text()) or []
        overrides = dict(line.lstrip("+~").split("=", 1) for line in lines)
        jobs.append(Job(folder, overrides, json.loads((folder / METRICS_JSON).read_text())))
    return jobs, unfinished


def swept_keys(jobs: list[Job]) -> list[str]:
    """Override keys whose value differs between jobs, in the order of the first job."""
    keys = list(dict.fromkeys(key for job in jobs for key in job.overrides))
    return [key for key in keys if len({job.overrides.get(key) for job in jobs}) > 1]


def table_rows(jobs: list[Job], keys: list[str]) -> tuple[list[dict[str, object]], list[str]]:
    """One row per job (swept values, then the metrics without their stage prefix) and the
    metric columns: test metrics where any job has them, else validation metrics."""
    stage = "test/" if any(key.startswith("test/") for job in jobs for key in job.metrics) else "val/"
    names = sorted({key[len(stage):] for job in jobs for key in job.metrics if key.startswith(stage)})
    errors = [name for name in names if name.startswith(("x_error_", "z_error_"))]
    columns = [name for name in _SCORES if name in names] + errors + (["vis_iou"] if "vis_iou" in names else [])
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


def write_report(multirun: Path, out: Path) -> list[Path]:
    """Write the table, the CSV and the plot for a multirun folder; their paths."""
    jobs, unfinished = read_jobs(multirun)
    for folder in unfinished:
        print(f"lanelab-sweep-report: {folder} has no {METRICS_JSON} (failed or unfinished); left out", file=sys.stderr)
    if not jobs:
        raise FileNotFoundError(f"{multirun}: no finished lanelab-train job (<job>/.hydra and {METRICS_JSON})")
    keys = swept_keys(jobs) or ["job"]
    if keys == ["job"]:
        jobs = [Job(job.folder, {"job": job.folder.name}, job.metrics) for job in jobs]
    rows, columns = table_rows(jobs, keys)
    out.mkdir(parents=True, exist_ok=True)

    markdown = f"# Sweep {multirun}\n\n" + markdown_table(rows, [*keys, *columns])
    with atomic_output(out / REPORT_MD) as tmp:
        tmp.write_text(markdown)
    with atomic_output(out / REPORT_CSV) as tmp, tmp.open("w", newline="") as f:
        writer = csv.DictWriter(f, [*keys, *columns])
        writer.writeheader()
        writer.writerows(rows)
    labels = [", ".join(str(row[key]) for key in keys) for row in rows]
    f1 = [100 * float(row["f1"]) for row in rows] if "f1" in columns else [float("nan")] * len(rows)
    plot_f1(out / PLOT_PNG, " / ".join(keys), labels, f1)
    print(markdown)
    return [out / REPORT_MD, out / REPORT_CSV, out / PLOT_PNG]


def plot_f1(path: Path, x_name: str, labels: list[str], f1: list[float]) -> None:
    """F1 (%) against the swept values: a line over numbers, points over names."""
    numeric = all(_is_number(label) for label in labels)
    x = [float(label) for label in labels] if numeric else list(range(len(labels)))
    try:
        import matplotlib
    except ImportError:
        _plot_with_opencv(path, x_name, labels, x, f1)
        return
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(figsize=(6, 4), dpi=100)
    axes.plot(x, f1, "o-" if numeric else "o")
    axes.set_xticks(x, labels)
    axes.set(xlabel=x_name, ylabel="F1 (%)", title="F1 against " + x_name)
    axes.grid(alpha=0.3)
    figure.tight_layout()
    with atomic_output(path) as tmp:
        figure.savefig(tmp, format="png")
    plt.close(figure)


def _plot_with_opencv(path: Path, x_name: str, labels: list[str], x: list[float], f1: list[float]) -> None:
    width, height, margin = 600, 400, 60
    canvas = np.full((height, width, 3), 255, np.uint8)
    black, grey, blue = (0, 0, 0), (200, 200, 200), (180, 110, 30)
    finite = [v for v in f1 if math.isfinite(v)] or [0.0]
    y_low, y_high = max(min(finite) - 1.0, 0.0), max(finite) + 1.0
    x_low, x_high = min(x), max(x) if max(x) > min(x) else min(x) + 1.0

    def pixel(xv: float, yv: float) -> tuple[int, int]:
        u = margin + (xv - x_low) / (x_high - x_low) * (width - 2 * margin)
        v = height - margin - (yv - y_low) / (y_high - y_low) * (height - 2 * margin)
        return round(u), round(v)

    for yv in np.linspace(y_low, y_high, 5):  # horizontal grid with F1 ticks
        u, v = pixel(x_low, yv)
        cv2.line(canvas, (margin, v), (width - margin, v), grey, 1)
        cv2.putText(canvas, f"{yv:.1f}", (5, v + 4), cv2.FONT_HERSHEY_SIMPLEX, 0.4, black, 1, cv2.LINE_AA)
    points = [pixel(xv, yv) for xv, yv in zip(x, f1) if math.isfinite(yv)]
    if len(points) > 1 and all(_is_number(label) for label in labels):
        cv2.polylines(canvas, [np.array(points, np.int32)], False, blue, 2, cv2.LINE_AA)
    for point in points:
        cv2.circle(canvas, point, 4, blue, -1, cv2.LINE_AA)
    for xv, label in zip(x, labels):
        u, _ = pixel(xv, y_low)
        cv2.putText(canvas, label, (u - 4 * len(label), height - margin + 18), cv2.FONT_HERSHEY_SIMPLEX, 0.4, black, 1)
    cv2.putText(canvas, x_name, (width // 2 - 4 * len(x_name), height - 15), cv2.FONT_HERSHEY_SIMPLEX, 0.5, black, 1)
    cv2.putText(canvas, "F1 (%)", (5, margin - 20), cv2.FONT_HERSHEY_SIMPLEX, 0.5, black, 1)
    ok, png = cv2.imencode(".png", canvas)
    assert ok, "PNG encoding of a uint8 picture cannot fail"
    with atomic_output(path) as tmp:
        tmp.write_bytes(png.tobytes())


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
