"""The ATen operators a call dispatches, recorded below autograd: what a GPU would launch.

At batch 1 a streaming frame's kernels are small and their launches, not their arithmetic, are
much of what it costs on a GPU (:mod:`lanelab.runtime.cuda_graph`); counting them needs no GPU.
A CUDA graph also refuses operators that move data between host and device, which the log shows,
and the bytes the operators write measure the memory traffic that is left when launches are few.

On the CPU a host-to-device copy is no operator at all, or a copy within the CPU: a log given
the tensors that the code may read (its inputs, parameters and buffers) also counts as one every
copy of a tensor from elsewhere (a module-level constant, say), which on a GPU would be host memory.
"""

from __future__ import annotations

from collections.abc import Iterable
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
# Operators that make a tensor from host data, read one back to the host, or wait for the device
# to learn the size of their result.
HOST_TRANSFERS = {
    torch.ops.aten.lift_fresh.default,
    torch.ops.aten._local_scalar_dense.default,
    torch.ops.aten.nonzero.default,
    torch.ops.aten.masked_select.default,
}
_MASKABLE = {torch.ops.aten.index.Tensor, torch.ops.aten.index_put.default, torch.ops.aten.index_put_.default}
_COPIES = {torch.ops.aten._to_copy.default, torch.ops.aten.copy_.default, torch.ops.aten.copy.default}


class OperatorLog(TorchDispatchMode):
    """``with OperatorLog() as log: fn()`` records fn's operators, in order, in ``log.operators``.

    sources: the tensors fn may read from outside; given, the log keeps every tensor fn makes
    (memory) to tell the tensors that come from elsewhere (see the module doc)."""

    def __init__(self, sources: Iterable[torch.Tensor] | None = None) -> None:
        super().__init__()
        self.operators: list[torch._ops.OpOverload] = []
        self.written: list[int] = []  # bytes of the tensors each operator returned
        self.transfers: list[str] = []  # what host_transfers returns, in order
        # Storages, held so that a freed one's address cannot come back as another tensor's.
        self._known = None if sources is None else {t.untyped_storage().data_ptr(): t for t in sources}

    def __torch_dispatch__(self, func: Any, types: Any, args: Any = (), kwargs: Any = None) -> Any:
        transfer = self._transfer(func, args)
        if transfer is not None:
            self.transfers.append(transfer)
        out = func(*args, **(kwargs or {}))
        self.operators.append(func)
        tensors = [t for t in pytree.tree_leaves(out) if isinstance(t, torch.Tensor)]
        self.written.append(sum(t.nbytes for t in tensors))
        if self._known is not None:
            self._known.update((t.untyped_storage().data_ptr(), t) for t in tensors)
        return out

    def _transfer(self, func: Any, args: Any) -> str | None:
        """How func(*args) moves data between host and device, or None."""
        if func in HOST_TRANSFERS:
            return str(func)
        if func in _MASKABLE and any(i is not None and i.dtype in (torch.bool, torch.uint8) for i in args[1]):
            return f"{func} by a boolean mask"  # which runs nonzero
        if self._known is not None and func in _COPIES:
            source = args[0] if func is torch.ops.aten._to_copy.default else args[1]
            if source.untyped_storage().data_ptr() not in self._known:
                return f"{func} of a tensor from elsewhere"
        return None

    def kernels(self) -> int:
        """How many of the operators compute a tensor (a kernel launch each on a GPU): not views,
        and in-place ones included (their aliased output is written)."""
        return sum(_computes(op) for op in self.operators)

    def bytes_written(self) -> int:
        """Bytes the operators of :meth:`kernels` write: on a GPU, where a step is bound by memory
        rather than launches, the traffic a change adds or saves (each write is read at least once)."""
        return sum(size for op, size in zip(self.operators, self.written) if _computes(op))

    def host_transfers(self) -> list[str]:
        """The operators that move data between host and device (which CUDA graphs refuse): those
        of HOST_TRANSFERS, indexing by a boolean mask, and given sources, copies from elsewhere."""
        return list(self.transfers)


def _computes(op: torch._ops.OpOverload) -> bool:
    returns = op._schema.returns
    tensors = any(isinstance(ret.type, (torch.TensorType, torch.ListType)) for ret in returns)  # not a dtype, a bool
    view = any(ret.alias_info is not None and not ret.alias_info.is_write for ret in returns)
    return tensors and not view and op not in _NO_KERNEL
