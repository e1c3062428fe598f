"""A 3D lane line, as every stage holds it: labels, the clip store, targets, predictions,
OpenLane files and pictures; and the OpenLane category ids it carries (DESIGN.md, "Lane
categories"). No torch: the stages before the model use it."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

# OpenLane's lane category ids, in the order of the detectors' classifier outputs.
LANE_CATEGORY_IDS: tuple[int, ...] = (0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 20, 21)
LEFT_CURBSIDE, RIGHT_CURBSIDE = 20, 21
# Their names (DESIGN.md), for legends and tables.
LANE_CATEGORY_NAMES: dict[int, str] = {
    0: "unknown", 1: "white dash", 2: "white solid", 3: "double white dash", 4: "double white solid",
    5: "white ldash-rsolid", 6: "white lsolid-rdash", 7: "yellow dash", 8: "yellow solid",
    9: "double yellow dash", 10: "double yellow solid", 11: "yellow ldash-rsolid", 12: "yellow lsolid-rdash",
    20: "left curbside", 21: "right curbside",
}  # fmt: skip
NO_TRACK = -1  # track id of a lane without identity (an OpenLane lane without ``track_id``, a prediction)


@dataclass(frozen=True, eq=False)
class Lane:
    """One 3D lane line of a frame.

    points: (P, 3) float, x, y, z in the frame's lane frame (x right, y forward, z up), metres,
    y ascending. visibility: (P,) in [0, 1]. category: OpenLane category id
    (:data:`LANE_CATEGORY_IDS`). track_id: the lane's identity across a clip's frames,
    :data:`NO_TRACK` if it has none. score: confidence, 1.0 for ground truth.
    track_id and score are keyword-only. Lanes compare by identity.
    """

    points: np.ndarray
    visibility: np.ndarray
    category: int
    track_id: int = field(default=NO_TRACK, kw_only=True)
    score: float = field(default=1.0, kw_only=True)
