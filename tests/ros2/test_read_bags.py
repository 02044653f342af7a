"""What a rosbag2 may hold besides what the adapters read (issue 28 items 1 and 4): an unknown ROS type (listed by
``info`` with its count, skipped by the Replayer with a count), an OMG IDL definition (refused with one line), a
damaged chunk (its images counted as lost, as for any recording), and the non-radar adapters against formulas."""

from __future__ import annotations

import pytest

pytest.importorskip("mcap_ros2", reason="the ros2 extra (mcap-ros2-support) is not installed")

import math  # noqa: E402
import struct  # noqa: E402

import numpy as np  # noqa: E402
from mcap.reader import make_reader  # noqa: E402
from mcap.writer import Writer as McapWriter  # noqa: E402
from mcap_ros2.writer import Writer  # noqa: E402

from impala_flow.cli import main  # noqa: E402
from impala_flow.io import MissionReader, Replayer, UnknownSchemaError  # noqa: E402
from impala_flow.testing import run_components  # noqa: E402
from impala_ros2 import msgdefs  # noqa: E402

from ..datasets import oxford_sample_or_skip  # noqa: E402
from .bags import BSCAN_TOPIC, write_oxford_bag  # noqa: E402

T0 = 1_700_000_000_000_000_000


def _stamp(t: int) -> dict:
    return {"sec": t // 1_000_000_000, "nanosec": t % 1_000_000_000}


def _schema(w: Writer, name: str):
    return w.register_msgdef(msgdefs.schema_name(name), msgdefs.schema_text(name))


def test_an_unknown_type_is_listed_and_skipped_with_a_count(tmp_path, ros2_codecs, capsys):
    bag = tmp_path / "unknown.mcap"
    w = Writer(str(bag))
    blob = w.register_msgdef("custom_msgs/msg/Blob", "uint8[] data\n")
    imu = _schema(w, "sensor_msgs/Imu")
    for k in range(3):
        t = T0 + k * 100_000_000
        w.write_message("/custom/blob", blob, {"data": b"xyz"}, log_time=t, publish_time=t)
        w.write_message("/imu", imu, {"header": {"stamp": _stamp(t), "frame_id": "imu"},
                                      "angular_velocity": {"x": 0.0, "y": 0.0, "z": 0.1 * k}}, log_time=t,
                        publish_time=t)
    w.finish()
    assert main(["info", str(bag)]) == 0
    line = next(ln for ln in capsys.readouterr().out.splitlines() if "/custom/blob" in ln)
    assert " 3 " in f" {line} " and "custom_msgs/msg/Blob" in line and "no codec" in line
    summary = run_components(Replayer("mission", path=str(bag))).extra["mission"]
    assert summary["skipped"] == {"/custom/blob": 3}
    assert summary["replayed"] == 3  # the IMU's yaw rates
    with MissionReader(bag, ros2_codecs) as r:
        assert [m.data.yaw_rate_radps for m in r.messages(["/imu"])] == pytest.approx([0.0, 0.1, 0.2])
        with pytest.raises(UnknownSchemaError, match="custom_msgs/msg/Blob"):
            list(r.messages(["/custom/blob"]))


def test_ros2idl_definitions_are_refused_with_one_line(tmp_path, ros2_codecs, capsys):
    bag = tmp_path / "idl.mcap"
    with open(bag, "wb") as f:
        w = McapWriter(f)
        w.start(profile="ros2")
        idl = b"module pkg { module msg { struct Thing { uint8 a; }; }; };"
        sid = w.register_schema("pkg/msg/Thing", "ros2idl", idl)
        cid = w.register_channel("/thing", "cdr", sid)
        w.add_message(cid, log_time=T0, data=b"\x00\x01\x00\x00\x07", publish_time=T0)
        w.finish()
    with MissionReader(bag, ros2_codecs) as r:
        with pytest.raises(UnknownSchemaError, match="ros2idl .*not read"):
            list(r.messages(["/thing"]))
        assert not r.info().channels[0].decodable
    assert main(["info", str(bag)]) == 0
    assert "/thing" in capsys.readouterr().out


def test_a_damaged_chunk_loses_its_turns_counted(tmp_path, ros2_codecs):
    folder = oxford_sample_or_skip()
    bag = tmp_path / "damaged.mcap"
    write_oxford_bag(folder, bag, chunk_size=200_000, truth=False)
    with open(bag, "rb") as f:
        summary = make_reader(f).get_summary()
        images = [m.log_time for _, ch, m in make_reader(f).iter_messages(topics=[BSCAN_TOPIC])]
    bad = next(c for c in summary.chunk_indexes[3:] if any(c.message_start_time <= t <= c.message_end_time
                                                            for t in images))
    inside = [t for t in images if bad.message_start_time <= t <= bad.message_end_time]
    data = bytearray(bag.read_bytes())
    data[bad.chunk_start_offset + bad.chunk_length - 40] ^= 0x10
    bag.write_bytes(bytes(data))
    rep = Replayer("mission", path=str(bag), streams=[BSCAN_TOPIC])
    out = run_components(rep).extra["mission"]
    assert out["lost"] == {BSCAN_TOPIC: len(inside)} and len(inside) >= 1
    assert out["replayed"] == (11 - len(inside)) * 400  # every other turn whole


def test_poses_motion_gps_and_detections(tmp_path, ros2_codecs):
    bag = tmp_path / "motion.mcap"
    w = Writer(str(bag))
    s = {n: _schema(w, n) for n in ("nav_msgs/Odometry", "geometry_msgs/PoseStamped", "geometry_msgs/TransformStamped",
                                    "sensor_msgs/NavSatFix", "geometry_msgs/TwistStamped", "radar_msgs/RadarScan")}
    yaw = 0.7
    q = {"x": 0.0, "y": 0.0, "z": math.sin(yaw / 2), "w": math.cos(yaw / 2)}
    h = {"stamp": _stamp(T0 + 5), "frame_id": "odom"}
    w.write_message("/odom", s["nav_msgs/Odometry"], {"header": h, "child_frame_id": "base_link", "pose": {
        "pose": {"position": {"x": 1.5, "y": -2.0, "z": 0.0}, "orientation": q}}}, log_time=T0 + 9)
    w.write_message("/pose", s["geometry_msgs/PoseStamped"], {"header": h, "pose": {
        "position": {"x": 3.0, "y": 4.0, "z": 0.0}, "orientation": q}}, log_time=T0 + 9)
    w.write_message("/tf_one", s["geometry_msgs/TransformStamped"], {"header": h, "child_frame_id": "radar",
                    "transform": {"translation": {"x": 0.5, "y": 0.25, "z": 1.0}, "rotation": q}}, log_time=T0 + 9)
    w.write_message("/twist", s["geometry_msgs/TwistStamped"], {"header": h, "twist": {
        "linear": {"x": 7.0, "y": 0.0, "z": 0.0}, "angular": {"x": 0.0, "y": 0.0, "z": -0.2}}}, log_time=T0 + 9)
    lat0, lon0 = 51.7600, -1.2600
    fixes = [(lat0, lon0, 0), (lat0 + 0.001, lon0, 0), (lat0, lon0 + 0.001, 0), (lat0, lon0, -1)]
    for k, (lat, lon, status) in enumerate(fixes):
        t = T0 + 10 + k
        w.write_message("/fix", s["sensor_msgs/NavSatFix"], {"header": {"stamp": _stamp(t), "frame_id": "gps"},
                        "status": {"status": status, "service": 1}, "latitude": lat, "longitude": lon,
                        "altitude": 60.0}, log_time=t)
    w.write_message("/radar_scan", s["radar_msgs/RadarScan"], {"header": h, "returns": [
        {"range": 10.0, "azimuth": 0.5, "elevation": 0.0, "doppler_velocity": -1.0, "amplitude": 20.0},
        {"range": 20.0, "azimuth": -0.25, "elevation": 0.0, "doppler_velocity": 2.0, "amplitude": 30.0}]},
        log_time=T0 + 9)
    w.finish()
    with MissionReader(bag, ros2_codecs) as r:
        got = {}
        for m in r.messages():
            got.setdefault(m.topic, []).append((m.t_ns, m.data))
        notes = {t: a.notes() for t, a in r.adapters().items()}
    for topic, (x, y) in (("/odom", (1.5, -2.0)), ("/pose", (3.0, 4.0)), ("/tf_one", (0.5, 0.25))):
        (t, p), = got[topic]
        assert t == T0 + 5 and (p.x_m, p.y_m) == (x, y) and p.theta_rad == pytest.approx(yaw, abs=1e-12)
        assert p.frame == "odom"
    (t, tw), = got["/twist"]
    assert (tw.speed_mps, tw.yaw_rate_radps) == (7.0, -0.2)
    (t, det), = got["/radar_scan"]
    assert det.range_m.tolist() == [10.0, 20.0] and det.azimuth_rad.tolist() == [0.5, -0.25]
    assert det.radial_speed_mps.tolist() == [-1.0, 2.0] and det.amplitude.tolist() == pytest.approx([100.0, 1000.0])
    # GPS: the first fix is the origin; 0.001 deg north and east on a sphere of the mean radius (haversine, an
    # independent formula): within 0.5 % of the ellipsoid's local east-north; the fix without a fix dropped
    fix = got["/fix"]
    assert len(fix) == 3 and (fix[0][1].x_m, fix[0][1].y_m) == (0.0, 0.0) and fix[0][1].frame == "enu"
    r_m = 6_371_008.8

    def haversine(lat1, lon1, lat2, lon2):
        p1, p2, dl = math.radians(lat1), math.radians(lat2), math.radians(lon2 - lon1)
        a = math.sin((p2 - p1) / 2) ** 2 + math.cos(p1) * math.cos(p2) * math.sin(dl / 2) ** 2
        return 2 * r_m * math.asin(math.sqrt(a))

    north, east = fix[1][1], fix[2][1]
    assert abs(north.x_m) < 1e-9 and north.y_m == pytest.approx(haversine(lat0, lon0, lat0 + 0.001, lon0), rel=5e-3)
    assert abs(east.y_m) < 1e-9 and east.x_m == pytest.approx(haversine(lat0, lon0, lat0, lon0 + 0.001), rel=5e-3)
    assert not north.heading_known
    assert any("1 fix(es) without a fix" in n for n in notes["/fix"])
    assert np.isfinite(north.cov_xyt).all()


def test_navtech_configuration_bin_size_in_both_sdk_units(tmp_path, ros2_codecs):
    """The configuration's bin_size: metres (SDKs dividing by 10 000) or the protocol's 0.1 mm count."""
    from impala_ros2.read.radar import _layout

    assert _layout(list(struct.pack("<d", 0.0438)), "<f8") == 0.0438
    assert _layout(list(struct.pack("<d", 438.0)), "<f8") == 438.0  # -> 0.0438 m by the adapter's rule
    assert _layout(list(struct.pack(">H", 438)), "<f8") == 438.0  # an SDK writing the raw uint16
    with pytest.raises(ValueError, match="3 bytes"):
        _layout([1, 2, 3], ">u2")
