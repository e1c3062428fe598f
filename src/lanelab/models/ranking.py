"""Top-k that picks the same candidates on every backend.

PNA's neighbour search takes the k nearest of candidates that are often tied: on straight
parallel lines the control points before and after a query lie exactly as far from its normal
plane. Eager torch, torch.export and onnxruntime round the values differently (~1e-6), so which
of two tied candidates wins differs between them, and an exported model drifts from the module
it was exported from. Shifting every candidate's value by ``margin`` times its position settles
a tie for the earlier candidate by a margin far above that rounding noise and far below any
difference that matters. Rounding the values instead would not do: values near a rounding step
flip as easily. No shift removes every flip (the tie only moves to where two candidates differ
by the shift), so it is used where values rarely differ by that much. On SparseLaneSTP
(benchmarks/RESULTS.md, "Exported streaming SparseLaneSTP") it helps PNA in exported graphs;
shifting TCA's distances too made a young model's export flip, and the memory's scores gained
nothing. Training keeps the plain nearest: the demo's SparseLaneSTP trained with the shift
scored 40.8 % on its held-out drives against 45.9 % (one seed).
"""

from __future__ import annotations

import torch
from torch import Tensor


def stable_topk(values: Tensor, k: int, *, margin: float) -> Tensor:
    """Indices (..., k) of the k smallest values (..., C) along the last axis, smallest first,
    with candidate c's value raised by margin · c (in float32 at least)."""
    values = values.to(torch.promote_types(values.dtype, torch.float32))
    position = torch.arange(values.shape[-1], device=values.device, dtype=values.dtype)
    return (values + margin * position).topk(k, dim=-1, largest=False).indices
