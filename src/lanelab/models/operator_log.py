"""The ATen operators a call dispatches, recorded below autograd: what a GPU would launch.

At batch 1 a streaming frame's kernels are small and their launches, not their arithmetic, are
much of what it costs on a GPU (:mod:`lanelab.models.cuda_graph`); counting them needs no GPU.
A CUDA graph also refuses operators that move data between host and device, which the log shows.
"""

from __future__ import annotations

from typing import Any

import torch
from torch.utils._python_dispatch import TorchDispatchMode

# Operators that return a tensor not declared a view, but launch no kernel.
_NO_KERNEL = {torch.ops.aten._unsafe_view.default, torch.ops.aten.empty.memory_format, torch.ops.aten.empty_strided.default}
# Operators that make a tensor from host data or read one back to the host.
HOST_TRANSFERS = {torch.ops.aten.lift_fresh.default, torch.ops.aten._local_scalar_dense.default}


class OperatorLog(TorchDispatchMode):
    """``with OperatorLog() as log: fn()`` records fn's operators, in order, in ``log.operators``."""

    def __init__(self) -> None:
        super().__init__()
        self.operators: list[torch._ops.OpOverload] = []

    def __torch_dispatch__(self, func: Any, types: Any, args: Any = (), kwargs: Any = None) -> Any:
        self.operators.append(func)
        return func(*args, **(kwargs or {}))

    def kernels(self) -> int:
        """How many of the operators compute a tensor (a kernel launch each on a GPU): not views,
        and in-place ones included (their aliased output is written)."""
        return sum(_computes(op) for op in self.operators)

    def host_transfers(self) -> list[str]:
        """The operators that move data between host and device (which CUDA graphs refuse)."""
        return [str(op) for op in self.operators if op in HOST_TRANSFERS]


def _computes(op: torch._ops.OpOverload) -> bool:
    returns = op._schema.returns
    tensors = any(isinstance(ret.type, (torch.TensorType, torch.ListType)) for ret in returns)  # not a dtype, a bool
    view = any(ret.alias_info is not None and not ret.alias_info.is_write for ret in returns)
    return tensors and not view and op not in _NO_KERNEL
