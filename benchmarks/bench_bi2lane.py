"""Bi²Lane inference speed against the number of history frames, with and without the frame cache.

    python benchmarks/bench_bi2lane.py [--configs tiny paper] [--history 0 1 2 3 4 5] [--device cpu|cuda]
        [--dtype fp32|bf16] [--cuda-graphs on|off] [--malloc default|reuse] [--frames 10] [--warmup 3]
        [--threads N] [--json out.json] [--count-operators]

Each configuration is conf/'s: "tiny" = ``experiment=tiny model=bi2lane`` (at its 64 x 96 images),
"paper" = ``model=bi2lane`` (ResNet-50, Anchor3DLane's anchors) at 360 x 480 (Anchor3DLane's input).
For every N (0: the single-frame baseline's computation, bi2lane with no history frames) a model
with random weights runs the same random clip of one stream, eval mode, no gradient, two ways:
- cached: ``reset`` once, then ``step`` per frame (one backbone pass a frame, the past frames'
  features from the cache);
- uncached: ``forward`` on the window of the N + 1 latest frames (N + 1 backbone passes).
On a GPU, cached streaming replays each frame's kernels from CUDA graphs (``model.net.cuda_graphs``,
``--cuda-graphs off`` to launch them one by one); the uncached ``forward`` always launches them.
Variants run interleaved frame by frame, so that load from other processes affects them alike;
figures are medians over the timed frames (after ``--warmup``). The paper's Table VI grows from
29 ms (1 history frame) to 44 ms (5), +52 %; "growth" below is the same ratio, 5 frames over 1.

``--malloc reuse`` (Linux, glibc) keeps freed memory in the process instead of handing every
block of over 32 MB back to the kernel, as a caching allocator (jemalloc, tcmalloc) does. The
paper configuration's per-frame tensors are tens of megabytes (4431 anchors x 20 points x 64
channels is 23 MB a frame), and glibc maps each one afresh: on the CPU the page faults of those
fresh pages, not the arithmetic, were most of what a history frame cost.

``--count-operators`` prints, instead of timings, how many operators that compute a tensor (not
views) one cached step runs per N, on the CPU but along the GPU's paths (grid_sample, one BLFA
call over all anchors): at batch 1 on a GPU each is a kernel launch, and launches, not
arithmetic, are most of what a history frame costs there. With the count, the megabytes those
operators write: what is left of a history frame's GPU time once launches are few is memory traffic.
"""

from __future__ import annotations

import argparse
import ctypes
import json
import platform
import statistics
import time
from contextlib import nullcontext
from pathlib import Path

import torch
from hydra.utils import instantiate

import lanelab.models.bi2lane.anchors as anchors_module
import lanelab.models.bi2lane.model as model_module
from lanelab.experiment.config import load_train_config
from lanelab.runtime.operator_log import OperatorLog

CONFIGS = {
    "tiny": (["experiment=tiny", "model=bi2lane"], (64, 96)),
    "paper": (["model=bi2lane"], (360, 480)),
}
CAMERA_KEYS = ("K", "T_lane_cam", "T_world_lane")


def build(config: str, history: int, device: torch.device, cuda_graphs: bool) -> torch.nn.Module:
    overrides, _ = CONFIGS[config]
    extra = [f"model.net.num_history_frames={history}", f"model.net.cuda_graphs={cuda_graphs}"]
    cfg = load_train_config([*overrides, *extra, "paths.output_dir=unused"])
    torch.manual_seed(0)
    return instantiate(cfg.model.net).to(device).eval()


def clip(num_frames: int, image_size: tuple[int, int], device: torch.device) -> list[dict[str, torch.Tensor]]:
    """A random clip of one stream: images, a forward-looking camera, an ego driving 2 m a frame."""
    H, W = image_size
    K = torch.tensor([[0.9 * W, 0.0, W / 2], [0.0, 0.9 * W, H / 2], [0.0, 0.0, 1.0]])
    T_lane_cam = torch.tensor([[1.0, 0, 0, 0], [0, 0, 1, 1.5], [0, -1, 0, 1.5], [0, 0, 0, 1]])
    frames = []
    for f in range(num_frames):
        pose = torch.eye(4, dtype=torch.float64)
        pose[1, 3] = 2.0 * f
        camera = {"K": K[None], "T_lane_cam": T_lane_cam[None], "T_world_lane": pose[None]}
        frames.append({"images": torch.randn(1, 3, H, W), **camera})
    return [{key: value.to(device) for key, value in frame.items()} for frame in frames]


def window(frames: list[dict[str, torch.Tensor]], f: int, history: int) -> dict[str, torch.Tensor]:
    """The windowed input of frame f: its N + 1 latest frames, a clip's start padded with its first frame."""
    positions = [max(p, 0) for p in range(f - history, f + 1)]
    batch = {key: torch.stack([frames[p][key] for p in positions], 1) for key in ("images", *CAMERA_KEYS)}
    batch["valid"] = torch.tensor([[p >= 0 for p in range(f - history, f + 1)]], device=batch["images"].device)
    return batch


def timed(call, device: torch.device) -> float:
    if device.type == "cuda":
        torch.cuda.synchronize()
    start = time.perf_counter()
    call()
    if device.type == "cuda":
        torch.cuda.synchronize()
    return time.perf_counter() - start


def run(config: str, histories: list[int], args: argparse.Namespace, device: torch.device) -> list[dict]:
    frames = clip(args.warmup + args.frames, CONFIGS[config][1], device)
    models = {n: build(config, n, device, args.cuda_graphs == "on") for n in histories}
    autocast = torch.autocast(device.type, dtype=torch.bfloat16) if args.dtype == "bf16" else nullcontext()
    times = {(n, mode): [] for n in histories for mode in ("cached", "uncached")}
    with torch.no_grad(), autocast:
        for model in models.values():
            model.reset(torch.ones(1, dtype=torch.bool, device=device))
        for f, frame in enumerate(frames):
            for n, model in models.items():
                cached = timed(lambda: model.step(frame), device)
                uncached = timed(lambda: model(window(frames, f, n)), device)
                if f >= args.warmup:
                    times[(n, "cached")].append(cached)
                    times[(n, "uncached")].append(uncached)
    rows = []
    for n in histories:
        for mode in ("cached", "uncached"):
            median = statistics.median(times[(n, mode)])
            rows.append({"config": config, "history_frames": n, "mode": mode, "ms": 1000 * median, "fps": 1 / median})
    return rows


def count_operators(config: str, histories: list[int]) -> list[dict]:
    """Operators of one cached step (after a few, so the cache is full) per N, on the CPU as a
    GPU runs it: grid_sample for every sample and BLFA over all anchors in one call."""
    device = torch.device("cpu")
    rows = []
    cpu_paths = anchors_module._LARGE_SAMPLE, model_module._CPU_AGGREGATION_CHUNK
    anchors_module._LARGE_SAMPLE = model_module._CPU_AGGREGATION_CHUNK = 1 << 62  # never taken
    try:
        for n in histories:
            model = build(config, n, device, cuda_graphs=False)
            frames = clip(n + 2, CONFIGS[config][1], device)
            with torch.no_grad():
                model.reset(torch.ones(1, dtype=torch.bool))
                for frame in frames[:-1]:
                    model.step(frame)
                with OperatorLog() as log:
                    model.step(frames[-1])
            written = log.bytes_written() / 1e6
            rows.append({"config": config, "history_frames": n, "operators": log.kernels(), "MB": written})
    finally:
        anchors_module._LARGE_SAMPLE, model_module._CPU_AGGREGATION_CHUNK = cpu_paths
    return rows


def reuse_freed_memory() -> None:
    """glibc: serve every allocation from the heap (no fresh mmap) and never trim the heap."""
    libc = ctypes.CDLL("libc.so.6")
    M_TRIM_THRESHOLD, M_MMAP_MAX = -1, -4  # mallopt parameters, malloc.h
    if not (libc.mallopt(M_MMAP_MAX, 0) and libc.mallopt(M_TRIM_THRESHOLD, 2**31 - 1)):
        raise SystemExit("--malloc reuse: glibc's mallopt refused")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--configs", nargs="+", default=["tiny", "paper"], choices=sorted(CONFIGS))
    parser.add_argument("--history", nargs="+", type=int, default=[0, 1, 2, 3, 4, 5])
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--dtype", default="fp32", choices=["fp32", "bf16"])
    parser.add_argument("--cuda-graphs", default="on", choices=["on", "off"], help="cached streaming on a GPU")
    parser.add_argument("--malloc", default="default", choices=["default", "reuse"],
                        help="reuse: keep freed memory for reuse (glibc; the CPU figures' allocator)")
    parser.add_argument("--frames", type=int, default=10)
    parser.add_argument("--warmup", type=int, default=3)
    parser.add_argument("--threads", type=int, default=None)
    parser.add_argument("--json", type=Path, default=None)
    parser.add_argument("--count-operators", action="store_true", help="count a step's operators instead of timing")
    args = parser.parse_args()
    if args.threads:
        torch.set_num_threads(args.threads)
    if args.malloc == "reuse":
        reuse_freed_memory()
    if args.count_operators:
        print_operator_counts(args)
        return
    device = torch.device(args.device)
    if device.type == "cuda":
        machine = torch.cuda.get_device_name(device)
    else:
        machine = f"{platform.processor() or platform.machine()}, {torch.get_num_threads()} threads"
    graphs = f", CUDA graphs {args.cuda_graphs}" if device.type == "cuda" else ""
    print(f"Bi²Lane inference, {args.dtype}{graphs}, malloc {args.malloc}, {machine}; medians over {args.frames} frames after {args.warmup}")
    print("| config | history frames | cached ms | cached FPS | uncached ms | uncached FPS |")
    print("|---|---:|---:|---:|---:|---:|")
    rows = []
    for config in args.configs:
        mine = run(config, args.history, args, device)
        rows += mine
        by = {(r["history_frames"], r["mode"]): r for r in mine}
        for n in args.history:
            c, u = by[(n, "cached")], by[(n, "uncached")]
            print(f"| {config} | {n} | {c['ms']:.1f} | {c['fps']:.1f} | {u['ms']:.1f} | {u['fps']:.1f} |")
        if {1, 5} <= set(args.history):
            for mode in ("cached", "uncached"):
                growth = by[(5, mode)]["ms"] / by[(1, mode)]["ms"] - 1
                per_frame = (by[(5, mode)]["ms"] - by[(1, mode)]["ms"]) / 4
                print(f"{config}, {mode}: 5 history frames cost {100 * growth:+.1f} % over 1, {per_frame:.2f} ms a"
                      " history frame (paper: +52 %)")
    if args.json:
        args.json.write_text(json.dumps({"machine": machine, "dtype": args.dtype, "cuda_graphs": args.cuda_graphs,
                                          "malloc": args.malloc, "rows": rows}, indent=1))


def print_operator_counts(args: argparse.Namespace) -> None:
    print("Bi²Lane, operators that compute a tensor in one cached step (each a kernel launch on a GPU)"
          " and the MB they write")
    print("| config | history frames | operators | MB written |")
    print("|---|---:|---:|---:|")
    rows = []
    for config in args.configs:
        mine = count_operators(config, args.history)
        rows += mine
        for row in mine:
            print(f"| {config} | {row['history_frames']} | {row['operators']} | {row['MB']:.0f} |")
        by = {row["history_frames"]: row for row in mine}
        if {1, 5} <= set(by):
            per_frame = {key: (by[5][key] - by[1][key]) / 4 for key in ("operators", "MB")}
            print(f"{config}: {per_frame['operators']:.1f} operators and {per_frame['MB']:.0f} MB written"
                  " per history frame")
    if args.json:
        args.json.write_text(json.dumps({"operators": rows}, indent=1))


if __name__ == "__main__":
    main()
