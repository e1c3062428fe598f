"""Latency per frame of the exported streaming detectors (lanelab-export) against eager ``step()``.

    python benchmarks/bench_export.py [--configs tiny paper bi2lane-tiny bi2lane-paper] [--device cpu|cuda]
        [--frames 20] [--warmup 3] [--threads N] [--json out.json]

For each configuration (SparseLaneSTP's "tiny" and "paper" of ``bench_sparselanestp.py``,
Bi²Lane's of ``bench_bi2lane.py`` with 3 history frames; random weights, eval mode, no gradient,
batch 1) the same synthetic clip (:func:`lanelab.deploy.export.synthetic_clip`, memory reset at
its first and middle frame) streams through:

- ``eager step``: ``step`` as lanelab-predict runs it (SparseLaneSTP: its sparse STA);
- ``eager step (dense STA)``: SparseLaneSTP with the dense attention the exported graph holds;
- ``torch.export``: the ExportedProgram's module (``ExplicitStateStep``, state carried as tensors);
- ``onnxruntime``: the ONNX file of lanelab-export on onnxruntime's CPU provider with as many
  threads as torch (the CUDA provider where onnxruntime has it and ``--device cuda``).

Variants run interleaved frame by frame, so that load from other processes affects them alike;
figures are medians over the timed frames after ``--warmup`` frames. The table also gives the
time each export took and the largest difference of the exported lanes from eager ``step()``.
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import torch
import bench_bi2lane
import bench_sparselanestp

from lanelab.deploy.explicit_state import INPUT_NAMES, OUTPUT_NAMES, ExplicitStateStep, settle_ties
from lanelab.deploy.export import example_inputs, graph_names, input_names, synthetic_clip, write_onnx
from lanelab.models.sparselanestp import SparseLaneSTP

Y = torch.linspace(3.0, 103.0, 100)  # the default data.y_grid
CONFIGS = [*bench_sparselanestp.CONFIGS, *(f"bi2lane-{name}" for name in bench_bi2lane.CONFIGS)]


def eager_models(config: str, device: torch.device) -> tuple[dict[str, torch.nn.Module], tuple[int, int]]:
    """The eager variants of a configuration (the exported one first) and its image size."""
    torch.manual_seed(0)
    if config.startswith("bi2lane-"):
        name = config.removeprefix("bi2lane-")
        net = bench_bi2lane.build(name, 3, device, cuda_graphs=False)
        return {"eager step": net}, bench_bi2lane.CONFIGS[name][1]
    setup = bench_sparselanestp.CONFIGS[config]
    net = SparseLaneSTP(**setup["model"]).to(device).eval()
    dense = SparseLaneSTP(**{**setup["model"], "attention": "dense"}).to(device).eval()
    dense.load_state_dict(net.state_dict())
    for model in (net, dense):
        settle_ties(model)  # the eager variants pick the keys the exported graphs pick
    return {"eager step": net, "eager step (dense STA)": dense}, setup["image_size"]


def runners(config: str, device: torch.device, folder: Path) -> tuple[dict[str, Callable], dict[str, float], tuple]:
    """Per variant, a function frame -> lanes (B, N, S, 4) carrying its own state; export
    seconds; the image size."""
    eager_nets, image_size = eager_models(config, device)
    net = next(iter(eager_nets.values()))
    step = ExplicitStateStep(net, Y.to(device)).eval()
    example = tuple(t.to(device) for t in example_inputs(step, image_size, 1))
    seconds = {}
    start = time.perf_counter()
    exported = torch.export.export(step, example).module()
    seconds["torch.export"] = time.perf_counter() - start

    def eager(model: torch.nn.Module) -> Callable:
        return lambda frame: model.decode(model.step(frame), Y.to(device))

    def stateful(run: Callable) -> Callable:
        state = list(step.initial_state(1, image_size, device).tensors())

        def call(frame: dict) -> torch.Tensor:
            outputs = run(*(frame[name] for name in INPUT_NAMES), *state)
            state[:] = outputs[len(OUTPUT_NAMES) : len(OUTPUT_NAMES) + len(state)]  # the picks follow
            return outputs[2]

        return call

    variants = {label: eager(model) for label, model in eager_nets.items()}
    variants["torch.export"] = stateful(exported)
    try:
        import onnxruntime
    except ImportError:
        print("onnxruntime is not installed: no ONNX row (pip install 'lanelab[export]')")
        return variants, seconds, image_size
    start = time.perf_counter()
    cpu_step = ExplicitStateStep(net.cpu(), Y).eval() if device.type != "cpu" else step
    cpu_example = tuple(t.cpu() for t in example)
    write_onnx(cpu_step, cpu_example, folder / "model.onnx", graph_names(cpu_step, cpu_example))
    net.to(device)
    seconds["onnxruntime"] = time.perf_counter() - start
    providers = ["CPUExecutionProvider"]
    if device.type == "cuda" and "CUDAExecutionProvider" in onnxruntime.get_available_providers():
        providers.insert(0, "CUDAExecutionProvider")
    options = onnxruntime.SessionOptions()
    options.intra_op_num_threads = torch.get_num_threads()  # as many threads as torch gets
    session = onnxruntime.InferenceSession(str(folder / "model.onnx"), options, providers=providers)

    def ort(*inputs: torch.Tensor) -> list[torch.Tensor]:
        outputs = session.run(None, {name: t.cpu().numpy() for name, t in zip(input_names(net), inputs)})
        return [torch.from_numpy(o).to(device) for o in outputs]

    variants["onnxruntime"] = stateful(ort)
    return variants, seconds, image_size


def measure(config: str, args: argparse.Namespace) -> list[dict]:
    device = torch.device(args.device)
    sync = torch.cuda.synchronize if device.type == "cuda" else (lambda: None)
    with tempfile.TemporaryDirectory() as folder:
        variants, export_seconds, image_size = runners(config, device, Path(folder))
        frames = [{k: v.to(device) for k, v in f.items()}
                  for f in synthetic_clip(image_size, args.warmup + args.frames, 1)]  # fmt: skip
        times: dict[str, list[float]] = {label: [] for label in variants}
        lanes: dict[str, list[torch.Tensor]] = {label: [] for label in variants}
        with torch.inference_mode():
            for frame in frames:
                for label, run in variants.items():
                    sync()
                    start = time.perf_counter()
                    out = run(frame)
                    sync()
                    times[label].append(time.perf_counter() - start)
                    lanes[label].append(out.float().cpu())
    reference = lanes["eager step"]
    rows = []
    for label in variants:
        seconds = statistics.median(times[label][args.warmup :])
        difference = max(float((a - b).abs().max()) for a, b in zip(lanes[label], reference))
        rows.append({"model": label, "ms_per_frame": 1e3 * seconds, "fps": 1 / seconds,
                     "export_s": export_seconds.get(label), "max_lane_difference": difference})  # fmt: skip
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--configs", nargs="+", choices=CONFIGS, default=["tiny", "paper"])
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--frames", type=int, default=20, help="timed frames")
    parser.add_argument("--warmup", type=int, default=3)
    parser.add_argument("--threads", type=int, help="torch CPU threads")
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    if args.threads:
        torch.set_num_threads(args.threads)
    print(f"device={args.device} torch={torch.__version__} threads={torch.get_num_threads()} "
          f"machine={platform.processor() or platform.machine()}")
    print(f"{'config':<13} {'variant':<24} {'ms/frame':>9} {'frames/s':>9} {'export s':>9} {'max |Δ lanes| m':>16}")
    rows = []
    for name in args.configs:
        for row in measure(name, args):
            rows.append({"config": name, **row})
            export_s = f"{row['export_s']:9.1f}" if row["export_s"] is not None else f"{'-':>9}"
            print(f"{name:<13} {row['model']:<24} {row['ms_per_frame']:9.1f} {row['fps']:9.2f} {export_s} "
                  f"{row['max_lane_difference']:16.2e}")
    if args.json:
        meta = {"device": args.device, "torch": torch.__version__, "machine": platform.processor()}
        args.json.write_text(json.dumps({"meta": meta, "rows": rows}, indent=2))


if __name__ == "__main__":
    main()
