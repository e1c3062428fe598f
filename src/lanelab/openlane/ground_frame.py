"""OpenLane's camera axes and the official evaluator's ground frame, both ways.

OpenLane stores a lane as ``xyz`` (3, N) in the Waymo camera axes (x forward, y left, z up)
with an ``extrinsic`` (4, 4) that maps those axes into the vehicle frame (x forward, y left,
z up). The official evaluator (OpenDriveLab/OpenLane,
``eval/LANE_evaluation/lane3d/eval_3D_lane.py``) scores lanes in its ground frame, whose axes
are lanelab's lane-frame axes (x right, y forward, z up), on the ground under the camera.

- Reading ground truth: :func:`ground_from_camera` and :func:`camera_lane_to_ground`, the
  evaluator's own conversion.
- Writing lanes of the lane frame as ground truth: :func:`extrinsic_above_origin` and
  :func:`lane_to_camera`, for the camera moved above the lane-frame origin, so that the
  evaluator reads the lanes back in the lane frame.

Every axis change is a signed permutation: products with it only move and negate entries,
exactly.
"""

from __future__ import annotations

import numpy as np

# Waymo camera axes (x forward, y left, z up) from OpenCV camera axes (x right, y down,
# z forward); its transpose maps back.
_WAYMO_FROM_OPENCV = np.array(
    [[0.0, 0.0, 1.0, 0.0], [-1.0, 0.0, 0.0, 0.0], [0.0, -1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]]
)
_OPENCV_FROM_WAYMO = _WAYMO_FROM_OPENCV.T.copy()
# Vehicle axes (x forward, y left, z up) from ground axes (x right, y forward, z up).
_VEHICLE_FROM_GROUND = np.array([[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
# Ground-style camera axes (x right, y forward, z up) from OpenCV camera axes.
_GROUND_FROM_OPENCV = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


def ground_from_camera(extrinsic: np.ndarray) -> np.ndarray:
    """The official evaluator's ground-from-camera transform (4, 4) for a GT extrinsic (4, 4).

    The extrinsic maps Waymo camera axes into the vehicle frame. The evaluator re-expresses
    its rotation to map OpenCV camera axes into ground axes (x right, y forward, z up), and
    keeps only the camera height of its translation: the ground frame lies under the camera,
    not under the vehicle origin (official ``cam_extrinsics[0:2, 3] = 0``).
    """
    T = np.array(extrinsic, dtype=np.float64)
    R = T[:3, :3]
    T[:3, :3] = _VEHICLE_FROM_GROUND.T @ R @ _VEHICLE_FROM_GROUND @ _GROUND_FROM_OPENCV
    T[0:2, 3] = 0.0
    return T


def camera_lane_to_ground(xyz: np.ndarray, ground_T_camera: np.ndarray) -> np.ndarray:
    """Lane points (3, N) in Waymo camera axes -> (N, 3) in the ground frame.

    Computed as the official ``E @ (inv(C) @ [xyz; 1])`` with the same (4, 4) @ (4, N)
    products, so that the floating-point result is the same.
    """
    homogeneous = np.vstack([xyz, np.ones((1, xyz.shape[1]))])
    return np.matmul(ground_T_camera, np.matmul(_OPENCV_FROM_WAYMO, homogeneous))[0:3, :].T


def extrinsic_above_origin(T_lane_cam: np.ndarray) -> np.ndarray:
    """The OpenLane ``extrinsic`` (4, 4) of a camera of extrinsic T_lane_cam (4, 4) moved
    above the lane-frame origin: its rotation and height kept, its x and y offsets dropped
    (the evaluator drops them too, see :func:`ground_from_camera`)."""
    extrinsic = np.eye(4)
    extrinsic[:3, :3] = _VEHICLE_FROM_GROUND @ T_lane_cam[:3, :3] @ _WAYMO_FROM_OPENCV[:3, :3].T
    extrinsic[2, 3] = T_lane_cam[2, 3]
    return extrinsic


def lane_to_camera(points: np.ndarray, T_lane_cam: np.ndarray) -> np.ndarray:
    """Lane-frame points (P, 3) -> (3, P) in the Waymo camera axes of the camera of extrinsic
    T_lane_cam (4, 4) moved above the lane-frame origin (:func:`extrinsic_above_origin`)."""
    R, height = T_lane_cam[:3, :3], T_lane_cam[2, 3]
    camera = R.T @ (points - [0.0, 0.0, height]).T  # (3, P), OpenCV axes
    return _WAYMO_FROM_OPENCV[:3, :3] @ camera
