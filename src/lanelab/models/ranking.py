"""The k smallest or largest values along the last axis, equal values ordered by index.

``torch.topk`` leaves the order of equal values to the kernel: it differs between devices and
from ONNX's TopK. Equal values are common where the model picks keys by distance (parallel
straight lines are exactly as far from a query on both sides), so the choice is pinned down:
the values, in float64, get a tie-breaker far below float32's resolution that grows with the
index (lower index first), and no two keys are equal. Eager code on any device, torch.export
and ONNX runtimes then pick the same elements. (A stable sort would do the same, but ONNX has
none.)
"""

from __future__ import annotations

import torch
from torch import Tensor

TIE_BREAK = 1e-10  # per index step; < 1e-7 over 1000 elements, far below a float32 step of the values


def _keys(values: Tensor, sign: float) -> Tensor:
    index = torch.arange(values.shape[-1], dtype=torch.float64, device=values.device)
    return values.double() + sign * TIE_BREAK * index


def smallest(values: Tensor, k: int) -> tuple[Tensor, Tensor]:
    """The k smallest of ``values`` (..., n) and their indices (..., k), ascending; of equal
    values the lower index first."""
    index = _keys(values, 1.0).topk(k, dim=-1, largest=False).indices
    return values.gather(-1, index), index


def largest(values: Tensor, k: int) -> tuple[Tensor, Tensor]:
    """The k largest of ``values`` (..., n) and their indices (..., k), descending; of equal
    values the lower index first."""
    index = _keys(values, -1.0).topk(k, dim=-1, largest=True).indices
    return values.gather(-1, index), index
