"""A function's GPU work recorded once as a CUDA graph and replayed on later calls.

At batch 1 a streaming frame's kernels are small and the GPU waits on Python to launch them:
Bi²Lane's refinement is 2N sequential chain steps of a few dozen kernels each, so every history
frame costs launches, not arithmetic. A CUDA graph records the kernels of one call and launches
them together afterwards. What it asks of the function: no host synchronisation (``.item()``,
``bool(tensor)``), no control flow on tensor values, and parameters that stay where they are
(``nn.Module.to`` moves them: the owner drops its graphs then, see ``Bi2Lane._apply``).

Each call copies its tensor arguments into the graph's static inputs and returns clones of the
static outputs, which the next replay overwrites.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Hashable
from typing import Any

import torch
from torch import Tensor


def _map_tensors(fn: Callable[[Tensor], Any], tree: Any) -> Any:
    """fn applied to every tensor of nested dicts, lists, tuples and dataclasses; other leaves kept."""
    if isinstance(tree, Tensor):
        return fn(tree)
    if dataclasses.is_dataclass(tree) and not isinstance(tree, type):
        fields = {f.name: _map_tensors(fn, getattr(tree, f.name)) for f in dataclasses.fields(tree)}
        return dataclasses.replace(tree, **fields)
    if isinstance(tree, dict):
        return {key: _map_tensors(fn, value) for key, value in tree.items()}
    if isinstance(tree, (list, tuple)):
        return type(tree)(_map_tensors(fn, value) for value in tree)
    return tree


def signature(args: tuple[Any, ...]) -> Hashable:
    """What a graph is specific to: each tensor argument's shape, dtype and device, the other
    arguments' values, and the CUDA autocast state (a bf16 graph is not an fp32 one)."""
    parts = tuple((tuple(a.shape), a.dtype, a.device) if isinstance(a, Tensor) else a for a in args)
    return parts, torch.is_autocast_enabled("cuda"), torch.get_autocast_dtype("cuda")


class CUDAGraphed:
    """fn(*args) whose CUDA work is replayed from a graph captured at the first call of each
    :func:`signature`; at most max_graphs of them (a stream has one, an evaluation's smaller last
    batch a second), beyond which calls run fn as it is. Arguments are tensors on one CUDA device
    and hashable constants; fn returns tensors in nested dicts, lists, tuples and dataclasses."""

    def __init__(self, fn: Callable[..., Any], max_graphs: int = 4, warmup: int = 2) -> None:
        self.fn, self.max_graphs, self.warmup = fn, max_graphs, warmup
        self._graphs: dict[Hashable, tuple[tuple[Any, ...], torch.cuda.CUDAGraph, Any]] = {}

    def __call__(self, *args: Any) -> Any:
        key = signature(args)
        entry = self._graphs.get(key)
        if entry is None:
            if len(self._graphs) >= self.max_graphs:
                return self.fn(*args)
            entry = self._graphs[key] = self._capture(args)
        inputs, graph, outputs = entry
        for static, arg in zip(inputs, args):
            if isinstance(arg, Tensor):
                static.copy_(arg)
        graph.replay()
        return _map_tensors(torch.Tensor.clone, outputs)

    def _capture(self, args: tuple[Any, ...]) -> tuple[tuple[Any, ...], torch.cuda.CUDAGraph, Any]:
        inputs = tuple(a.clone() if isinstance(a, Tensor) else a for a in args)
        # Autocast's cache of cast weights would live outside the graph and be freed when the
        # caller's autocast ends: warm up and capture without it, so the casts are recorded.
        autocast = torch.autocast("cuda", dtype=torch.get_autocast_dtype("cuda"),
                                  enabled=torch.is_autocast_enabled("cuda"), cache_enabled=False)  # fmt: skip
        side = torch.cuda.Stream()  # warm-up off the default stream, as torch.cuda.graph asks
        side.wait_stream(torch.cuda.current_stream())
        with autocast, torch.cuda.stream(side):
            for _ in range(self.warmup):
                self.fn(*inputs)
        torch.cuda.current_stream().wait_stream(side)
        graph = torch.cuda.CUDAGraph()
        with autocast, torch.cuda.graph(graph):
            outputs = self.fn(*inputs)
        return inputs, graph, outputs
