"""Foxglove mirrors: decode the protobuf back with the foxglove classes and check values."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from foxglove_schemas_protobuf.Grid_pb2 import Grid as FxGrid
from foxglove_schemas_protobuf.PointCloud_pb2 import PointCloud
from foxglove_schemas_protobuf.PoseInFrame_pb2 import PoseInFrame
from foxglove_schemas_protobuf.PosesInFrame_pb2 import PosesInFrame
from google.protobuf.descriptor_pb2 import FileDescriptorSet
from mcap.reader import make_reader

import impala_msgs
from impala_flow import msgs
from impala_flow.io import CodecRegistry, MissionWriter
from impala_view.mirrors import foxglove_topic


def _mirrors(path: Path) -> dict[str, tuple]:
    out = {}
    with open(path, "rb") as f:
        for schema, channel, m in make_reader(f, validate_crcs=True).iter_messages():
            if channel.topic.startswith("/foxglove/"):
                out[channel.topic] = (schema, channel, m)
    return out


def test_mirrors_decode_with_foxglove_classes(tmp_path: Path,
                                              registry: CodecRegistry) -> None:
    path = tmp_path / "m.mcap"
    t_ns = 12_345_678_901
    grid = np.arange(12, dtype=">f4").reshape(3, 4)
    with MissionWriter(path, codecs=registry) as w:
        for topic, t in [("slam/pose", msgs.Pose2D), ("slam/traj", msgs.Trajectory2D),
                         ("slam/map", msgs.Grid), ("radar/points", msgs.Points2D),
                         ("odo/speed", impala_msgs.Speed)]:
            w.add_topic(topic, t)
        w.write("slam/pose", t_ns, msgs.Pose2D(1.5, -2.0, math.pi / 2, frame="odom"))
        w.write("slam/traj", t_ns, msgs.Trajectory2D(
            np.array([0, 1]), np.array([[0.0, 0.0, 0.0], [1.0, 2.0, math.pi]])))
        w.write("slam/map", t_ns, msgs.Grid(grid, 0.5, 10.0, 20.0, frame="map"))
        w.write("radar/points", t_ns, msgs.Points2D(np.array([[1.0, 2.0], [3.0, 4.0]]),
                                                    np.array([7.0, 8.0])))
        w.write("odo/speed", t_ns, impala_msgs.Speed(3.0))
    mirrors = _mirrors(path)
    assert set(mirrors) == {foxglove_topic(t) for t in
                            ("slam/pose", "slam/traj", "slam/map", "radar/points")}

    schema, channel, m = mirrors["/foxglove/slam/pose"]
    assert schema.name == "foxglove.PoseInFrame" and schema.encoding == "protobuf"
    assert channel.message_encoding == "protobuf"
    assert channel.metadata["impala_flow.mirror_of"] == "slam/pose"
    fds = FileDescriptorSet.FromString(schema.data)
    assert "foxglove/PoseInFrame.proto" in [f.name for f in fds.file]
    p = PoseInFrame.FromString(m.data)
    assert p.frame_id == "odom" and p.timestamp.seconds == 12 and \
        p.timestamp.nanos == 345_678_901
    assert (p.pose.position.x, p.pose.position.y) == (1.5, -2.0)
    q = p.pose.orientation
    assert math.isclose(2 * math.atan2(q.z, q.w), math.pi / 2) and q.x == q.y == 0

    tr = PosesInFrame.FromString(mirrors["/foxglove/slam/traj"][2].data)
    assert len(tr.poses) == 2 and tr.poses[1].position.y == 2.0
    assert math.isclose(tr.poses[1].orientation.z, 1.0)

    g = FxGrid.FromString(mirrors["/foxglove/slam/map"][2].data)
    assert g.column_count == 4 and g.cell_size.x == 0.5 and g.cell_stride == 4
    assert g.row_stride == 16 and g.fields[0].name == "value"
    assert (g.pose.position.x, g.pose.position.y) == (9.75, 19.75)  # corner of cell (0, 0)
    np.testing.assert_array_equal(np.frombuffer(g.data, "<f4").reshape(3, 4), grid)

    pc = PointCloud.FromString(mirrors["/foxglove/radar/points"][2].data)
    assert [f.name for f in pc.fields] == ["x", "y", "z", "value"] and pc.point_stride == 16
    pts = np.frombuffer(pc.data, "<f4").reshape(-1, 4)
    np.testing.assert_array_equal(pts, [[1, 2, 0, 7], [3, 4, 0, 8]])


def test_foxglove_can_be_disabled(tmp_path: Path, registry: CodecRegistry) -> None:
    path = tmp_path / "m.mcap"
    with MissionWriter(path, codecs=registry, foxglove=False) as w:
        w.add_topic("slam/pose", msgs.Pose2D)
        w.write("slam/pose", 0, msgs.Pose2D(0, 0, 0))
    assert _mirrors(path) == {}


def test_radar_and_objects_mirrors(tmp_path: Path, registry: CodecRegistry) -> None:
    """Detections as a point cloud with their fields (x = r cos az, y = r sin az), a scan as a
    32FC1 image of 10 log10(power), objects as scene entities named by their ids."""
    from foxglove_schemas_protobuf.RawImage_pb2 import RawImage
    from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate

    path = tmp_path / "m.mcap"
    t_ns = 2_000_000_000
    det = impala_msgs.RadarDetections(turn=3, t_ns=np.array([1, 2]), beam=np.array([5, 90]),
                               azimuth_rad=np.array([0.0, math.pi / 2]), range_m=np.array([10.0, 20.0]),
                               radial_speed_mps=np.array([-1.5, 0.25]), amplitude=np.array([3.0, 4.0]),
                               score=np.array([0.9, 0.5]))
    power = np.array([[1.0, 10.0, 100.0], [0.001, 1e6, 0.0]], np.float32)
    scan = impala_msgs.RadarScan(turn=3, t_ns=np.array([1, 2]), azimuth_rad=np.array([0.0, 0.1]), power=power,
                          down=np.zeros((0, 0), np.float32), config=impala_msgs.RadarConfig(
                              "x", 24e9, 200e6, 1000.0, 100.0, 3, 0.05, 1.0, 2, 0.0, 10.0))
    objects = impala_msgs.ObjectStates(ids=np.array([7, 12]), xy_m=np.array([[1.0, 2.0], [3.0, 4.0]]),
                                v_xy_mps=np.array([[3.0, 4.0], [0.0, 0.0]]))
    with MissionWriter(path, codecs=registry) as w:
        for topic, t in [("pairer/detections", impala_msgs.RadarDetections), ("radar/scan", impala_msgs.RadarScan),
                         ("tracker/tracks", impala_msgs.ObjectStates)]:
            w.add_topic(topic, t)
        w.write("pairer/detections", t_ns, det)
        w.write("radar/scan", t_ns, scan)
        w.write("tracker/tracks", t_ns, objects)
    mirrors = _mirrors(path)

    pc = PointCloud.FromString(mirrors["/foxglove/pairer/detections"][2].data)
    names = [f.name for f in pc.fields]
    assert names == ["x", "y", "z", "range_m", "radial_speed_mps", "amplitude", "score", "beam"]
    pts = np.frombuffer(pc.data, "<f4").reshape(-1, len(names))
    np.testing.assert_allclose(pts[:, :2], [[10.0, 0.0], [0.0, 20.0]], atol=1e-5)
    np.testing.assert_array_equal(pts[:, 3:], np.array([[10, -1.5, 3, 0.9, 5], [20, 0.25, 4, 0.5, 90]], "<f4"))
    assert pc.frame_id == "radar"

    img = RawImage.FromString(mirrors["/foxglove/radar/scan"][2].data)
    assert (img.width, img.height, img.encoding, img.step) == (3, 2, "32FC1", 12)
    db = np.frombuffer(img.data, "<f4").reshape(2, 3)
    np.testing.assert_allclose(db[0], [0.0, 10.0, 20.0], atol=1e-5)
    np.testing.assert_allclose(db[1, :2], [-30.0, 60.0], atol=1e-4)
    assert np.isfinite(db).all()  # zero power: a very low level, never -inf

    scene = SceneUpdate.FromString(mirrors["/foxglove/tracker/tracks"][2].data)
    assert [e.id for e in scene.entities] == ["7", "12"]
    moving, still = scene.entities
    assert moving.texts[0].text == "id 7  5.0 m/s" and moving.arrows[0].shaft_length == 5.0
    q = moving.arrows[0].pose.orientation
    assert math.isclose(2 * math.atan2(q.z, q.w), math.atan2(4.0, 3.0))  # along the velocity
    assert (moving.cubes[0].pose.position.x, moving.cubes[0].pose.position.y) == (1.0, 2.0)
    assert not still.arrows and still.texts[0].text == "id 12  0.0 m/s"


def _generic_decoders(schema, channel):
    """A decoder built from the file alone (no impala-flow): protobuf from the stored
    FileDescriptorSet with Google's library, JSON validated against the stored JSON Schema."""
    import json

    import jsonschema
    from google.protobuf import descriptor_pool, message_factory

    if channel.message_encoding == "protobuf":
        pool = descriptor_pool.DescriptorPool()
        for fd in FileDescriptorSet.FromString(schema.data).file:
            pool.Add(fd)
        cls = message_factory.GetMessageClass(pool.FindMessageTypeByName(schema.name))
        return cls.FromString
    assert channel.message_encoding == "json" and schema.encoding == "jsonschema"
    validator = jsonschema.Draft202012Validator(json.loads(schema.data))

    def decode(data: bytes) -> dict:
        value = json.loads(data)
        validator.validate(value)
        return value

    return decode


def test_every_stream_of_a_recorded_mission_has_a_generic_view(tmp_path: Path) -> None:
    """Simulated and processed missions (recorded by io.Recorder): every recorded topic has a
    /foxglove/ channel that decodes without impala-flow, one message per recorded message, and
    the scalar values are exactly the recorded ones."""
    from impala_flow.cli import main
    from impala_flow.io import MissionReader

    mission = tmp_path / "m.mcap"
    assert main(["simulate", "beynes", "-o", str(mission), "--duration", "3s", "--no-progress"]) == 0
    graph = Path(__file__).resolve().parents[2] / "graphs" / "rslam.yaml"
    out = tmp_path / "rslam"
    assert main(["run", str(graph), "--var", f"mission={mission}", "--var", f"out={out}", "--no-progress"]) == 0
    processed = sorted(out.glob("*.mcap"))
    assert processed
    for path in [mission, *processed]:
        native, views = {}, {}
        with open(path, "rb") as f:
            reader = make_reader(f)
            decoders = {}
            for schema, channel, m in reader.iter_messages():
                if channel.topic == "/tf":  # the frame tree: a view of the poses (test below)
                    assert channel.message_encoding == "protobuf"
                    _generic_decoders(schema, channel)(m.data)
                elif channel.topic.startswith("/foxglove/"):
                    dec = decoders.setdefault(channel.id, _generic_decoders(schema, channel))
                    views.setdefault(channel.topic[len("/foxglove"):].lstrip("/"), []).append((m.log_time, dec(m.data)))
                else:
                    native[channel.topic] = native.get(channel.topic, 0) + 1
        assert set(views) == set(native), path
        assert {t: len(v) for t, v in views.items()} == native, path
        with MissionReader(path) as r:
            for rec in r.messages():
                fields = getattr(rec.data, "__dataclass_fields__", {})
                for name in ("speed_mps", "yaw_rate_radps"):
                    if name in fields:
                        t, view = next(v for v in views[rec.topic] if v[0] == rec.t_ns)
                        assert view[name] == getattr(rec.data, name)


def test_frame_transforms_place_the_vehicle_and_the_radar(tmp_path: Path) -> None:
    """/tf (foxglove.FrameTransforms): each recorded pose places its frame in the pose's own
    frame (the best vehicle pose places 'vehicle', the radar rides on it), equal to the pose."""
    from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms

    from impala_flow.cli import main
    from impala_flow.io import MissionReader

    mission = tmp_path / "m.mcap"
    assert main(["simulate", "beynes", "-o", str(mission), "--duration", "2s", "--no-progress"]) == 0
    with MissionReader(mission) as r:
        poses = {m.t_ns: m.data for m in r.messages(["gps/pose"])}
        assert "/tf" not in r.topics  # a view, like the mirrors: not a stream to replay
    n = 0
    with open(mission, "rb") as f:
        for schema, channel, m in make_reader(f).iter_messages(topics=["/tf"]):
            assert schema.name == "foxglove.FrameTransforms" and channel.message_encoding == "protobuf"
            vehicle, radar = FrameTransforms.FromString(m.data).transforms
            p = poses[m.log_time]
            assert (vehicle.parent_frame_id, vehicle.child_frame_id) == (p.frame, "vehicle")
            assert (vehicle.translation.x, vehicle.translation.y) == (p.x_m, p.y_m)
            assert math.isclose(2 * math.atan2(vehicle.rotation.z, vehicle.rotation.w), p.theta_rad, abs_tol=1e-12)
            assert (radar.parent_frame_id, radar.child_frame_id) == ("vehicle", "radar")
            n += 1
    assert n == len(poses) == 20
