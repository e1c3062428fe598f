"""Bi²Lane's streaming state: the past frames' front-view features and cameras, so that a new
frame costs one backbone pass however many history frames the model reads.

Each ``push`` of a frame returns the window the windowed model would read: the N cached
frames, oldest first, then the new one. A stream that starts (a reset, or the first push) has
no past: its window repeats the new frame, marked invalid, as the window dataset pads a clip's
start (:mod:`lanelab.data.dataset`), so streaming computes what the windowed model computes.
Cached features are detached (StreamPETR's rule): no gradient reaches an earlier step.
"""

from __future__ import annotations

import torch
from torch import Tensor

# What a window holds per frame besides the features: (B, F, ...) each.
CAMERA_KEYS = ("K", "T_lane_cam", "T_world_lane")


class FrameCache:
    """The last num_frames (N + 1, the current frame included) frames of B streams; a plain
    object without parameters, allocated at the first push."""

    def __init__(self, num_frames: int) -> None:
        if num_frames < 1:
            raise ValueError(f"a frame cache holds at least the current frame, got num_frames={num_frames}")
        self.num_frames = num_frames
        self._window: dict[str, Tensor] | None = None  # features, K, ..., valid: (B, F, ...)
        self._fresh: Tensor | None = None  # (B,) bool: the stream starts at its next push

    def reset(self, mask: Tensor) -> None:
        """Forget the past of the streams where mask (B,) bool is True. A mask of another batch
        size must reset every stream (a new set of streams)."""
        if self._fresh is None:
            return
        if mask.shape[0] != self._fresh.shape[0]:
            if not bool(mask.all()):
                raise ValueError("a reset that changes the batch size must reset every stream")
            self._window = self._fresh = None
            return
        self._fresh = self._fresh | mask.to(self._fresh.device)

    def push(self, features: Tensor, K: Tensor, T_lane_cam: Tensor, T_world_lane: Tensor) -> dict[str, Tensor]:
        """Add the new frame of every stream: features (B, C, h, w), K (B, 3, 3), T_lane_cam and
        T_world_lane (B, 4, 4). Returns the window: "features" (B, F, C, h, w), K, T_lane_cam,
        T_world_lane (B, F, ...) and "valid" (B, F) bool, the new frame last (with its gradient)."""
        new = {"features": features, "K": K, "T_lane_cam": T_lane_cam, "T_world_lane": T_world_lane}
        B, F = features.shape[0], self.num_frames
        if self._window is None:
            self._fresh = torch.ones(B, dtype=torch.bool, device=features.device)
        elif self._fresh.shape[0] != B:
            raise ValueError("the batch size changed without a reset of every stream")
        started = torch.arange(F, device=features.device) == F - 1  # a fresh window: only the new frame is real
        window = {}
        for key, value in new.items():
            repeated = value[:, None].expand(B, F, *value.shape[1:])
            if self._window is None:
                window[key] = repeated
                continue
            shifted = torch.cat([self._window[key][:, 1:].to(value), value[:, None]], dim=1)
            fresh = self._fresh.view(B, *[1] * (shifted.dim() - 1))
            window[key] = torch.where(fresh, repeated, shifted)
        continued = torch.ones(B, F, dtype=torch.bool, device=features.device)
        if self._window is not None:
            continued = torch.cat([self._window["valid"][:, 1:], continued[:, :1]], dim=1)
        window["valid"] = torch.where(self._fresh[:, None], started.expand(B, F), continued)
        self._window = {key: value.detach() for key, value in window.items()}
        self._fresh = torch.zeros_like(self._fresh)
        return window
