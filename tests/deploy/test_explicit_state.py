"""The streaming step with its memory as explicit tensors equals ``step()`` (before any export),
for SparseLaneSTP's memory queue and Bi²Lane's frame cache."""

import sys
from pathlib import Path

import pytest
import torch

from lanelab.deploy.explicit_state import ExplicitStateStep, settle_ties, state_names
from lanelab.models.sparselanestp.memory_queue import MemoryQueue

MODEL_TESTS = Path(__file__).resolve().parents[1] / "models"
sys.path[:0] = [str(MODEL_TESTS / "bi2lane"), str(MODEL_TESTS / "sparselanestp")]  # the detectors' test builds
from test_bi2lane import build as build_bi2lane  # noqa: E402
from test_bi2lane import tiny_net  # noqa: E402, F401 (a fixture)
from test_bi2lane import window_batch  # noqa: E402
from test_sparselanestp import B, F, H, W, frame, model, window  # noqa: E402


def test_explicit_state_steps_as_step_does_resets_included() -> None:
    net = model().eval()
    settle_ties(net)  # as the graph does
    y = torch.linspace(3.0, 103.0, 30)
    explicit = ExplicitStateStep(net, y).eval()
    batch = window()
    state = explicit.initial_state(B, (H, W)).tensors()
    net.reset(torch.ones(B, dtype=torch.bool))
    resets = [torch.tensor([True, True]), torch.tensor([False, False]), torch.tensor([False, True])]
    with torch.inference_mode():
        for f in range(F):
            inputs = {**frame(batch, f), "reset": resets[f]}
            expected = net.step(inputs)
            points, logits, lanes, *state = explicit(*(inputs[k] for k in ("images", "K", "T_lane_cam", "T_world_lane", "reset")), *state)
            state, picks = state[:4], state[4:]
            assert len(picks) == 2 * 2 + 1  # per decoder layer PNA and TCA, then the memory's lines
            torch.testing.assert_close(points, expected["points"][-1], atol=1e-5, rtol=0)
            torch.testing.assert_close(logits, expected["logits"][-1], atol=1e-5, rtol=0)
            torch.testing.assert_close(lanes, net.decode(expected, y), atol=1e-5, rtol=0)
    assert state[3].tolist() == [[True, True], [True, False]]  # stream 1 was reset at the last frame: one slot since


def test_a_queue_state_loads_back_as_it_was() -> None:
    queue = MemoryQueue(num_frames=2, num_lines=1)
    embeddings, points = torch.randn(1, 3, 4, 8), torch.randn(1, 3, 4, 4)
    queue.push(embeddings, points, torch.tensor([[0.1, 0.9, 0.5]]), torch.eye(4, dtype=torch.float64)[None])
    other = MemoryQueue(num_frames=2, num_lines=1)
    other.load(queue.state())
    assert torch.equal(other.read(torch.eye(4, dtype=torch.float64)[None]).embeddings,
                       queue.read(torch.eye(4, dtype=torch.float64)[None]).embeddings)  # fmt: skip
    assert torch.equal(queue.state().embeddings[0, 0, 0], embeddings[0, 1])  # the most confident line, newest slot


def test_bi2lane_with_its_frame_cache_as_state_steps_as_step_does(tiny_net) -> None:  # noqa: F811
    net = build_bi2lane(tiny_net, num_history_frames=2)
    y = torch.linspace(3.0, 103.0, 30)
    explicit = ExplicitStateStep(net, y).eval()
    assert state_names(net) == ("features", "K", "T_lane_cam", "T_world_lane", "valid")
    clip = window_batch(2, 5, seed=4)
    state = explicit.initial_state(2, (64, 96)).tensors()
    assert state[0].shape == (2, 2, tiny_net["embed_dim"], 8, 12)  # N past frames of stride-8 features
    resets = [torch.tensor([True, True]), *[torch.tensor([False, False])] * 3, torch.tensor([False, True])]
    with torch.inference_mode():
        for f in range(5):
            inputs = {**{key: clip[key][:, f] for key in ("images", "K", "T_lane_cam", "T_world_lane")}, "reset": resets[f]}
            expected = net.step(inputs)
            points, logits, lanes, *state = explicit(*(inputs[k] for k in ("images", "K", "T_lane_cam", "T_world_lane", "reset")), *state)
            torch.testing.assert_close(points, expected["points"][-1], atol=1e-5, rtol=0)
            torch.testing.assert_close(logits, expected["logits"][-1], atol=1e-5, rtol=0)
            torch.testing.assert_close(lanes, net.decode(expected, y), atol=1e-5, rtol=0)
    assert state[4].tolist() == [[True, True], [False, True]]  # stream 1 restarted at the last frame: one real past frame


def test_a_frame_state_must_fit_the_cache(tiny_net) -> None:  # noqa: F811
    net = build_bi2lane(tiny_net, num_history_frames=2)
    state = build_bi2lane(tiny_net, num_history_frames=3).empty_memory_state(1, (64, 96))
    with pytest.raises(ValueError, match="a state of 3 frames does not fit a cache of 2 past frames"):
        net.new_memory().load(state)
