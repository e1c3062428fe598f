"""SparseLaneSTP streaming inference speed and the cost of temporal fusion.

    python benchmarks/bench_sparselanestp.py [--configs tiny paper] [--device cpu|cuda]
        [--dtype fp32|bf16] [--cuda-graphs on|off] [--frames 10] [--warmup 3] [--threads N] [--json out.json]
        [--count-operators]

For each configuration three models with random weights stream the same random clip
(``reset`` once, then ``step`` per frame, eval mode, no gradient):
- ``SparseLaneSTP``: T = 3 memory frames, STA (SLA + PNA + TCA; ``auto``: the fused dense kernel on a
  GPU, the sparse path on a CPU, as conf/model/sparselanestp.yaml), Catmull-Rom;
- ``T=0``: the same model without the memory (SLA + PNA only);
- ``LATR-like``: the single-frame baseline (T = 0, global self-attention, discrete).
The variants run interleaved, frame by frame, so that load from other processes affects them
alike; figures are medians over the timed frames (after ``--warmup`` frames). The temporal
overhead is time(T=3) / time(T=0) - 1; the paper reports 9 % (Fig. 7: 11.0 vs 12.1 FPS
against LATR with six layers). ``--dtype bf16`` runs under torch.autocast. On a GPU a step
replays from a CUDA graph (``cuda_graphs``, :mod:`lanelab.runtime.cuda_graph`); ``--cuda-graphs off``
launches its kernels one by one.

``--count-operators`` prints, instead of timings, how many operators that compute a tensor one
streaming step runs (with a full memory), for STA's sparse and dense paths, counted on the CPU
(``lanelab.runtime.operator_log``; the count does not depend on the image size, so small images
are used). At batch 1 on a GPU each is a kernel launch, and the launches are what a frame costs.

The paper configuration is §5.2's: ResNet-50, 720 x 960, L = 6, N = 40, M = 20, T = 3; the
rest follows LATR's OpenLane config (C = 256, 4 heads, FFN 2048, x in [-30, 30] m,
z in [-5, 5] m, y in [3, 103] m) with N_mem = 10 lines per memory frame and deformable
attention over 4 FPN levels x 4 points.
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import time
from contextlib import nullcontext
from pathlib import Path

import torch

from lanelab.geometry import make_transform
from lanelab.models.categories import NUM_LANE_CATEGORIES
from lanelab.models.sparselanestp import SparseLaneSTP
from lanelab.runtime.operator_log import OperatorLog

_COMMON = dict(
    dropout=0.1, attention="auto", use_sla=True, use_pna=True, use_tca=True, pna_neighbors=2,
    tca_neighbors=10, num_classes=NUM_LANE_CATEGORIES, x_range=(-30.0, 30.0), y_range=(3.0, 103.0),
    z_range=(-5.0, 5.0), representation="catmull_rom", head_hidden_layers=2, ground_encoding=True, anchor_span=12.25, dca_content_weights=True,
    lateral_search={"num_candidates": 9, "search_range": 2.0},
)  # fmt: skip
CONFIGS = {
    "paper": dict(
        image_size=(720, 960),
        model=dict(
            _COMMON, backbone_depth=50, backbone_width=64, embed_dim=256, num_lines=40, num_points=20,
            query_convs=4, mask_dim=256, num_layers=6, num_heads=4, ffn_dim=2048, dca_levels=4, dca_points=4,
            num_memory_frames=3, num_memory_lines=10,
        ),  # fmt: skip
    ),
    "tiny": dict(
        image_size=(128, 192),
        model=dict(
            _COMMON, backbone_depth=18, backbone_width=16, embed_dim=64, num_lines=12, num_points=10,
            query_convs=2, mask_dim=32, num_layers=2, num_heads=4, ffn_dim=128, dca_levels=4, dca_points=4,
            num_memory_frames=3, num_memory_lines=4, tca_neighbors=6,
        ),  # fmt: skip
    ),
}
VARIANTS = {
    "SparseLaneSTP T=3": {},
    "T=0": {"num_memory_frames": 0},
    "LATR-like": {"num_memory_frames": 0, "attention": "global", "representation": "discrete"},
}


def clip(num_frames: int, image_size: tuple[int, int], device: torch.device) -> list[dict[str, torch.Tensor]]:
    """A random clip seen by a camera 1.5 m up, driving 1 m per frame."""
    height, width = image_size
    focal = 1.0 * width
    K = torch.tensor([[focal, 0.0, width / 2], [0.0, focal, height / 2], [0.0, 0.0, 1.0]])
    R = torch.tensor([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])  # optical -> lane axes
    T_lane_cam = make_transform(R, torch.tensor([0.0, 0.0, 1.5]))
    generator = torch.Generator().manual_seed(0)
    frames = []
    for f in range(num_frames):
        T_world_lane = make_transform(torch.eye(3), torch.tensor([0.0, float(f), 0.0]))
        frame = {
            "images": torch.randn(1, 3, height, width, generator=generator),
            "K": K[None],
            "T_lane_cam": T_lane_cam[None],
            "T_world_lane": T_world_lane[None],
        }
        frames.append({key: value.to(device) for key, value in frame.items()})
    return frames


def measure(config: dict, args: argparse.Namespace) -> dict[str, dict]:
    """Stream the clip through every variant, interleaved frame by frame, so that a change of
    machine load (shared CPUs) affects all of them alike."""
    device = torch.device(args.device)
    models = {}
    for label, variant in VARIANTS.items():
        torch.manual_seed(0)
        net = SparseLaneSTP(**{**config["model"], **variant}, cuda_graphs=args.cuda_graphs == "on")
        models[label] = net.to(device).eval()
    frames = clip(args.warmup + args.frames, config["image_size"], device)
    autocast = torch.autocast(device.type, dtype=torch.bfloat16) if args.dtype == "bf16" else nullcontext()
    sync = torch.cuda.synchronize if device.type == "cuda" else (lambda: None)
    times: dict[str, list[float]] = {label: [] for label in models}
    peak: dict[str, float] = {}
    with torch.inference_mode(), autocast:
        for model in models.values():
            model.reset(torch.ones(1, dtype=torch.bool, device=device))
        for frame in frames:
            for label, model in models.items():
                if device.type == "cuda":
                    before = torch.cuda.memory_allocated()
                    torch.cuda.reset_peak_memory_stats()
                sync()
                start = time.perf_counter()
                model.step(frame)
                sync()
                times[label].append(time.perf_counter() - start)
                if device.type == "cuda":  # working memory of a step, beyond what was allocated before
                    step_peak = (torch.cuda.max_memory_allocated() - before) / 2**20
                    peak[label] = max(peak.get(label, 0.0), step_peak)
    results = {}
    for label, model in models.items():
        seconds = statistics.median(times[label][args.warmup :])
        results[label] = {
            "ms_per_frame": 1e3 * seconds,
            "fps": 1 / seconds,
            "parameters_M": sum(p.numel() for p in model.parameters()) / 1e6,
        }
        if label in peak:
            results[label]["step_peak_MiB"] = peak[label]
    return results


def count_operators(config: dict) -> dict[str, dict[str, int]]:
    """Operators of one streaming step per variant and STA path, on the CPU (module doc)."""
    counts: dict[str, dict[str, int]] = {}
    frames = clip(6, (96, 128), torch.device("cpu"))
    for label, variant in VARIANTS.items():
        for path in ("sparse", "dense"):
            torch.manual_seed(0)
            model = SparseLaneSTP(**{**config["model"], "attention": path, **variant}).eval()
            with torch.no_grad():  # not inference mode, which logs composites (linear, dropout) undecomposed
                model.reset(torch.ones(1, dtype=torch.bool))
                for frame in frames[:-1]:  # T = 3 memory frames filled
                    model.step(frame)
                with OperatorLog() as log:
                    model.step(frames[-1])
            counts.setdefault(label, {})[path] = log.kernels()
    return counts


def print_operator_counts(args: argparse.Namespace) -> None:
    print("SparseLaneSTP, operators that compute a tensor in one streaming step (each a kernel launch on a GPU)")
    print("| config | model | STA sparse | STA dense |")
    print("|---|---|---:|---:|")
    for name in args.configs:
        counts = count_operators(CONFIGS[name])
        for label, by_path in counts.items():
            print(f"| {name} | {label} | {by_path['sparse']} | {by_path['dense']} |")
        for path in ("sparse", "dense"):
            growth = counts["SparseLaneSTP T=3"][path] / counts["T=0"][path] - 1
            print(f"{name}, STA {path}: the memory (T=3 vs T=0) adds {100 * growth:+.0f} % operators")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--configs", nargs="+", choices=sorted(CONFIGS), default=["tiny", "paper"])
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--dtype", choices=["fp32", "bf16"], default="fp32")
    parser.add_argument("--cuda-graphs", default="on", choices=["on", "off"], help="streaming steps on a GPU")
    parser.add_argument("--frames", type=int, default=10, help="timed frames")
    parser.add_argument("--warmup", type=int, default=3)
    parser.add_argument("--threads", type=int, help="torch CPU threads")
    parser.add_argument("--json", type=Path)
    parser.add_argument("--count-operators", action="store_true", help="count a step's operators instead of timing")
    args = parser.parse_args()
    if args.threads:
        torch.set_num_threads(args.threads)
    if args.count_operators:
        print_operator_counts(args)
        return

    rows = []
    graphs = f" cuda_graphs={args.cuda_graphs}" if args.device.startswith("cuda") else ""
    print(f"device={args.device} dtype={args.dtype}{graphs} torch={torch.__version__} threads={torch.get_num_threads()}")
    memory = f" {'step MiB':>9}" if args.device.startswith("cuda") else ""
    print(f"{'config':<6} {'model':<18} {'ms/frame':>9} {'frames/s':>9} {'params (M)':>10}{memory}")
    for name in args.configs:
        results = measure(CONFIGS[name], args)
        for label, result in results.items():
            rows.append({"config": name, "model": label, **result})
            memory = f" {result['step_peak_MiB']:9.0f}" if "step_peak_MiB" in result else ""
            print(f"{name:<6} {label:<18} {result['ms_per_frame']:9.1f} {result['fps']:9.2f} {result['parameters_M']:10.2f}{memory}")
        overhead = results["SparseLaneSTP T=3"]["ms_per_frame"] / results["T=0"]["ms_per_frame"] - 1
        rows.append({"config": name, "temporal_overhead": overhead})
        print(f"{name:<6} temporal overhead (T=3 vs T=0): {100 * overhead:+.1f} %  (paper: +9 %)")
    if args.json:
        meta = {"device": args.device, "dtype": args.dtype, "cuda_graphs": args.cuda_graphs, "torch": torch.__version__,
                "machine": platform.processor()}  # fmt: skip
        args.json.write_text(json.dumps({"meta": meta, "rows": rows}, indent=2))


if __name__ == "__main__":
    main()
