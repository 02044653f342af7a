"""Mirrors of messages in Foxglove's well-known protobuf schemas (registered by the view plugin
through ``registry.add_mirror``; the engine's writer knows no Foxglove schema).

A recording opens in Foxglove as it is: next to the exact ``impala-flow-bin`` channel
``slam/pose``, the writer adds the channel ``/foxglove/slam/pose`` (see
:func:`foxglove_topic`) carrying the same samples as ``foxglove.PoseInFrame`` (schema
encoding ``protobuf``, schema data = the FileDescriptorSet of ``foxglove-schemas-protobuf``).

=================== ========================= ==========================================
impala type         Foxglove schema           notes
=================== ========================= ==========================================
Pose2D              foxglove.PoseInFrame      yaw -> quaternion about z
Trajectory2D        foxglove.PosesInFrame     one pose per row of ``xyt``
Grid                foxglove.Grid             corner = cell (0, 0) centre - cell_m / 2
Points2D            foxglove.PointCloud       fields x, y, z (= 0), value (float32)
ObjectStates        foxglove.SceneUpdate      one entity per object (id = its id): a car-sized
                                              box, a label "id N  V m/s", a velocity arrow
                                              of length V x 1 s; lifetime 0.5 s
RadarDetections     foxglove.PointCloud       frame ``radar``: x = r cos(az), y = r sin(az),
                                              z = 0, range_m, radial_speed_mps, amplitude,
                                              score, beam (float32)
RadarScan           foxglove.RawImage         ``32FC1``, one row per beam, one column per
                                              range bin, 10 log10(power) (dB); frame ``radar``
=================== ========================= ==========================================

Every other type (speeds, yaw rates, twists, any plugin's message, plain numbers) is
mirrored as JSON with a JSON Schema generated from its dataclass
(:func:`impala_flow.io.json_schema`), so every stream of a recording has a channel generic
MCAP tools and Foxglove's Plot panel decode. The mirror channels carry the metadata
``impala_flow.mirror_of = <topic>`` (:data:`impala_flow.io.MIRROR_KEY`); readers of impala
types skip them. The frame tree (the recorder's pose topics and the radar mount) is written as
``foxglove.FrameTransforms`` on ``/tf`` (:func:`frame_transforms`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
from foxglove_schemas_protobuf.ArrowPrimitive_pb2 import ArrowPrimitive
from foxglove_schemas_protobuf.Color_pb2 import Color
from foxglove_schemas_protobuf.CubePrimitive_pb2 import CubePrimitive
from foxglove_schemas_protobuf.FrameTransform_pb2 import FrameTransform
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from foxglove_schemas_protobuf.Grid_pb2 import Grid as FxGrid
from foxglove_schemas_protobuf.PackedElementField_pb2 import PackedElementField
from foxglove_schemas_protobuf.PointCloud_pb2 import PointCloud
from foxglove_schemas_protobuf.Pose_pb2 import Pose
from foxglove_schemas_protobuf.PoseInFrame_pb2 import PoseInFrame
from foxglove_schemas_protobuf.PosesInFrame_pb2 import PosesInFrame
from foxglove_schemas_protobuf.Quaternion_pb2 import Quaternion
from foxglove_schemas_protobuf.RawImage_pb2 import RawImage
from foxglove_schemas_protobuf.SceneEntity_pb2 import SceneEntity
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from foxglove_schemas_protobuf.TextPrimitive_pb2 import TextPrimitive
from foxglove_schemas_protobuf.Vector2_pb2 import Vector2
from foxglove_schemas_protobuf.Vector3_pb2 import Vector3
from google.protobuf.descriptor import FileDescriptor
from google.protobuf.descriptor_pb2 import FileDescriptorSet
from google.protobuf.duration_pb2 import Duration
from google.protobuf.timestamp_pb2 import Timestamp

import impala_msgs
from impala_flow import msgs
from impala_flow.io import Mirror, encode_json, json_schema

__all__ = ["mirror_for", "json_mirror", "tf_mirror", "foxglove_topic", "file_descriptor_set",
           "FOXGLOVE_PREFIX", "TF_TOPIC", "frame_transforms"]

FOXGLOVE_PREFIX = "/foxglove/"


def foxglove_topic(topic: str) -> str:
    """Topic of the Foxglove mirror of ``topic`` (``slam/pose`` -> ``/foxglove/slam/pose``)."""
    return FOXGLOVE_PREFIX + topic.lstrip("/")


def file_descriptor_set(message_class: Any) -> bytes:
    """Serialized FileDescriptorSet of a protobuf message class and all its dependencies."""
    fds = FileDescriptorSet()
    seen: set[str] = set()

    def add(fd: FileDescriptor) -> None:
        if fd.name in seen:
            return
        seen.add(fd.name)
        for dep in fd.dependencies:
            add(dep)
        fd.CopyToProto(fds.file.add())

    add(message_class.DESCRIPTOR.file)
    return fds.SerializeToString()


def _stamp(t_ns: int) -> Timestamp:
    s, ns = divmod(int(t_ns), 1_000_000_000)
    return Timestamp(seconds=s, nanos=ns)


def _pose(x: float, y: float, theta: float) -> Pose:
    h = 0.5 * float(theta)
    return Pose(position=Vector3(x=float(x), y=float(y), z=0.0),
                orientation=Quaternion(x=0.0, y=0.0, z=math.sin(h), w=math.cos(h)))


def _pose2d(p: msgs.Pose2D, t_ns: int) -> bytes:
    return PoseInFrame(timestamp=_stamp(t_ns), frame_id=p.frame,
                       pose=_pose(p.x_m, p.y_m, p.theta_rad)).SerializeToString()


def _trajectory(tr: msgs.Trajectory2D, t_ns: int) -> bytes:
    xyt = np.asarray(tr.xyt, dtype=np.float64).reshape(-1, 3)
    return PosesInFrame(timestamp=_stamp(t_ns), frame_id=tr.frame,
                        poses=[_pose(*row) for row in xyt.tolist()]).SerializeToString()


_NUMERIC = {"u1": PackedElementField.UINT8, "i1": PackedElementField.INT8,
            "u2": PackedElementField.UINT16, "i2": PackedElementField.INT16,
            "u4": PackedElementField.UINT32, "i4": PackedElementField.INT32,
            "f4": PackedElementField.FLOAT32, "f8": PackedElementField.FLOAT64}


def _grid_cells(data: np.ndarray) -> np.ndarray:
    """Little-endian cells of a type Foxglove knows (bool -> u1, complex -> |.|, 64-bit -> f8)."""
    a = np.asarray(data)
    if a.dtype.kind == "b":
        a = a.astype(np.uint8)
    elif a.dtype.kind == "c":
        a = np.abs(a).astype(np.float32)
    key = f"{a.dtype.kind}{a.dtype.itemsize}"
    if key not in _NUMERIC:
        a, key = a.astype(np.float64), "f8"
    return np.ascontiguousarray(a, dtype=a.dtype.newbyteorder("<")), key


def _grid(g: msgs.Grid, t_ns: int) -> bytes:
    cells, key = _grid_cells(g.data)
    if cells.ndim == 2:
        cells = cells[:, :, None]
    rows, cols, n_ch = cells.shape
    size = cells.dtype.itemsize
    names = ["value"] if n_ch == 1 else [f"c{i}" for i in range(n_ch)]
    half = 0.5 * g.cell_m
    return FxGrid(
        timestamp=_stamp(t_ns), frame_id=g.frame,
        pose=_pose(g.origin_x_m - half, g.origin_y_m - half, 0.0),
        column_count=cols, cell_size=Vector2(x=g.cell_m, y=g.cell_m),
        row_stride=cols * n_ch * size, cell_stride=n_ch * size,
        fields=[PackedElementField(name=n, offset=i * size, type=_NUMERIC[key])
                for i, n in enumerate(names)],
        data=cells.tobytes(),
    ).SerializeToString()


def _cloud(frame: str, t_ns: int, columns: dict[str, np.ndarray]) -> bytes:
    n = len(next(iter(columns.values())))
    packed = np.empty((n, len(columns)), dtype="<f4")
    for i, col in enumerate(columns.values()):
        packed[:, i] = col
    return PointCloud(
        timestamp=_stamp(t_ns), frame_id=frame, pose=_pose(0.0, 0.0, 0.0),
        point_stride=4 * len(columns),
        fields=[PackedElementField(name=k, offset=4 * i, type=PackedElementField.FLOAT32)
                for i, k in enumerate(columns)],
        data=packed.tobytes(),
    ).SerializeToString()


def _points(p: msgs.Points2D, t_ns: int) -> bytes:
    xy = np.asarray(p.xy_m, dtype=np.float64).reshape(-1, 2)
    value = np.asarray(p.value, dtype=np.float64).reshape(-1)
    if len(value) != len(xy):
        value = np.zeros(len(xy))
    return _cloud(p.frame, t_ns, {"x": xy[:, 0], "y": xy[:, 1], "z": np.zeros(len(xy)),
                                  "value": value})


#: what an object looks like in the 3D panel (a car: tracker output and movers' truth)
_BOX_M = (4.5, 1.8, 1.5)
_OBJECT_COLOR = Color(r=1.0, g=0.55, b=0.1, a=0.8)
_OBJECT_LIFETIME = Duration(seconds=0, nanos=500_000_000)


def _objects(o: impala_msgs.ObjectStates, t_ns: int) -> bytes:
    xy = np.asarray(o.xy_m, dtype=np.float64).reshape(-1, 2)
    v = np.asarray(o.v_xy_mps, dtype=np.float64).reshape(-1, 2)
    ids = np.asarray(o.ids).reshape(-1)
    if len(v) != len(xy):
        v = np.zeros_like(xy)
    if len(ids) != len(xy):
        ids = np.arange(len(xy))
    stamp = _stamp(t_ns)
    entities = []
    for (x, y), (vx, vy), oid in zip(xy.tolist(), v.tolist(), ids.tolist(), strict=True):
        speed, heading = math.hypot(vx, vy), math.atan2(vy, vx)
        pose = _pose(x, y, heading)
        pose.position.z = 0.5 * _BOX_M[2]
        label = _pose(x, y, 0.0)
        label.position.z = _BOX_M[2] + 0.5
        arrow = _pose(x, y, heading)
        arrow.position.z = _BOX_M[2]
        entities.append(SceneEntity(
            timestamp=stamp, frame_id=o.frame, id=str(oid), lifetime=_OBJECT_LIFETIME,
            cubes=[CubePrimitive(pose=pose, size=Vector3(x=_BOX_M[0], y=_BOX_M[1], z=_BOX_M[2]),
                                 color=_OBJECT_COLOR)],
            texts=[TextPrimitive(pose=label, billboard=True, font_size=14.0, scale_invariant=True,
                                 color=Color(r=1.0, g=1.0, b=1.0, a=1.0), text=f"id {oid}  {speed:.1f} m/s")],
            arrows=[ArrowPrimitive(pose=arrow, shaft_length=max(speed, 1e-3), shaft_diameter=0.15,
                                   head_length=0.6, head_diameter=0.4, color=_OBJECT_COLOR)] if speed > 0 else [],
            metadata=[]))
    return SceneUpdate(entities=entities).SerializeToString()


def _detections(d: impala_msgs.RadarDetections, t_ns: int) -> bytes:
    r = np.asarray(d.range_m, dtype=np.float64).reshape(-1)
    az = np.asarray(d.azimuth_rad, dtype=np.float64).reshape(-1)
    n = len(r)

    def col(a: np.ndarray) -> np.ndarray:
        a = np.asarray(a, dtype=np.float64).reshape(-1)
        return a if len(a) == n else np.full(n, np.nan)

    return _cloud("radar", t_ns, {"x": r * np.cos(az), "y": r * np.sin(az), "z": np.zeros(n),
                                  "range_m": r, "radial_speed_mps": col(d.radial_speed_mps),
                                  "amplitude": col(d.amplitude), "score": col(d.score),
                                  "beam": col(d.beam)})


def _scan(sc: impala_msgs.RadarScan, t_ns: int) -> bytes:
    p = np.asarray(sc.power, dtype=np.float64)
    if p.ndim != 2:
        p = p.reshape(len(np.asarray(sc.azimuth_rad)), -1) if p.size else np.zeros((0, 0))
    db = 10.0 * np.log10(np.maximum(p, np.finfo(np.float64).tiny))  # zero power: -3077 dB, not -inf
    img = np.ascontiguousarray(db, dtype="<f4")
    rows, cols = img.shape
    return RawImage(timestamp=_stamp(t_ns), frame_id="radar", width=cols, height=rows,
                    encoding="32FC1", step=4 * cols, data=img.tobytes()).SerializeToString()


_TABLE: dict[type, tuple[Any, Callable[[Any, int], bytes]]] = {
    msgs.Pose2D: (PoseInFrame, _pose2d),
    msgs.Trajectory2D: (PosesInFrame, _trajectory),
    msgs.Grid: (FxGrid, _grid),
    msgs.Points2D: (PointCloud, _points),
    impala_msgs.ObjectStates: (SceneUpdate, _objects),
    impala_msgs.RadarDetections: (PointCloud, _detections),
    impala_msgs.RadarScan: (RawImage, _scan),
}
_cache: dict[tuple[type, bool], Mirror | None] = {}


def mirror_for(t: type, json_views: bool = False) -> Mirror | None:
    """The Foxglove mirror of type ``t``: its Foxglove schema (table above), else, with
    ``json_views``, its JSON view (:func:`impala_flow.io.json_schema`); None for ``None``."""
    key = (t, json_views)
    if key in _cache:
        return _cache[key]
    entry = _TABLE.get(t)
    if entry is not None:
        pb, convert = entry
        m: Mirror | None = Mirror(pb.DESCRIPTOR.full_name, file_descriptor_set(pb), convert,
                                  prefix=FOXGLOVE_PREFIX)
    elif t is type(None) or not json_views:
        m = None
    else:
        name, schema = json_schema(t)
        m = Mirror(name, schema, _json_convert, "jsonschema", "json", prefix=FOXGLOVE_PREFIX)
    _cache[key] = m
    return m


def json_mirror(t: type) -> Mirror | None:
    """The fallback mirror (registered for ``object``): the JSON view of any type but ``None``."""
    return mirror_for(t, json_views=True)


#: topic of the frame tree (``foxglove.FrameTransforms``), next to the mirrors
TF_TOPIC = "/tf"


def frame_transforms(transforms: list[tuple[str, str, float, float, float, float]], t_ns: int) -> bytes:
    """``foxglove.FrameTransforms`` of planar transforms (parent, child, x, y, z, yaw): the pose
    of ``child`` in ``parent``, stamped ``t_ns``."""
    stamp = _stamp(t_ns)
    out = []
    for parent, child, x, y, z, yaw in transforms:
        p = _pose(x, y, yaw)
        out.append(FrameTransform(timestamp=stamp, parent_frame_id=parent, child_frame_id=child,
                                  translation=Vector3(x=float(x), y=float(y), z=float(z)),
                                  rotation=p.orientation))
    return FrameTransforms(transforms=out).SerializeToString()


def tf_mirror(key: Any = None) -> Mirror:
    """The frame-tree mirror (registered for :data:`impala_flow.io.TRANSFORMS`): ``/tf``."""
    return Mirror(FrameTransforms.DESCRIPTOR.full_name, file_descriptor_set(FrameTransforms), frame_transforms,
                  topic=TF_TOPIC)


def _json_convert(value: Any, t_ns: int) -> bytes:
    return encode_json(value)
