"""A detector's streaming step with its memory as explicit tensors: the graph that
``lanelab-export`` writes (torch.export, ONNX), which holds no Python state.

    (images, K, T_lane_cam, T_world_lane, reset, *state_in) -> (points, logits, lanes, *state_out, *picks)

One call is one ``step`` of B streams of a detector with a streaming memory object
(SparseLaneSTP's :class:`~lanelab.models.sparselanestp.memory_queue.MemoryQueue`, Bi²Lane's
:class:`~lanelab.models.bi2lane.frame_cache.FrameCache`): the memory is rebuilt from
``state_in``, emptied where ``reset`` is True, read and pushed as ``step`` does, and handed back
as ``state_out``; the caller feeds ``state_out`` into the next call. ``initial_state`` is the
state of an empty memory (a first frame must also set ``reset``, as every clip start does).

Inputs and outputs (B streams, N lines or anchors, M points, K categories, S lane samples at
the y grid ``y``):

- images (B, 3, H, W) float32: normalised RGB, as the data pipeline makes it;
- K (B, 3, 3) float32: intrinsics of the images as given; T_lane_cam (B, 4, 4) float32;
- T_world_lane (B, 4, 4) float64: the ego pose;
- reset (B,) bool: a clip starts, empty the memory first;
- points (B, N, M, 4) float32: the predicted points (x, y, z, v), metres (SparseLaneSTP: the
  last layer's control points; Bi²Lane: every anchor's proposal at the anchors' y);
- logits (B, N, K + 1) float32: class logits, background last;
- lanes (B, N, S, 4) float32: the lines decoded at ``y``, (x, y, z, v);
- the state, in and out alike, :func:`state_names` in order:
  - SparseLaneSTP (:class:`~lanelab.models.sparselanestp.memory_queue.QueueState`, T memory frames of N_mem
    lines of C channels, slot 0 the newest frame): embeddings (B, T, N_mem, M, C) float32,
    points (B, T, N_mem, M, 4) float32 (each slot in its own frame's lane frame), poses
    (B, T, 4, 4) float64 (T_world_lane of each slot's frame), valid (B, T) bool;
  - Bi²Lane (:class:`~lanelab.models.bi2lane.frame_cache.FrameState`, the N_h past frames,
    oldest first): features (B, N_h, C, h, w) float32, K (B, N_h, 3, 3) float32, T_lane_cam
    (B, N_h, 4, 4) float32, T_world_lane (B, N_h, 4, 4) float64, valid (B, N_h) bool.
- picks: the indices (int64) of every top-k the step took, in order (SparseLaneSTP: per decoder
  layer the parallel neighbours (B, N, M, N, k) and the memory tokens of TCA (B, N, M, k_t),
  then the lines kept in memory (B, N_mem); Bi²Lane: none). A deployment ignores them; the
  export check replays them in ``step()`` (:mod:`lanelab.runtime.ranking`).

SparseLaneSTP's spatio-temporal attention runs its dense implementation, the sparse one's
reference: the same keys and the same result (:mod:`lanelab.models.sparselanestp.spatio_temporal_attention`);
the sparse one sizes its key band from the data (a Python int), which a static graph cannot
hold. Its parallel neighbours settle near-ties for the earlier point (:func:`settle_ties`), so
that every backend picks the same keys; a module the graph is checked against must settle
them alike. Bi²Lane makes no such choices.
"""

from __future__ import annotations

import copy
import dataclasses

import torch
from torch import Tensor, nn

from lanelab.models.bi2lane import Bi2Lane
from lanelab.models.bi2lane.frame_cache import FrameState
from lanelab.models.sparselanestp import SparseLaneSTP
from lanelab.models.sparselanestp.memory_queue import QueueState
from lanelab.models.sparselanestp.spatio_temporal_attention import SpatioTemporalAttention
from lanelab.models.sparselanestp.sta_masks import PNA_TIE_MARGIN_M
from lanelab.runtime.ranking import recording_picks

INPUT_NAMES = ("images", "K", "T_lane_cam", "T_world_lane", "reset")
OUTPUT_NAMES = ("points", "logits", "lanes")


def settle_ties(net: nn.Module, margin: float = PNA_TIE_MARGIN_M) -> None:
    """Make every spatio-temporal attention of net settle near-tied parallel neighbours for the
    earlier point, by ``margin`` metres per position (:mod:`lanelab.runtime.ranking`): what an
    exported step and the module it is compared with must share."""
    for module in net.modules():
        if isinstance(module, SpatioTemporalAttention):
            module.pna_tie_margin = margin


def state_names(net: SparseLaneSTP | Bi2Lane) -> tuple[str, ...]:
    """The names of a detector's streaming state tensors, in order: its memory's State fields."""
    return tuple(field.name for field in dataclasses.fields(type(net.new_memory()).State))


class ExplicitStateStep(nn.Module):
    """net: a SparseLaneSTP or Bi2Lane (copied; a SparseLaneSTP's attention set to dense, its
    ties settled); y (S,): metres, where ``lanes`` samples the lines."""

    def __init__(self, net: SparseLaneSTP | Bi2Lane, y: Tensor) -> None:
        super().__init__()
        self.net = copy.deepcopy(net)
        self.net.cuda_graphs = False  # this step is traced and exported, not replayed
        settle_ties(self.net)
        for module in self.net.modules():
            if isinstance(module, SpatioTemporalAttention) and module.impl in ("auto", "sparse"):
                module.impl = "dense"
        self.register_buffer("y", torch.as_tensor(y, dtype=torch.float32), persistent=False)

    def initial_state(
        self, batch: int, image_size: tuple[int, int], device: torch.device | str | None = None
    ) -> QueueState | FrameState:
        """The state of an empty memory for ``batch`` streams of images of image_size (H, W)."""
        return self.net.empty_memory_state(batch, image_size, device)

    def forward(
        self, images: Tensor, K: Tensor, T_lane_cam: Tensor, T_world_lane: Tensor, reset: Tensor, *state: Tensor
    ) -> tuple[Tensor, ...]:
        """One streaming step (shapes in the module doc): (points, logits, lanes, *state, *picks),
        the state after this frame, then the indices of every top-k the step took, in order."""
        memory = self.net.new_memory()
        memory.load(type(memory).State(*state))
        frame = {"images": images, "K": K, "T_lane_cam": T_lane_cam, "T_world_lane": T_world_lane, "reset": reset}
        with recording_picks() as picks:
            outputs = self.net.step_with(memory, frame)
        lanes = self.net.decode(outputs, self.y)
        return (outputs["points"][-1], outputs["logits"][-1], lanes, *memory.state().tensors(), *picks)
