"""The ATen operators a call dispatches, recorded below autograd: what a GPU would launch.

At batch 1 a streaming frame's kernels are small and their launches, not their arithmetic, are
much of what it costs on a GPU (:mod:`lanelab.models.cuda_graph`); counting them needs no GPU.
A CUDA graph also refuses operators that move data between host and device, which the log shows,
and the bytes the operators write measure the memory traffic that is left when launches are few.
"""

from __future__ import annotations

from typing import Any

import torch
from torch.utils import _pytree as pytree
from torch.utils._python_dispatch import TorchDispatchMode

# Operators that return a tensor not declared a view, but launch no kernel.
_NO_KERNEL = {
    torch.ops.aten._unsafe_view.default,
    torch.ops.aten.empty.memory_format,
    torch.ops.aten.empty_strided.default,
    torch.ops.aten.empty_like.default,
    torch.ops.aten.new_empty.default,
    torch.ops.aten.new_empty_strided.default,
}
# Operators that make a tensor from host data or read one back to the host.
HOST_TRANSFERS = {torch.ops.aten.lift_fresh.default, torch.ops.aten._local_scalar_dense.default}


class OperatorLog(TorchDispatchMode):
    """``with OperatorLog() as log: fn()`` records fn's operators, in order, in ``log.operators``."""

    def __init__(self) -> None:
        super().__init__()
        self.operators: list[torch._ops.OpOverload] = []
        self.written: list[int] = []  # bytes of the tensors each operator returned

    def __torch_dispatch__(self, func: Any, types: Any, args: Any = (), kwargs: Any = None) -> Any:
        out = func(*args, **(kwargs or {}))
        self.operators.append(func)
        self.written.append(sum(t.nbytes for t in pytree.tree_leaves(out) if isinstance(t, torch.Tensor)))
        return out

    def kernels(self) -> int:
        """How many of the operators compute a tensor (a kernel launch each on a GPU): not views,
        and in-place ones included (their aliased output is written)."""
        return sum(_computes(op) for op in self.operators)

    def bytes_written(self) -> int:
        """Bytes the operators of :meth:`kernels` write: on a GPU, where a step is bound by memory
        rather than launches, the traffic a change adds or saves (each write is read at least once)."""
        return sum(size for op, size in zip(self.operators, self.written) if _computes(op))

    def host_transfers(self) -> list[str]:
        """The operators that move data between host and device (which CUDA graphs refuse)."""
        return [str(op) for op in self.operators if op in HOST_TRANSFERS]


def _computes(op: torch._ops.OpOverload) -> bool:
    returns = op._schema.returns
    tensors = any(isinstance(ret.type, (torch.TensorType, torch.ListType)) for ret in returns)  # not a dtype, a bool
    view = any(ret.alias_info is not None and not ret.alias_info.is_write for ret in returns)
    return tensors and not view and op not in _NO_KERNEL
