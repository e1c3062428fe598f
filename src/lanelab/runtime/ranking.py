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

No shift settles every pick, so the export check replays the graph's picks: every top-k of a
detector's step goes through :func:`topk`; an exported step returns the picks it made
(:func:`recording_picks`), and the check runs the eager step with those picks
(:func:`forcing_picks`), which also measures how far each forced pick is from the eager step's
own choice. A graph that computes what ``step()`` computes then agrees with it to float rounding,
and a pick it made differently is shown to be a near-tie, not a mistake.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from contextlib import contextmanager

import torch
from torch import Tensor

# The picks of the topk calls made while recording_picks is active, in call order.
_recorded: list[Tensor] | None = None
# The picks topk takes instead of its own while forcing_picks is active, and how far each was from its own.
_forced: list[Tensor] | None = None
_deviations: list[float] = []


def topk(values: Tensor, k: int, *, largest: bool = False, margin: float = 0.0) -> tuple[Tensor, Tensor]:
    """(values at the picks, indices), both (..., k): the k smallest (``largest``: greatest) of
    values (..., C) along the last axis, best first; ranked with candidate c's value raised by
    margin · c (in float32 at least) when margin is not 0. Recorded or replaced while
    :func:`recording_picks` or :func:`forcing_picks` is active."""
    ranked = values
    if margin:
        ranked = values.to(torch.promote_types(values.dtype, torch.float32))
        ranked = ranked + margin * torch.arange(values.shape[-1], device=values.device, dtype=ranked.dtype)
    if _forced is not None:
        if not _forced:
            raise RuntimeError("the step made more picks than the ones it is given")
        index = _forced.pop(0).to(values.device)
        _deviations.append(deviation(ranked, index, largest))
        return values.gather(-1, index), index
    best, index = ranked.topk(k, dim=-1, largest=largest)
    if _recorded is not None:
        _recorded.append(index)
    return (values.gather(-1, index) if margin else best), index  # shifted values are not the values


def deviation(ranked: Tensor, index: Tensor, largest: bool = False) -> float:
    """How far picks index (..., k) are from the top-k of ranked (..., C): the largest gap
    between the values picked and the best ones, position by position, relative to 1 + |value|
    (0: the same choice up to ties); infinite where a pick is invalid (not finite) and the
    best is not, or the reverse."""
    if index.numel() == 0:
        return 0.0
    picked = ranked.gather(-1, index).double()
    best = ranked.topk(index.shape[-1], dim=-1, largest=largest).values.double()
    if not torch.equal(picked.isfinite(), best.isfinite()):
        return float("inf")
    gap = ((picked - best).abs() / (1 + best.abs())).nan_to_num(0.0)  # two infinite values: no difference
    return float(gap.max())


@contextmanager
def recording_picks() -> Iterator[list[Tensor]]:
    """Collect the indices of every :func:`topk` called inside, in call order."""
    global _recorded
    outer, _recorded = _recorded, []
    try:
        yield _recorded
    finally:
        _recorded = outer


@contextmanager
def forcing_picks(picks: Sequence[Tensor]) -> Iterator[list[float]]:
    """Inside, :func:`topk` takes these picks, in order, instead of its own; yields the
    :func:`deviation` of each. Raises when picks are left over at the end."""
    global _forced, _deviations
    outer = _forced, _deviations
    _forced, _deviations = list(picks), []
    try:
        yield _deviations
        if _forced:
            raise RuntimeError(f"the step made {len(picks) - len(_forced)} picks, {len(picks)} were given")
    finally:
        _forced, _deviations = outer
