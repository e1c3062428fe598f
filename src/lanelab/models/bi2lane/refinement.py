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

The two directions are independent chains of equal length, so :func:`refine` runs them in
lockstep as one batch (each with its own offset head): at batch 1 a chain step is a few dozen
small kernels, and the history frames cost launches rather than arithmetic.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, NamedTuple

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

    def forward(self, anchors: Tensor, order: Sequence[int], *window: Any) -> Refined:
        """This direction alone: anchors (A, M, 3) in the first visited frame; order: the frame
        indices visited; window: features, K, T_lane_cam, T_world_lane, valid, image_size, as
        :func:`refine` takes them."""
        return refine([self], anchors, [order], *window)[0]


def refine(
    directions: Sequence[TemporalRefinement],
    anchors: Tensor,
    orders: Sequence[Sequence[int]],
    features: Tensor,
    K: Tensor,
    T_lane_cam: Tensor,
    T_world_lane: Tensor,
    valid: Tensor,
    image_size: tuple[int, int],
) -> list[Refined]:
    """The chains of D directions run in lockstep, each with its own offset head, as one batch
    of D x B streams: step s of every chain is one sampling and one (grouped) head call, so two
    directions cost the kernel launches of one.

    anchors (A, M, 3) in the first frame each direction visits; orders: each direction's visited
    frame indices, all of one length; features (B, F, C, h, w) of every frame; K (B, F, 3, 3),
    T_lane_cam, T_world_lane (B, F, 4, 4), valid (B, F) bool; the current frame is the last
    (F - 1). One :class:`Refined` per direction, in the order given."""
    D, S = len(directions), len(orders[0])
    if any(len(order) != S for order in orders):
        raise ValueError(f"directions run in lockstep over windows of one length, got orders {orders}")
    if S > 1 and any(direction.offsets is None for direction in directions):
        raise ValueError("this refinement was built without steps: it visits the current frame only")
    if len({direction.alignment for direction in directions}) > 1:
        raise ValueError("directions run in lockstep with one temporal alignment setting")
    B, current = features.shape[0], features.shape[1] - 1

    def at(tensor: Tensor, step: int) -> Tensor:
        """(D·B, ...) of the frames the directions visit at this step, by slicing: an index list
        would be a host-to-device copy, which CUDA graphs refuse."""
        return torch.cat([tensor[:, order[step]] for order in orders])

    # Metres in at least float32: bf16 steps are half a metre at 100 m.
    points = anchors.to(torch.promote_types(features.dtype, torch.float32)).expand(D * B, *anchors.shape)
    lanes, sampled_at, detections, detection_valid = [], [], [], []
    if S > 1:  # the ego motions the steps need, in one batch: into the current frame and into the next visited one
        visited = torch.stack([at(T_world_lane, step) for step in range(S)], 1)  # (D·B, S, 4, 4)
        into_current = ego_motion(T_world_lane[:, current, None].repeat(D, 1, 1, 1), visited)
        into_next = ego_motion(visited[:, 1:], visited[:, :-1])
        offsets = grouped_mlp([direction.offsets for direction in directions])
    for step in range(S):
        grid = sampling_grid(points, at(K, step), at(T_lane_cam, step), image_size)
        lane = sample_features(at(features, step), grid)  # (D·B, A, M, C)
        lanes.append(lane)
        sampled_at.append(points)
        if step == S - 1:
            break
        shifts = offsets(lane.flatten(-2).reshape(D, -1, lane.shape[-2] * lane.shape[-1]))  # (D, B·A, 2M)
        dx, dz = shifts.reshape(*lane.shape[:2], 2, -1).unbind(-2)  # (D·B, A, M) each
        refined = points + torch.stack([dx, torch.zeros_like(dx), dz], dim=-1)  # eq. 2
        detections.append(move_points(into_current[:, step], refined))
        step_valid = at(valid, step)
        detection_valid.append(step_valid)
        if directions[0].alignment:  # eq. 3
            refined = move_points(into_next[:, step], refined)
        points = torch.where(step_valid[:, None, None, None], refined, points)
    results = []
    for d in range(D):
        mine = slice(d * B, (d + 1) * B)
        if detections:
            found = torch.stack([t[mine] for t in detections], 1)
            found_valid = torch.stack([t[mine] for t in detection_valid], 1)
        else:
            found, found_valid = points.new_zeros(B, 0, *points.shape[1:]), valid.new_zeros(B, 0)
        results.append(Refined([t[mine] for t in lanes], [t[mine] for t in sampled_at], found, found_valid))
    return results


def grouped_mlp(mlps: Sequence[nn.Sequential]) -> Callable[[Tensor], Tensor]:
    """x (D, N, in) -> (D, N, out), slice d through mlps[d] (Linear and activation layers, all
    of one layout), as batched matrix products: one kernel a layer for all D."""
    if len(mlps) == 1:
        return lambda x: mlps[0](x)
    layers = []
    for group in zip(*mlps):
        if isinstance(group[0], nn.Linear):
            weight = torch.stack([layer.weight for layer in group]).transpose(1, 2)  # (D, in, out)
            bias = torch.stack([layer.bias for layer in group])[:, None]  # (D, 1, out)
            layers.append(lambda x, w=weight, b=bias: torch.baddbmm(b.to(x.dtype), x, w.to(x.dtype)))
        else:
            layers.append(group[0])

    def run(x: Tensor) -> Tensor:
        for layer in layers:
            x = layer(x)
        return x

    return run
