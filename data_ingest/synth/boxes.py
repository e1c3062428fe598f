"""Boxes standing on the road: vehicle parts, barriers, buildings, trees, lights.

A box is laid out in road coordinates (see :mod:`road`): from arc length ``s[0]`` (its
rear) to ``s[1]`` (its front), laterally from ``d[end, 0]`` (left) to ``d[end, 1]`` (right)
at each end, and from ``z[0]`` to ``z[1]`` metres above the surface. Its corners follow the
road, so a barrier segment bends and climbs with it. A box whose ``faces`` keep a single face
is a decal: a tail light or a windscreen on its parent's face. Boxes are both drawn
(:mod:`render`) and used as occluders of the lanes (:mod:`labels`).
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from data_ingest.synth.road import Road

REAR, FRONT, LEFT, RIGHT, TOP, BOTTOM = range(6)
# Corner c = 4 * end + 2 * side + level (end: rear/front, side: left/right, level: bottom/top);
# each face lists its corners in order around it.
FACE_CORNERS = np.array([[0, 2, 3, 1], [4, 6, 7, 5], [0, 4, 5, 1], [2, 6, 7, 3], [1, 5, 7, 3], [0, 4, 6, 2]])
_END, _SIDE, _LEVEL = np.arange(8) // 4, np.arange(8) // 2 % 2, np.arange(8) % 2
ALL_BUT_BOTTOM = np.array([True, True, True, True, True, False])


@dataclass(frozen=True)
class Boxes:
    """B boxes as a struct of arrays.

    s: (B, 2) arc length of rear and front. d: (B, 2, 2) lateral offsets [end, left/right].
    z: (B, 2) bottom and top above the surface. color: (B, 3) BGR in 0..255.
    faces: (B, 6) bool, the faces drawn (rear, front, left, right, top, bottom).
    key: (B,) painter's key, the arc length of the near end of the object a box belongs to.
    layer: (B,) int, drawing order among the boxes of one object. emissive: (B,) bool (lights).
    """

    s: np.ndarray
    d: np.ndarray
    z: np.ndarray
    color: np.ndarray
    faces: np.ndarray
    key: np.ndarray
    layer: np.ndarray
    emissive: np.ndarray

    def __len__(self) -> int:
        return len(self.s)

    def __getitem__(self, index: np.ndarray) -> Boxes:
        return Boxes(**{f.name: getattr(self, f.name)[index] for f in fields(self)})

    @staticmethod
    def empty() -> Boxes:
        return make_boxes(np.zeros((0, 2)), np.zeros(0), np.zeros(0), np.zeros(0), np.zeros(0), (0, 0, 0), np.zeros(0))

    @staticmethod
    def concat(parts: list[Boxes]) -> Boxes:
        return Boxes(**{f.name: np.concatenate([getattr(p, f.name) for p in parts]) for f in fields(Boxes)})

    def overlapping(self, s_min: float, s_max: float) -> Boxes:
        """The boxes that reach into the arc length interval [s_min, s_max]."""
        return self[(self.s.max(axis=1) >= s_min) & (self.s.min(axis=1) <= s_max)]

    def corners(self, road: Road) -> np.ndarray:
        """(B, 8, 3) world corners, indexed as in :data:`FACE_CORNERS`."""
        return road.surface(self.s[:, _END], self.d[:, _END, _SIDE], self.z[:, _LEVEL])

    def face_quads(self, road: Road) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The drawn faces: quads (F, 4, 3) world, outward directions (F, 3), box index (F,), face index (F,)."""
        corners = self.corners(road)
        box, face = np.nonzero(self.faces)
        quads = corners[box[:, None], FACE_CORNERS[face]]
        # Centre of the box to centre of the face points outwards, for decals too (they have a thickness).
        outward = quads.mean(axis=1) - corners[box].mean(axis=1)
        return quads, outward, box, face


def make_boxes(s: np.ndarray, left: np.ndarray, right: np.ndarray, bottom: np.ndarray, top: np.ndarray,
               color: np.ndarray, key: np.ndarray, layer: int | np.ndarray = 0, emissive: bool | np.ndarray = False,
               faces: np.ndarray = ALL_BUT_BOTTOM) -> Boxes:
    """Boxes from broadcastable pieces: s (B, 2); left, right (B,) or (B, 2) per end; bottom, top, key (B,);
    color (B, 3) or (3,); faces (6,) or (B, 6)."""
    s = np.asarray(s, float)
    n = len(s)
    left, right = (_per_end(x, n) for x in (left, right))
    bottom, top = (np.broadcast_to(np.asarray(x, float), (n,)) for x in (bottom, top))
    return Boxes(
        s=s,
        d=np.stack([left, right], axis=-1),
        z=np.stack([bottom, top], axis=-1),
        color=np.broadcast_to(np.asarray(color, float), (n, 3)).copy(),
        faces=np.broadcast_to(faces, (n, 6)).copy(),
        key=np.broadcast_to(np.asarray(key, float), (n,)).copy(),
        layer=np.broadcast_to(np.asarray(layer), (n,)).astype(np.int64),
        emissive=np.broadcast_to(np.asarray(emissive, bool), (n,)).copy(),
    )


def _per_end(offset: np.ndarray, n: int) -> np.ndarray:
    """(n, 2) lateral offsets at both ends from (n,) (the same at both) or (n, 2)."""
    offset = np.asarray(offset, float)
    return np.broadcast_to(offset[:, None] if offset.ndim == 1 else offset, (n, 2))
