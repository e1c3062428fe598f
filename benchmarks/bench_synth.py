"""Synthetic drive-log generator speed: frames per second at 360x480 and 720x960.

    python benchmarks/bench_synth.py [--frames 100] [--repeats 3] [--json out.json]

For each resolution and scenario it times, in one run, (a) the world + renderer +
ground truth alone (``SyntheticDrive.frames()``) and (b) the whole log written as MCAP
(JPEG images, zstd chunks, ROS 2 encoding). Figures are medians over ``--repeats``.
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import tempfile
import time
from pathlib import Path

import torch

from data_ingest.synth.config import load_synth_config
from data_ingest.synth.drive import SyntheticDrive
from data_ingest.synth.mcap_writer import write_drive_log

RESOLUTIONS = [(360, 480), (720, 960)]
SCENARIOS = {
    "highway/day/sun": ["world.environment=highway", "world.daytime=day", "world.weather=sun"],
    "urban/night/rain": ["world.environment=urban", "world.daytime=night", "world.weather=rain"],
    "rural/day/fog": ["world.environment=rural", "world.daytime=day", "world.weather=fog"],
}


def _rate(frames: int, fn) -> float:
    start = time.perf_counter()
    fn()
    return frames / (time.perf_counter() - start)


def measure(height: int, width: int, scenario: list[str], frames: int, repeats: int) -> dict:
    fps = 10.0
    cfg = load_synth_config([f"camera.height={height}", f"camera.width={width}",
                             f"duration_s={frames / fps}", f"fps={fps}", *scenario])
    render, write = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for repeat in range(repeats):
            render.append(_rate(frames, lambda: sum(1 for _ in SyntheticDrive(cfg, 0).frames())))
            path = Path(tmp) / f"bench_{repeat}.mcap"
            write.append(_rate(frames, lambda: write_drive_log(path, SyntheticDrive(cfg, 0), cfg)))
        size = path.stat().st_size
    return {"render_fps": statistics.median(render), "write_fps": statistics.median(write),
            "mb_per_min": size / 1e6 / (frames / fps) * 60}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=100)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    torch.set_num_threads(1)

    print(f"machine: {platform.processor() or platform.machine()}, {torch.get_num_threads()} torch thread, "
          f"{args.frames} frames x {args.repeats} repeats, medians")
    print(f"{'resolution':<11}{'scenario':<19}{'render+GT fps':>14}{'MCAP log fps':>14}{'MB/min':>9}")
    rows = []
    for height, width in RESOLUTIONS:
        for name, overrides in SCENARIOS.items():
            row = {"resolution": f"{height}x{width}", "scenario": name,
                   **measure(height, width, overrides, args.frames, args.repeats)}
            rows.append(row)
            print(f"{row['resolution']:<11}{name:<19}{row['render_fps']:>14.1f}{row['write_fps']:>14.1f}"
                  f"{row['mb_per_min']:>9.1f}")
    if args.json:
        args.json.write_text(json.dumps(rows, indent=2))


if __name__ == "__main__":
    main()
