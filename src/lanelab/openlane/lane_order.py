"""The order of a lane's points: OpenLane files list some lanes far to near, a clip store near
to far (DESIGN.md: y ascending).

The order is not cosmetic: the official evaluator reads a lane's first and last points as
stored to decide whether it lies in range (:func:`lanelab.metrics.lane_sampling.overlaps_y_range`),
so the same points scored in the other order can count differently. A store made by
``lanelab-openlane`` therefore tags each frame whose file lists lanes far to near with their
indices (:func:`near_to_far`, :data:`FAR_TO_NEAR_TAG`, :func:`far_to_near_tag`), and ground truth exported from the
store lists them as the source did again (:func:`source_order`). Stores made by ``lanelab-once`` record the order of ONCE labels the
same way. A lane whose y is not monotonic
in its file cannot be restored this way: the store keeps its points sorted by y.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from lanelab.lanes import Lane

FAR_TO_NEAR_TAG = "openlane.far_to_near"  # comma-separated indices of a frame's lanes listed far to near


def near_to_far(points: np.ndarray) -> tuple[np.ndarray, bool]:
    """The order (P,) that sorts lane-frame points (P, 3) by y (stable), and whether the source
    lists them far to near (its first point farther than its last)."""
    return np.argsort(points[:, 1], kind="stable"), len(points) >= 2 and bool(points[0, 1] > points[-1, 1])


def far_to_near_tag(indices: Sequence[int]) -> dict[str, str]:
    """The frame tag that records which of its lanes (indices in the store's order) the source
    listed far to near; no tag when none was."""
    return {FAR_TO_NEAR_TAG: ",".join(str(i) for i in indices)} if indices else {}


def source_order(lanes: Sequence[Lane], tags: Mapping[str, str]) -> list[Lane]:
    """A store frame's lanes (points near to far) with those its tags name listed far to near again
    (against :class:`~lanelab.lanes.Lane`'s y-ascending rule, as the files to be written want them)."""
    reversed_lanes = {int(i) for i in tags.get(FAR_TO_NEAR_TAG, "").split(",") if i}
    return [
        Lane(lane.points[::-1], lane.visibility[::-1], lane.category, track_id=lane.track_id, score=lane.score)
        if i in reversed_lanes else lane
        for i, lane in enumerate(lanes)
    ]  # fmt: skip
