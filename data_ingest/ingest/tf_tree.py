"""A TF buffer: the transforms of /tf and /tf_static as a tree of frames, looked up at any time.

As in ROS tf2, every frame has one parent. An edge parent <- child is either static (valid
at all times) or a time series of samples, interpolated between them (linear in translation,
slerp in rotation, :mod:`lanelab.geometry`) and undefined outside them. :meth:`TfTree.lookup`
composes target <- ... <- source through the frames' common ancestor, vectorised over stamps.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass

import numpy as np
import torch

from data_ingest.ingest.messages import Transform
from lanelab.geometry import compose, invert, make_transform, quaternion_to_rotation, slerp


@dataclass(frozen=True)
class _Series:
    """Samples of one edge: stamps (K,) int64 ascending and unique, translations (K, 3), quaternions (K, 4)."""

    stamps: np.ndarray
    translations: np.ndarray
    quaternions: np.ndarray

    @classmethod
    def of(cls, samples: list[Transform]) -> _Series:
        stamps = np.array([s.stamp_ns for s in samples], dtype=np.int64)
        # Sort by stamp; of equal stamps keep the last received, as tf2 overwrites.
        order = np.lexsort((np.arange(len(stamps)), stamps))
        keep = np.append(stamps[order][1:] != stamps[order][:-1], True)
        order = order[keep]
        return cls(stamps[order], np.array([samples[i].translation for i in order], dtype=np.float64),
                   np.array([samples[i].rotation for i in order], dtype=np.float64))

    def at(self, stamps: np.ndarray) -> tuple[torch.Tensor, np.ndarray]:
        """Poses (N, 4, 4) at ``stamps`` (N,) and whether each lies within the samples (N,) bool."""
        valid = (stamps >= self.stamps[0]) & (stamps <= self.stamps[-1])
        if len(self.stamps) == 1:
            i = j = np.zeros(len(stamps), dtype=np.int64)
            alpha = np.zeros(len(stamps))
        else:
            i = np.clip(np.searchsorted(self.stamps, stamps, side="right") - 1, 0, len(self.stamps) - 2)
            j = i + 1
            alpha = (stamps - self.stamps[i]) / (self.stamps[j] - self.stamps[i])
        a = alpha[:, None]
        translation = (1 - a) * self.translations[i] + a * self.translations[j]
        q = slerp(torch.from_numpy(self.quaternions[i]), torch.from_numpy(self.quaternions[j]), torch.from_numpy(alpha))
        return make_transform(quaternion_to_rotation(q), torch.from_numpy(translation)), valid


class TfTree:
    """Frames and the transforms between them, filled by :meth:`add`, read by :meth:`lookup`."""

    def __init__(self) -> None:
        self._parent: dict[str, str] = {}
        self._static: dict[str, Transform] = {}
        self._samples: dict[str, list[Transform]] = {}
        self._series: dict[str, _Series] = {}
        self.conflicts: Counter = Counter()  # (child, other parent) -> transforms ignored

    def add(self, transform: Transform, static: bool) -> None:
        """Add a transform parent <- child; a child keeps the first parent it was given (tf2's tree rule)."""
        parent = self._parent.setdefault(transform.child, transform.parent)
        if parent != transform.parent:
            self.conflicts[(transform.child, transform.parent)] += 1
            return
        if static:
            self._static[transform.child] = transform
        else:
            self._samples.setdefault(transform.child, []).append(transform)
            self._series.pop(transform.child, None)

    def _chain(self, frame: str) -> list[str]:
        """``frame`` and its ancestors up to the root."""
        chain = [frame]
        while chain[-1] in self._parent and self._parent[chain[-1]] not in chain:
            chain.append(self._parent[chain[-1]])
        return chain

    def _common_ancestor(self, a: str, b: str) -> str | None:
        ancestors = set(self._chain(a))
        return next((frame for frame in self._chain(b) if frame in ancestors), None)

    def connected(self, a: str, b: str) -> bool:
        return self._common_ancestor(a, b) is not None

    def describe(self, limit: int = 12) -> str:
        """The tree's edges for a message: "odom -> base_link (501 samples), base_link -> camera (static)"."""
        edges = [f"{self._parent[c]} -> {c} (" + ("static" if c in self._static else f"{len(self._samples[c])} samples")
                 + ")" for c in sorted(self._parent)]
        if not edges:
            return "no transforms at all"
        return ", ".join(edges[:limit]) + (f", ... ({len(edges)} edges)" if len(edges) > limit else "")

    def time_range(self, frame: str) -> str:
        """The times the edge parent <- ``frame`` covers, for messages."""
        if frame in self._static:
            return "static"
        stamps = self._edge_series(frame).stamps
        return f"{stamps[0] / 1e9:.3f}-{stamps[-1] / 1e9:.3f} s"

    def _edge_series(self, child: str) -> _Series:
        if child not in self._series:
            self._series[child] = _Series.of(self._samples[child])
        return self._series[child]

    def _up(self, frame: str, ancestor: str, stamps: np.ndarray) -> tuple[torch.Tensor, np.ndarray, str | None]:
        """T_ancestor_frame (N, 4, 4), where it is defined (N,), and the first edge that is not, by child name."""
        T = torch.eye(4, dtype=torch.float64).expand(len(stamps), 4, 4)
        valid = np.ones(len(stamps), dtype=bool)
        first_gap = None
        chain = self._chain(frame)
        for child in chain[:chain.index(ancestor)]:  # the edges parent <- child below the ancestor
            if child in self._static:
                tf = self._static[child]
                edge = make_transform(quaternion_to_rotation(torch.tensor(tf.rotation, dtype=torch.float64)),
                                      torch.tensor(tf.translation, dtype=torch.float64))
            else:
                edge, edge_valid = self._edge_series(child).at(stamps)
                if first_gap is None and not edge_valid.all():
                    first_gap = child
                valid &= edge_valid
            T = compose(edge, T)
        return T, valid, first_gap

    def lookup(self, target: str, source: str, stamps: np.ndarray) -> tuple[np.ndarray, np.ndarray, str | None]:
        """T_target_source at ``stamps`` (N,) int64 ns.

        Returns the poses (N, 4, 4) float64, where they are defined (N,) bool (every edge on the
        way has samples around the stamp), and the child frame of the first edge that lacks
        some (None when all are defined). Raises KeyError when the frames are not connected.
        """
        ancestor = self._common_ancestor(target, source)
        if ancestor is None:
            raise KeyError(f"no TF path between {target!r} and {source!r}")
        stamps = np.asarray(stamps, dtype=np.int64)
        T_anc_source, valid_source, gap_source = self._up(source, ancestor, stamps)
        T_anc_target, valid_target, gap_target = self._up(target, ancestor, stamps)
        T = compose(invert(T_anc_target), T_anc_source)
        return T.numpy(), valid_source & valid_target, gap_target or gap_source

    def parent(self, child: str) -> str:
        return self._parent[child]
