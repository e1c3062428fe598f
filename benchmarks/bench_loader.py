"""Loader speed: training samples per second for F = 4 frames at 360x480, with 0, 1 and 2 workers.

    python benchmarks/bench_loader.py [--frames 200] [--batches 12] [--repeats 3] [--json out.json]

The store holds synthetic drives (JPEG quality 90, as ``lanelab-synth`` writes them), written
straight from the generator with the clip store's writer. Each measurement is the training
loader of ``ClipDataModule`` as ``conf/data/clips.yaml`` + ``conf/sampler/window.yaml`` build it
(4 frames, photometric augmentation, lane targets), timed over ``--batches`` batches after the
first (which pays for starting the workers); figures are medians over ``--repeats`` fresh
loaders. A second table splits one sample's time into its stages (0 workers).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import tempfile
import time
from pathlib import Path

import cv2
import torch
from hydra.utils import instantiate
from omegaconf import OmegaConf

from data_ingest.synth.config import load_synth_config
from data_ingest.synth.drive import SyntheticDrive
from lanelab.geometry.frames import extrinsic_base_to_lane, pose_base_to_lane
from lanelab.store import ClipEntry, FrameRecord, Manifest, write_clip, write_manifest
from lanelab.store.image_codec import decode_image

CONF = Path(__file__).resolve().parents[1] / "conf"
HEIGHT, WIDTH, NUM_FRAMES, BATCH_SIZE = 360, 480, 4, 8


def write_store(root: Path, num_frames: int, clip_frames: int = 100) -> None:
    """Synthetic drives at 360x480 as a store of clips of ``clip_frames`` frames."""
    cfg = load_synth_config([f"camera.height={HEIGHT}", f"camera.width={WIDTH}", "fps=10",
                             f"duration_s={clip_frames / 10}"])
    entries = []
    for clip in range(-(-num_frames // clip_frames)):
        drive = SyntheticDrive(cfg, clip)
        T_lane_cam = extrinsic_base_to_lane(torch.from_numpy(drive.camera.T_base_cam)).numpy()
        records = []
        for frame in drive.frames():
            ok, jpeg = cv2.imencode(".jpg", frame.image, [cv2.IMWRITE_JPEG_QUALITY, 90])
            assert ok
            records.append(FrameRecord(
                frame.timestamp_ns, jpeg.tobytes(), "jpeg", WIDTH, HEIGHT, drive.camera.K, T_lane_cam,
                pose_base_to_lane(torch.from_numpy(frame.T_world_base)).numpy(), True,
                frame.lanes,
                frame.tags,
            ))
        clip_id = f"synth{clip:03d}"
        write_clip(root, clip_id, records)
        entries.append(ClipEntry(clip_id, f"synth{clip}.mcap", "train", len(records), records[0].timestamp_ns,
                                 records[-1].timestamp_ns))
    write_manifest(root, Manifest(clips=entries))


def data_module(store: Path, num_workers: int):
    cfg = OmegaConf.create({"data": OmegaConf.load(CONF / "data" / "clips.yaml"),
                            "sampler": OmegaConf.load(CONF / "sampler" / "window.yaml")})
    cfg.data = OmegaConf.merge(cfg.data, {"store": str(store), "image_size": [HEIGHT, WIDTH], "num_frames": NUM_FRAMES,
                                          "batch_size": BATCH_SIZE, "num_workers": num_workers})
    return instantiate(cfg.data)


def loader_rate(store: Path, num_workers: int, batches: int) -> float:
    """Samples per second of a fresh training loader, after its first batch."""
    iterator = iter(data_module(store, num_workers).train_dataloader())
    next(iterator)
    start = time.perf_counter()
    for _ in range(batches):
        next(iterator)
    return batches * BATCH_SIZE / (time.perf_counter() - start)


def stage_times(store: Path, samples: int) -> dict[str, float]:
    """Median milliseconds per sample of each stage, measured on their own."""
    dataset = data_module(store, 0).dataset("train")
    clip_id = dataset.index.clip_ids[0]
    times: dict[str, list[float]] = {"read 4 frames": [], "decode 4 JPEGs": [], "lane targets": [], "whole sample": []}
    for i in range(samples):
        end = NUM_FRAMES + i % 50
        t0 = time.perf_counter()
        records = dataset.store.read_frames(clip_id, end - NUM_FRAMES, end)
        t1 = time.perf_counter()
        for record in records:
            decode_image(record)
        t2 = time.perf_counter()
        dataset.targets(records[-1].lanes)
        t3 = time.perf_counter()
        dataset[end - 1]
        t4 = time.perf_counter()
        for name, seconds in zip(times, (t1 - t0, t2 - t1, t3 - t2, t4 - t3)):
            times[name].append(seconds * 1e3)
    return {name: statistics.median(values) for name, values in times.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=200, help="frames in the store")
    parser.add_argument("--batches", type=int, default=12, help=f"timed batches of {BATCH_SIZE} per measurement")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    torch.set_num_threads(1)  # as in a DataLoader worker

    with tempfile.TemporaryDirectory() as tmp:
        store = Path(tmp) / "store"
        write_store(store, args.frames)
        print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, load average "
              f"{os.getloadavg()[0]:.1f}, {torch.get_num_threads()} torch thread in the main process; "
              f"F={NUM_FRAMES} at {HEIGHT}x{WIDTH}, batch {BATCH_SIZE}, {args.batches} batches x {args.repeats} "
              "repeats, medians")
        print(f"{'workers':>7}{'samples/s':>11}{'frames/s':>10}{'ms/sample':>11}")
        rows = []
        for workers in (0, 1, 2):
            rate = statistics.median(loader_rate(store, workers, args.batches) for _ in range(args.repeats))
            rows.append({"workers": workers, "samples_per_s": rate, "frames_per_s": rate * NUM_FRAMES})
            print(f"{workers:>7}{rate:>11.1f}{rate * NUM_FRAMES:>10.1f}{1e3 / rate:>11.1f}")

        stages = stage_times(store, 30)
        print(f"\n{'stage (0 workers)':<20}{'ms/sample':>10}")
        for name, ms in stages.items():
            print(f"{name:<20}{ms:>10.2f}")
    if args.json:
        args.json.write_text(json.dumps({"loader": rows, "stages_ms": stages}, indent=2))


if __name__ == "__main__":
    main()
