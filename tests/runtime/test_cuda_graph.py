"""CUDA-graph replay (lanelab.runtime.cuda_graph). The replay tests need a GPU (CI has none: they
are skipped there and run on a device machine); the signature test runs everywhere. Bi²Lane's
graphed streaming is tested in test_bi2lane.py."""

from __future__ import annotations

import pytest
import torch

from lanelab.runtime.cuda_graph import CUDAGraphed, signature

cuda = pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA device")


def test_a_graph_is_specific_to_shapes_dtypes_constants_and_autocast():
    a = torch.zeros(2, 3)
    base = signature((a, (64, 96)))
    assert signature((torch.ones(2, 3), (64, 96))) == base  # values do not matter
    assert signature((torch.zeros(1, 3), (64, 96))) != base
    assert signature((a.double(), (64, 96))) != base
    assert signature((a, (32, 96))) != base
    with torch.autocast("cuda", dtype=torch.bfloat16):
        assert signature((a, (64, 96))) != base


@cuda
def test_replays_follow_new_inputs_and_return_outputs_of_their_own():
    weight = torch.randn(8, 8, device="cuda")
    graphed = CUDAGraphed(lambda x, scale: {"y": [torch.relu(x @ weight) * scale]})
    first_input = torch.randn(4, 8, device="cuda")
    first = graphed(first_input, 2.0)["y"][0]
    second_input = torch.randn(4, 8, device="cuda")
    second = graphed(second_input, 2.0)["y"][0]
    torch.testing.assert_close(second, torch.relu(second_input @ weight) * 2.0)
    torch.testing.assert_close(first, torch.relu(first_input @ weight) * 2.0)  # not overwritten by the replay
    weight.mul_(3.0)  # parameters are read where they are: updated in place, the replay sees it
    torch.testing.assert_close(graphed(second_input, 2.0)["y"][0], torch.relu(second_input @ weight) * 2.0)
    graphed(torch.randn(2, 8, device="cuda"), 2.0)  # another shape: a second graph
    assert len(graphed._graphs) == 2
