"""Memory queue of past lane queries, SparseLaneSTP §3.3 (eq. 8-10), after StreamPETR.

After each frame the N_mem most confident lines (their M query embeddings and control points)
enter a FIFO that keeps the past T frames:
    Q_mem = [Q^(t-1)_:N_mem | ... | Q^(t-T)_:N_mem]     (eq. 8),   P_mem likewise (eq. 9).
Each slot keeps the ego pose of its frame, so ``read`` can propagate the stored control points
into any current frame (eq. 10):
    p^(t-k)->(t) = T_world_lane(t)^-1 · T_world_lane(t-k) · p^(t-k),   visibility unchanged.
Contents are detached (StreamPETR): no gradient flows into earlier frames. Streams are batched:
``reset(mask)`` empties the streams that start a new clip, without touching the others.

Token order of ``read``: frame slot (age 1 = the previous frame first), line, point, so tokens
[l·M, (l + 1)·M) are the M points of one stored line.

The queue's contents are four tensors (:class:`QueueState`): ``state`` hands them out and
``load`` puts them back, so a graph without Python objects (an exported model,
:class:`lanelab.deploy.explicit_state.ExplicitStateStep`) carries the memory as inputs and outputs.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, fields

import torch
from torch import Tensor

from lanelab.geometry import compose, invert, transform_points
from lanelab.runtime.ranking import topk


@dataclass
class MemoryState:
    """The memory as the current frame sees it; K = T · N_mem · M tokens, one per control point.

    embeddings (B, K, C); points (B, K, 4) = (x, y, z, v) propagated into the current lane
    frame; valid (B, K) bool (slots not filled since the last reset are invalid);
    age (B, K) long, frames back (1 = the previous frame).
    """

    embeddings: Tensor
    points: Tensor
    valid: Tensor
    age: Tensor

    def map(self, fn: Callable[[Tensor], Tensor]) -> MemoryState:
        """The state with fn applied to every tensor (e.g. selecting or repeating batch elements)."""
        return MemoryState(**{field.name: fn(getattr(self, field.name)) for field in fields(self)})


@dataclass
class QueueState:
    """What a memory queue holds, slot 0 the newest frame, T slots of N_mem lines of M points.

    embeddings (B, T, N_mem, M, C) the lines' query embeddings; points (B, T, N_mem, M, 4)
    control points (x, y, z, v), each slot in the lane frame of its own frame (propagated only
    when read); poses (B, T, 4, 4) T_world_lane of each slot's frame (the dtype of the poses
    pushed: float64 for world coordinates); valid (B, T) bool, the slots filled since the last
    reset. An empty queue is all zeros with identity poses and no valid slot.
    """

    embeddings: Tensor
    points: Tensor
    poses: Tensor
    valid: Tensor

    def tensors(self) -> tuple[Tensor, Tensor, Tensor, Tensor]:
        return self.embeddings, self.points, self.poses, self.valid


class MemoryQueue:
    """FIFO of the num_lines (N_mem) most confident lines of each of the past num_frames (T)
    frames. A plain object without parameters; its buffers are allocated at the first push."""

    State = QueueState

    def __init__(self, num_frames: int, num_lines: int) -> None:
        if num_frames < 0 or num_lines < 1:
            raise ValueError(f"need num_frames >= 0 and num_lines >= 1, got {num_frames}, {num_lines}")
        self.num_frames, self.num_lines = num_frames, num_lines
        # Per slot, newest first: (B, T, N_mem, M, C), (B, T, N_mem, M, 4), (B, T, 4, 4), (B, T).
        self._embeddings: Tensor | None = None
        self._points: Tensor | None = None
        self._poses: Tensor | None = None
        self._valid: Tensor | None = None

    def reset(self, mask: Tensor) -> None:
        """Empty the streams where mask (B,) bool is True (clip starts). Before the first push
        there is nothing to empty; a mask of another batch size must reset every stream."""
        if self._valid is None:
            return
        if mask.shape[0] != self._valid.shape[0]:
            if not bool(mask.all()):
                raise ValueError("a reset that changes the batch size must reset every stream")
            self._embeddings = self._points = self._poses = self._valid = None
            return
        self._valid = self._valid & ~mask.to(self._valid.device)[:, None]

    def push(self, embeddings: Tensor, control_points: Tensor, scores: Tensor, T_world_lane: Tensor) -> None:
        """Store the current frame's num_lines most confident lines as the newest slot.

        embeddings (B, N, M, C); control_points (B, N, M, 4) in the current lane frame;
        scores (B, N) confidence; T_world_lane (B, 4, 4) the current ego pose.
        """
        if self.num_frames == 0:
            return
        B, N = scores.shape
        if N < self.num_lines:
            raise ValueError(f"cannot keep {self.num_lines} lines of {N}")
        if self._valid is None:
            self._allocate(embeddings, control_points, T_world_lane)
        elif self._valid.shape[0] != B:
            raise ValueError("batch size changed without a reset of every stream")
        top = topk(scores.detach(), self.num_lines, largest=True)[1][:, :, None, None]  # (B, N_mem, 1, 1)
        embeddings = embeddings.detach().gather(1, top.expand(-1, -1, *embeddings.shape[2:]))
        control_points = control_points.detach().gather(1, top.expand(-1, -1, *control_points.shape[2:]))
        self._embeddings = _enqueue(self._embeddings, embeddings)
        self._points = _enqueue(self._points, control_points)
        self._poses = _enqueue(self._poses, T_world_lane.detach())
        self._valid = _enqueue(self._valid, torch.ones(B, dtype=torch.bool, device=scores.device))

    def read(self, T_world_lane: Tensor) -> MemoryState | None:
        """The memory propagated into the frame with ego pose T_world_lane (B, 4, 4) (eq. 10);
        None when there is nothing to read (T = 0 or nothing pushed yet)."""
        if self._valid is None:
            return None
        B, T, L, M, C = self._embeddings.shape
        # Relative motion in the poses' precision (float64 for world coordinates), then cast.
        T_now_past = compose(invert(T_world_lane.to(self._poses))[:, None], self._poses)  # (B, T, 4, 4)
        points = self._points.flatten(2, 3)  # (B, T, L·M, 4)
        xyz = transform_points(T_now_past, points[..., :3].to(T_now_past)).to(points)
        points = torch.cat([xyz, points[..., 3:]], dim=-1)
        age = torch.arange(1, T + 1, device=points.device)[None, :, None].expand(B, T, L * M)
        return MemoryState(
            embeddings=self._embeddings.reshape(B, T * L * M, C),
            points=points.reshape(B, T * L * M, 4),
            valid=self._valid[:, :, None].expand(B, T, L * M).reshape(B, -1),
            age=age.reshape(B, -1),
        )

    def state(self) -> QueueState | None:
        """The contents as tensors (not copies); None before the first push."""
        if self._valid is None:
            return None
        return QueueState(self._embeddings, self._points, self._poses, self._valid)

    def load(self, state: QueueState) -> None:
        """Take ``state`` (of T = num_frames slots of num_lines lines) as the contents."""
        if state.valid.shape[1] != self.num_frames or state.points.shape[2] != self.num_lines:
            raise ValueError(f"a state of {state.valid.shape[1]} frames of {state.points.shape[2]} lines does not fit "
                             f"a queue of {self.num_frames} frames of {self.num_lines} lines")
        self._embeddings, self._points, self._poses, self._valid = state.tensors()

    def empty_state(
        self,
        batch: int,
        num_points: int,
        embed_dim: int,
        dtypes: tuple[torch.dtype, torch.dtype, torch.dtype] = (torch.float32, torch.float32, torch.float64),
        device: torch.device | str | None = None,
    ) -> QueueState:
        """An empty queue's state for ``batch`` streams of lines of ``num_points`` points and
        ``embed_dim`` channels; dtypes of the embeddings, points and poses."""
        B, T, L, M, C = batch, self.num_frames, self.num_lines, num_points, embed_dim
        return QueueState(
            embeddings=torch.zeros(B, T, L, M, C, dtype=dtypes[0], device=device),
            points=torch.zeros(B, T, L, M, 4, dtype=dtypes[1], device=device),
            poses=torch.eye(4, dtype=dtypes[2], device=device).expand(B, T, 4, 4).clone(),
            valid=torch.zeros(B, T, dtype=torch.bool, device=device),
        )

    def _allocate(self, embeddings: Tensor, control_points: Tensor, T_world_lane: Tensor) -> None:
        B, _, M, C = embeddings.shape
        dtypes = embeddings.dtype, control_points.dtype, T_world_lane.dtype
        self.load(self.empty_state(B, M, C, dtypes, embeddings.device))


def _enqueue(queue: Tensor, newest: Tensor) -> Tensor:
    """queue (B, T, ...) with newest (B, ...) in front and the oldest slot dropped."""
    return torch.cat([newest.to(queue)[:, None], queue[:, :-1]], dim=1)
