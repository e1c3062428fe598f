"""ROS 2 message definitions (``ros2msg`` schema texts) of the sensor messages in a drive log.

An MCAP ``ros2msg`` schema is the type's own definition followed by the definition of
every type nested in it, each after a ``====`` separator line and a ``MSG: pkg/Type`` line,
as rosbag2 writes them. Only the fields are kept here; the comments and constants of the
upstream ``.msg`` files carry no data.
"""

from __future__ import annotations

COMPRESSED_IMAGE = "sensor_msgs/msg/CompressedImage"
IMAGE = "sensor_msgs/msg/Image"
CAMERA_INFO = "sensor_msgs/msg/CameraInfo"
TF_MESSAGE = "tf2_msgs/msg/TFMessage"

SEPARATOR = "=" * 80

# Fields of each type as in ROS 2 (Humble and later), keyed by "pkg/Type".
_FIELDS: dict[str, str] = {
    "builtin_interfaces/Time": """
int32 sec
uint32 nanosec""",
    "std_msgs/Header": """
builtin_interfaces/Time stamp
string frame_id""",
    "geometry_msgs/Vector3": """
float64 x
float64 y
float64 z""",
    "geometry_msgs/Quaternion": """
float64 x 0
float64 y 0
float64 z 0
float64 w 1""",
    "geometry_msgs/Transform": """
geometry_msgs/Vector3 translation
geometry_msgs/Quaternion rotation""",
    "geometry_msgs/TransformStamped": """
std_msgs/Header header
string child_frame_id
geometry_msgs/Transform transform""",
    "tf2_msgs/TFMessage": """
geometry_msgs/TransformStamped[] transforms""",
    "sensor_msgs/CompressedImage": """
std_msgs/Header header
string format
uint8[] data""",
    "sensor_msgs/Image": """
std_msgs/Header header
uint32 height
uint32 width
string encoding
uint8 is_bigendian
uint32 step
uint8[] data""",
    "sensor_msgs/RegionOfInterest": """
uint32 x_offset
uint32 y_offset
uint32 height
uint32 width
bool do_rectify""",
    "sensor_msgs/CameraInfo": """
std_msgs/Header header
uint32 height
uint32 width
string distortion_model
float64[] d
float64[9] k
float64[9] r
float64[12] p
uint32 binning_x
uint32 binning_y
sensor_msgs/RegionOfInterest roi""",
}


def _nested_types(short_name: str, found: list[str]) -> list[str]:
    """Every "pkg/Type" used by ``short_name``'s fields, depth first, each once."""
    for line in _FIELDS[short_name].strip().splitlines():
        field_type = line.split()[0].split("[")[0]  # drop array bounds: "float64[9]" -> "float64"
        if "/" in field_type and field_type not in found:
            found.append(field_type)
            _nested_types(field_type, found)
    return found


def msgdef(datatype: str) -> str:
    """The full schema text of ``datatype`` ("pkg/msg/Type"), nested definitions included."""
    package, _, name = datatype.split("/")
    short_name = f"{package}/{name}"
    parts = [_FIELDS[short_name].strip()]
    parts += [f"MSG: {nested}\n{_FIELDS[nested].strip()}" for nested in _nested_types(short_name, [])]
    return f"\n{SEPARATOR}\n".join(parts) + "\n"
