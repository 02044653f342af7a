"""The ROS 2 message definitions the ros2 plugin knows, for reading and for writing.

Each definition is the `.msg` text of one type (fields and constants, comments left out), every field type spelled
with its package (``geometry_msgs/Point``, never a bare ``Point``). `schema_text(name)` gives what an MCAP ``ros2msg``
schema holds: the type's text followed by each dependency's text under a ``MSG: package/Type`` line, separated by a
line of 80 ``=`` (the layout rosbag2 and mcap-ros2-support write and read). `schema_name(name)` gives the schema name
rosbag2 writes (``sensor_msgs/msg/Image``).

Sources: the standard ROS 2 interfaces (Humble: builtin_interfaces, std_msgs, geometry_msgs, nav_msgs,
sensor_msgs, tf2_msgs, unique_identifier_msgs), radar_msgs 0.2 as released (ros-perception/radar_msgs; its
development branch adds ``sensor_properties`` to RadarScan: a reader decodes with the text stored in the file, so
either reads), and Navtech's ROS 2 driver (iasdk ``ros2/src/messages``, package ``messages``): its configuration and
FFT-data messages carry every value as a byte array, documented in `NAVTECH_BYTE_LAYOUT`.
"""

from __future__ import annotations

import re

SEPARATOR = "=" * 80

DEFINITIONS: dict[str, str] = {
    "builtin_interfaces/Time": """\
int32 sec
uint32 nanosec
""",
    "std_msgs/Header": """\
builtin_interfaces/Time stamp
string frame_id
""",
    "geometry_msgs/Point": """\
float64 x
float64 y
float64 z
""",
    "geometry_msgs/Vector3": """\
float64 x
float64 y
float64 z
""",
    "geometry_msgs/Quaternion": """\
float64 x 0
float64 y 0
float64 z 0
float64 w 1
""",
    "geometry_msgs/Pose": """\
geometry_msgs/Point position
geometry_msgs/Quaternion orientation
""",
    "geometry_msgs/PoseStamped": """\
std_msgs/Header header
geometry_msgs/Pose pose
""",
    "geometry_msgs/PoseWithCovariance": """\
geometry_msgs/Pose pose
float64[36] covariance
""",
    "geometry_msgs/Transform": """\
geometry_msgs/Vector3 translation
geometry_msgs/Quaternion rotation
""",
    "geometry_msgs/TransformStamped": """\
std_msgs/Header header
string child_frame_id
geometry_msgs/Transform transform
""",
    "geometry_msgs/Twist": """\
geometry_msgs/Vector3 linear
geometry_msgs/Vector3 angular
""",
    "geometry_msgs/TwistStamped": """\
std_msgs/Header header
geometry_msgs/Twist twist
""",
    "geometry_msgs/TwistWithCovariance": """\
geometry_msgs/Twist twist
float64[36] covariance
""",
    "nav_msgs/Odometry": """\
std_msgs/Header header
string child_frame_id
geometry_msgs/PoseWithCovariance pose
geometry_msgs/TwistWithCovariance twist
""",
    "nav_msgs/Path": """\
std_msgs/Header header
geometry_msgs/PoseStamped[] poses
""",
    "nav_msgs/MapMetaData": """\
builtin_interfaces/Time map_load_time
float32 resolution
uint32 width
uint32 height
geometry_msgs/Pose origin
""",
    "nav_msgs/OccupancyGrid": """\
std_msgs/Header header
nav_msgs/MapMetaData info
int8[] data
""",
    "sensor_msgs/Image": """\
std_msgs/Header header
uint32 height
uint32 width
string encoding
uint8 is_bigendian
uint32 step
uint8[] data
""",
    "sensor_msgs/Imu": """\
std_msgs/Header header
geometry_msgs/Quaternion orientation
float64[9] orientation_covariance
geometry_msgs/Vector3 angular_velocity
float64[9] angular_velocity_covariance
geometry_msgs/Vector3 linear_acceleration
float64[9] linear_acceleration_covariance
""",
    "sensor_msgs/NavSatStatus": """\
int8 STATUS_NO_FIX=-1
int8 STATUS_FIX=0
int8 STATUS_SBAS_FIX=1
int8 STATUS_GBAS_FIX=2
int8 status
uint16 SERVICE_GPS=1
uint16 SERVICE_GLONASS=2
uint16 SERVICE_COMPASS=4
uint16 SERVICE_GALILEO=8
uint16 service
""",
    "sensor_msgs/NavSatFix": """\
std_msgs/Header header
sensor_msgs/NavSatStatus status
float64 latitude
float64 longitude
float64 altitude
float64[9] position_covariance
uint8 COVARIANCE_TYPE_UNKNOWN=0
uint8 COVARIANCE_TYPE_APPROXIMATED=1
uint8 COVARIANCE_TYPE_DIAGONAL_KNOWN=2
uint8 COVARIANCE_TYPE_KNOWN=3
uint8 position_covariance_type
""",
    "tf2_msgs/TFMessage": """\
geometry_msgs/TransformStamped[] transforms
""",
    "unique_identifier_msgs/UUID": """\
uint8[16] uuid
""",
    "radar_msgs/RadarReturn": """\
float32 range
float32 azimuth
float32 elevation
float32 doppler_velocity
float32 amplitude
""",
    "radar_msgs/RadarScan": """\
std_msgs/Header header
radar_msgs/RadarReturn[] returns
""",
    "radar_msgs/RadarTrack": """\
uint16 NO_CLASSIFICATION=0
uint16 STATIC=1
uint16 DYNAMIC=2
unique_identifier_msgs/UUID uuid
geometry_msgs/Point position
geometry_msgs/Vector3 velocity
geometry_msgs/Vector3 acceleration
geometry_msgs/Vector3 size
uint16 classification
float32[6] position_covariance
float32[6] velocity_covariance
float32[6] acceleration_covariance
float32[6] size_covariance
""",
    "radar_msgs/RadarTracks": """\
std_msgs/Header header
radar_msgs/RadarTrack[] tracks
""",
    # Navtech's ROS 2 driver (iasdk ros2/src/messages, package "messages"), topics radar_data/configuration_data
    # and radar_data/fft_data; its B-scan publisher sends sensor_msgs/Image 8UC1 on radar_data/b_scan_image.
    "messages/RadarConfigurationMessage": """\
std_msgs/Header header
uint8[] azimuth_samples
uint8[] encoder_size
uint8[] bin_size
uint8[] range_in_bins
uint8[] expected_rotation_rate
""",
    "messages/RadarFftDataMessage": """\
std_msgs/Header header
uint8[] angle
uint8[] azimuth
uint8[] sweep_counter
uint8[] ntp_seconds
uint8[] ntp_split_seconds
uint8[] data
uint8[] data_length
""",
}

# How Navtech's driver fills the byte arrays of its two messages (iasdk ros2 colossus_publisher.cpp and
# net_conversion.cpp): integers in network order (big-endian); doubles as their 8 IEEE-754 bytes in the host's order
# (little-endian on the x86 and ARM hosts it runs on). bin_size is the SDK's Configuration::bin_size() as a double:
# metres in the SDK versions whose accessor divides the protocol's 0.1 mm units by 10000, the raw 0.1 mm count in
# those that return the uint16 (a value of 1 or more is therefore 0.1 mm units: no radar has 1 m bins).
NAVTECH_BYTE_LAYOUT: dict[str, dict[str, str]] = {
    "messages/RadarConfigurationMessage": {
        "azimuth_samples": ">u2",
        "encoder_size": ">u2",
        "bin_size": "<f8",
        "range_in_bins": ">u2",
        "expected_rotation_rate": ">u2",  # mHz (the protocol's rotation_speed)
    },
    "messages/RadarFftDataMessage": {
        "angle": "<f8",  # the driver's azimuth / azimuth_samples * 360 (not used: the encoder count is exact)
        "azimuth": ">u2",  # encoder count
        "sweep_counter": ">u2",
        "ntp_seconds": ">u4",
        "ntp_split_seconds": ">u4",  # nanoseconds
        "data": "u1",
        "data_length": ">u2",
    },
}

_PRIMITIVES = frozenset(
    "bool byte char float32 float64 int8 uint8 int16 uint16 int32 uint32 int64 uint64 string wstring".split()
)
_FIELD_TYPE = re.compile(r"^\s*([A-Za-z0-9_/]+)")


def short_name(name: str) -> str:
    """``sensor_msgs/msg/Image`` or ``sensor_msgs/Image`` -> ``sensor_msgs/Image``."""
    parts = name.split("/")
    if len(parts) == 3 and parts[1] == "msg":
        return f"{parts[0]}/{parts[2]}"
    return name


def schema_name(name: str) -> str:
    """The schema name rosbag2 writes for a type: ``sensor_msgs/Image`` -> ``sensor_msgs/msg/Image``."""
    package, _, type_name = short_name(name).partition("/")
    return f"{package}/msg/{type_name}"


def dependencies(name: str) -> list[str]:
    """Every type `name` uses, directly or not, depth first in order of appearance, each once."""
    seen: list[str] = []

    def visit(type_name: str) -> None:
        for line in DEFINITIONS[type_name].splitlines():
            match = _FIELD_TYPE.match(line)
            if match is None:
                continue
            field_type = match.group(1)
            if field_type in _PRIMITIVES or field_type in seen:
                continue
            if field_type not in DEFINITIONS:
                raise KeyError(f"{type_name} uses {field_type}, which has no definition here")
            seen.append(field_type)
            visit(field_type)

    visit(short_name(name))
    return seen


def schema_text(name: str) -> str:
    """The ``ros2msg`` schema data of a type: its text, then each dependency under ``MSG: package/Type``."""
    key = short_name(name)
    if key not in DEFINITIONS:
        raise KeyError(f"no ROS 2 definition for {name!r}; known: {', '.join(sorted(DEFINITIONS))}")
    parts = [DEFINITIONS[key].rstrip("\n")]
    for dependency in dependencies(key):
        parts.append(f"{SEPARATOR}\nMSG: {dependency}\n{DEFINITIONS[dependency].rstrip(chr(10))}")
    return "\n".join(parts) + "\n"
