"""SparseLaneSTP (Pittner et al.): the full temporal sparse 3D lane detector, Fig. 1.

    image -> ResNet -> FPN -> lane query generator -> 0Q, 0P, instance masks
          -> L decoder layers (STA with the memory queue -> DCA -> FFN), shared heads -> lP, classes
          -> the N_mem most confident lines enter the memory queue for the next frames

It is a :class:`lanelab.models.api.LaneDetector`; two ways to run the same weights:
- ``forward(batch)``, windowed (training, evaluation on windows): the F frames of a window are
  unrolled oldest -> current through a fresh memory queue, reset where a frame follows padding;
- ``reset(mask)`` / ``step(frame)``, streaming (inference, streaming training): one frame per
  call, the memory queue carried across calls. A step is one call of fixed shapes on the
  queue's fixed-size state (an empty queue is all slots invalid), the reset inside it, and makes
  no tensor from host data: streaming inference on a GPU replays it from a CUDA graph
  (:mod:`lanelab.runtime.cuda_graph`), as Bi²Lane's.
Like StreamPETR, memory contents are detached: gradients never flow into earlier frames.

The single-frame LATR-like baseline is a configuration of the same code: num_memory_frames=0,
attention="global", representation="discrete".

Where the paper is silent we follow LATR, except where noted: C3..C5 into a 4-level FPN; the
query generator on the stride-8 level; post-norm decoder layers with iterative refinement.
Unlike LATR, the initial queries 0Q are the content (LATR starts from zeros and uses them as
positions; §3.2 feeds 0Q to the decoder) with PE(P) as positions, and the deformable attention
samples the FPN levels directly (Deformable DETR) where LATR first fuses them into one map.
The memory keeps the lines with the highest foreground class probability (StreamPETR's top-k
by score, with DETR's softmax score). The image features carry LATR's 3D ground positional
encoding (models.sparselanestp.ground_encoding).

Three options make a small model learn from a short schedule (issue "The detectors must learn";
each can be switched off to get the paper's / LATR's behaviour): learned lateral line anchors
(anchor_span, DAB-DETR / Anchor3DLane style) with lanes assigned to lines by them
(HungarianMatcher(match_on="anchors"), one-to-many with positive_distance), and sample weights
in the deformable cross-attention that depend on the sampled content (dca_content_weights). A
fourth, a lateral search after every layer that moves each control point across the road onto
the marking it sees (lateral_search, models.sparselanestp.lateral_search), is off in the configurations: it
did not improve the near-range error on held-out drives.

A fifth reads the road (issue "Decoders that read the road"): ``lateral_offset`` adds a dense
lateral-offset map (models.sparselanestp.lateral_offset) whose direct read moves each line's initial points
onto the lane it sees, before the decoder starts. Off in the papers' configurations (null),
on at the tiny size the demo trains (conf/model_size/tiny).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any, NamedTuple

import torch
from torch import Tensor, nn

from lanelab.models.api import TARGET_KEYS
from lanelab.models.parts.backbone import ResNet
from lanelab.models.parts.fpn import FPN
from lanelab.models.parts.heads import LaneHead
from lanelab.models.sparselanestp.decoder import DecoderLayer, LaneDecoder
from lanelab.models.sparselanestp.deformable_attention import DeformableCrossAttention
from lanelab.models.sparselanestp.ground_encoding import GroundPositionalEncoding
from lanelab.models.sparselanestp.lateral_offset import LateralOffsetReader
from lanelab.models.sparselanestp.lateral_search import LateralSearch
from lanelab.models.sparselanestp.memory_queue import MemoryQueue, MemoryState, QueueState
from lanelab.models.sparselanestp.positional_encoding import PointPositionalEncoding
from lanelab.models.sparselanestp.query_denoising import QueryDenoising
from lanelab.models.sparselanestp.query_init import LaneQueryGenerator
from lanelab.models.sparselanestp.spatio_temporal_attention import SpatioTemporalAttention
from lanelab.runtime.cuda_graph import CUDAGraphed

# LATR's neck reads C3..C5; the query generator reads the finest FPN level (stride 8). A stride-4
# lateral-offset map also reads C2.
_BACKBONE_STAGES = (1, 2, 3)
_BACKBONE_STAGES_FINE = (0, 1, 2, 3)


class _Encoded(NamedTuple):
    """The memory-independent part of one frame: FPN levels [(B, C, H_l, W_l)], queries 0Q
    (B, N, M, C), initial point logits (B, N, M, 3), instance-mask logits (B, N, H/8, W/8),
    the lateral-offset map (B, 2, h, w) or None."""

    features: list[Tensor]
    queries: Tensor
    logits: Tensor
    masks: Tensor
    offsets: Tensor | None


class SparseLaneSTP(nn.Module):
    """All sizes come from the configuration (conf/model), none is defaulted here.

    Backbone and neck: backbone_depth (18, 34, 50), backbone_width (64 = the paper's ResNet),
    embed_dim C (FPN and queries).
    Queries: num_lines N, num_points M, query_convs, mask_dim (the instance branch).
    Decoder: num_layers L, num_heads, ffn_dim, dropout; deformable attention over dca_levels
    FPN levels (LATR: 4, strides 8 to 64) with dca_points samples per head and level;
    dca_content_weights: weigh the samples by their content too (models.sparselanestp.deformable_attention).
    Attention: attention ("auto" / "sparse" / "dense": STA with masked relations, computed as
    models.sparselanestp.spatio_temporal_attention picks; "global": full self-attention over the N x M
    queries, the LATR baseline), use_sla, use_pna, use_tca,
    pna_neighbors (2 per adjacent line), tca_neighbors M_TCA.
    Memory: num_memory_frames T (0 disables temporal fusion), num_memory_lines N_mem.
    Heads: num_classes K (without background), x_range, y_range, z_range (metres),
    representation ("catmull_rom" or "discrete"), head_hidden_layers.
    Image positions: ground_encoding adds LATR's 3D ground positional encoding to the image
    features the cross-attention reads (models.sparselanestp.ground_encoding).
    Line anchors: anchor_span (metres) spreads the N lines' learned lateral anchors evenly over
    [-anchor_span, anchor_span] (models.sparselanestp.query_init); null: no anchors.
    lateral_search: {num_candidates, search_range (metres)} of a LateralSearch after every decoder
    layer, on the finest feature level; null: none.
    lateral_offset: {stride (4 or 8), hidden, read_range, num_reads, iterations} of a
    LateralOffsetReader whose map moves the initial points onto the lanes it reads; null: none.
    denoising: {groups, max_shift (metres), max_angle (degrees)} of the QueryDenoising that,
    in training, also decodes noised ground-truth lanes (models.sparselanestp.query_denoising); null: none.
    cuda_graphs: streaming inference on a GPU replays each step from a CUDA graph (the same
    results, without the launch cost of its ~2,000 small kernels); not with attention="sparse",
    whose key band is sized from the data.
    """

    def __init__(
        self,
        *,
        backbone_depth: int,
        backbone_width: int,
        embed_dim: int,
        num_lines: int,
        num_points: int,
        query_convs: int,
        mask_dim: int,
        num_layers: int,
        num_heads: int,
        ffn_dim: int,
        dropout: float,
        dca_levels: int,
        dca_points: int,
        attention: str,
        use_sla: bool,
        use_pna: bool,
        use_tca: bool,
        pna_neighbors: int,
        tca_neighbors: int,
        num_memory_frames: int,
        num_memory_lines: int,
        num_classes: int,
        x_range: Sequence[float],
        y_range: Sequence[float],
        z_range: Sequence[float],
        representation: str,
        head_hidden_layers: int,
        ground_encoding: bool,
        anchor_span: float | None,
        dca_content_weights: bool,
        lateral_search: Mapping[str, float] | None,
        lateral_offset: Mapping[str, Any] | None = None,
        denoising: Mapping[str, Any] | None = None,
        cuda_graphs: bool = True,
    ) -> None:
        super().__init__()
        reader = dict(lateral_offset) if lateral_offset is not None else None
        stride = None if reader is None else reader.pop("stride")
        if stride not in (None, 4, 8):
            raise ValueError(f"lateral_offset.stride must be 4 or 8, got {stride}")
        self.backbone = ResNet(backbone_depth, backbone_width, _BACKBONE_STAGES_FINE if stride == 4 else _BACKBONE_STAGES)
        neck_channels = self.backbone.out_channels[-len(_BACKBONE_STAGES) :]
        self.neck = FPN(neck_channels, embed_dim, dca_levels)
        self.reader = None
        if reader is not None:
            fine_channels = self.backbone.out_channels[0] if stride == 4 else None
            self.reader = LateralOffsetReader(embed_dim, fine_channels, **reader)
        anchor_logits = None
        if anchor_span is not None:
            if not 0 <= anchor_span < min(-x_range[0], x_range[1]):
                raise ValueError(f"anchor_span={anchor_span} must lie inside x_range {tuple(x_range)}")
            unit = (torch.linspace(-anchor_span, anchor_span, num_lines) - x_range[0]) / (x_range[1] - x_range[0])
            anchor_logits = torch.logit(unit)
        self.query_generator = LaneQueryGenerator(
            embed_dim, num_lines, num_points, query_convs, mask_dim, head_hidden_layers, anchor_logits
        )
        head = LaneHead(
            embed_dim, num_points, num_classes, tuple(x_range), tuple(y_range), tuple(z_range),
            representation, head_hidden_layers,
        )  # fmt: skip
        layers = [
            DecoderLayer(
                embed_dim,
                ffn_dim,
                dropout,
                SpatioTemporalAttention(
                    embed_dim, num_heads, num_neighbors=pna_neighbors, m_tca=tca_neighbors, use_sla=use_sla,
                    use_pna=use_pna, use_tca=use_tca, dropout=dropout, impl=attention,
                ),  # fmt: skip
                DeformableCrossAttention(embed_dim, num_heads, dca_levels, dca_points, dca_content_weights),
            )
            for _ in range(num_layers)
        ]
        searches = None
        if lateral_search is not None:
            searches = [LateralSearch(embed_dim, **lateral_search) for _ in range(num_layers)]
        self.decoder = LaneDecoder(layers, head, PointPositionalEncoding(embed_dim), searches)
        self.ground_encoding = (
            GroundPositionalEncoding(embed_dim, tuple(x_range), tuple(y_range), tuple(z_range)) if ground_encoding else None
        )
        if self.reader is not None:  # the spline at the reader's y (S, M), made once rather than per step
            self.register_buffer("read_basis", self.head.curves.bases(self.reader.read_y)[0], persistent=False)
        self.denoising = None if denoising is None else QueryDenoising(embed_dim, num_points, **denoising)
        self.num_memory_frames, self.num_memory_lines = num_memory_frames, num_memory_lines
        self.embed_dim, self.num_points = embed_dim, num_points
        self._stream = self.new_memory()  # the streaming state
        self.cuda_graphs = cuda_graphs and attention != "sparse"
        self._graphed: CUDAGraphed | None = None  # the streaming step's, made at first use

    @property
    def head(self) -> LaneHead:
        return self.decoder.head

    # ----------------------------------------------------------------- windowed
    def forward(self, batch: Mapping[str, Tensor], all_frames: bool = False) -> dict[str, Any]:
        """Windowed forward over the F frames of a batch.

        batch: images (B, F, 3, H, W), K (B, F, 3, 3), T_lane_cam (B, F, 4, 4),
        T_world_lane (B, F, 4, 4), valid (B, F) bool (False: padding before a clip start);
        K in pixels of the images as given (after any resizing).
        Returns the current (last) frame's outputs (see ``step``); in training with query
        denoising, also "denoising", the noised lanes' (``_denoise``), for which the batch's
        ground truth (TARGET_KEYS) is read. With all_frames, every
        per-frame output gets a frame axis after the batch axis (B, F, ...), "memory" is left out,
        and every frame is differentiable; otherwise the earlier frames only fill the memory,
        without gradient. Without a memory (num_memory_frames = 0) the earlier frames cannot
        change the current frame's outputs, and only the current frame is run.
        """
        targets = None
        if self.denoising is not None and self.training and not all_frames:
            targets = {key: batch[key] for key in TARGET_KEYS}
        if self.num_memory_frames == 0 and not all_frames:
            batch = {key: batch[key][:, -1:] for key in ("images", "K", "T_lane_cam", "T_world_lane", "valid")}
        images, valid = batch["images"], batch["valid"]
        B, F = images.shape[:2]
        if all_frames or F == 1:
            encoded = self._encode(images, batch["K"], batch["T_lane_cam"])
        else:
            with torch.no_grad():
                encoded = self._encode(images[:, :-1], batch["K"][:, :-1], batch["T_lane_cam"][:, :-1])
            encoded += self._encode(images[:, -1:], batch["K"][:, -1:], batch["T_lane_cam"][:, -1:])

        memory = self.new_memory()
        outputs = []
        for f in range(F):
            if f > 0:  # the frame after padding starts a clip: it sees an empty memory
                memory.reset(~valid[:, f - 1])
            with torch.set_grad_enabled(torch.is_grad_enabled() and (all_frames or f == F - 1)):
                outputs.append(
                    self._decode(
                        encoded[f],
                        batch["K"][:, f], batch["T_lane_cam"][:, f], batch["T_world_lane"][:, f],
                        tuple(images.shape[-2:]), memory, targets if f == F - 1 else None,
                    )  # fmt: skip
                )
        if not all_frames:
            return outputs[-1]
        tensors = [key for key, value in outputs[-1].items() if key not in ("memory", "anchors") and value is not None]
        stacked = {key: torch.stack([out[key] for out in outputs], dim=_frame_axis(key)) for key in tensors}
        return {**stacked, "anchors": outputs[-1]["anchors"]}

    # ---------------------------------------------------------------- streaming
    def reset(self, mask: Tensor) -> None:
        """Empty the streaming memory of the batch elements where mask (B,) is True (clip
        starts). Changing the stream's batch size needs a reset of every element."""
        self._stream.reset(mask)

    def step(self, frame: Mapping[str, Tensor]) -> dict[str, Any]:
        """One streaming step.

        frame: images (B, 3, H, W), K (B, 3, 3), T_lane_cam (B, 4, 4), T_world_lane (B, 4, 4)
        and optionally reset (B,) bool, which calls ``reset`` first.
        Returns, for this frame:
            points      (L, B, N, M, 4)  control points (x, y, z, v) of every decoder layer,
                                         metres; [-1] is the prediction
            logits      (L, B, N, K + 1) class logits of every layer, background last
            init_points (B, N, M, 4)     the query generator's initial control points 0P (after
                                         the lateral-offset read, with one)
            masks       (B, N, H/8, W/8) auxiliary instance-mask logits (stride of FPN level 0)
            offsets     (B, 2, h, w)     the lateral-offset map (offset in image widths, confidence
                                         logit; models.sparselanestp.lateral_offset), or None
            anchors     (N,) the lines' lateral anchors (metres), or None without anchors
            memory      MemoryState | None, the propagated memory this frame attended to (what
                        the temporal regulariser, eq. 12-13, compares with); None without a
                        memory (T = 0); after a reset every slot is invalid
        """
        return self.step_with(self._stream, frame)

    def step_with(self, memory: MemoryQueue, frame: Mapping[str, Tensor]) -> dict[str, Any]:
        """``step`` against the given memory queue instead of the model's own (an exported
        graph carries its memory as tensors: lanelab.deploy.explicit_state)."""
        images, T_world_lane = frame["images"], frame["T_world_lane"]
        B = images.shape[0]
        reset = frame["reset"].to(images.device) if "reset" in frame else images.new_zeros(B, dtype=torch.bool)
        state = memory.state()
        if self.num_memory_frames > 0 and (state is None or state.valid.shape[0] != B):
            memory.reset(reset)  # a new batch size: every stream must start
            memory.load(memory.empty_state(B, self.num_points, self.embed_dim,
                                           (torch.float32, torch.float32, T_world_lane.dtype), images.device))  # fmt: skip
        state = () if self.num_memory_frames == 0 else memory.state().tensors()
        outputs, state = self._streaming_call(images)(images, frame["K"], frame["T_lane_cam"], T_world_lane, reset, *state)
        if state:
            memory.load(QueueState(*state))
        return outputs

    def new_memory(self) -> MemoryQueue:
        """An empty streaming state of this model: its memory queue."""
        return MemoryQueue(self.num_memory_frames, self.num_memory_lines)

    def empty_memory_state(
        self, batch: int, image_size: tuple[int, int], device: torch.device | str | None = None
    ) -> QueueState:
        """The state of an empty memory for ``batch`` streams (of any image size)."""
        return self.new_memory().empty_state(batch, self.num_points, self.embed_dim, device=device)

    def anchors(self) -> Tensor | None:
        """The lines' lateral anchors x (N,), metres; None when the model has none."""
        logits = self.query_generator.anchor_logits
        if logits is None:
            return None
        low, high = self.head.x_range
        return logits.sigmoid() * (high - low) + low

    # ------------------------------------------------------------------ decoding
    def decode(self, outputs: Mapping[str, Tensor], y: Tensor) -> Tensor:
        """Dense lanes (..., N, S, 4) = (x, y, z, v) at longitudinal positions y (S,) from the
        last layer's control points of ``forward`` / ``step`` outputs (any leading axes)."""
        return self.head.decode(outputs["points"][-1], y)

    # ----------------------------------------------------------------- internals
    def _streaming_call(self, images: Tensor) -> Any:
        """The streaming step (``_stream_step``): replayed from a CUDA graph for inference on a GPU."""
        if not (self.cuda_graphs and images.is_cuda and not self.training and not torch.is_grad_enabled()):
            return self._stream_step
        if self._graphed is None:
            self._graphed = CUDAGraphed(self._stream_step)
        return self._graphed

    def _apply(self, fn: Any, recurse: bool = True) -> "SparseLaneSTP":
        self._graphed = None  # a captured graph reads the parameters where they were before the move
        return super()._apply(fn, recurse)

    def _stream_step(
        self, images: Tensor, K: Tensor, T_lane_cam: Tensor, T_world_lane: Tensor, reset: Tensor, *state: Tensor
    ) -> tuple[dict[str, Any], tuple[Tensor, ...]]:
        """One streaming frame on the memory queue's state as tensors (``QueueState``, none
        without a memory): images (B, 3, H, W), K (B, 3, 3), T_lane_cam, T_world_lane (B, 4, 4),
        reset (B,) bool (emptied first). Returns the outputs of ``step`` and the state after it."""
        memory = self.new_memory()
        if state:
            memory.load(QueueState(*state))
        memory.reset(reset)
        (encoded,) = self._encode(images[:, None], K[:, None], T_lane_cam[:, None])
        outputs = self._decode(encoded, K, T_lane_cam, T_world_lane, tuple(images.shape[-2:]), memory)
        return outputs, () if not state else memory.state().tensors()

    def _encode(self, images: Tensor, K: Tensor, T_lane_cam: Tensor) -> list[_Encoded]:
        """The per-frame work, batched over frames: images (B, F, 3, H, W) with their K
        (B, F, 3, 3) and T_lane_cam (B, F, 4, 4) -> F encodings."""
        B, F = images.shape[:2]
        K, T_lane_cam, image_size = K.flatten(0, 1), T_lane_cam.flatten(0, 1), tuple(images.shape[-2:])
        stages = self.backbone(images.flatten(0, 1))
        features = self.neck(stages[-len(_BACKBONE_STAGES) :])
        if self.ground_encoding is not None:  # before the query generator: its line embeddings pool positions too
            features = self.ground_encoding(features, K, T_lane_cam, image_size)
        queries, logits, masks = self.query_generator(features[0])
        offsets = None
        if self.reader is not None:
            offsets = self.reader(features[0], stages[0] if len(stages) > len(_BACKBONE_STAGES) else None)
            logits = self._read_lines(offsets, logits, K, T_lane_cam, image_size)
        per_frame = [[level.unflatten(0, (B, F))[:, f] for level in features] for f in range(F)]
        queries, logits, masks = (t.unflatten(0, (B, F)) for t in (queries, logits, masks))
        offsets = [None] * F if offsets is None else offsets.unflatten(0, (B, F)).unbind(1)
        return [_Encoded(per_frame[f], queries[:, f], logits[:, f], masks[:, f], offsets[f]) for f in range(F)]

    def _read_lines(
        self, offsets: Tensor, logits: Tensor, K: Tensor, T_lane_cam: Tensor, image_size: tuple[int, int]
    ) -> Tensor:
        """Initial point logits (B, N, M, 3) moved sideways onto the lanes the lateral-offset map
        (B, 2, h, w) shows (models.sparselanestp.lateral_offset)."""
        points = self.head.control_points(logits)[..., :3]

        def curve(shifts: Tensor) -> Tensor:
            shifted = torch.cat([points[..., :1] + shifts[..., None], points[..., 1:]], -1)
            with torch.autocast(shifted.device.type, enabled=False):  # metres, in the points' precision
                return self.read_basis.to(shifted) @ shifted

        shifts = self.reader.line_shifts(offsets, curve, self.head.y, K, T_lane_cam, image_size)
        return self.head.shift_x(logits, shifts)

    def _decode(
        self,
        encoded: _Encoded,
        K: Tensor,
        T_lane_cam: Tensor,
        T_world_lane: Tensor,
        image_size: tuple[int, int],
        memory: MemoryQueue,
        targets: Mapping[str, Tensor] | None = None,
    ) -> dict[str, Any]:
        """Decode one frame against the memory, then push its most confident lines; with targets
        (the frame's ground truth), decode its noised lanes too."""
        state = memory.read(T_world_lane)
        points, logits, queries = self.decoder(
            encoded.queries, encoded.logits, state, encoded.features, K, T_lane_cam, image_size
        )
        # Confidence = the best foreground class probability (DETR's score). The queue detaches.
        memory.push(queries, points[-1], logits[-1].softmax(-1)[..., :-1].amax(-1), T_world_lane)
        outputs = {
            "points": points,
            "logits": logits,
            "init_points": self.head.control_points(encoded.logits),
            "masks": encoded.masks,
            "offsets": encoded.offsets,
            "anchors": self.anchors(),
            "memory": state,
        }
        if targets is not None and targets["gt_mask"].shape[1] > 0:  # a batch without lanes has none to noise
            outputs["denoising"] = self._denoise(encoded, state, targets, K, T_lane_cam, image_size)
        return outputs

    def _denoise(
        self,
        encoded: _Encoded,
        memory: MemoryState | None,
        targets: Mapping[str, Tensor],
        K: Tensor,
        T_lane_cam: Tensor,
        image_size: tuple[int, int],
    ) -> dict[str, Tensor]:
        """The frame's ground-truth lanes (G per sample), noised R times, through the decoder on
        the same image and memory as the detection's lines, in a pass of their own.
        Returns points (L, B, R G, M, 4) and logits (L, B, R G, K + 1): line r G + g is the r-th
        noised copy of lane g."""
        R = self.denoising.groups
        points, line_mask = self.denoising.noised_points(targets, self.head.y)
        BR, G = line_mask.shape
        queries = self.denoising.queries(self.query_generator.point_embedding.weight, (BR, G))

        def repeat(tensor: Tensor) -> Tensor:  # one batch element per group
            return tensor.repeat_interleave(R, 0)

        if memory is not None:
            memory = memory.map(repeat)
        all_points, all_logits, _ = self.decoder(
            queries, self.head.point_logits(points), memory, [repeat(level) for level in encoded.features],
            repeat(K), repeat(T_lane_cam), image_size, line_mask,
        )  # fmt: skip
        L, B = all_points.shape[0], BR // R
        return {
            "points": all_points.reshape(L, B, R * G, *all_points.shape[-2:]),
            "logits": all_logits.reshape(L, B, R * G, -1),
        }


def _frame_axis(key: str) -> int:
    """Where the frame axis goes in stacked outputs: after the batch axis, which per-layer
    outputs (points, logits) have second."""
    return 2 if key in ("points", "logits") else 1
