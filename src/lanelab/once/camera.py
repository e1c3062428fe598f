"""The camera of a ONCE-3DLanes store, and lanes between its camera frame and the lane frame.

ONCE-3DLanes labels hold lanes in the camera frame (OpenCV axes: x right, y down, z forward)
and a projection matrix, but no extrinsic. LATR's ONCE loader (JMoonr/LATR,
``data/Load_Data.py``, ``preprocess_data_from_json_once``; the same matrix in
``experiments/runner.py``, ``save_eval_result_once``) puts every frame's camera at a fixed
height of 1.5 m above the ground, pitched by 0.3 degrees, with the ground origin directly below
it (``cam_extrinsics[0:2, 3] = 0``). lanelab's ONCE stores use that camera as ``T_lane_cam``
(the values live in ``conf/once.yaml``): the lane frame's axes are DESIGN.md's (x right,
y forward, z up), its origin on the ground under the camera, as in OpenLane stores.

LATR writes its rotation as ``inv(R_vg) @ R_pitch @ R_vg @ R_gc``; that product is a rotation
about the lane frame's x axis after the OpenCV -> lane axis swap, :func:`fixed_T_lane_cam`. Its
optical axis points 0.3 degrees *up* (a point 10 m ahead lies 0.052 m above the camera's height),
as LATR's matrix has it.
"""

from __future__ import annotations

import math

import numpy as np

# Lane-frame axes (x right, y forward, z up) from OpenCV camera axes (x right, y down, z forward).
_LANE_FROM_OPENCV = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


def fixed_T_lane_cam(height: float, pitch_deg: float) -> np.ndarray:
    """T_lane_cam (4, 4): a camera ``height`` metres above the lane-frame origin, its axes the
    lane frame's turned by ``pitch_deg`` about x (positive: looking up, LATR's sign)."""
    pitch = math.radians(pitch_deg)
    c, s = math.cos(pitch), math.sin(pitch)
    T = np.eye(4)
    T[:3, :3] = np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]]) @ _LANE_FROM_OPENCV
    T[2, 3] = height
    return T


def camera_to_lane(points: np.ndarray, T_lane_cam: np.ndarray) -> np.ndarray:
    """Camera-frame points (P, 3) -> lane frame (P, 3), float64."""
    return np.asarray(points, np.float64) @ T_lane_cam[:3, :3].T + T_lane_cam[:3, 3]


def lane_to_camera(points: np.ndarray, T_lane_cam: np.ndarray) -> np.ndarray:
    """Lane-frame points (P, 3) -> camera frame (P, 3), float64 (the inverse of :func:`camera_to_lane`)."""
    return (np.asarray(points, np.float64) - T_lane_cam[:3, 3]) @ T_lane_cam[:3, :3]
