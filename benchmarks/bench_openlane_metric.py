"""Throughput of the OpenLane 3D-lane metric: frames/s on synthetic frames.

    python benchmarks/bench_openlane_metric.py [--frames 10000] [--lanes 10] [--json out.json]

Each frame has `lanes` GT lanes (4 % of points invisible) and as many predictions (jittered
copies, some shifted a lane over or shortened), 20-60 points each, in the ground frame; the
timing covers evaluate_frame on every frame plus summarize, not JSON reading.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from lanelab.metrics.openlane import evaluate_frame, summarize


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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=10_000)
    parser.add_argument("--lanes", type=int, default=10)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", help="also write the numbers to this file")
    args = parser.parse_args()

    rng = np.random.default_rng(args.seed)
    frames = [synthetic_frame(rng, args.lanes) for _ in range(args.frames)]
    start = time.perf_counter()
    metrics = summarize(evaluate_frame(*frame) for frame in frames)
    seconds = time.perf_counter() - start

    row = {
        "frames": args.frames,
        "lanes_per_frame": args.lanes,
        "seconds": round(seconds, 3),
        "frames_per_s": round(args.frames / seconds, 1),
        "f1": round(metrics["f1"], 4),
    }
    width = max(map(len, row))
    for key, value in row.items():
        print(f"{key:<{width}}  {value}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(row, f, indent=2)


if __name__ == "__main__":
    main()
