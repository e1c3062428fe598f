"""A TF buffer: the transforms of /tf and /tf_static as a tree of frames, looked up at any time.

As in ROS tf2, every frame has one parent. An edge parent <- child is either static (valid
at all times) or a time series of samples, interpolated between them (linear in translation,
slerp in rotation, :mod:`lanelab.geometry`) and undefined outside them. :meth:`TfTree.lookup`
composes target <- ... <- source through the frames' common ancestor, vectorised over stamps.

A time series is also undefined where its samples cannot be trusted (:data:`FAULTS`):

- across a gap between two samples longer than the caller's limit (``max_gap_ns``): the
  motion in between is unknown, a straight line through it is a guess;
- where the samples are ambiguous: a sample stamped before one received earlier on the same
  edge that disagrees with the others at its stamp (more than ``agreement`` metres away, or
  radians turned: a sensor clock that jumped back, so that two stretches of the drive claim
  the same times) makes every sample between its stamp and the latest stamp before it
  ambiguous; two different transforms at one stamp make that stamp so. A late sample that
  agrees (messages merely out of order) is used. :meth:`TfTree.problems` describes what was
  found, one line per edge.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass

import numpy as np
import torch

from data_ingest.ingest.messages import Transform
from lanelab.geometry import compose, invert, make_transform, quaternion_to_rotation, rotation_to_quaternion, slerp


# Why a time series is undefined at a stamp (0: it is defined there).
OUTSIDE, GAP, AMBIGUOUS = 1, 2, 3
FAULTS = {OUTSIDE: "outside", GAP: "gap", AMBIGUOUS: "ambiguous"}
SAME = 1e-9  # translations (m) and quaternion components (of q or -q) this close are one transform


@dataclass(frozen=True)
class _Series:
    """Samples of one edge: stamps (K,) int64 ascending and unique, translations (K, 3), quaternions
    (K, 4), which samples are ambiguous (K,) bool, and what made them so (lines for messages)."""

    stamps: np.ndarray
    translations: np.ndarray
    quaternions: np.ndarray
    ambiguous: np.ndarray
    problems: tuple[str, ...]

    @classmethod
    def of(cls, samples: list[Transform], agreement: float | None) -> _Series:
        """The series of ``samples`` in the order received; a late sample further than ``agreement``
        (m or rad) from the others makes its span ambiguous (None: late samples are trusted)."""
        received = np.array([s.stamp_ns for s in samples], dtype=np.int64)
        translations = np.array([s.translation for s in samples], dtype=np.float64)
        quaternions = np.array([s.rotation for s in samples], dtype=np.float64)
        stamps, kept = _sorted(received)
        t, q = translations[kept], quaternions[kept]
        # Two different transforms at one stamp: which is right cannot be told.
        order = np.lexsort((np.arange(len(received)), received))
        t_all, q_all, s_all = translations[order], quaternions[order], received[order]
        same = np.abs(t_all[1:] - t_all[:-1]).max(axis=1) <= SAME
        dq = np.minimum(np.abs(q_all[1:] - q_all[:-1]).max(axis=1), np.abs(q_all[1:] + q_all[:-1]).max(axis=1))
        same &= dq <= SAME  # q and -q are one rotation
        conflicting = np.unique(s_all[1:][(s_all[1:] == s_all[:-1]) & ~same])
        # A sample stamped before one received earlier that disagrees with the samples received in
        # order: the stamps between are claimed twice.
        latest = np.maximum.accumulate(received)
        back = np.flatnonzero(received[1:] < latest[:-1]) + 1
        if len(back) and agreement is not None:
            in_order = np.ones(len(received), dtype=bool)
            in_order[back] = False
            on_time, kept_on_time = _sorted(received[in_order])
            reference = cls(on_time, translations[in_order][kept_on_time], quaternions[in_order][kept_on_time],
                            np.zeros(len(on_time), dtype=bool), ())
            T, fault = reference.at(received[back])
            apart = np.linalg.norm(T[:, :3, 3].numpy() - translations[back], axis=1)
            turned = _turn(rotation_to_quaternion(T[:, :3, :3]).numpy(), quaternions[back])
            back = back[((apart > agreement) | (turned > agreement)) & (fault == 0)]  # elsewhere nothing to compare
        elif agreement is None:
            back = back[:0]
        ambiguous = np.isin(stamps, conflicting)
        if len(back):
            starts = np.searchsorted(stamps, received[back], side="left")
            ends = np.searchsorted(stamps, latest[back - 1], side="right")
            depth = np.zeros(len(stamps) + 1, dtype=np.int64)
            np.add.at(depth, starts, 1)
            np.add.at(depth, ends, -1)
            ambiguous |= np.cumsum(depth)[:-1] > 0
        problems = []
        if len(back):
            steps = latest[back - 1] - received[back]
            k = int(np.argmax(steps))
            problems.append(f"{len(back)} sample(s) stamped before one received earlier and off the others' path "
                            f"(largest step back {steps[k] / 1e9:.3f} s, at {latest[back[k] - 1] / 1e9:.3f} s: "
                            "the clock jumped back?)")
        if len(conflicting):
            problems.append(f"{len(conflicting)} stamp(s) with two different transforms (first at "
                            f"{conflicting[0] / 1e9:.3f} s)")
        return cls(stamps, t, q, ambiguous, tuple(problems))

    def at(self, stamps: np.ndarray, max_gap_ns: int | None = None) -> tuple[torch.Tensor, np.ndarray]:
        """Poses (N, 4, 4) at ``stamps`` (N,), and why each is undefined (N,) int8: 0 where it is
        defined, else OUTSIDE the samples, across a GAP longer than ``max_gap_ns`` (None: any gap
        is bridged), or between samples of which one is AMBIGUOUS."""
        fault = np.zeros(len(stamps), dtype=np.int8)
        if len(self.stamps) == 1:
            i = j = np.zeros(len(stamps), dtype=np.int64)
            alpha = np.zeros(len(stamps))
        else:
            i = np.clip(np.searchsorted(self.stamps, stamps, side="right") - 1, 0, len(self.stamps) - 2)
            j = i + 1
            alpha = (stamps - self.stamps[i]) / (self.stamps[j] - self.stamps[i])
        # A sample weighs in unless the stamp is exactly at the other one.
        fault[(self.ambiguous[i] & (alpha < 1)) | (self.ambiguous[j] & (alpha > 0))] = AMBIGUOUS
        if max_gap_ns is not None:
            fault[(self.stamps[j] - self.stamps[i] > max_gap_ns) & (alpha > 0) & (alpha < 1)] = GAP
        fault[(stamps < self.stamps[0]) | (stamps > self.stamps[-1])] = OUTSIDE
        a = alpha[:, None]
        translation = (1 - a) * self.translations[i] + a * self.translations[j]
        q = slerp(torch.from_numpy(self.quaternions[i]), torch.from_numpy(self.quaternions[j]), torch.from_numpy(alpha))
        return make_transform(quaternion_to_rotation(q), torch.from_numpy(translation)), fault


def _sorted(stamps: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unique ``stamps`` ascending, and the index of each: of equal stamps the last received, as tf2 overwrites."""
    order = np.lexsort((np.arange(len(stamps)), stamps))
    last = np.append(stamps[order][1:] != stamps[order][:-1], True)
    return stamps[order][last], order[last]


def _turn(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The angle (rad) between the rotations of unit quaternions a and b (..., 4): q and -q are one."""
    return 2 * np.arccos(np.clip(np.abs(np.sum(a * b, axis=-1)), 0.0, 1.0))


class TfTree:
    """Frames and the transforms between them, filled by :meth:`add`, read by :meth:`lookup`.

    agreement: how far (m, or rad) a sample received after a later-stamped one may lie from the
    others' path at its stamp before the span it claims is ambiguous (None: never).
    """

    def __init__(self, agreement: float | None = None) -> None:
        self._agreement = agreement
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
            self._series[child] = _Series.of(self._samples[child], self._agreement)
        return self._series[child]

    def _up(self, frame: str, ancestor: str, stamps: np.ndarray, max_gap_ns: int | None,
            faults: dict[tuple[str, str], np.ndarray]) -> torch.Tensor:
        """T_ancestor_frame (N, 4, 4); adds to ``faults`` the stamps each edge leaves undefined
        (those of an edge nearer ``frame`` first)."""
        T = torch.eye(4, dtype=torch.float64).expand(len(stamps), 4, 4)
        chain = self._chain(frame)
        for child in chain[:chain.index(ancestor)]:  # the edges parent <- child below the ancestor
            if child in self._static:
                tf = self._static[child]
                edge = make_transform(quaternion_to_rotation(torch.tensor(tf.rotation, dtype=torch.float64)),
                                      torch.tensor(tf.translation, dtype=torch.float64))
            else:
                edge, fault = self._edge_series(child).at(stamps, max_gap_ns)
                undefined = np.logical_or.reduce([*faults.values(), np.zeros(len(stamps), dtype=bool)])
                for code, kind in FAULTS.items():
                    new = (fault == code) & ~undefined
                    if new.any():
                        faults[(child, kind)] = new
            T = compose(edge, T)
        return T

    def lookup(self, target: str, source: str, stamps: np.ndarray, max_gap_ns: int | None = None
               ) -> tuple[np.ndarray, np.ndarray, dict[tuple[str, str], np.ndarray]]:
        """T_target_source at ``stamps`` (N,) int64 ns, never interpolated across more than ``max_gap_ns``.

        Returns the poses (N, 4, 4) float64, where they are defined (N,) bool, and why the others
        are not: (child frame of the edge, "outside" | "gap" | "ambiguous") -> (N,) bool, each
        undefined stamp under the first edge that fails it. Raises KeyError when the frames are
        not connected.
        """
        ancestor = self._common_ancestor(target, source)
        if ancestor is None:
            raise KeyError(f"no TF path between {target!r} and {source!r}")
        stamps = np.asarray(stamps, dtype=np.int64)
        faults: dict[tuple[str, str], np.ndarray] = {}
        T_anc_target = self._up(target, ancestor, stamps, max_gap_ns, faults)
        T_anc_source = self._up(source, ancestor, stamps, max_gap_ns, faults)
        T = compose(invert(T_anc_target), T_anc_source)
        valid = ~np.logical_or.reduce([*faults.values(), np.zeros(len(stamps), dtype=bool)])
        return T.numpy(), valid, faults

    def problems(self) -> list[str]:
        """Lines naming the edges whose samples are ambiguous somewhere, and why."""
        return [f"TF {self._parent[child]} -> {child}: " + "; ".join(series.problems)
                for child in sorted(self._samples) if (series := self._edge_series(child)).problems]

    def parent(self, child: str) -> str:
        return self._parent[child]
