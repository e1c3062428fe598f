"""The drive-log contract (DESIGN.md, "Drive-log contract"): the topics and frames of a drive
log and the role each topic plays, shared by ``lanelab-synth``, which writes drive logs, and
``lanelab-ingest``, which reads them.

Types accepted per role; ROS 2 names with or without ``/msg/``:

=============  ===============================================  ==================================
role           ROS 2 (``ros2msg`` / ``cdr``)                    Foxglove (``protobuf`` or ``json``)
=============  ===============================================  ==================================
image          sensor_msgs/CompressedImage, sensor_msgs/Image   foxglove.CompressedImage, RawImage
occluders      the image types (a mask: non-zero where a vehicle or object hides the road)
calibration    sensor_msgs/CameraInfo                           foxglove.CameraCalibration
transforms     tf2_msgs/TFMessage                               foxglove.FrameTransform(s)
lanes, tags    —                                                lanelab.Lanes3D, lanelab.Tags (json)
lanes2d        —                                                lanelab.Lanes2D (json)
=============  ===============================================  ==================================

The topics (``topics.image``, ... :class:`TopicsConfig`) and frames (``frames.world``,
``frames.ego``: :class:`FramesConfig`) are options of both commands. Their default names
(``/camera/front/image``, ``odom``, ``base_link``, ...) live, as every default does, in
``conf/drive_log/topics.yaml``, which ``conf/synth.yaml``, ``conf/ingest.yaml`` and
``conf/predict.yaml`` include; this module types them and checks them (:func:`check_names`).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

from omegaconf import MISSING

from lanelab.config_checks import ConfigError

IMAGE, CALIBRATION, TRANSFORMS, LANES, LANES2D, TAGS = "image", "calibration", "transforms", "lanes", "lanes2d", "tags"
OCCLUDERS = "occluders"
# lanelab's own message types (JSON only; their layout is DESIGN.md's, their schemas data_ingest.synth.lanelab_msgs)
LANES3D_TYPE, LANES2D_TYPE, TAGS_TYPE = "lanelab.Lanes3D", "lanelab.Lanes2D", "lanelab.Tags"
TYPES = {
    IMAGE: ("sensor_msgs/CompressedImage", "sensor_msgs/Image", "foxglove.CompressedImage", "foxglove.RawImage"),
    CALIBRATION: ("sensor_msgs/CameraInfo", "foxglove.CameraCalibration"),
    TRANSFORMS: ("tf2_msgs/TFMessage", "foxglove.FrameTransform", "foxglove.FrameTransforms"),
    OCCLUDERS: ("sensor_msgs/CompressedImage", "sensor_msgs/Image", "foxglove.CompressedImage", "foxglove.RawImage"),
    LANES: (LANES3D_TYPE,),
    LANES2D: (LANES2D_TYPE,),
    TAGS: (TAGS_TYPE,),
}
JSON_ONLY = (LANES, LANES2D, TAGS)  # lanelab's own messages exist only as JSON


@dataclass
class TopicsConfig:
    """The topic of each role: ``tf`` and ``tf_static`` are transforms; ``lanes2d`` holds 2D
    lane detections (``lanelab.Lanes2D``) and ``occluders`` occluder masks of the images (an
    image type, non-zero where something hides the road), the auto-labeler's inputs."""

    image: str = MISSING
    calibration: str = MISSING
    tf: str = MISSING
    tf_static: str = MISSING
    lanes: str = MISSING
    lanes2d: str = MISSING
    occluders: str = MISSING
    tags: str = MISSING


@dataclass
class FramesConfig:
    """The TF frames of the ego pose, world <- ego (the camera frame comes from the images)."""

    world: str = MISSING
    ego: str = MISSING


def check_names(topics: TopicsConfig, frames: FramesConfig) -> None:
    """Raise :class:`ConfigError` naming the first empty topic or frame name."""
    for group, names in (("topics", topics), ("frames", frames)):
        for key, value in asdict(names).items():
            if not value:
                raise ConfigError(f"{group}.{key} is empty")
