"""graphs/oxford.yaml on the real Oxford Radar RobotCar scans, recorded with ``ros2: beside`` (issue 28, "done
when": the recording of that run decodes as ROS 2 messages with the generic decoder): R-SLAM's poses, twists and
map and FMT's poses read back with mcap-ros2-support's decoder equal the native samples (the map by the documented
occupancy scaling). Skips without the data."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from impala_flow.cli import main
from impala_flow.io import MissionReader

from ..datasets import oxford_sample_or_skip
from .helpers import channels, ns, ros_messages, yaw

GRAPH = Path(__file__).resolve().parents[2] / "graphs" / "oxford.yaml"


@pytest.fixture(scope="module")
def oxford_ros2(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = oxford_sample_or_skip()
    tmp = tmp_path_factory.mktemp("oxford_ros2")
    mission = tmp / "oxford-sample.mcap"
    assert main(["import", "oxford", str(folder), "-o", str(mission), "--no-progress"]) == 0
    graph = yaml.safe_load(GRAPH.read_text())
    graph["record"]["ros2"] = "beside"
    (tmp / "oxford.yaml").write_text(yaml.safe_dump(graph, sort_keys=False))
    out = tmp / "out"
    assert main(["run", str(tmp / "oxford.yaml"), "--var", f"mission={mission}", "--var", f"out={out}",
                 "--no-progress"]) == 0
    return out / "oxford.mcap"


def test_the_oxford_run_decodes_as_ros2_messages_equal_to_its_native_samples(oxford_ros2: Path) -> None:
    ros = ros_messages(oxford_ros2)
    with MissionReader(oxford_ros2) as r:
        native = {t: list(r.messages([t])) for t in r.topics}
    assert len(native["slam/pose"]) == 11  # one pose per scan
    for topic in ("slam/pose", "slam/prediction", "fmt/pose"):
        got = ros["/" + topic]
        assert len(got) == len(native[topic]) > 0
        for (t, schema, m), s in zip(got, native[topic], strict=True):
            assert schema == "geometry_msgs/msg/PoseStamped"
            assert t == s.t_ns == ns(m.header.stamp) and m.header.frame_id == s.data.frame
            assert (m.pose.position.x, m.pose.position.y) == (s.data.x_m, s.data.y_m)
            assert yaw(m.pose.orientation) == pytest.approx(s.data.theta_rad, abs=1e-12)
    twists = ros["/slam/twist"]
    assert [(ns(m.header.stamp), m.twist.linear.x, m.twist.angular.z) for _, _, m in twists] == [
        (s.t_ns, s.data.speed_mps, s.data.yaw_rate_radps) for s in native["slam/twist"]]
    maps = ros["/slam/map"]
    assert len(maps) == len(native["slam/map"]) > 0
    for (_, schema, g), s in zip(maps, native["slam/map"], strict=True):
        grid = s.data
        assert schema == "nav_msgs/msg/OccupancyGrid"
        assert (g.info.height, g.info.width) == grid.data.shape
        assert g.info.resolution == float(np.float32(grid.cell_m))  # MapMetaData.resolution is a float32
        assert g.info.origin.position.x == grid.origin_x_m - grid.cell_m / 2
        cells = np.array(g.data, dtype=np.int8).reshape(grid.data.shape)
        v = grid.data.astype(np.float64)
        expected = np.rint(100 * (v - v.min()) / (v.max() - v.min()))  # a dB map: min..max -> 0..100
        assert np.array_equal(cells, expected.astype(np.int8)) and cells.min() == 0 and cells.max() == 100
    # the vehicle placed by R-SLAM's pose on /tf, with its odometry; the registration (fmt/transform) has no
    # ROS 2 message and is not written
    assert {m.child_frame_id for _, _, m in ros["/slam/pose/odometry"]} == {"vehicle"}
    assert {m.child_frame_id for _, _, m in ros["/fmt/pose/odometry"]} == {"fmt/pose"}  # a frame of its own name
    assert len(ros["/tf"]) == 3 * len(native["slam/pose"])  # one update per recorded pose
    assert "/fmt/transform" not in channels(oxford_ros2)
