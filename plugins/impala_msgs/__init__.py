"""impala_msgs: the domain messages the radar-chain plugins share (as ROS keeps sensor_msgs apart from its core).

Rotating FMCW radar beams and their acquisition settings, scans and detections, odometer and
gyro readings, states and existence of tracked objects. The engine knows none of them: this
package declares them in the ``impala_flow.messages`` entry point group (``TYPES``, and
``LEGACY``: older versions read from recordings and upgraded), so every installed registry and
recording reader knows them; plugins import them from here::

    from impala_msgs import RadarBeam, RadarConfig

Schema names (``impala.RadarBeam``...) are what recordings store; they do not depend on where
the classes live.
"""

from .sensors import (
    CHIRP_DOWN,
    CHIRP_UP,
    SPEED_OF_LIGHT_MPS,
    ObjectStates,
    RadarBeam,
    RadarBeamV1,
    RadarConfig,
    RadarDetections,
    RadarScan,
    Speed,
    TrackExistence,
    YawRate,
    upgrade_radar_beam_v1,
)

#: the message types of this package (registered by the engine when installed)
TYPES: tuple[type, ...] = (
    RadarConfig, RadarBeam, RadarScan, RadarDetections, Speed, YawRate, ObjectStates, TrackExistence,
)

#: older versions, read from recordings and upgraded: (old type, upgrade function)
LEGACY: tuple[tuple[type, object], ...] = ((RadarBeamV1, upgrade_radar_beam_v1),)

__all__ = [
    "RadarConfig", "RadarBeam", "RadarScan", "RadarDetections", "Speed", "YawRate", "ObjectStates",
    "TrackExistence", "SPEED_OF_LIGHT_MPS", "CHIRP_UP", "CHIRP_DOWN", "RadarBeamV1", "upgrade_radar_beam_v1",
    "TYPES", "LEGACY",
]
