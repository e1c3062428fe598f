"""SparseLaneSTP's streaming step is one call of fixed shapes on tensors alone: it makes no
tensor from host data and reads nothing back (what a CUDA graph cannot hold), checked on the CPU
with the operator log; on a GPU it replays from a graph and gives what it gives eagerly."""

import pytest
import torch
from test_sparselanestp import B, F, frame, model, window

from lanelab.runtime.operator_log import OperatorLog

# The step as a GPU runs it: the dense STA ("auto" there), the lateral-offset read, lateral search.
STREAMING = {"attention": "dense", "lateral_offset": {"stride": 4, "hidden": 8, "read_range": (5.0, 30.0),
                                                      "num_reads": 6, "iterations": 2}}  # fmt: skip


def clip(num_frames: int) -> list[dict[str, torch.Tensor]]:
    """num_frames frames driving on (the window's F frames, again and again); the first resets
    both streams, the fifth stream 1."""
    batch = window()
    frames = [frame(batch, f % F) for f in range(num_frames)]
    frames[0]["reset"] = torch.tensor([True, True])
    frames[4]["reset"] = torch.tensor([False, True])
    return frames


def test_a_streaming_step_makes_no_tensor_from_host_data_and_reads_nothing_back():
    net = model(**STREAMING).eval()
    frames = clip(6)
    with torch.no_grad():
        for f, step in enumerate(frames):
            before = net._stream.state()
            sources = [*net.parameters(), *net.buffers(), *step.values(), *(before.tensors() if before else ())]
            with OperatorLog(sources) as log:
                net.step(step)
            assert log.kernels() > 500  # the whole step ran under the log
            assert log.host_transfers() == [], f"frame {f}"
            valid = net._stream.state().valid
            if f == 3:
                assert valid.all()  # every memory slot filled: the step read a full memory
            if f == 4:
                assert valid.tolist() == [[True, True], [True, False]]  # stream 1 started again


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA device (run on a device machine)")
@pytest.mark.parametrize("dtype", [torch.float32, torch.bfloat16])
def test_sparselanestp_streaming_with_graphs_equals_it_without(dtype):
    eager = model(**STREAMING, cuda_graphs=False).cuda().eval()
    graphed = model(**STREAMING).cuda().eval()
    tolerance = 1e-4 if dtype == torch.float32 else 5e-2
    with torch.no_grad(), torch.autocast("cuda", dtype=dtype, enabled=dtype != torch.float32):
        for step in clip(6):
            step = {key: value.cuda() for key, value in step.items()}
            want, got = eager.step(step), graphed.step(step)
            for key in ("points", "logits"):
                torch.testing.assert_close(got[key].float(), want[key].float(), atol=tolerance, rtol=tolerance)
            torch.testing.assert_close(got["memory"].points, want["memory"].points, atol=tolerance, rtol=tolerance)
    assert graphed._graphed is not None and eager._graphed is None
    graphed.cpu()  # a move drops the graph, which reads the parameters where they were
    assert graphed._graphed is None
