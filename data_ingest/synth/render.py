"""The camera image of a frame, drawn with OpenCV through the ground truth's camera model.

The scene is a soup of world quads: slices of the road (verges, asphalt, painted stripes,
curb faces) and the faces of boxes (vehicles, scenery). Each frame they are culled, clipped
to the near plane, projected with :class:`camera.View` in one batch, shaded by distance
(:mod:`appearance`) and filled far to near: the painter's order is the arc length of the
far end of a road slice, or of the near end of an object, so a crest hides the road behind
it and a vehicle hides the road under it. Road slices break at every dash end, so dashes
are real quads with real gaps.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import cv2
import numpy as np

from data_ingest.synth.appearance import ImageEffects, Look, shade, sky_rows
from data_ingest.synth.boxes import Boxes
from data_ingest.synth.camera import SUBPIXEL_BITS, View, cv_points
from data_ingest.synth.frame import CameraModel
from data_ingest.synth.road import Road

DRAW_RANGE_M = 400.0  # at least; more when the labels reach farther
BEHIND_M = 2.0  # the road starts this far behind base_link; the camera sees it from ~5 m ahead
DASH_DETAIL_M = 150.0  # farther dashes are sub-pixel: drawn as a faint solid line instead
SLICE_GROWTH, MIN_SLICE_M, MAX_SLICE_M = 0.03, 0.5, 10.0  # slices lengthen with distance
BAND, ASPHALT, PAINT, CURB, BOX = 0, 1, 2, 3, 10  # drawing order within one slice / object
FACE_SHADE = np.array([0.88, 0.88, 0.72, 0.72, 1.05, 0.5])  # rear, front, left, right, top, bottom
SNOW_PATCH_M = 2.0  # painted lines are covered by snow in patches of this length
GLOW_RADIUS_M = 0.35  # of a light's halo at night
PAINT_OVERLAP_M = 0.05  # stripes reach this far into the next slice: no pixel row lost between slices
# Slice corners: (near, lo) (near, hi) (far, hi) (far, lo).
_HI, _NEAR = np.array([False, True, True, False]), np.array([True, True, False, False])


@dataclass(frozen=True)
class _Quads:
    """World quads to draw. corners: (P, 4, 3); color: (P, 3) BGR; key: (P,) arc length,
    larger first; layer: (P,) then smaller first; outward: (P, 3) facing, zero = both ways;
    emissive, reflective, paint: (P,) bool; coverage: (P,) fraction of the quad that is
    paint (far dashed lines)."""

    corners: np.ndarray
    color: np.ndarray
    key: np.ndarray
    layer: np.ndarray
    outward: np.ndarray
    emissive: np.ndarray
    reflective: np.ndarray
    paint: np.ndarray
    coverage: np.ndarray

    def __getitem__(self, index: np.ndarray) -> _Quads:
        return _Quads(**{f.name: getattr(self, f.name)[index] for f in fields(self)})

    @staticmethod
    def concat(parts: list[_Quads]) -> _Quads:
        return _Quads(**{f.name: np.concatenate([getattr(p, f.name) for p in parts]) for f in fields(_Quads)})


class _Strips:
    """Strips along the road, one quad per slice, placed on the surface with one call."""

    def __init__(self, road: Road, breaks: np.ndarray) -> None:
        self.road = road
        self.far = breaks[1:]
        self.mid = (breaks[:-1] + breaks[1:]) / 2
        self.s = np.stack([breaks[:-1], breaks[:-1], breaks[1:], breaks[1:]], axis=1)  # (K, 4) at the corners
        self._parts: list[dict] = []

    def add(self, lo: np.ndarray, hi: np.ndarray, color, layer: int, mask: np.ndarray | None = None,
            height: np.ndarray | float = 0.0, reflective: bool = False, paint: bool = False,
            coverage: float = 1.0, overlap: float = 0.0) -> None:
        """A strip from lateral offset lo to hi, each (K, 4) at the slices' corners, on the slices in ``mask``;
        ``overlap`` lengthens its quads at both ends (m)."""
        mask = np.ones(len(self.mid), bool) if mask is None else mask
        n = int(mask.sum())
        s = self.s + np.where(_NEAR, -overlap, overlap)
        self._parts.append(dict(
            s=s[mask], d=np.where(_HI, hi, lo)[mask], z=np.broadcast_to(height, self.s.shape)[mask],
            color=np.broadcast_to(np.asarray(color, float), (n, 3)), key=self.far[mask],
            layer=np.full(n, layer), reflective=np.full(n, reflective), paint=np.full(n, paint),
            coverage=np.full(n, coverage)))

    def wall(self, offset: np.ndarray, height: float, color, layer: int) -> None:
        """An upright strip (a curb face) at ``offset`` (K, 4), from the surface up to ``height``."""
        self.add(offset, offset, color, layer, height=np.where(_HI, height, 0.0))

    def quads(self) -> _Quads:
        part = {key: np.concatenate([p[key] for p in self._parts]) for key in self._parts[0]}
        n = len(part["key"])
        return _Quads(self.road.surface(part["s"], part["d"], part["z"]), part["color"], part["key"], part["layer"],
                      np.zeros((n, 3)), np.zeros(n, bool), part["reflective"], part["paint"], part["coverage"])


class Renderer:
    """Draws frames of one drive: its road, static scenery and look, seen by ``camera``.

    rng: draws the weather and noise tiles once, so equal seeds give equal images.
    draw_range: how far ahead of the ego the road and objects are drawn (m).
    """

    def __init__(self, road: Road, scenery: Boxes, camera: CameraModel, look: Look,
                 rng: np.random.Generator, draw_range: float = DRAW_RANGE_M) -> None:
        self.road, self.scenery, self.camera, self.look = road, scenery, camera, look
        self.draw_range = draw_range
        self.effects = ImageEffects(look, camera.width, camera.height, rng)
        self._sky = sky_rows(look, camera.height)
        self._relative = _slice_grid(draw_range + BEHIND_M)
        lines = road.cross_section.lines
        markings = [line.marking for line in lines if line.marking is not None]
        self._dashes = sorted({(m.period, m.dash) for m in markings if m.dash is not None})
        self._line_ends = np.array(sorted({e for line in lines for e in (line.start, line.end) if np.isfinite(e)}))
        self._asphalt = look.palette["asphalt"]

    def render(self, view: View, ego_s: float, vehicles: Boxes, frame_index: int) -> np.ndarray:
        """(H, W, 3) BGR uint8 image of the frame seen by ``view``, the ego at arc length ``ego_s``."""
        near = max(ego_s - BEHIND_M, 0.0)
        far = min(ego_s + self.draw_range, self.road.length)
        quads = _Quads.concat([self._road_quads(self._breaks(near, far, ego_s), ego_s),
                               self._box_quads(Boxes.concat([self.scenery.overlapping(near, far), vehicles]))])
        seen = view.polygons(quads.corners, quads.outward)
        quads = quads[seen.index]
        distance = np.linalg.norm(seen.centre, axis=1)
        depth = seen.centre[:, 2]
        # A stripe thinner than a pixel covers only part of the pixels it touches: blend it into the asphalt.
        coverage = np.where(quads.paint, quads.coverage * np.clip(_thickness(seen.uv), 0.0, 1.0), 1.0)[:, None]
        color = self._asphalt + (quads.color - self._asphalt) * coverage
        color = shade(self.look, color, distance, seen.centre[:, 0] / depth, quads.emissive, quads.reflective)

        image = self._background(view)
        order = np.lexsort((-distance, quads.layer, -quads.key))
        points = cv_points(seen.uv[order])
        outline = (quads.paint & (coverage[:, 0] < 1.0))[order].tolist()
        for polygon, bgr, thin in zip(points, np.clip(color[order], 0, 255).tolist(), outline):
            cv2.fillConvexPoly(image, polygon, bgr, cv2.LINE_8, SUBPIXEL_BITS)
            if thin:  # a fill may skip pixels of a sub-pixel stripe; its outline keeps it unbroken
                cv2.polylines(image, [polygon], True, bgr, 1, cv2.LINE_8, SUBPIXEL_BITS)
        if self.look.daytime == "night":
            self._glow(image, seen.uv[quads.emissive].mean(axis=1), depth[quads.emissive], color[quads.emissive])
        return self.effects.apply(image, frame_index)

    def _breaks(self, near: float, far: float, ego_s: float) -> np.ndarray:
        """(K + 1,) slice boundaries: a grid that coarsens with distance, plus every dash and line end."""
        breaks = [near + self._relative[self._relative <= far - near], [far], self._line_ends]
        detail = min(ego_s + DASH_DETAIL_M, far)
        for period, dash in self._dashes:
            starts = np.arange(np.ceil(near / period), np.floor(detail / period) + 1) * period
            breaks += [starts, starts + dash]
        s = np.unique(np.concatenate(breaks))
        s = s[(s >= near) & (s <= far)]
        return s[np.concatenate([[True], np.diff(s) > 1e-3])]

    def _road_quads(self, breaks: np.ndarray, ego_s: float) -> _Quads:
        xs, palette = self.road.cross_section, self.look.palette
        strips = _Strips(self.road, breaks)
        edge = {side: xs.line_offset(xs.curbside(side), strips.s) for side in (-1, 1)}
        strips.add(edge[-1], edge[1], self._asphalt, ASPHALT, reflective=True)
        for band in xs.bands:
            inner, outer = edge[band.side] + band.side * band.inner, edge[band.side] + band.side * band.outer
            lo, hi = (outer, inner) if band.side < 0 else (inner, outer)
            strips.add(lo, hi, palette[band.material], BAND, height=band.height)
        if xs.curb_height > 0:
            for side in (-1, 1):
                strips.wall(edge[side], xs.curb_height, palette["curb"], CURB)
        detailed = strips.mid < ego_s + DASH_DETAIL_M
        for line in xs.lines:
            marking = line.marking
            if marking is None:
                continue
            shown = (strips.mid >= line.start) & (strips.mid <= line.end) & ~self._under_snow(line.track_id, strips.mid)
            color = self.look.yellow if marking.color == "yellow" else self.look.white
            offset = xs.line_offset(line, strips.s)  # at the slice ends: overlapping stripes bend with the line
            # Near dashes are quads of their own; far ones are a faint line with the dashes' share of paint.
            for mask, coverage in ((shown & detailed & marking.painted(strips.mid), 1.0),
                                   (shown & ~detailed, marking.paint_share)):
                for stripe in marking.stripe_offsets():
                    strips.add(offset + stripe - marking.width / 2, offset + stripe + marking.width / 2, color, PAINT,
                               mask, reflective=True, paint=True, coverage=coverage, overlap=PAINT_OVERLAP_M)
        return strips.quads()

    def _under_snow(self, track_id: int, s: np.ndarray) -> np.ndarray:
        """(K,) bool: patches of line ``track_id`` covered by snow at s (K,), fixed on the road."""
        if self.look.snow_cover <= 0:
            return np.zeros(len(s), bool)
        patch = np.floor(s / SNOW_PATCH_M)
        noise = np.abs(np.sin(patch * 12.9898 + track_id * 78.233) * 43758.5453) % 1.0
        return noise < self.look.snow_cover

    def _box_quads(self, boxes: Boxes) -> _Quads:
        corners, outward, box, face = boxes.face_quads(self.road)
        n = len(box)
        return _Quads(corners, boxes.color[box] * FACE_SHADE[face][:, None], boxes.key[box], BOX + boxes.layer[box],
                      outward, boxes.emissive[box], np.zeros(n, bool), np.zeros(n, bool), np.ones(n))

    def _background(self, view: View) -> np.ndarray:
        """Sky above the horizon, far terrain below it."""
        W, H = self.camera.width, self.camera.height
        (u0, v0), (u1, v1) = np.nan_to_num(view.horizon())
        slope = (v1 - v0) / (u1 - u0) if u1 != u0 else 0.0
        row = lambda u: float(np.clip(v0 + slope * (u - u0), -1e6, 1e6))  # noqa: E731
        start = int(np.clip(2 * H - round(row(W / 2)), 0, 3 * H))
        image = np.ascontiguousarray(np.broadcast_to(self._sky[start:start + H, None, :], (H, W, 3)))
        ground = np.array([[-1, row(-1)], [W + 1, row(W + 1)], [W + 1, H + 1], [-1, H + 1]])
        terrain = shade(self.look, self.look.palette["terrain"][None], np.array([self.draw_range]), np.zeros(1),
                        np.zeros(1, bool), np.zeros(1, bool))[0]
        cv2.fillConvexPoly(image, cv_points(ground), np.clip(terrain, 0, 255).tolist(), cv2.LINE_8, SUBPIXEL_BITS)
        return image

    def _glow(self, image: np.ndarray, uv: np.ndarray, depth: np.ndarray, color: np.ndarray) -> None:
        """Halos around the lights at night."""
        glow = np.zeros_like(image)
        radius = self.camera.K[0, 0] * GLOW_RADIUS_M / depth
        for (u, v), r, bgr in zip(uv, radius, np.clip(color * 0.6, 0, 255).tolist()):
            if np.isfinite(u + v) and r >= 0.5:
                cv2.circle(glow, (int(u), int(v)), int(np.ceil(r)), bgr, -1)
        cv2.add(image, cv2.GaussianBlur(glow, (0, 0), 2.0), dst=image)


def _thickness(uv: np.ndarray) -> np.ndarray:
    """(P,) image width in pixels of stripe quads (P, >=4, 2), across their run (near edge against the
    direction from the near to the far edge). Clipped quads, all off-image, give meaningless values."""
    near, far = (uv[:, 0] + uv[:, 1]) / 2, (uv[:, 2] + uv[:, 3]) / 2
    along = (far - near) / np.maximum(np.linalg.norm(far - near, axis=1, keepdims=True), 1e-9)
    across = uv[:, 1] - uv[:, 0]
    return np.abs(across[:, 0] * along[:, 1] - across[:, 1] * along[:, 0])


def _slice_grid(length: float) -> np.ndarray:
    """Slice boundaries over ``length`` m from the road's near end: fine near the camera, coarser far away."""
    s, grid = 0.0, [0.0]
    while s < length:
        s += float(np.clip(SLICE_GROWTH * (s - BEHIND_M), MIN_SLICE_M, MAX_SLICE_M))
        grid.append(s)
    return np.array(grid)
