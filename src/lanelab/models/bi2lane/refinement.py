"""Bi-directional temporal refinement (BDTR, Bi²Lane §III-A.2 and §III-B, eq. 2-6), one direction
per :class:`TemporalRefinement`.

Starting from the anchors in the first frame it visits, each step samples the lane feature of
the current anchors in that frame (eq. 1, 4), predicts their offsets S (eq. 2), and carries the
refined anchors A + S into the next frame it visits (eq. 3):
    A_next = T_{this -> next}(A + S),
the temporal alignment of Table VII (``alignment=False``: T is the identity, the detected lane is
carried in ego coordinates). The forward direction visits t-N, ..., t (eq. 5), the reverse one
t, t-1, ..., t-N (eq. 6); each yields its lane-feature set, one (B, A, M, C) per frame, stacked in
visiting order.

The paper leaves open where the chains start and how padded frames are treated. Both start from
the configured anchors in the first frame they visit (the reverse one: the current frame's
anchors, so that the two directions are independent, as the ablations of Table V need). A
padded frame before a clip's start (``valid`` False) refines nothing: the anchors pass through
it unchanged, so a window that starts at a clip's first frame is refined as if it started there.
Each step's refined anchors A + S are also returned, moved into the current frame with the true
ego motion whatever ``alignment`` says: they are the lanes that frame detected, which the
criterion supervises, as Anchor3DLane supervises every stage of its iterative regression.

The two directions are independent chains of equal length, so :func:`refine` runs them in
lockstep as one batch (each with its own offset head). At batch 1 on a GPU a history frame costs
its chain step's kernel launches more than their arithmetic, so everything a step needs that
does not depend on the refined anchors is prepared once for all steps: a step is fifteen kernels.
Without autograd (streaming) each step's lanes are written straight into the stack whose views BLFA
reads as the history, so that BLFA does not stack the history again.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, NamedTuple

import torch
from torch import Tensor, nn

from lanelab.models.bi2lane.anchors import ego_motion, grid_projection, move_points, project_to_grid, sample_features
from lanelab.models.parts.heads import mlp


class Refined(NamedTuple):
    """One direction's result over the frames it visited, in visiting order.

    features: (S + 1, B, A, M, C) the lane feature of each visited frame (eq. 1, 4);
    anchors: [(B, A, M, 3)] the anchors it was sampled at, in that frame's lane frame;
    detections: (B, S, A, M, 3) the refined anchors A + S of every step but the last, moved into
    the current frame (S = visited frames - 1); detection_valid: (B, S) bool, the step's frame
    was real (not padding)."""

    features: Tensor
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
    directions cost the kernel launches of one. What does not depend on the refined anchors
    (the visited frames, their projections, the ego motions, the offset heads' weights) is
    prepared for all steps at once (module doc).

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

    def visiting(tensor: Tensor) -> Tensor:
        """(S, D·B, ...): at each step, the frames the directions visit, in one stack of slices (an
        index list would be a host-to-device copy, which CUDA graphs refuse)."""
        stacked = torch.stack([tensor[:, order[step]] for step in range(S) for order in orders])
        return stacked.unflatten(0, (S, D)).flatten(1, 2)

    # Metres in at least float32: bf16 steps are half a metre at 100 m.
    points = anchors.to(torch.promote_types(features.dtype, torch.float32)).expand(D * B, *anchors.shape)
    frames, projections = visiting(features), grid_projection(visiting(K), visiting(T_lane_cam), image_size)
    lanes, stack, sampled_at, refined_anchors = [], None, [], []
    if S > 1:  # the offset heads, the frames' validity and the ego motions into the next visited frames
        offsets = offset_heads([direction.offsets for direction in directions], features.dtype)
        visited_valid = visiting(valid)
        visited = visiting(T_world_lane)  # (S, D·B, 4, 4)
        rotation, translation = rigid_motion(ego_motion(visited[1:], visited[:-1]), points.dtype)  # into the next
    for step in range(S):
        lane = sample_features(frames[step], project_to_grid(points, projections[step]))  # (D·B, A, M, C)
        if step == 0 and not torch.is_grad_enabled():
            stack = lane.new_empty(S, *lane.shape)
        # Laid out (A, M, C) once, as the offset head reads it flattened and BLFA by rows, not as grid_sample's
        # (C, A, M). With autograd the lanes are stacked after the chain: writing into the stack in place would
        # change what the offset head saved of the earlier steps for its backward pass.
        lane = lane.contiguous() if stack is None else stack[step].copy_(lane)
        lanes.append(lane)
        sampled_at.append(points)
        if step == S - 1:
            break
        shifts = offsets(lane.reshape(D, -1, lane.shape[-2] * lane.shape[-1]))  # (D, B·A, M·3)
        refined = points + shifts.view(points.shape)  # eq. 2
        refined_anchors.append(refined)
        if directions[0].alignment:  # eq. 3
            refined = torch.baddbmm(translation[step], refined.flatten(1, 2), rotation[step]).view(points.shape)
        points = torch.where(visited_valid[step, :, None, None, None], refined, points)
    if refined_anchors:  # the detections: each step's refined anchors, moved into the current frame
        steps = torch.stack(refined_anchors, 1)  # (D·B, S - 1, A, M, 3)
        into_current = ego_motion(T_world_lane[:, current, None], visited[:-1].transpose(0, 1).unflatten(0, (D, B)))
        found = move_points(into_current.flatten(0, 1), steps).unflatten(0, (D, B))
        found_valid = visited_valid[:-1].T.unflatten(0, (D, B))
    else:
        found = points.new_zeros(D, B, 0, *points.shape[1:])
        found_valid = valid.new_zeros(D, B, 0)
    features = torch.stack(lanes) if stack is None else stack  # (S, D·B, A, M, C)
    results = []
    for d in range(D):
        mine = slice(d * B, (d + 1) * B)
        results.append(Refined(features[:, mine], [t[mine] for t in sampled_at], found[d], found_valid[d]))
    return results


def offset_heads(mlps: Sequence[nn.Sequential], dtype: torch.dtype) -> Callable[[Tensor], Tensor]:
    """The offset heads O (eq. 2) of D directions as one function: lane features x (D, N, M·C),
    slice d through mlps[d], -> offsets (D, N, M·3) = (Δx, 0, Δz) per point. Each layer is one
    batched matrix product for all D, with the weights stacked (and cast to dtype) once per call.
    The last layer's rows are interleaved with zero rows for y, so that a step adds its offsets
    to the points (M, 3) in one kernel."""
    layers: list[Callable[[Tensor], Tensor]] = []
    for index, group in enumerate(zip(*mlps)):
        if not isinstance(group[0], nn.Linear):
            layers.append(group[0])
            continue
        weight = torch.stack([layer.weight for layer in group])  # (D, out, in)
        bias = torch.stack([layer.bias for layer in group])  # (D, out)
        if index == len(mlps[0]) - 1:  # (Δx.., Δz..) -> (Δx, 0, Δz) per point
            weight = _with_zero_y(weight.unflatten(1, (2, -1))).flatten(1, 2)
            bias = _with_zero_y(bias.unflatten(1, (2, -1))).flatten(1, 2)
        weight, bias = weight.transpose(1, 2).to(dtype), bias[:, None].to(dtype)
        layers.append(lambda x, w=weight, b=bias: torch.baddbmm(b, x, w))

    def run(x: Tensor) -> Tensor:
        for layer in layers:
            x = layer(x)
        return x

    return run


def _with_zero_y(xz: Tensor) -> Tensor:
    """(D, 2, M, ...) rows of Δx then Δz -> (D, M, 3, ...) rows (Δx, 0, Δz) per point."""
    dx, dz = xz.unbind(1)
    return torch.stack([dx, torch.zeros_like(dx), dz], 2)


def rigid_motion(T: Tensor, dtype: torch.dtype) -> tuple[Tensor, Tensor]:
    """Rigid transforms T (..., 4, 4) as (R^T (..., 3, 3), t (..., 1, 3)) in dtype: points (N, 3)
    move to ``torch.baddbmm(t, points, R^T)``, one kernel."""
    return T[..., :3, :3].transpose(-1, -2).to(dtype).contiguous(), T[..., None, :3, 3].to(dtype)
