"""SparseLaneSTP's streaming step with its memory as explicit tensors: the graph that
``lanelab-export`` writes (torch.export, ONNX), which holds no Python state.

    (images, K, T_lane_cam, T_world_lane, reset, *state_in) -> (points, logits, lanes, *state_out)

One call is one ``SparseLaneSTP.step`` of B streams: the memory queue is rebuilt from
``state_in`` (:class:`~lanelab.models.memory_queue.QueueState`: embeddings, points, poses,
valid), emptied where ``reset`` is True, read and pushed as ``step`` does, and handed back as
``state_out``; the caller feeds ``state_out`` into the next call. ``initial_state`` is the
state of an empty memory (a first frame must also set ``reset``, as every clip start does).

Inputs and outputs (B streams, N lines, M control points, K categories, S lane samples at the
y grid ``y``; T memory frames of N_mem lines of C channels):

- images (B, 3, H, W) float32: normalised RGB, as the data pipeline makes it;
- K (B, 3, 3) float32: intrinsics of the images as given; T_lane_cam (B, 4, 4) float32;
- T_world_lane (B, 4, 4) float64: the ego pose;
- reset (B,) bool: a clip starts, empty the memory first;
- points (B, N, M, 4) float32: the last layer's control points (x, y, z, v), metres;
- logits (B, N, K + 1) float32: class logits, background last;
- lanes (B, N, S, 4) float32: the lines decoded at ``y``, (x, y, z, v);
- the state, in and out alike (:class:`~lanelab.models.memory_queue.QueueState`, slot 0 the
  newest frame): embeddings (B, T, N_mem, M, C) float32, points (B, T, N_mem, M, 4) float32
  (each slot in its own frame's lane frame), poses (B, T, 4, 4) float64 (T_world_lane of each
  slot's frame), valid (B, T) bool.

The spatio-temporal attention runs its dense implementation, the sparse one's reference: the
same keys and the same result (:mod:`lanelab.models.spatio_temporal_attention`); the sparse
one sizes its key band from the data (a Python int), which a static graph cannot hold. Its
parallel neighbours settle near-ties for the earlier point (:func:`settle_ties`), so that every
backend picks the same keys; a module the graph is checked against must settle them alike.
"""

from __future__ import annotations

import copy

import torch
from torch import Tensor, nn

from lanelab.models.memory_queue import MemoryQueue, QueueState
from lanelab.models.sparselanestp import SparseLaneSTP
from lanelab.models.spatio_temporal_attention import SpatioTemporalAttention
from lanelab.models.sta_masks import PNA_TIE_MARGIN_M

INPUT_NAMES = ("images", "K", "T_lane_cam", "T_world_lane", "reset")
OUTPUT_NAMES = ("points", "logits", "lanes")
STATE_NAMES = ("embeddings", "points", "poses", "valid")  # QueueState's fields, in its order


def settle_ties(net: nn.Module, margin: float = PNA_TIE_MARGIN_M) -> None:
    """Make every spatio-temporal attention of net settle near-tied parallel neighbours for the
    earlier point, by ``margin`` metres per position (:mod:`lanelab.models.ranking`): what an
    exported step and the module it is compared with must share."""
    for module in net.modules():
        if isinstance(module, SpatioTemporalAttention):
            module.pna_tie_margin = margin


class ExplicitStateStep(nn.Module):
    """net: a SparseLaneSTP (copied; the copy's attention set to dense, its ties settled); y (S,):
    metres, where ``lanes`` samples the lines."""

    def __init__(self, net: SparseLaneSTP, y: Tensor) -> None:
        super().__init__()
        self.net = copy.deepcopy(net)
        settle_ties(self.net)
        for module in self.net.modules():
            if isinstance(module, SpatioTemporalAttention) and module.impl == "sparse":
                module.impl = "dense"
        self.register_buffer("y", torch.as_tensor(y, dtype=torch.float32), persistent=False)

    def _queue(self) -> MemoryQueue:
        return MemoryQueue(self.net.num_memory_frames, self.net.num_memory_lines)

    def initial_state(self, batch: int, device: torch.device | str | None = None) -> QueueState:
        """The state of an empty memory for ``batch`` streams."""
        return self._queue().empty_state(batch, self.net.num_points, self.net.embed_dim, device=device)

    def forward(
        self,
        images: Tensor,
        K: Tensor,
        T_lane_cam: Tensor,
        T_world_lane: Tensor,
        reset: Tensor,
        embeddings: Tensor,
        points: Tensor,
        poses: Tensor,
        valid: Tensor,
    ) -> tuple[Tensor, ...]:
        """One streaming step (shapes in the module doc): (points, logits, lanes, embeddings,
        points, poses, valid), the last four the state after this frame."""
        memory = self._queue()
        memory.load(QueueState(embeddings, points, poses, valid))
        frame = {"images": images, "K": K, "T_lane_cam": T_lane_cam, "T_world_lane": T_world_lane, "reset": reset}
        outputs = self.net.step_with(memory, frame)
        lanes = self.net.decode(outputs, self.y)
        return (outputs["points"][-1], outputs["logits"][-1], lanes, *memory.state().tensors())
