"""Ego poses from ONCE's per-sequence annotations (the release's ``data/<sequence>/<sequence>.json``).

That file holds ``calib.cam01.cam_to_velo`` (4, 4), the front camera in the LiDAR frame, and
``frames``, each with ``frame_id`` (the stamp, as the label's file name) and ``pose``: the LiDAR
frame in the sequence's world frame, as ONCE's devkit reads it: 7 numbers, a quaternion
``[qx, qy, qz, qw]`` then a translation ``[tx, ty, tz]`` (a 4 x 4 matrix is accepted too). With the
store's fixed camera, ``T_world_lane = pose @ cam_to_velo @ inv(T_lane_cam)``: the motion between
two frames is the camera's, exactly.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from lanelab.json_files import LaneFileError, load_json_object, numeric_array, require, require_list

CAMERA = "cam01"


def sequence_file(poses: str | os.PathLike[str], sequence: str) -> Path:
    """Where a sequence's annotations lie under ``poses``: ``<sequence>/<sequence>.json`` (the
    release's data folder) or ``<sequence>.json``; the first when neither is there."""
    nested = Path(poses) / sequence / f"{sequence}.json"
    flat = Path(poses) / f"{sequence}.json"
    return flat if not nested.is_file() and flat.is_file() else nested


def read_world_from_camera(path: str | os.PathLike[str]) -> dict[str, np.ndarray]:
    """frame_id -> T_world_cam (4, 4) of the front camera, from a sequence annotation file;
    LaneFileError names the file and the fault."""
    data = load_json_object(path)
    calib = require(require(data, "calib", path), CAMERA, path, "'calib'")
    lidar_from_camera = numeric_array(require(calib, "cam_to_velo", path, f"'calib.{CAMERA}'"), (4, 4),
                                      f"'calib.{CAMERA}.cam_to_velo'", path)  # fmt: skip
    poses = {}
    for i, frame in enumerate(require_list(data, "frames", path)):
        where = f"frames[{i}]"
        frame_id = str(require(frame, "frame_id", path, where))
        poses[frame_id] = _pose_matrix(require(frame, "pose", path, where), f"{where}.pose", path) @ lidar_from_camera
    for frame_id, pose in poses.items():
        if not np.isfinite(pose).all():
            raise LaneFileError(path, f"the pose of frame {frame_id} holds NaN or inf")
    return poses


def _pose_matrix(value: object, what: str, path: str | os.PathLike[str]) -> np.ndarray:
    """A ONCE pose: [qx, qy, qz, qw, tx, ty, tz] or (4, 4) -> (4, 4)."""
    if isinstance(value, list) and len(value) == 4:  # a matrix, row by row
        return numeric_array(value, (4, 4), what, path)
    pose = numeric_array(value, (7,), what, path)
    if not np.isfinite(pose).all() or np.linalg.norm(pose[:4]) == 0:
        raise LaneFileError(path, f"{what} is not a rotation quaternion and translation: {pose.tolist()}")
    T = np.eye(4)
    T[:3, :3] = Rotation.from_quat(pose[:4]).as_matrix()
    T[:3, 3] = pose[4:]
    return T
