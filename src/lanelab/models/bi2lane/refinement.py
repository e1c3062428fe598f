"""Bi-directional temporal refinement (BDTR, Bi²Lane §III-A.2 and §III-B, eq. 2-6), one direction
per :class:`TemporalRefinement`.

Starting from the anchors in the first frame it visits, each step samples the lane feature of
the current anchors in that frame (eq. 1, 4), predicts their offsets S (eq. 2), and carries the
refined anchors A + S into the next frame it visits (eq. 3):
    A_next = T_{this -> next}(A + S),
the temporal alignment of Table VII (``alignment=False``: T is the identity, the detected lane is
carried in ego coordinates). The forward direction visits t-N, ..., t (eq. 5), the reverse one
t, t-1, ..., t-N (eq. 6); each yields its lane-feature set, one (B, A, M, C) per frame.

The paper leaves open where the chains start and how padded frames are treated. Both start from
the configured anchors in the first frame they visit (the reverse one: the current frame's
anchors, so that the two directions are independent, as the ablations of Table V need). A
padded frame before a clip's start (``valid`` False) refines nothing: the anchors pass through
it unchanged, so a window that starts at a clip's first frame is refined as if it started there.
Each step's refined anchors A + S are also returned, moved into the current frame with the true
ego motion whatever ``alignment`` says: they are the lanes that frame detected, which the
criterion supervises, as Anchor3DLane supervises every stage of its iterative regression.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import torch
from torch import Tensor, nn

from lanelab.models.bi2lane.anchors import ego_motion, move_points, sample_features, sampling_grid
from lanelab.models.heads import mlp


class Refined(NamedTuple):
    """One direction's result over the frames it visited, in visiting order.

    features: [(B, A, M, C)] the lane feature of each visited frame (eq. 1, 4);
    anchors: [(B, A, M, 3)] the anchors it was sampled at, in that frame's lane frame;
    detections: (B, S, A, M, 3) the refined anchors A + S of every step but the last, moved into
    the current frame (S = visited frames - 1); detection_valid: (B, S) bool, the step's frame
    was real (not padding)."""

    features: list[Tensor]
    anchors: list[Tensor]
    detections: Tensor
    detection_valid: Tensor


class TemporalRefinement(nn.Module):
    """One direction of BDTR. embed_dim C of the sampled features; num_points M; hidden_dim and
    num_hidden: the offset head O's MLP over the M x C lane feature (Anchor3DLane's regression
    branch layout); alignment: move anchors with the ego motion between frames (Table VII);
    steps: whether any frame is visited before the current one (False for the single-frame
    baseline, which then has no offset head: a parameter it never uses would stall DDP)."""

    def __init__(
        self, embed_dim: int, num_points: int, hidden_dim: int, num_hidden: int, alignment: bool, steps: bool = True
    ) -> None:
        super().__init__()
        self.offsets = mlp(num_points * embed_dim, hidden_dim, 2 * num_points, num_hidden) if steps else None
        if self.offsets is not None:  # offsets start at zero: before training the anchors pass frames unchanged
            nn.init.zeros_(self.offsets[-1].weight)
            nn.init.zeros_(self.offsets[-1].bias)
        self.alignment = alignment

    def forward(
        self,
        anchors: Tensor,
        order: Sequence[int],
        features: Tensor,
        K: Tensor,
        T_lane_cam: Tensor,
        T_world_lane: Tensor,
        valid: Tensor,
        image_size: tuple[int, int],
    ) -> Refined:
        """anchors (A, M, 3) in the first visited frame; order: the frame indices visited;
        features (B, F, C, h, w) of every frame; K (B, F, 3, 3), T_lane_cam, T_world_lane
        (B, F, 4, 4), valid (B, F) bool; the current frame is the last (F - 1)."""
        B = features.shape[0]
        current = features.shape[1] - 1
        # Metres in at least float32: bf16 steps are half a metre at 100 m.
        points = anchors.to(torch.promote_types(features.dtype, torch.float32)).expand(B, *anchors.shape)
        lanes, sampled_at, detections, detection_valid = [], [], [], []
        if len(order) > 1 and self.offsets is None:
            raise ValueError("this refinement was built without steps: it visits the current frame only")
        # The ego motions the steps need, in one batch each: into the current frame (B, F, 4, 4)
        # and on into the frame visited next (B, S, 4, 4); none when only the current frame is visited.
        steps = len(order) > 1
        into_current = ego_motion(T_world_lane[:, current, None], T_world_lane) if steps else None
        into_next = None
        if steps:  # the visited poses by slicing: an index list would be a host-to-device copy, which CUDA graphs refuse
            visited = torch.stack([T_world_lane[:, f] for f in order], 1)
            into_next = ego_motion(visited[:, 1:], visited[:, :-1])
        for step, frame in enumerate(order):
            grid = sampling_grid(points, K[:, frame], T_lane_cam[:, frame], image_size)
            lane = sample_features(features[:, frame], grid)  # (B, A, M, C)
            lanes.append(lane)
            sampled_at.append(points)
            if step == len(order) - 1:
                break
            dx, dz = self.offsets(lane.flatten(-2)).unflatten(-1, (2, -1)).unbind(-2)  # (B, A, M) each, eq. 2
            refined = points + torch.stack([dx, torch.zeros_like(dx), dz], dim=-1)
            detections.append(move_points(into_current[:, frame], refined))
            detection_valid.append(valid[:, frame])
            if self.alignment:  # eq. 3
                refined = move_points(into_next[:, step], refined)
            points = torch.where(valid[:, frame, None, None, None], refined, points)
        if not detections:
            return Refined(lanes, sampled_at, points.new_zeros(B, 0, *points.shape[1:]), valid.new_zeros(B, 0))
        return Refined(lanes, sampled_at, torch.stack(detections, 1), torch.stack(detection_valid, 1))
