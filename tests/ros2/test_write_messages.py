"""Every type the ros2 output format writes, through the engine's MissionWriter, read back with
mcap-ros2-support's generic decoder from the schemas stored in the file: stamps exact from int ns,
yaw back from the quaternion by the textbook formula, grids by the documented 0..100 / -1 scaling,
B-scans value for value, and the native channels untouched beside them."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader

import impala_msgs
from impala_flow import msgs
from impala_flow.io import MIRROR_KEY, CodecError, MissionReader, MissionWriter, run_codecs
from impala_flow.plugins import DISABLE_ENV, load_registry
from impala_ros2.write import encode as enc
from impala_ros2.write import writer as ros2_writer

from .helpers import SCAN_POWER, T0, channels, codecs, ns, ros_messages, write_every_type, yaw


@pytest.fixture(scope="module")
def written(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_every_type(tmp_path_factory.mktemp("ros2") / "all.mcap")


def test_every_ros2_channel_has_a_ros2msg_schema_cdr_and_is_a_mirror_beside_the_native_ones(written: Path) -> None:
    ch = channels(written)
    ros = {t: c for t, c in ch.items() if c[2] == "cdr"}
    assert {t: c[0] for t, c in ros.items()} == {
        "/slam/pose": "geometry_msgs/msg/PoseStamped", "/slam/pose/path": "nav_msgs/msg/Path",
        "/slam/pose/odometry": "nav_msgs/msg/Odometry", "/tf": "tf2_msgs/msg/TFMessage",
        "/gps/pose": "geometry_msgs/msg/PoseStamped", "/gps/pose/path": "nav_msgs/msg/Path",
        "/graph/trajectory": "nav_msgs/msg/Path", "/odo/twist": "geometry_msgs/msg/TwistStamped",
        "/map/prob": "nav_msgs/msg/OccupancyGrid", "/map/db": "nav_msgs/msg/OccupancyGrid",
        "/map/bool": "nav_msgs/msg/OccupancyGrid", "/radar/detections": "radar_msgs/msg/RadarScan",
        "/tracker/tracks": "radar_msgs/msg/RadarTracks", "/radar/scan": "sensor_msgs/msg/Image",
        "/radar/beams": "sensor_msgs/msg/Image"}
    assert {c[1] for c in ros.values()} == {"ros2msg"}
    assert ros["/slam/pose/path"][3] == {MIRROR_KEY: "slam/pose"} and ros["/tf"][3] == {MIRROR_KEY: "frames"}
    assert "/odo/speed" not in ch  # no ROS 2 message for a Speed: not written (and said in the summary)
    with open(written, "rb") as f:
        assert make_reader(f).get_header().profile == "impala-flow"
    with MissionReader(written) as r:  # the native streams, as they were: the ROS 2 channels are skipped
        assert sorted(r.topics) == sorted(["slam/pose", "gps/pose", "graph/trajectory", "odo/twist", "map/prob",
                                           "map/db", "map/bool", "radar/detections", "tracker/tracks",
                                           "radar/scan", "radar/beams", "odo/speed"])
        assert [m.data.theta_rad for m in r.messages(["slam/pose"])] == [0.3, -2.9, 3.1]


def test_poses_stamps_exact_yaw_back_by_formula_path_grows_odometry_covariance(written: Path) -> None:
    ros = ros_messages(written)
    poses = ros["/slam/pose"]
    assert [t for t, _, _ in poses] == [T0, T0 + 1, T0 + 2]
    for i, ((_, _, m), theta) in enumerate(zip(poses, [0.3, -2.9, 3.1], strict=True)):
        assert (m.header.stamp.sec, m.header.stamp.nanosec) == (1_700_000_000, 123_456_789 + i)
        assert m.header.frame_id == "odom"
        assert (m.pose.position.x, m.pose.position.y, m.pose.position.z) == (1.5 * i, -2.0, 0.0)
        assert yaw(m.pose.orientation) == pytest.approx(theta, abs=1e-12)
        q = m.pose.orientation
        assert q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w == pytest.approx(1.0, abs=1e-15)
    paths = [m for _, _, m in ros["/slam/pose/path"]]
    assert [len(p.poses) for p in paths] == [1, 2, 3]
    assert [ns(p.header.stamp) for p in paths[-1].poses] == [T0, T0 + 1, T0 + 2]
    assert [p.pose.position.x for p in paths[-1].poses] == [0.0, 1.5, 3.0]
    odo = [m for _, _, m in ros["/slam/pose/odometry"]]
    assert [o.child_frame_id for o in odo] == ["vehicle"] * 3 and odo[1].header.frame_id == "odom"
    cov = np.array(odo[1].pose.covariance).reshape(6, 6)
    expected = np.zeros((6, 6))
    expected[0, 0], expected[1, 1], expected[5, 5] = 0.01, 0.02, 0.003
    assert np.array_equal(cov, expected) and not np.any(odo[0].pose.covariance)  # empty cov_xyt: unknown (zeros)
    assert odo[0].twist.covariance[0] == -1.0  # twist not known from a pose
    assert "/gps/pose/odometry" not in ros  # places no frame: no odometry


def test_tf_message_carries_each_transform_of_the_frame_tree(written: Path) -> None:
    tfs = [m for _, _, m in ros_messages(written)["/tf"]]
    assert len(tfs) == 3
    a, b = tfs[2].transforms
    assert (a.header.frame_id, a.child_frame_id, ns(a.header.stamp)) == ("odom", "vehicle", T0 + 2)
    assert (a.transform.translation.x, a.transform.translation.y) == (3.0, -2.0)
    assert yaw(a.transform.rotation) == pytest.approx(3.1, abs=1e-12)
    assert (b.header.frame_id, b.child_frame_id, b.transform.translation.z) == ("vehicle", "radar", 1.2)


def test_trajectory_twist_as_path_and_twist_stamped(written: Path) -> None:
    ros = ros_messages(written)
    (_, _, path), = ros["/graph/trajectory"]
    assert [ns(p.header.stamp) for p in path.poses] == [T0, T0 + 7] and ns(path.header.stamp) == T0 + 10
    assert [(p.pose.position.x, p.pose.position.y) for p in path.poses] == [(0.0, 1.0), (2.0, 3.0)]
    assert [yaw(p.pose.orientation) for p in path.poses] == pytest.approx([0.5, -0.5], abs=1e-12)
    (_, _, tw), = ros["/odo/twist"]
    assert (tw.header.frame_id, tw.twist.linear.x, tw.twist.angular.z) == ("vehicle", 3.5, -0.25)


def test_grids_as_occupancy_by_the_documented_scaling(written: Path) -> None:
    ros = ros_messages(written)
    (_, _, prob), = ros["/map/prob"]
    # values in [0, 1]: round(100 v); NaN: -1 (unknown); rows = y, columns = x, row-major
    assert (prob.info.width, prob.info.height, prob.info.resolution) == (3, 2, 0.5)
    assert list(prob.data) == [0, 25, 50, 100, -1, 99]
    assert (prob.info.origin.position.x, prob.info.origin.position.y) == (9.75, 19.75)  # corner of cell (0, 0)
    assert ns(prob.header.stamp) == T0 + 12 and prob.header.frame_id == "map"
    (_, _, db), = ros["/map/db"]
    # any other range: min -> 0, max -> 100, linear: (v + 10) / 40
    assert list(db.data) == [round(100 * (v + 10) / 40) for v in (-10.0, 0.0, 30.0, 20.0)] == [0, 25, 100, 75]
    assert (db.info.origin.position.x, db.info.origin.position.y) == (-5.0, -1.0)
    (_, _, b), = ros["/map/bool"]
    assert list(b.data) == [100, 0]


def test_occupancy_cells_appended_in_one_piece_are_the_bytes_the_encoder_writes_cell_by_cell() -> None:
    from impala_ros2.write import convert

    ch = ros2_writer._channel("/m", "nav_msgs/OccupancyGrid")
    data = np.random.default_rng(5).normal(size=(7, 13))
    msg, cells = convert.occupancy_grid(T0, "frame_x", data, 0.3, 1.0, 2.0)
    whole = dict(msg, data=np.frombuffer(cells, dtype=np.int8).tolist())
    assert enc.encode_with_tail(ch, msg, cells) == enc.encode(ch, whole)


def test_detections_and_tracks_as_radar_msgs(written: Path) -> None:
    ros = ros_messages(written)
    (_, _, scan), = ros["/radar/detections"]
    assert scan.header.frame_id == "radar" and ns(scan.header.stamp) == T0 + 15
    r = scan.returns
    assert [(x.range, x.azimuth, x.amplitude, x.elevation) for x in r] == [(12.5, 0.25, 7.0, 0.0),
                                                                          (40.0, -1.0, 9.0, 0.0)]
    assert r[0].doppler_velocity == 1.5 and math.isnan(r[1].doppler_velocity)  # NaN: not measured
    (_, _, tracks), = ros["/tracker/tracks"]
    a, b = tracks.tracks
    assert [int.from_bytes(bytes(t.uuid.uuid), "big") for t in (a, b)] == [7, 123456789012]
    assert (b.position.x, b.position.y, b.velocity.x, b.velocity.y) == (3.0, 4.0, -1.0, 2.0)
    # cov over (x, y, vx, vy): position = upper triangle of the xy block, velocity of the v block
    assert list(a.position_covariance) == [0.0, 1.0, 0.0, 5.0, 0.0, 0.0]
    assert list(a.velocity_covariance) == [10.0, 11.0, 0.0, 15.0, 0.0, 0.0]
    assert list(b.position_covariance) == [2.0, 0.0, 0.0, 2.0, 0.0, 0.0]


def test_scans_and_turns_of_beams_as_32fc1_bscans(written: Path) -> None:
    ros = ros_messages(written)
    (_, _, img), = ros["/radar/scan"]
    assert (img.height, img.width, img.encoding, img.step, img.is_bigendian) == (3, 4, "32FC1", 16, 0)
    assert ns(img.header.stamp) == T0 + 3 and img.header.frame_id == "radar"  # the turn's first beam
    assert np.array_equal(np.frombuffer(bytes(img.data), dtype="<f4").reshape(3, 4), SCAN_POWER.astype(np.float32))
    beams = ros["/radar/beams"]  # 3 turns: two complete, the last one written when the file closes
    assert [(t, ns(m.header.stamp), m.height, m.width) for t, _, m in beams] == [
        (T0 + 102, T0 + 100, 3, 4), (T0 + 201, T0 + 200, 2, 4), (T0 + 300, T0 + 300, 1, 4)]
    rows = np.frombuffer(bytes(beams[1][2].data), dtype="<f4").reshape(2, 4)
    assert rows.tolist() == [[1.0, 0.0, 0.5, 1e6], [1.0, 1.0, 0.5, 1e6]]


def test_only_writes_a_ros2_file_without_native_channels_or_mirrors(tmp_path: Path) -> None:
    path = tmp_path / "only.mcap"
    with MissionWriter(path, codecs=codecs(), foreign=("ros2",), native=False, foxglove=True,
                       json_views=True) as w:
        w.add_topic("slam/pose", msgs.Pose2D, "vehicle")
        w.add_topic("odo/speed", impala_msgs.Speed)
        w.write("slam/pose", T0, msgs.Pose2D(1.0, 2.0, 0.5))
        w.write("odo/speed", T0, impala_msgs.Speed(1.0))
        w.write_transforms(T0, [("map", "vehicle", 1.0, 2.0, 0.0, 0.5)])
    with open(path, "rb") as f:
        assert make_reader(f).get_header().profile == "ros2"
    ch = channels(path)
    assert sorted(ch) == ["/slam/pose", "/slam/pose/odometry", "/slam/pose/path", "/tf"]
    assert all(c[1:3] == ("ros2msg", "cdr") and MIRROR_KEY not in c[3] for c in ch.values())
    assert ros_messages(path)["/slam/pose"][0][2].pose.position.y == 2.0


def test_a_path_keeps_its_newest_poses_within_its_bound(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(ros2_writer, "PATH_MAX_POSES", 4)
    path = tmp_path / "p.mcap"
    with MissionWriter(path, codecs=codecs(), foreign=("ros2",), native=False) as w:
        w.add_topic("p", msgs.Pose2D)
        for i in range(10):
            w.write("p", T0 + i, msgs.Pose2D(float(i), 0.0, 0.0))
    paths = [m for _, _, m in ros_messages(path)["/p/path"]]
    assert [len(p.poses) for p in paths] == [1, 2, 3, 4, 4, 4, 4, 4, 4, 4]
    assert [p.pose.position.x for p in paths[-1].poses] == [6.0, 7.0, 8.0, 9.0]


def test_asking_for_ros2_without_the_plugin_is_one_line_with_the_pip_line(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(DISABLE_ENV, "ros2")
    with pytest.raises(CodecError) as e:
        MissionWriter(tmp_path / "x.mcap", codecs=run_codecs(load_registry()), foreign=("ros2",))
    assert str(e.value) == ("ros2 output unavailable: no plugin registers it (the 'ros2' plugin: "
                            "pip install 'impala-flow[ros2]')")
    monkeypatch.delenv(DISABLE_ENV)
    import impala_ros2.plugin

    monkeypatch.setattr(impala_ros2.plugin, "REQUIRES", ("mcap_ros2_is_not_installed",))
    with pytest.raises(CodecError) as e:
        MissionWriter(tmp_path / "y.mcap", codecs=run_codecs(load_registry()), foreign=("ros2",))
    assert str(e.value) == ("ros2 output unavailable: plugin 'ros2' needs mcap_ros2_is_not_installed: "
                            "pip install 'impala-flow[ros2]'")


@pytest.mark.parametrize("frame", ["", "m", "map", "odom", "odom_x", "a_longer_frame"])
def test_a_path_assembled_from_poses_encoded_once_is_the_bytes_the_encoder_writes_for_the_whole(frame: str) -> None:
    from impala_ros2.write import convert

    ch = ros2_writer._channel("/p/path", "nav_msgs/Path")
    poses = [convert.pose_stamped(T0 + i, frame[: i % (len(frame) + 1)], 0.1 * i, -i, 0.3 * i) for i in range(7)]
    for n in range(len(poses) + 1):
        msg = convert.path(T0, frame, poses[:n])
        parts = [enc.element("geometry_msgs/PoseStamped", p) for p in poses[:n]]
        assert enc.encode_with_elements(ch, convert.path(T0, frame, []), parts) == enc.encode(ch, msg)


def test_two_streams_on_one_ros_topic_is_an_error_naming_both(tmp_path: Path) -> None:
    with MissionWriter(tmp_path / "c.mcap", codecs=codecs(), foreign=("ros2",)) as w:
        w.add_topic("a.b", msgs.Twist2D)
        with pytest.raises(ValueError, match="ROS 2 topic '/a_b' of stream 'a_b' is already written for 'a.b': "
                                             "rename one of the streams"):
            w.add_topic("a_b", msgs.Twist2D)
        w.add_topic("p", msgs.Pose2D)
        with pytest.raises(ValueError, match="ROS 2 topic '/p/path' of stream 'p/path' is already written for 'p'"):
            w.add_topic("p/path", msgs.Trajectory2D)
        with pytest.raises(ValueError, match="ROS 2 topic '/tf' of stream 'tf' is already written for the frame tree"):
            w.add_topic("tf", msgs.Trajectory2D)
