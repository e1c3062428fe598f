"""Sparse vs dense spatio-temporal attention: time and peak memory of one STA layer.

    python benchmarks/bench_sta.py [--batch 1 2 3 4] [--repeats 9] [--geometry lanes|random]
                                   [--device cpu|cuda] [--dtype float32|bfloat16] [--json out.json]

The paper configuration: N = 40 lines, M = 20 points, T = 3 memory frames of N_mem = 5 lines
(K = 300 tokens), M_TCA = 10, C = 256, H = 8 heads. Three implementations of the same layer:
- sparse:         ``impl="sparse"`` (block-diagonal SLA, banded PNA and TCA);
- dense (fused):  ``impl="dense"``, masked scaled-dot-product attention on torch's fused
                  kernel (flash on CPU, memory-efficient on CUDA), which never builds the matrix;
- dense (matrix): the same call on SDPA's math backend, which materialises the
                  (N·M) x (N·M + K) attention matrix of every head: the "standard attention
                  layer that uses masking" the paper timed (supplementary C.2).
Times are medians over ``repeats`` rounds, the variants interleaved within a round so that a
busy machine slows them alike: "fwd" under no_grad (inference), "train" forward + backward.
Peak memory is the most memory allocated during one call beyond what existed before it
(inputs, weights): torch.cuda.max_memory_allocated on a GPU, the torch profiler's memory
timeline on CPU. The neighbour search (shared by both paths) is included in every figure.

Geometry: "lanes" places the 40 proposals as gently curving, roughly parallel lanes and the
memory as lanes seen from further back (what a trained model produces); "random" scatters the
control points (an untrained model; the sparse band then widens towards the whole line).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import statistics
import tempfile
import time
import warnings
from pathlib import Path

import torch
from torch.nn.attention import SDPBackend, sdpa_kernel

from lanelab.models.sparselanestp.memory_queue import MemoryState
from lanelab.models.sparselanestp.spatio_temporal_attention import SpatioTemporalAttention
from lanelab.models.sparselanestp.sta_masks import density, find_neighbours, neighbour_masks

N, M, T, N_MEM, M_TCA, C, H = 40, 20, 3, 5, 10, 256, 8
K = T * N_MEM * M
Y = torch.linspace(3.0, 103.0, M)
VARIANTS = {"sparse": ("sparse", False), "dense (fused)": ("dense", False), "dense (matrix)": ("dense", True)}


def lane_points(batch: int, lines: int, generator: torch.Generator, back: float = 0.0) -> torch.Tensor:
    """(batch, lines, M, 4) gently curving, roughly parallel lanes seen from ``back`` metres behind."""
    offset = torch.linspace(-10.0, 10.0, lines) + 0.3 * torch.randn(batch, lines, generator=generator)
    bend = 2e-4 * torch.randn(batch, 1, 1, generator=generator)
    x = offset[..., None] + bend * (Y + back) ** 2
    return torch.stack([x, (Y - back).expand_as(x), 0.01 * Y.expand_as(x), torch.ones_like(x)], dim=-1)


def make_inputs(batch: int, geometry: str, device: torch.device, dtype: torch.dtype) -> dict:
    g = torch.Generator().manual_seed(0)
    if geometry == "lanes":
        points = lane_points(batch, N, g)
        past = torch.cat([lane_points(batch, N_MEM, g, back=1.5 * k) for k in range(1, T + 1)], dim=1)
    else:
        x = 20 * torch.rand(batch, N, M, generator=g) - 10
        points = torch.stack([x, Y.expand_as(x), torch.rand_like(x), torch.ones_like(x)], -1)
        past = points[:, : T * N_MEM] + torch.randn(batch, T * N_MEM, M, 4, generator=g)
    memory = MemoryState(
        embeddings=torch.randn(batch, K, C, generator=g).to(device, dtype),
        points=past.reshape(batch, K, 4).to(device, dtype),
        valid=torch.ones(batch, K, dtype=torch.bool, device=device),
        age=torch.arange(1, T + 1, device=device).repeat_interleave(N_MEM * M).expand(batch, K),
    )
    tensors = {
        "queries": torch.randn(batch, N, M, C, generator=g),
        "query_pos": torch.randn(batch, N, M, C, generator=g),
        "points": points,
        "memory_pos": torch.randn(batch, K, C, generator=g),
    }
    return {**{k: v.to(device, dtype) for k, v in tensors.items()}, "memory": memory}


def call(layer: SpatioTemporalAttention, inputs: dict, train: bool, materialise: bool) -> None:
    backend = sdpa_kernel(SDPBackend.MATH) if materialise else contextlib.nullcontext()
    with backend, torch.set_grad_enabled(train):
        queries = inputs["queries"].requires_grad_(train)
        out = layer(queries, inputs["query_pos"], inputs["points"], inputs["memory"], inputs["memory_pos"])
        if train:
            out.float().square().mean().backward()


def sync(device: torch.device) -> None:
    if device.type == "cuda":
        torch.cuda.synchronize(device)


def seconds(fn, device: torch.device) -> float:
    sync(device)
    start = time.perf_counter()
    fn()
    sync(device)
    return time.perf_counter() - start


def peak_mib(fn, device: torch.device) -> float:
    if device.type == "cuda":
        sync(device)
        before = torch.cuda.memory_allocated(device)
        torch.cuda.reset_peak_memory_stats(device)
        fn()
        sync(device)
        return (torch.cuda.max_memory_allocated(device) - before) / 2**20
    from torch.profiler import ProfilerActivity, profile

    with profile(activities=[ProfilerActivity.CPU], profile_memory=True, record_shapes=True, with_stack=True) as prof:
        fn()
    with tempfile.TemporaryDirectory() as tmp, warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)  # the CPU memory timeline has no successor yet
        path = Path(tmp) / "timeline.json"
        prof.export_memory_timeline(str(path), device="cpu")
        _, sizes = json.loads(path.read_text())
    return max((sum(sample) for sample in sizes), default=0) / 2**20


def band_width(points: torch.Tensor, valid: torch.Tensor) -> int:
    """The sparse path's band width W for neighbour point indices points (B, N, M, ...)."""
    rows = torch.arange(M).view(M, *[1] * (points.dim() - 3))
    return min(2 * int((points - rows).abs()[valid].max()) + 1, M)


def describe(geometry: str) -> tuple[dict, dict]:
    inputs = make_inputs(1, geometry, torch.device("cpu"), torch.float32)
    memory = inputs["memory"]
    neighbours = find_neighbours(inputs["points"], memory.points, memory.valid, None, 2, M_TCA)
    fractions = density(neighbour_masks(neighbours, N, M, K))
    widths = {"PNA": band_width(neighbours.pna_index, neighbours.pna_valid),
              "TCA": band_width(neighbours.tca_index % M, neighbours.tca_valid)}  # fmt: skip
    return fractions, widths


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--batch", type=int, nargs="+", default=[1, 2, 3, 4])
    parser.add_argument("--repeats", type=int, default=9)
    parser.add_argument("--geometry", choices=["lanes", "random"], default="lanes")
    parser.add_argument("--device", default="cuda" if torch.cuda.is_available() else "cpu")
    parser.add_argument("--dtype", choices=["float32", "bfloat16"], default="float32")
    parser.add_argument("--json", help="also write the results to this file")
    args = parser.parse_args()
    device, dtype = torch.device(args.device), getattr(torch, args.dtype)

    fractions, widths = describe(args.geometry)
    print(f"N={N} M={M} T={T} N_mem={N_MEM} M_TCA={M_TCA} C={C} H={H} geometry={args.geometry} device={device} "
          f"dtype={args.dtype} threads={torch.get_num_threads()}")  # fmt: skip
    print("active relations: " + ", ".join(f"{k} {100 * v:.2f}%" for k, v in fractions.items())
          + "; sparse band W: " + ", ".join(f"{k} {v}" for k, v in widths.items()))  # fmt: skip

    torch.manual_seed(0)
    sparse = SpatioTemporalAttention(C, H, 2, M_TCA, impl="sparse").to(device, dtype)
    dense = SpatioTemporalAttention(C, H, 2, M_TCA, impl="dense").to(device, dtype)
    dense.load_state_dict(sparse.state_dict())
    layers = {"sparse": sparse, "dense": dense}

    rows = []
    for batch in args.batch:
        inputs = make_inputs(batch, args.geometry, device, dtype)
        calls = {(name, train): (lambda impl=impl, m=m, train=train: call(layers[impl], inputs, train, m))
                 for name, (impl, m) in VARIANTS.items() for train in (False, True)}  # fmt: skip
        for fn in calls.values():  # warm-up
            fn()
        times = {key: [] for key in calls}
        for _ in range(args.repeats):  # interleaved rounds
            for key, fn in calls.items():
                times[key].append(seconds(fn, device))
        for name in VARIANTS:
            row = {"B": batch, "impl": name}
            for mode, train in (("fwd", False), ("train", True)):
                row[f"{mode}_ms"] = 1e3 * statistics.median(times[name, train])
                row[f"{mode}_MiB"] = peak_mib(calls[name, train], device)
            rows.append(row)

    print(f"\n{'B':>2} {'impl':<15} {'fwd ms':>8} {'fwd MiB':>8} {'train ms':>9} {'train MiB':>9}"
          f"   {'dense/sparse: time fwd, train':<30} {'memory fwd, train'}")  # fmt: skip
    for row in rows:
        ratios = ""
        if row["impl"] != "sparse":
            base = next(r for r in rows if r["B"] == row["B"] and r["impl"] == "sparse")
            ratio = {key: row[key] / max(base[key], 1e-9) for key in ("fwd_ms", "train_ms", "fwd_MiB", "train_MiB")}
            ratios = (f"   {ratio['fwd_ms']:5.1f}x, {ratio['train_ms']:5.1f}x" + " " * 16
                      + f"{ratio['fwd_MiB']:5.1f}x, {ratio['train_MiB']:5.1f}x")  # fmt: skip
        print(f"{row['B']:>2} {row['impl']:<15} {row['fwd_ms']:8.2f} {row['fwd_MiB']:8.1f} "
              f"{row['train_ms']:9.2f} {row['train_MiB']:9.1f}{ratios}")  # fmt: skip
    if args.json:
        summary = {"args": vars(args), "density": fractions, "band_width": widths, "rows": rows}
        Path(args.json).write_text(json.dumps(summary, indent=2))


if __name__ == "__main__":
    main()
