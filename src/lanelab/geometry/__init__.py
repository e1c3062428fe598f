"""Geometry core: rigid transforms, frame conventions, pinhole camera, Catmull-Rom curves and the
lanes of control points in either representation (``curves``).

Everything is torch, batched over leading dimensions and float32/float64 safe.
Conventions are those of DESIGN.md, "Coordinate frames and units".
"""

from lanelab.geometry.camera import (
    backproject,
    backproject_to_lane,
    cell_centres,
    image_extent,
    in_image,
    intersect_ground,
    pixel_rays,
    project,
    project_lane_points,
)
from lanelab.geometry.catmull_rom import (
    CR_MATRIX,
    control_point_y,
    cr_matrix,
    curve_arguments,
    evaluate,
    fit_control_points,
    sampling_matrix,
)
from lanelab.geometry.curves import REPRESENTATIONS, LaneCurves, interpolate_in_y, lane_bases, sample_lanes
from lanelab.geometry.frames import (
    T_BASE_LANE,
    T_LANE_BASE,
    base_lane_transform,
    base_link_to_lane,
    extrinsic_base_to_lane,
    lane_base_transform,
    lane_to_base_link,
    pose_base_to_lane,
)
from lanelab.geometry.transforms import (
    compose,
    euler_to_rotation,
    interpolate_pose,
    invert,
    make_transform,
    quaternion_to_rotation,
    rotation_to_quaternion,
    slerp,
    transform_points,
)

__all__ = [
    "CR_MATRIX",
    "REPRESENTATIONS",
    "T_BASE_LANE",
    "T_LANE_BASE",
    "LaneCurves",
    "backproject",
    "backproject_to_lane",
    "cell_centres",
    "image_extent",
    "base_lane_transform",
    "base_link_to_lane",
    "compose",
    "control_point_y",
    "cr_matrix",
    "curve_arguments",
    "euler_to_rotation",
    "evaluate",
    "extrinsic_base_to_lane",
    "fit_control_points",
    "in_image",
    "interpolate_in_y",
    "interpolate_pose",
    "intersect_ground",
    "invert",
    "lane_base_transform",
    "lane_bases",
    "lane_to_base_link",
    "make_transform",
    "pixel_rays",
    "pose_base_to_lane",
    "project",
    "project_lane_points",
    "quaternion_to_rotation",
    "rotation_to_quaternion",
    "sample_lanes",
    "sampling_matrix",
    "slerp",
    "transform_points",
]
