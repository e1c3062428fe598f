"""Bi²Lane's streaming state: the past frames' front-view features and cameras, so that a new
frame costs one backbone pass however many history frames the model reads.

Each ``push`` of a frame returns the window the windowed model would read: the N cached
frames, oldest first, then the new one. A stream that starts (a reset, or the first push) has
no past: its window repeats the new frame, marked invalid, as the window dataset pads a clip's
start (:mod:`lanelab.data.dataset`), so streaming computes what the windowed model computes.
Cached features are detached (StreamPETR's rule): no gradient reaches an earlier step.
The contents are a :class:`FrameState` (``state`` / ``load``): an exported graph carries them
as tensors (lanelab.deploy.explicit_state).
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import Tensor


@dataclass
class FrameState:
    """What a frame cache holds: the last N frames of B streams, oldest first.

    features (B, N, C, h, w) their front-view features; K (B, N, 3, 3), T_lane_cam (B, N, 4, 4)
    their cameras; T_world_lane (B, N, 4, 4) their ego poses (float64: world coordinates);
    valid (B, N) bool, the frames that are real (not the padding of a stream's start). An
    empty cache is zero features, identity cameras and poses, no valid frame.
    """

    features: Tensor
    K: Tensor
    T_lane_cam: Tensor
    T_world_lane: Tensor
    valid: Tensor

    def tensors(self) -> tuple[Tensor, Tensor, Tensor, Tensor, Tensor]:
        return self.features, self.K, self.T_lane_cam, self.T_world_lane, self.valid


class FrameCache:
    """The last num_frames (N + 1, the current frame included) frames of B streams; a plain
    object without parameters, filled at the first push (or ``load``)."""

    State = FrameState

    def __init__(self, num_frames: int) -> None:
        if num_frames < 1:
            raise ValueError(f"a frame cache holds at least the current frame, got num_frames={num_frames}")
        self.num_frames = num_frames
        self._past: FrameState | None = None  # the last num_frames - 1 frames
        self._fresh: Tensor | None = None  # (B,) bool: the stream starts at its next push

    def reset(self, mask: Tensor) -> None:
        """Forget the past of the streams where mask (B,) bool is True. A mask of another batch
        size must reset every stream (a new set of streams)."""
        if self._fresh is None:
            return
        if mask.shape[0] != self._fresh.shape[0]:
            if not bool(mask.all()):
                raise ValueError("a reset that changes the batch size must reset every stream")
            self._past = self._fresh = None
            return
        self._fresh = self._fresh | mask.to(self._fresh.device)

    def push(self, features: Tensor, K: Tensor, T_lane_cam: Tensor, T_world_lane: Tensor) -> dict[str, Tensor]:
        """Add the new frame of every stream: features (B, C, h, w), K (B, 3, 3), T_lane_cam and
        T_world_lane (B, 4, 4). Returns the window: "features" (B, F, C, h, w), K, T_lane_cam,
        T_world_lane (B, F, ...) and "valid" (B, F) bool, the new frame last (with its gradient)."""
        new = {"features": features, "K": K, "T_lane_cam": T_lane_cam, "T_world_lane": T_world_lane}
        B, F = features.shape[0], self.num_frames
        if self._past is None:
            self._fresh = torch.ones(B, dtype=torch.bool, device=features.device)
        elif self._fresh.shape[0] != B:
            raise ValueError("the batch size changed without a reset of every stream")
        started = torch.arange(F, device=features.device) == F - 1  # a fresh window: only the new frame is real
        window = {}
        for key, value in new.items():
            repeated = value[:, None].expand(B, F, *value.shape[1:])
            if self._past is None:
                window[key] = repeated
                continue
            shifted = torch.cat([getattr(self._past, key).to(value), value[:, None]], dim=1)
            fresh = self._fresh.view(B, *[1] * (shifted.dim() - 1))
            window[key] = torch.where(fresh, repeated, shifted)
        continued = torch.ones(B, F, dtype=torch.bool, device=features.device)
        if self._past is not None:
            continued = torch.cat([self._past.valid, continued[:, :1]], dim=1)
        fresh = self._fresh[:, None]  # a choice between flags written as logic: ONNX runtimes lack a bool Where
        window["valid"] = (fresh & started) | (~fresh & continued)
        self._past = FrameState(**{key: value[:, 1:].detach() for key, value in window.items()})
        self._fresh = torch.zeros_like(self._fresh)
        return window

    def state(self) -> FrameState | None:
        """The contents as tensors (not copies); None before the first push."""
        return self._past

    def load(self, state: FrameState) -> None:
        """Take ``state`` (of num_frames - 1 frames) as the contents; no stream starts afresh."""
        if state.valid.shape[1] != self.num_frames - 1:
            raise ValueError(f"a state of {state.valid.shape[1]} frames does not fit a cache of "
                             f"{self.num_frames - 1} past frames")  # fmt: skip
        self._past = state
        self._fresh = torch.zeros(state.valid.shape[0], dtype=torch.bool, device=state.valid.device)

    def empty_state(
        self, batch: int, feature_shape: tuple[int, int, int], device: torch.device | str | None = None
    ) -> FrameState:
        """An empty cache's state for ``batch`` streams of features of feature_shape (C, h, w)."""
        B, N = batch, self.num_frames - 1

        def identity(size: int, dtype: torch.dtype = torch.float32) -> Tensor:
            return torch.eye(size, dtype=dtype, device=device).expand(B, N, size, size).clone()

        return FrameState(
            features=torch.zeros(B, N, *feature_shape, device=device),
            K=identity(3),
            T_lane_cam=identity(4),
            T_world_lane=identity(4, torch.float64),
            valid=torch.zeros(B, N, dtype=torch.bool, device=device),
        )
