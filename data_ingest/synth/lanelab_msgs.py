"""The lanelab JSON messages of a drive log: ``lanelab.Lanes3D``, ``Lanes2D`` and ``Tags``.

Their layout is fixed by DESIGN.md ("Drive-log contract"); the schemas below are the
``jsonschema`` records written with them. Times follow Foxglove's JSON convention
(``{"sec", "nsec"}``). Floats are written with ``repr`` precision, so they read back
bit-exact.
"""

from __future__ import annotations

from typing import Any, Mapping, Sequence

from data_ingest.contract import LANES2D_TYPE, LANES3D_TYPE, TAGS_TYPE
from data_ingest.synth.foxglove_json import TIME_SCHEMA
from data_ingest.synth.frame import Lane2D
from lanelab.lanes import Lane

_POINT3 = {"type": "array", "items": {"type": "number"}, "minItems": 3, "maxItems": 3}
_POINT2 = {"type": "array", "items": {"type": "number"}, "minItems": 2, "maxItems": 2}

SCHEMAS: dict[str, dict[str, Any]] = {
    LANES3D_TYPE: {
        "title": LANES3D_TYPE,
        "description": "3D lane lines; points in frame_id at timestamp",
        "type": "object",
        "properties": {
            "timestamp": TIME_SCHEMA,
            "frame_id": {"type": "string"},
            "lanes": {
                "type": "array",
                "items": {
                    "type": "object",
                    "properties": {
                        "track_id": {"type": "integer"},
                        "category": {"type": "integer", "description": "OpenLane category id"},
                        "points": {"type": "array", "items": _POINT3},
                        "visibility": {"type": "array", "items": {"type": "number", "minimum": 0, "maximum": 1}},
                        "score": {"type": "number", "description": "a predicted lane's confidence (optional)"},
                    },
                    "required": ["track_id", "category", "points", "visibility"],
                },
            },
        },
        "required": ["timestamp", "frame_id", "lanes"],
    },
    LANES2D_TYPE: {
        "title": LANES2D_TYPE,
        "description": "2D lane detections in the image of frame_id, pixel coordinates",
        "type": "object",
        "properties": {
            "timestamp": TIME_SCHEMA,
            "frame_id": {"type": "string"},
            "lanes": {
                "type": "array",
                "items": {
                    "type": "object",
                    "properties": {
                        "uv": {"type": "array", "items": _POINT2},
                        "score": {"type": "number"},
                        "category": {"type": "integer", "description": "OpenLane category id"},
                    },
                    "required": ["uv", "score", "category"],
                },
            },
        },
        "required": ["timestamp", "frame_id", "lanes"],
    },
    TAGS_TYPE: {
        "title": TAGS_TYPE,
        "description": "Scenario tags (weather, daytime, environment, curvature, ...)",
        "type": "object",
        "properties": {
            "timestamp": TIME_SCHEMA,
            "tags": {"type": "object", "additionalProperties": {"type": "string"}},
        },
        "required": ["timestamp", "tags"],
    },
}


def time_json(t_ns: int) -> dict[str, int]:
    sec, nsec = divmod(int(t_ns), 1_000_000_000)
    return {"sec": sec, "nsec": nsec}


def lanes3d(t_ns: int, frame_id: str, lanes: Sequence[Lane], scores: bool = False) -> dict[str, Any]:
    """A ``lanelab.Lanes3D`` message; each lane's points must already be in ``frame_id``.
    scores: write each lane's ``score`` (predictions; labels have none)."""
    return {
        "timestamp": time_json(t_ns),
        "frame_id": frame_id,
        "lanes": [
            {
                "track_id": int(lane.track_id),
                "category": int(lane.category),
                "points": lane.points.tolist(),
                "visibility": lane.visibility.tolist(),
                **({"score": float(lane.score)} if scores else {}),
            }
            for lane in lanes
        ],
    }


def lanes2d(t_ns: int, frame_id: str, lanes: Sequence[Lane2D]) -> dict[str, Any]:
    """A ``lanelab.Lanes2D`` message of detections in the image of camera ``frame_id``."""
    return {
        "timestamp": time_json(t_ns),
        "frame_id": frame_id,
        "lanes": [
            {"uv": lane.uv.tolist(), "score": float(lane.score), "category": int(lane.category)}
            for lane in lanes
        ],
    }


def tags(t_ns: int, values: Mapping[str, str]) -> dict[str, Any]:
    """A ``lanelab.Tags`` message."""
    return {"timestamp": time_json(t_ns), "tags": {str(k): str(v) for k, v in values.items()}}

