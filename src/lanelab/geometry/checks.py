"""Value checks on tensors that step aside while torch traces a graph.

``torch.export`` and ``torch.compile`` cannot branch on a tensor's values; an exported model
(lanelab-export) runs the same code as the eager one, so a check of values holds for eager
calls and is skipped while tracing (the traced graph has fixed, already checked constants).
"""

from __future__ import annotations

import torch
from torch import Tensor


def holds(condition: Tensor) -> bool:
    """``bool(condition.all())``; True while a graph is being traced (export, compile)."""
    return torch.compiler.is_compiling() or bool(condition.all())
