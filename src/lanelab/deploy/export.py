"""A trained SparseLaneSTP's or Bi²Lane's streaming step as a file that runs without lanelab: its
memory as explicit inputs and outputs (``state_in_*`` -> ``state_out_*``), a reset flag, and the lanes
decoded in the graph (:class:`lanelab.deploy.explicit_state.ExplicitStateStep` has the layout).

Formats:

- ``torch``: ``torch.export``'s ExportedProgram, saved with ``torch.export.save`` (.pt2); run it
  with ``torch.export.load(path).module()(images, K, T_lane_cam, T_world_lane, reset, *state)``;
- ``onnx``: the ONNX graph of ``torch.onnx.export`` (the dynamo exporter, at the opset the
  installed exporter chooses), for onnxruntime or any ONNX runtime; inputs and outputs by name.

Both hold ``lanelab`` metadata (JSON; the .pt2's extra file ``lanelab.json``, the ONNX model's
``metadata_props``): the names and order of inputs and outputs, the image pipeline (size, crop,
mean, std), the y grid of ``lanes``, the categories of ``logits``, the visibility threshold and
lane NMS distance (NMS stays outside the graph: it is a loop over lanes), and the state's
tensors (shape per stream, dtype).

:func:`check` runs a written file over a clip, its state carried from frame to frame, beside
``step`` of the eager model with the graph's discrete choices replayed, and returns the largest
difference of every output (:func:`difference`: lane points in metres, any other tensor relative
to its scale) and how near a tie every choice the graph made differently was.
"""

from __future__ import annotations

import contextlib
import io
import json
import logging
import math
import warnings
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

import torch
from torch import Tensor

from lanelab.atomic_file import atomic_output
from lanelab.deploy.explicit_state import INPUT_NAMES, OUTPUT_NAMES, ExplicitStateStep, settle_ties, state_names
from lanelab.deploy.trained import TrainedDetector
from lanelab.geometry import make_transform
from lanelab.lanes import LANE_CATEGORY_IDS
from lanelab.models.bi2lane import Bi2Lane
from lanelab.models.bi2lane.frame_cache import FrameState
from lanelab.models.sparselanestp import SparseLaneSTP
from lanelab.models.sparselanestp.memory_queue import QueueState
from lanelab.runtime.ranking import forcing_picks

METADATA_KEY = "lanelab"
EXPORTABLE = (SparseLaneSTP, Bi2Lane)
# The outputs and state tensors that hold lane points (x, y, z in metres, visibility): the check
# compares them in metres, whatever their range (fp32 rounds 100 m to 8e-6 m).
LANE_POINTS = frozenset({"points", "lanes", "state_out_points"})

Frame = dict[str, Tensor]  # images, K, T_lane_cam, T_world_lane, reset; batch first


class ExportError(RuntimeError):
    """The exporter could not write the model, or its check failed; the message says why."""


def input_names(net: SparseLaneSTP | Bi2Lane) -> tuple[str, ...]:
    """The graph's inputs in order: the frame's, then ``state_in_<name>`` of each state tensor."""
    return INPUT_NAMES + tuple(f"state_in_{name}" for name in state_names(net))


def output_names(net: SparseLaneSTP | Bi2Lane, num_picks: int = 0) -> tuple[str, ...]:
    """The graph's outputs in order: the detections, ``state_out_<name>``, then ``pick_<i>`` of
    the step's num_picks top-k choices (lanelab.deploy.explicit_state)."""
    state = tuple(f"state_out_{name}" for name in state_names(net))
    return OUTPUT_NAMES + state + tuple(f"pick_{i}" for i in range(num_picks))


def graph_names(step: ExplicitStateStep, example: tuple[Tensor, ...]) -> dict[str, list[str]]:
    """{"inputs": [...], "outputs": [...]}: the names of the graph of ``step`` traced with
    ``example`` (one eager call counts the picks, which depend on the model's configuration)."""
    with torch.no_grad():
        num_picks = len(step(*example)) - len(output_names(step.net))
    return {"inputs": list(input_names(step.net)), "outputs": list(output_names(step.net, num_picks))}


@dataclass(frozen=True)
class Exported:
    """A written file: its format, the ONNX opset (None for torch) and its metadata."""

    path: Path
    format: str
    opset: int | None
    metadata: dict[str, Any]


def export(step: ExplicitStateStep, fmt: str, out: str | Path, example: tuple[Tensor, ...], metadata: dict[str, Any],
           check_with: Callable[[Path], None] | None = None) -> Exported:
    """Write ``step``, traced with the inputs ``example`` (their batch size is the file's), as
    ``fmt`` to ``out``, atomically; ``metadata`` is added to the file's (see the module).
    ``check_with(path)`` runs on the written file before it takes its name (raise to refuse it:
    nothing is left then)."""
    metadata = {**metadata, **graph_names(step, example), "batch": example[0].shape[0]}
    with atomic_output(out) as tmp:
        if fmt == "torch":
            program = torch.export.export(step, example)
            with open(tmp, "wb") as handle:  # a handle: torch wants a path ending in .pt2, the temporary does not
                torch.export.save(program, handle, extra_files={f"{METADATA_KEY}.json": json.dumps(metadata)})
            opset = None
        else:
            opset = write_onnx(step, example, tmp, metadata)
        if check_with is not None:
            check_with(tmp)
    return Exported(Path(out), fmt, opset, metadata)


def export_checkpoint(trained: TrainedDetector, fmt: str, out: str | Path, batch: int, check_frames: int,
                      tolerance: float) -> tuple[Exported, dict[str, float]]:
    """Export a loaded checkpoint's detector (SparseLaneSTP or Bi²Lane) for ``batch`` streams;
    unless ``check_frames`` is 0, check the written file over a synthetic clip of that many
    frames against ``step`` (ExportError, and no file, when an output's :func:`difference` is
    more than ``tolerance``). Returns the file and the largest difference of each output (empty
    without a check)."""
    net = trained.net
    if not isinstance(net, EXPORTABLE):
        names = ", ".join(kind.__name__ for kind in EXPORTABLE)
        raise ExportError(f"lanelab-export exports {names}; this checkpoint's detector is {type(net).__name__}")
    net, y = net.cpu().eval(), trained.y.cpu()
    settle_ties(net)  # the check's step() picks the keys the graph picks
    step = ExplicitStateStep(net, y).eval()
    image_size = trained.resize.height, trained.resize.width
    differences: dict[str, float] = {}

    def check_file(path: Path) -> None:
        differences.update(check(net, y, runner(path, fmt), synthetic_clip(image_size, check_frames, batch)))
        refused = {name: value for name, value in differences.items() if value > tolerance}
        if refused:
            raise ExportError(refusal(refused, fmt, check_frames, tolerance))

    example = example_inputs(step, image_size, batch)
    metadata = metadata_of(trained, step.initial_state(1, image_size))
    exported = export(step, fmt, out, example, metadata, check_file if check_frames else None)
    return exported, differences


def refusal(refused: dict[str, float], fmt: str, frames: int, tolerance: float) -> str:
    """Why the check refused a file (its outputs over the tolerance, by name) and the two ways on."""
    worst = max(refused, key=refused.get)
    value = refused[worst]
    unit = "m" if worst in LANE_POINTS else "relative"
    wider = f"check.tolerance={10 ** math.ceil(math.log10(value)):g}" if math.isfinite(value) else "check.tolerance=..."
    other = "format=torch (torch.export: the eager model's operators)" if fmt == "onnx" else "check.frames=0 (no check)"
    return (f"the exported model differs from step() by {value:.3g} ({unit}) in {worst} over {frames} frames, more "
            f"than check.tolerance={tolerance:g}; nothing written. If that is close enough, export again with {wider}, "
            f"or with {other}")


def metadata_of(trained: TrainedDetector, state: QueueState | FrameState) -> dict[str, Any]:
    """What a deployment needs besides the graph (the module doc), from the checkpoint and the
    initial state of one stream."""
    net, module, resize = trained.net, trained.module, trained.resize
    data = trained.config["data"]
    return {
        "model": type(net).__name__,
        "checkpoint": str(trained.checkpoint),
        "image_size": [resize.height, resize.width],
        "crop": None if resize.crop is None else list(resize.crop),
        "mean": list(data["mean"]),
        "std": list(data["std"]),
        "y": trained.y.cpu().tolist(),
        "categories": [*LANE_CATEGORY_IDS, "background"],
        "visibility_threshold": module.metric_config.visibility_threshold,
        "nms_distance": module.nms_distance,
        "state": {field.name: {"shape": list(getattr(state, field.name).shape[1:]),
                               "dtype": str(getattr(state, field.name).dtype).removeprefix("torch.")}
                  for field in fields(state)},
    }


def write_onnx(step: ExplicitStateStep, example: tuple[Tensor, ...], path: Path, metadata: dict[str, Any]) -> int:
    """Write ``step`` traced with ``example`` as an ONNX file at ``path`` with ``metadata``
    under the ``lanelab`` key (its "inputs" and "outputs" name the graph's: :func:`graph_names`);
    the opset the exporter chose."""
    try:
        import onnx
    except ImportError:
        raise ExportError("format=onnx needs the onnx and onnxscript packages: pip install 'lanelab[export]'") from None
    # The exporter reports its progress on stdout, warns of torchvision ops it cannot offer, and its
    # graph optimiser logs every rewrite; a failure raises with all that matters.
    with contextlib.redirect_stdout(io.StringIO()), _quiet("torch.onnx", "onnxscript", "onnx_ir"), \
            warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)
        torch.onnx.export(step, example, str(path), dynamo=True, input_names=metadata["inputs"],
                          output_names=metadata["outputs"], external_data=False, verbose=False)  # fmt: skip
    model = onnx.load(str(path))
    entry = model.metadata_props.add()
    entry.key, entry.value = METADATA_KEY, json.dumps(metadata)
    onnx.save(model, str(path))
    return next(o.version for o in model.opset_import if o.domain in ("", "ai.onnx"))


@contextlib.contextmanager
def _quiet(*loggers: str) -> Iterator[None]:
    """The named loggers at ERROR and above for the time of the block."""
    levels = {name: logging.getLogger(name).level for name in loggers}
    for name in loggers:
        logging.getLogger(name).setLevel(logging.ERROR)
    try:
        yield
    finally:
        for name, level in levels.items():
            logging.getLogger(name).setLevel(level)


def example_inputs(step: ExplicitStateStep, image_size: Sequence[int], batch: int) -> tuple[Tensor, ...]:
    """Inputs of the right shapes and dtypes for tracing: the first frame of :func:`synthetic_clip`
    and an empty memory."""
    frame = synthetic_clip(image_size, 1, batch)[0]
    return (*(frame[name] for name in INPUT_NAMES), *step.initial_state(batch, tuple(image_size)).tensors())


def synthetic_clip(image_size: Sequence[int], num_frames: int, batch: int, seed: int = 0) -> list[Frame]:
    """A clip of ``num_frames`` frames for ``batch`` streams, without a dataset: noise images of
    ``image_size`` (H, W) (normalised), a camera 1.5 m up looking ahead with a 53° field of view,
    an ego driving 2 m per frame while turning; reset at the first and the middle frame."""
    height, width = image_size
    generator = torch.Generator().manual_seed(seed)
    K = torch.tensor([[width, 0.0, width / 2], [0.0, width, height / 2], [0.0, 0.0, 1.0]])
    optical_to_lane = torch.tensor([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
    T_lane_cam = make_transform(optical_to_lane, torch.tensor([0.0, 0.0, 1.5]))
    frames = []
    for f in range(num_frames):
        yaw = torch.tensor(0.01 * f, dtype=torch.float64)
        rotation = torch.tensor([[yaw.cos(), -yaw.sin(), 0.0], [yaw.sin(), yaw.cos(), 0.0], [0.0, 0.0, 1.0]],
                                dtype=torch.float64)  # fmt: skip
        pose = make_transform(rotation, torch.tensor([0.0, 2.0 * f, 0.0], dtype=torch.float64))
        frames.append({
            "images": torch.randn(batch, 3, height, width, generator=generator),
            "K": K.expand(batch, 3, 3).clone(),
            "T_lane_cam": T_lane_cam.expand(batch, 4, 4).clone(),
            "T_world_lane": pose.expand(batch, 4, 4).clone(),
            "reset": torch.full((batch,), f in (0, num_frames // 2)),
        })  # fmt: skip
    return frames


def runner(path: str | Path, fmt: str) -> Callable[..., tuple[Tensor, ...]]:
    """A function running the written file on the CPU: its inputs' tensors in order -> its
    outputs' (onnxruntime for ONNX)."""
    if fmt == "torch":
        with open(path, "rb") as handle:
            module = torch.export.load(handle).module()
        return lambda *inputs: tuple(module(*inputs))
    try:
        import onnxruntime
    except ImportError:
        raise ExportError("checking an ONNX file needs onnxruntime: pip install 'lanelab[export]' "
                          "(or check.frames=0 to export without the check)") from None
    session = onnxruntime.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    names = [i.name for i in session.get_inputs()], [o.name for o in session.get_outputs()]

    def run(*inputs: Tensor) -> tuple[Tensor, ...]:
        outputs = session.run(names[1], {name: t.cpu().numpy() for name, t in zip(names[0], inputs)})
        return tuple(torch.from_numpy(output) for output in outputs)

    return run


def check(net: SparseLaneSTP | Bi2Lane, y: Tensor, run: Callable[..., tuple[Tensor, ...]],
          clip: Sequence[Frame]) -> dict[str, float]:
    """Run the exported step ``run`` over ``clip`` (its state carried from frame to frame) and
    ``net.step_with`` beside it, with a memory object of its own and the graph's picks replayed
    (:func:`lanelab.runtime.ranking.forcing_picks`). The largest :func:`difference` of each
    output and state tensor over the clip, by name, and under "picks" (models that pick) the
    largest relative gap between a pick of the graph and the eager step's own choice: near 0
    where they chose alike or between near-tied candidates."""
    net = net.eval()
    images = clip[0]["images"]
    memory = net.new_memory()
    empty = net.empty_memory_state(images.shape[0], tuple(images.shape[-2:]))
    memory.load(empty)  # the graph reads an empty memory's slots too, and picks among them alike
    state = empty.tensors()
    names = output_names(net)
    worst = dict.fromkeys(names, 0.0)
    for frame in clip:
        outputs = run(*(frame[name] for name in INPUT_NAMES), *state)
        picks = outputs[len(names):]
        with torch.inference_mode(), forcing_picks(picks) as deviations:
            reference = net.step_with(memory, frame)
            expected = [reference["points"][-1], reference["logits"][-1], net.decode(reference, y)]
        expected += list(memory.state().tensors())
        for name, got, want in zip(names, outputs, expected):
            worst[name] = max(worst[name], difference(name, got, want))
        if picks:
            worst["picks"] = max(worst.get("picks", 0.0), *deviations)
        state = outputs[len(OUTPUT_NAMES) : len(names)]
    return worst


def difference(name: str, got: Tensor, want: Tensor) -> float:
    """How far the file's output or state tensor ``name`` is from the eager step's, as the check
    judges it: the largest absolute difference, in metres for lane points (:data:`LANE_POINTS`),
    and for any other tensor divided by its scale, its largest magnitude but at least 1:
    features and logits have no unit, and fp32's rounding grows with their size, which grows
    with training (a trained SparseLaneSTP's memory embeddings, up to 4.3, differ by 1.4e-4)."""
    got, want = got.detach().double().cpu(), want.detach().double().cpu()
    if not got.numel():
        return 0.0
    largest = float((got - want).abs().max())
    return largest if name in LANE_POINTS else largest / max(1.0, float(want.abs().max()))
