"""lanelab-export: the streaming SparseLaneSTP with its memory as explicit state, through
torch.export and ONNX (run by onnxruntime), equals ``step()`` over a 20-frame clip of a drive
log with its memory carried (and reset mid-clip), within 1e-4 in fp32."""

from __future__ import annotations

import dataclasses
import json
import sys
import zipfile
from pathlib import Path

import onnx
import onnxruntime
import pytest
import torch

from data_ingest.ingest.frames import read_frames
from data_ingest.ingest.mcap_reader import ReadReport
from data_ingest.ingest.spill import Spill
from lanelab.deploy.config import load_export_config
from lanelab.deploy.export import (
    ALL_INPUTS,
    ALL_OUTPUTS,
    METADATA_KEY,
    check,
    export,
    export_checkpoint,
    runner,
    synthetic_clip,
)
from lanelab.deploy.export_cli import run
from lanelab.deploy.trained import load_trained
from lanelab.models.explicit_state import ExplicitStateStep
from lanelab.models.sparselanestp import SparseLaneSTP
from log_predict.config import load_predict_config

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "models"))
from test_sparselanestp import BASELINE  # noqa: E402

TOLERANCE = 1e-4
RESETS = (0, 12)  # the clip's start, and a reset in the middle


def log_clip(checkpoint: Path, log: Path) -> list[dict[str, torch.Tensor]]:
    """The 20 frames of a synthetic drive log as the model takes them, resets at RESETS."""
    trained = load_trained(checkpoint, "cpu")
    cfg = load_predict_config([f"checkpoint={checkpoint}", f"input={log}"])
    with Spill() as spill:
        frames = read_frames(log, cfg, spill, ReadReport(log.stat().st_size)).frames
        records = [dataclasses.replace(f.record, image=spill.get(f.image.data)) for f in frames]
    assert len(records) == 20
    return [{**trained.model_input(r), "reset": torch.tensor([i in RESETS])} for i, r in enumerate(records)]


@pytest.mark.parametrize("fmt, suffix", [("torch", ".pt2"), ("onnx", ".onnx")])
def test_the_exported_step_equals_step_over_a_clip_with_memory(fmt: str, suffix: str, checkpoint: Path, synth_log,
                                                               tmp_path: Path) -> None:
    trained = load_trained(checkpoint, "cpu")
    exported, _ = export_checkpoint(trained, fmt, tmp_path / f"model{suffix}", batch=1, check_frames=0, tolerance=TOLERANCE)
    clip = log_clip(checkpoint, synth_log("foxglove-protobuf"))
    run_file = runner(exported.path, fmt)
    differences = check(trained.net, trained.y, run_file, clip)
    assert set(differences) == set(ALL_OUTPUTS)
    assert max(differences.values()) <= TOLERANCE, differences

    # The memory is in the graph: carried, it changes the lanes of the frames after the first.
    state = ExplicitStateStep(trained.net, trained.y).initial_state(1).tensors()
    carried, fresh = [], []
    for frame in clip:
        inputs = [frame[name] for name in ALL_INPUTS[:5]]
        outputs = run_file(*inputs, *state)
        state = outputs[3:]
        carried.append(outputs[2])
        fresh.append(run_file(*inputs[:4], torch.tensor([True]), *state)[2])
    assert max(float((a - b).abs().max()) for a, b in zip(carried[1:], fresh[1:])) > 10 * TOLERANCE
    assert bool(state[3].all())  # every memory slot filled at the end

    if fmt == "onnx":
        session = onnxruntime.InferenceSession(str(exported.path), providers=["CPUExecutionProvider"])
        assert [i.name for i in session.get_inputs()] == list(ALL_INPUTS)
        assert [o.name for o in session.get_outputs()] == list(ALL_OUTPUTS)
        props = {p.key: p.value for p in onnx.load(str(exported.path)).metadata_props}
        metadata = json.loads(props[METADATA_KEY])
    else:
        with zipfile.ZipFile(exported.path) as archive:
            name = next(n for n in archive.namelist() if n.endswith(f"{METADATA_KEY}.json"))
            metadata = json.loads(archive.read(name))
    assert metadata["y"] == trained.y.tolist() and metadata["image_size"] == [64, 96]
    assert metadata["memory"] == {"frames": 3, "lines": 4, "points": 11, "channels": 32}


def test_a_single_frame_model_exports_without_memory(tmp_path: Path) -> None:
    torch.manual_seed(0)
    net = SparseLaneSTP(**BASELINE).eval()
    y = torch.linspace(3.0, 103.0, 20)
    step = ExplicitStateStep(net, y).eval()
    clip = synthetic_clip((64, 96), 4, batch=2)
    example = (*(clip[0][name] for name in ALL_INPUTS[:5]), *step.initial_state(2).tensors())
    exported = export(step, "torch", tmp_path / "baseline.pt2", example, {})
    assert exported.metadata["batch"] == 2
    differences = check(net, y, runner(exported.path, "torch"), clip)
    assert max(differences.values()) <= TOLERANCE, differences


def test_a_failed_check_writes_nothing(checkpoint: Path, tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    out = tmp_path / "model.pt2"
    options = [f"checkpoint={checkpoint}", "format=torch", f"out={out}", "check.frames=3", "check.tolerance=1e-30"]
    assert run(load_export_config(options)) == 1
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert "differs from step() by" in line and "nothing written" in line
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("option, message", [
    ("format=tflite", "format='tflite' is not one of onnx, torch"),
    ("check.frames=-1", "check.frames=-1 must be >= 0"),
])  # fmt: skip
def test_bad_options_are_named(option: str, message: str, checkpoint: Path, tmp_path: Path) -> None:
    with pytest.raises(ValueError, match=message):
        load_export_config([f"checkpoint={checkpoint}", f"out={tmp_path / 'x'}", option])
