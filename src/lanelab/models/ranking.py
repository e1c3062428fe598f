"""The k smallest or largest values along the last axis, compared at a resolution, equal ones
taken lower index first.

The model picks keys by distance (the PNA and TCA neighbours of a query) and memory lines by
score. Such choices are discontinuous: where two candidates are (nearly) equally good, float
noise decides, and float noise differs between kernels, devices and runtimes (about 1e-6 between
eager torch, torch.export and onnxruntime). Parallel straight lines are exactly as far from a
query on both sides, so near-ties are common, and a flipped choice changes a line by
centimetres. So values are compared at a ``resolution`` (a millimetre for distances): values
in the same step are equal, and of equal values the lower index comes first (``torch.topk``
leaves their order to the kernel; ONNX's TopK puts the lower index first). A choice between
candidates closer than the resolution is arbitrary anyway; this way every runtime makes it the
same, and the outputs of an exported graph match eager code's.
"""

from __future__ import annotations

import torch
from torch import Tensor


def _keys(values: Tensor, resolution: float, sign: float) -> Tensor:
    """Float64 keys: the values in whole steps of ``resolution``, plus ``sign`` x index / n, which
    orders equal steps by index and never reorders different ones."""
    n = values.shape[-1]
    index = torch.arange(n, dtype=torch.float64, device=values.device) / n
    return torch.round(values.double() / resolution) + sign * index


def smallest(values: Tensor, k: int, resolution: float) -> tuple[Tensor, Tensor]:
    """The k smallest of ``values`` (..., n) at ``resolution`` and their indices (..., k),
    ascending; of values in the same step the lower index first."""
    index = _keys(values, resolution, 1.0).topk(k, dim=-1, largest=False).indices
    return values.gather(-1, index), index


def largest(values: Tensor, k: int, resolution: float) -> tuple[Tensor, Tensor]:
    """The k largest of ``values`` (..., n) at ``resolution`` and their indices (..., k),
    descending; of values in the same step the lower index first."""
    index = _keys(values, resolution, -1.0).topk(k, dim=-1, largest=True).indices
    return values.gather(-1, index), index
