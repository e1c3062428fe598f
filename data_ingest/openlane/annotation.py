"""One OpenLane annotation file -> a clip-store frame's time, calibration, pose and lanes.

The lane frame of an OpenLane store
-----------------------------------
A store made by ``lanelab-openlane`` uses as its lane frame the official evaluator's ground
frame (:func:`lanelab.openlane.ground_frame.ground_from_camera`): the lane-frame axes of
DESIGN.md (x right, y forward, z up; the vehicle's axes re-ordered), with the origin on the
vehicle frame's ground plane (z = 0) **directly below the camera**, not below the vehicle
origin (``base_link``) as in stores ingested from drive logs: the evaluator drops the
camera's forward and lateral offset (its ``cam_extrinsics[0:2, 3] = 0``). Keeping its frame
means that

- ``T_lane_cam`` is the evaluator's conversion of the extrinsic and the lanes its conversion
  of the ground truth, bit for bit (then rounded to float32 by the store);
- lanes predicted in the lane frame *are* OpenLane prediction ``xyz``: they are written
  without conversion and score as the official evaluator scores them;
- y ranges (3-103 m) are measured from the camera, as in every published OpenLane number.

Lanes, K and T_lane_cam project as in any store: ``uv ~ K · inv(T_lane_cam) · p``. The ego
pose is ``T_world_lane = pose · T_vehicle_lane`` (:func:`vehicle_from_lane`), so the motion
between two frames is the vehicle's, exactly. The store's lanes run near to far (y
ascending); the evaluator reads a ground-truth lane as stored, so a lane stored far to near
that ends before y = 3 m is dropped there (a quirk of its range test) but kept here.

OpenLane's conventions (OpenDriveLab/OpenLane, ``anno_criterion/Lane/README.md``,
``data/Coordinate_Sys.md``): ``extrinsic`` (4, 4) maps the Waymo camera axes (x forward, y
left, z up) into the vehicle frame (x forward, y left, z up); ``intrinsic`` (3, 3) is the
pinhole matrix of the usual camera axes (x right, y down, z forward); ``pose`` (4, 4, from
v1.2 on) is the vehicle frame in the segment's world frame; each lane has ``xyz`` (3, N) in
the Waymo camera axes, ``visibility`` (N,), ``category``, and ``track_id`` (unique in its
segment; not every lane has one). A file is named by the Waymo timestamp in microseconds
followed by "00": 18 digits in units of 10 ns.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from lanelab.data_paths import path_problem
from lanelab.geometry.frames import T_BASE_LANE
from lanelab.geometry.intrinsics import pinhole_problem
from lanelab.json_files import LaneFileError, numeric_array, require, require_list
from lanelab.lanes import NO_TRACK, Lane
from lanelab.openlane.ground_frame import camera_lane_to_ground, ground_from_camera
from lanelab.openlane.lane_order import near_to_far
from lanelab.openlane.read import read_camera_header

NS_PER_NAME_UNIT = 10  # file names count 10 ns units (microseconds followed by "00")


@dataclass(frozen=True)
class Annotation:
    """One OpenLane frame in lanelab's terms.

    K: (3, 3). T_lane_cam: (4, 4), OpenCV camera -> lane frame. T_world_lane: (4, 4) ego
    pose, None when the file has no ``pose``. lanes: in the lane frame, y ascending, lanes
    with fewer than two points left out (no line; the evaluator drops them too). far_to_near:
    the indices of the lanes the file lists far to near (:mod:`lanelab.openlane.lane_order`).
    """

    file_path: str
    timestamp_ns: int
    K: np.ndarray
    T_lane_cam: np.ndarray
    T_world_lane: np.ndarray | None
    lanes: list[Lane]
    far_to_near: tuple[int, ...] = ()


def timestamp_ns(path: str | os.PathLike[str]) -> int:
    """The time of an annotation file from its name: '155840113564752100.json' -> ns."""
    stem = Path(path).stem
    if not stem.isdigit():
        raise LaneFileError(path, "the file name is not an OpenLane timestamp (digits only)")
    return int(stem) * NS_PER_NAME_UNIT


def vehicle_from_lane(extrinsic: np.ndarray) -> np.ndarray:
    """T_vehicle_lane (4, 4): the lane frame of an extrinsic (4, 4) in the vehicle frame.

    The vehicle frame has base_link's axes (x forward, y left, z up), so the rotation is
    T_base_lane's; the origin is the camera's (x, y) on the vehicle's ground plane, so that
    ``T_vehicle_lane @ ground_from_camera(E)`` is ``E`` with OpenCV camera axes.
    """
    T = T_BASE_LANE.numpy().copy()
    T[0:2, 3] = extrinsic[0:2, 3]
    return T


def read_annotation(path: str | os.PathLike[str]) -> Annotation:
    """Read and validate one annotation file; LaneFileError names the file and the fault."""
    data, file_path, K, extrinsic = read_camera_header(path)
    problem = pinhole_problem(K)
    if problem:
        raise LaneFileError(path, f"'intrinsic' is not a pinhole matrix: {problem}")
    problem = path_problem(file_path)  # the image is read there, and predictions are written there
    if problem:
        raise LaneFileError(path, f"'file_path' {file_path!r} {problem}: refused")
    T_lane_cam = ground_from_camera(extrinsic)
    T_world_lane = None
    if "pose" in data:
        pose = numeric_array(data["pose"], (4, 4), "'pose'", path)
        T_world_lane = pose @ vehicle_from_lane(extrinsic)
    lanes = [
        _lane(lane, T_lane_cam, path, f"lane_lines[{i}]")
        for i, lane in enumerate(require_list(data, "lane_lines", path))
    ]
    kept = [(lane, far_to_near) for lane, far_to_near in lanes if len(lane.points) >= 2]
    return Annotation(
        file_path=file_path,
        timestamp_ns=timestamp_ns(path),
        K=K,
        T_lane_cam=T_lane_cam,
        T_world_lane=T_world_lane,
        lanes=[lane for lane, _ in kept],
        far_to_near=tuple(i for i, (_, far_to_near) in enumerate(kept) if far_to_near),
    )


def _lane(lane: Any, T_lane_cam: np.ndarray, path: str | os.PathLike[str], where: str) -> tuple[Lane, bool]:
    """The lane near to far, and whether the file lists it far to near."""
    xyz = numeric_array(require(lane, "xyz", path, where), (3, None), f"{where}.xyz", path)
    visibility = numeric_array(require(lane, "visibility", path, where), (None,), f"{where}.visibility", path)
    if len(visibility) != xyz.shape[1]:
        raise LaneFileError(path, f"{where}: {len(visibility)} visibility values for {xyz.shape[1]} points")
    points = camera_lane_to_ground(xyz, T_lane_cam)
    order, far_to_near = near_to_far(points)  # the store's lanes run near to far
    return Lane(
        track_id=_integer(lane.get("track_id", NO_TRACK), f"{where}.track_id", path),
        category=_integer(require(lane, "category", path, where), f"{where}.category", path),
        points=points[order].astype(np.float32),
        visibility=visibility[order].astype(np.float32),
    ), far_to_near


def _integer(value: Any, what: str, path: str | os.PathLike[str]) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not (
        math.isfinite(value) and value == int(value)
    ):
        raise LaneFileError(path, f"{what} must be an integer, got {value!r}")
    return int(value)
