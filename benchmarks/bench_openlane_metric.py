"""Throughput of the OpenLane 3D-lane metric: frames/s on synthetic frames.

    python benchmarks/bench_openlane_metric.py [--frames 10000] [--lanes 10] [--batch 32]
                                               [--json out.json]

Each frame has `lanes` GT lanes (4 % of points invisible) and as many predictions (jittered
copies, some shifted a lane over or shortened), 20-60 points each, in the ground frame.
Rows, for the official config and the long-range one (SparseLaneSTP: 3..200 m, four error
ranges, Vis-IoU):

- "frames": evaluate_frame on every frame plus summarize (the file evaluator without
  JSON reading);
- "metric": OpenLaneMetric.update on batches of `batch` frames (NaN-padded float32
  tensors, built beforehand) plus compute -- the validation-loop path.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np
import torch

from lanelab.metrics.openlane import OpenLaneConfig, evaluate_frame, summarize
from lanelab.metrics.openlane_metric import LaneBatch, OpenLaneMetric


def synthetic_frame(rng: np.random.Generator, lanes: int) -> tuple[list, list, list, list, list]:
    gt, vis, gt_cat, pred, pred_cat = [], [], [], [], []
    for i in range(lanes):
        x0 = -12.0 + 24.0 * (i + rng.random()) / lanes
        bend = rng.normal(0.0, 5e-4)
        y = np.sort(rng.uniform(0.0, rng.uniform(40.0, 120.0), rng.integers(20, 60)))
        lane = np.stack([x0 + bend * y**2, y, 0.01 * y], axis=1)
        gt.append(lane)
        vis.append((rng.random(len(y)) > 0.04).astype(float))
        gt_cat.append(int(rng.integers(1, 13)))
        noisy = lane + rng.normal(0.0, 0.2, lane.shape)
        if rng.random() < 0.2:
            noisy[:, 0] += 3.5
        pred.append(noisy[: max(2, int(len(y) * rng.uniform(0.5, 1.0)))])
        pred_cat.append(gt_cat[-1] if rng.random() < 0.8 else int(rng.integers(1, 13)))
    return gt, vis, gt_cat, pred, pred_cat


def as_batches(frames: list, size: int) -> list[tuple[LaneBatch, LaneBatch]]:
    """(predictions, GT) LaneBatch pairs of `size` frames, float32 as a model gives them."""
    batches = []
    for start in range(0, len(frames), size):
        chunk = frames[start : start + size]
        gt, vis, gt_cat, pred, pred_cat = (list(column) for column in zip(*chunk))
        pred_vis = [[np.ones(len(lane)) for lane in lanes] for lanes in pred]
        pair = LaneBatch.from_lists(pred, pred_vis, pred_cat), LaneBatch.from_lists(gt, vis, gt_cat)
        batches.append(tuple(
            b._replace(points=b.points.float(), visibility=b.visibility.float()) for b in pair
        ))
    return batches


def timed(run) -> tuple[float, dict]:
    start = time.perf_counter()
    metrics = run()
    return time.perf_counter() - start, metrics


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=10_000)
    parser.add_argument("--lanes", type=int, default=10)
    parser.add_argument("--batch", type=int, default=32)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", help="also write the rows to this file")
    args = parser.parse_args()

    torch.set_num_threads(1)
    rng = np.random.default_rng(args.seed)
    frames = [synthetic_frame(rng, args.lanes) for _ in range(args.frames)]
    batches = as_batches(frames, args.batch)

    def metric_path(config: OpenLaneConfig) -> dict:
        metric = OpenLaneMetric(config)
        for preds, target in batches:
            metric.update(preds, target)
        return {key: float(value) for key, value in metric.compute().items()}

    rows = []
    configs = {"official": OpenLaneConfig(), "long_range": OpenLaneConfig.long_range()}
    for name, config in configs.items():
        runs = {
            "frames": lambda: summarize(evaluate_frame(*f, config=config) for f in frames),
            "metric": lambda: metric_path(config),
        }
        for path, run in runs.items():
            seconds, metrics = timed(run)
            rows.append({
                "config": name,
                "path": path,
                "frames": args.frames,
                "lanes_per_frame": args.lanes,
                "seconds": round(seconds, 2),
                "frames_per_s": round(args.frames / seconds, 1),
                "f1": round(metrics["f1"], 4),
            })

    columns = list(rows[0])
    print("| " + " | ".join(columns) + " |")
    print("|" + "---|" * len(columns))
    for row in rows:
        print("| " + " | ".join(str(row[c]) for c in columns) + " |")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(rows, f, indent=2)


if __name__ == "__main__":
    main()
