"""Bi²Lane (Li et al.): temporal 3D lane detection by bi-directional temporal refinement (BDTR) and
bi-level feature aggregation (BLFA), Fig. 2.

    N + 1 images -> ResNet -> FPN (stride 8) -> front-view features I_{t-N} .. I_t
    3D anchors --BDTR forward  (t-N -> t, eq. 5)--> lane-feature set {F_e}
               --BDTR reverse  (t -> t-N, eq. 6)--> lane-feature set {F~_e}
    each set --BLFA (point level to history, line level among a lane's points, eq. 7-10)-->
    concatenated (eq. 11) -> heads: class, x / z offsets of the anchor, visibility (eq. 12-13)
    current features -> BEV (IPM) -> lane mask, the auxiliary loss of eq. 14 (training only)

It is a :class:`lanelab.models.api.LaneDetector`; two ways to run the same weights:
- ``forward(batch)``, windowed: the last N + 1 frames of each window (oldest first);
- ``reset(mask)`` / ``step(frame)``, streaming: one frame per call, the past frames' features
  cached (:class:`FrameCache`), so a frame costs one backbone pass; equal to windowed.

Every ablation of the paper's Tables III-VII is a constructor argument: the single-frame
baseline (num_history_frames=0: the anchors sampled on the current frame only, no BDTR, no
BLFA), the aggregation level (Table IV), the direction (Table V), the number of history frames
(Table VI), the temporal alignment (Table VII); Table III's "+BDTR" is aggregation="none".

Where the paper is silent: anchors, their projection, sampling and heads follow Anchor3DLane
(models.bi2lane.anchors; the heads are MLPs over a lane's M x C feature, as its DecodeLayer);
the image features are the stride-8 level of an FPN over C3..C5 (Anchor3DLane uses a dilated
ResNet at stride 8); the BEV branch follows PersFormer (models.bi2lane.bev).
Proposals are the anchors plus their offsets at the anchors' fixed y (§III-D,
P = (x + Δx, y, z + Δz, vis)); decoded linearly between points (LATR's discrete points).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any, TypedDict

import torch
from torch import Tensor, nn

from lanelab.geometry import control_point_y
from lanelab.geometry.curves import LaneCurves
from lanelab.models.bi2lane.aggregation import BiLevelAggregation
from lanelab.models.bi2lane.anchors import anchor_families
from lanelab.models.bi2lane.bev import BEVSegmentation
from lanelab.models.bi2lane.frame_cache import FrameCache, FrameState
from lanelab.models.bi2lane.refinement import TemporalRefinement, refine
from lanelab.models.parts.backbone import ResNet
from lanelab.models.parts.fpn import FPN
from lanelab.models.parts.heads import mlp
from lanelab.runtime.cuda_graph import CUDAGraphed

DIRECTIONS = ("forward", "reverse", "bidirectional")
# The FPN reads C3..C5 and gives one level, stride 8.
_BACKBONE_STAGES = (1, 2, 3)
# Anchors per BLFA call on a CPU. Each anchor's aggregation is its own; in chunks, the copies of the history
# that the products make and the feed-forward layers' activations (at the paper size N x 23 MB and 90 MB
# for all 4431 anchors) stay under glibc's 32 MB, above which every allocation is fresh pages from the
# kernel. Five history frames cost +33-35 % over one with one call, +4-25 % in chunks (glibc's defaults,
# benchmarks/RESULTS.md).
_CPU_AGGREGATION_CHUNK = 512
# The paper's Table VI goes to 5 history frames; the age embedding of the point level is sized for it.
MAX_HISTORY_FRAMES = 5


class AnchorFamilies(TypedDict):
    """model.net.anchors (models.bi2lane.anchors.anchor_families)."""

    x_range: tuple[float, float]  # metres: start x spread evenly over it; anchors must keep half their points inside
    num_x: int  # start x positions
    yaws: list[float]  # degrees
    pitches: list[float]  # degrees


class BEVBranch(TypedDict):
    """model.net.bev (models.bi2lane.bev.BEVSegmentation)."""

    x_range: tuple[float, float]  # metres, the ground region of the lane mask
    y_range: tuple[float, float]
    size: tuple[int, int]  # (rows, columns) of its grid
    hidden: int  # channels of the head


class Bi2Lane(nn.Module):
    """All sizes come from the configuration (conf/model/bi2lane.yaml), none is defaulted here.

    backbone_depth, backbone_width: the ResNet; embed_dim C: FPN and lane-feature channels.
    num_points M over y_range (metres): the anchors' fixed y; anchors: their families.
    num_history_frames N (0: the single-frame baseline); direction: "forward", "reverse" or
    "bidirectional" (Table V); aggregation: "none", "point", "line" or "bilevel" (Table IV);
    temporal_alignment: move anchors between frames by the ego motion (Table VII).
    num_heads, ffn_dim, dropout: BLFA's attention layers; head_hidden_dim, head_hidden_layers:
    the MLPs of the class / x / z / visibility heads; offset_hidden_dim: the hidden width of
    BDTR's offset heads (eq. 2, with head_hidden_layers), which run once per history frame.
    num_classes K (without background); bev: the auxiliary BEV branch, None: none.
    cuda_graphs: streaming inference on a GPU replays each frame's kernels from CUDA graphs
    (:mod:`lanelab.runtime.cuda_graph`; the same results, without the launch cost of BDTR's steps).
    """

    def __init__(
        self,
        *,
        backbone_depth: int,
        backbone_width: int,
        embed_dim: int,
        num_points: int,
        y_range: Sequence[float],
        anchors: AnchorFamilies,
        num_history_frames: int,
        direction: str,
        aggregation: str,
        temporal_alignment: bool,
        num_heads: int,
        ffn_dim: int,
        dropout: float,
        head_hidden_dim: int,
        head_hidden_layers: int,
        offset_hidden_dim: int,
        num_classes: int,
        bev: BEVBranch | None,
        cuda_graphs: bool = True,
    ) -> None:
        super().__init__()
        if direction not in DIRECTIONS:
            raise ValueError(f"direction must be one of {DIRECTIONS}, got {direction!r}")
        if not 0 <= num_history_frames <= MAX_HISTORY_FRAMES:
            raise ValueError(f"num_history_frames must lie in 0..{MAX_HISTORY_FRAMES}, got {num_history_frames}")
        self.backbone = ResNet(backbone_depth, backbone_width, _BACKBONE_STAGES)
        self.neck = FPN(self.backbone.out_channels, embed_dim, 1)
        y = control_point_y(num_points, *y_range)
        self.register_buffer("anchors", anchor_families(y, **anchors), persistent=False)  # (A, M, 3)
        self.curves = LaneCurves("discrete", num_points, tuple(y_range))
        self.num_history_frames, self.direction = num_history_frames, direction
        self.directions = ("forward", "reverse") if direction == "bidirectional" else (direction,)
        # One refinement and one aggregation per direction, in the order of self.directions.
        self.refinement = nn.ModuleList(
            TemporalRefinement(embed_dim, num_points, offset_hidden_dim, head_hidden_layers, temporal_alignment,
                               steps=num_history_frames > 0)
            for _ in self.directions
        )
        self.aggregation = nn.ModuleList(
            BiLevelAggregation(embed_dim, num_points, num_history_frames, aggregation, num_heads, ffn_dim, dropout)
            for _ in self.directions
        )
        lane_dim = len(self.directions) * num_points * embed_dim  # eq. 11's concatenation, flattened
        self.classifier = mlp(lane_dim, head_hidden_dim, num_classes + 1, head_hidden_layers)
        self.x_head = mlp(lane_dim, head_hidden_dim, num_points, head_hidden_layers)
        self.z_head = mlp(lane_dim, head_hidden_dim, num_points, head_hidden_layers)
        self.vis_head = mlp(lane_dim, head_hidden_dim, num_points, head_hidden_layers)
        for branch in (self.x_head, self.z_head):  # proposals start on their anchors
            nn.init.zeros_(branch[-1].weight)
            nn.init.zeros_(branch[-1].bias)
        self.bev = None if bev is None else BEVSegmentation(embed_dim, **bev)
        self._stream = self.new_memory()
        self.cuda_graphs = cuda_graphs
        self._graphed: tuple[CUDAGraphed, CUDAGraphed] | None = None  # (encode, detect), made at first use

    # ----------------------------------------------------------------- windowed
    def forward(self, batch: Mapping[str, Tensor]) -> dict[str, Any]:
        """The current (last) frame's outputs (see ``step``) from the last N + 1 frames of a
        batch: images (B, F, 3, H, W), K (B, F, 3, 3), T_lane_cam, T_world_lane (B, F, 4, 4),
        valid (B, F) bool; F >= N + 1."""
        F, needed = batch["images"].shape[1], self.num_history_frames + 1
        if F < needed:
            raise ValueError(f"Bi2Lane with num_history_frames={self.num_history_frames} needs windows of at least "
                             f"{needed} frames (data.num_frames), got {F}")  # fmt: skip
        window = {key: batch[key][:, F - needed :] for key in ("images", "K", "T_lane_cam", "T_world_lane", "valid")}
        features = self._encode(window.pop("images"))
        return self._detect(features, **window, image_size=tuple(batch["images"].shape[-2:]))

    # ---------------------------------------------------------------- streaming
    def reset(self, mask: Tensor) -> None:
        """Forget the cached past of the streams where mask (B,) is True (clip starts)."""
        self._stream.reset(mask)

    def step(self, frame: Mapping[str, Tensor]) -> dict[str, Any]:
        """One streaming step: frame holds images (B, 3, H, W), K (B, 3, 3), T_lane_cam,
        T_world_lane (B, 4, 4) and optionally reset (B,) bool, which calls ``reset`` first.
        Returns, for this frame:
            points           (1, B, A, M, 4) proposals (x, y, z, v) at the anchors' y, metres
            logits           (1, B, A, K + 1) class logits, background last
            anchors          (A, M, 3) the anchors
            detections       (B, S, A, M, 3) every BDTR step's refined anchors (the lanes each
                             history frame detected), in the current lane frame
            detection_valid  (B, S) bool, the step's frame was real
            bev_logits       (B, rows, columns) lane-mask logits of the BEV branch, with bev_x
                             (columns,) and bev_y (rows,), the cells' centres (training only)
        """
        return self.step_with(self._stream, frame)

    def step_with(self, cache: FrameCache, frame: Mapping[str, Tensor]) -> dict[str, Any]:
        """``step`` against the given frame cache instead of the model's own (an exported graph
        carries its cache as tensors: lanelab.deploy.explicit_state)."""
        if "reset" in frame:
            cache.reset(frame["reset"])
        images = frame["images"]
        encode, detect = self._streaming_calls(images)
        features = encode(images[:, None])[:, 0]
        window = cache.push(features, frame["K"], frame["T_lane_cam"], frame["T_world_lane"])
        cameras = (window[key] for key in ("K", "T_lane_cam", "T_world_lane", "valid"))
        return detect(window["features"], *cameras, tuple(images.shape[-2:]))

    def new_memory(self) -> FrameCache:
        """An empty streaming state of this model: the cache of its N past frames."""
        return FrameCache(self.num_history_frames + 1)

    def empty_memory_state(
        self, batch: int, image_size: tuple[int, int], device: torch.device | str | None = None
    ) -> FrameState:
        """The state of an empty cache for ``batch`` streams of images of image_size (H, W)."""
        training = self.training
        self.eval()  # the feature map's size, as the encoder makes it, without touching batch-norm statistics
        with torch.no_grad():
            probe = self._encode(torch.zeros(1, 1, 3, *image_size, device=self.anchors.device))
        self.train(training)
        return self.new_memory().empty_state(batch, tuple(probe.shape[2:]), device)

    # ------------------------------------------------------------------ decoding
    def decode(self, outputs: Mapping[str, Any], y: Tensor) -> Tensor:
        """Dense lanes (B, A, S, 4) = (x, y, z, v) of the proposals at y (S,) in y_range."""
        points = outputs["points"][-1]
        dense = self.curves.sample(points, y.to(points))
        x, _, z, v = dense.unbind(-1)
        return torch.stack([x, y.to(points).expand_as(x), z, v], dim=-1)

    # ----------------------------------------------------------------- internals
    def _streaming_calls(self, images: Tensor) -> tuple[Any, Any]:
        """(encode, detect) for a streaming frame: replayed from CUDA graphs for inference on a GPU."""
        if not (self.cuda_graphs and images.is_cuda and not self.training and not torch.is_grad_enabled()):
            return self._encode, self._detect
        if self._graphed is None:
            self._graphed = CUDAGraphed(self._encode), CUDAGraphed(self._detect)
        return self._graphed

    def _apply(self, fn: Any, recurse: bool = True) -> "Bi2Lane":
        self._graphed = None  # captured graphs read the parameters where they were before the move
        return super()._apply(fn, recurse)

    def _encode(self, images: Tensor) -> Tensor:
        """images (B, F, 3, H, W) -> stride-8 features (B, F, C, H / 8, W / 8), batched over frames."""
        B, F = images.shape[:2]
        return self.neck(self.backbone(images.flatten(0, 1)))[0].unflatten(0, (B, F))

    def _detect(
        self, features: Tensor, K: Tensor, T_lane_cam: Tensor, T_world_lane: Tensor, valid: Tensor,
        image_size: tuple[int, int],
    ) -> dict[str, Any]:  # fmt: skip
        """BDTR, BLFA and the heads over a window of F = N + 1 frames' features (B, F, C, h, w)."""
        F = features.shape[1]
        camera = (K, T_lane_cam, T_world_lane, valid, image_size)
        orders = {"forward": list(range(F)), "reverse": list(range(F - 1, -1, -1))}
        fused, detections, detection_valid = [], [], []
        chains = refine(self.refinement, self.anchors, [orders[name] for name in self.directions], features, *camera)
        for name, refined, aggregation in zip(self.directions, chains, self.aggregation):
            # The history as the direction visited it (views of its stack): forward oldest first, reverse newest first.
            lanes = refined.features  # (F, B, A, M, C)
            if name == "forward":
                current, history, history_valid = lanes[-1], lanes[:-1], valid[:, :-1]
            else:
                current, history, history_valid = lanes[0], lanes[1:], valid[:, :-1].flip(1)
            fused.append(_aggregate(aggregation, current, history, history_valid, oldest_first=name == "forward"))
            detections.append(refined.detections)
            detection_valid.append(refined.detection_valid)
        lanes = torch.cat(fused, dim=-1).flatten(-2)  # (B, A, M * D * C), eq. 11
        dx, dz = self.x_head(lanes).float(), self.z_head(lanes).float()
        visibility = self.vis_head(lanes).float().sigmoid()
        anchors = self.anchors.float()
        x, y, z = anchors.unbind(-1)
        points = torch.stack([x + dx, y.expand_as(dx), z + dz, visibility], -1)
        outputs = {
            "points": points[None],
            "logits": self.classifier(lanes)[None],
            "anchors": self.anchors,
            "detections": torch.cat(detections, 1),
            "detection_valid": torch.cat(detection_valid, 1),
        }
        if self.bev is not None and self.training:
            outputs["bev_logits"] = self.bev(features[:, -1], K[:, -1], T_lane_cam[:, -1], image_size)
            outputs["bev_x"], outputs["bev_y"] = self.bev.x, self.bev.y
        return outputs


def _aggregate(
    aggregation: BiLevelAggregation, current: Tensor, history: Tensor, history_valid: Tensor, oldest_first: bool
) -> Tensor:
    """BLFA of one direction: current (B, A, M, C), history (N, B, A, M, C) and history_valid
    (B, N) in one order of time (``oldest_first`` or newest first), as (B, A, M, N, C) for the
    point level; on a CPU in chunks of anchors (_CPU_AGGREGATION_CHUNK)."""
    A = current.shape[1]
    chunk = _CPU_AGGREGATION_CHUNK if current.device.type == "cpu" else A
    history = history.permute(1, 2, 3, 0, 4)
    parts = []
    for start in range(0, A, chunk):
        anchors = slice(start, start + chunk)
        parts.append(aggregation(current[:, anchors], history[:, anchors], history_valid, oldest_first))
    return parts[0] if len(parts) == 1 else torch.cat(parts, 1)
