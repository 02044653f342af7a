"""Navtech radar turns from rosbag2 recordings (issue 28 items 1, 2, 4): a bag written with mcap-ros2-support's
writer from the Oxford scans on disk, as Navtech's ROS 2 driver publishes them (tests/ros2/bags.py), read through the
ros2 plugin's adapters, against the direct Oxford import of the same scans."""

from __future__ import annotations

import pytest

pytest.importorskip("mcap_ros2", reason="the ros2 extra (mcap-ros2-support) is not installed")

import math  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from impala_flow.cli import main  # noqa: E402
from impala_flow.io import MissionReader, open_recording  # noqa: E402

from ..datasets import oxford_sample_or_skip, radiate_head_or_skip  # noqa: E402
from .bags import BSCAN_TOPIC, ENCODER_SIZE, FFT_TOPIC, oxford_scans, write_oxford_bag, write_radiate_bag  # noqa: E402

#: Navtech's B-scan puts encoder e on row e // 14; Oxford's rows are at 13 + 14 i: row i is 13/5600 of a turn
#: before its encoder angle, and the direct import's -0.95 deg offset applies to the encoder angle
BSCAN_OFFSET_DEG = -0.95 - 13 / ENCODER_SIZE * 360.0


@pytest.fixture(scope="module")
def direct(tmp_path_factory):
    folder = oxford_sample_or_skip()
    path = tmp_path_factory.mktemp("direct") / "oxford.mcap"
    assert main(["import", "oxford", str(folder), "-o", str(path), "--no-progress"]) == 0
    return folder, path


def _beams(path: Path, codecs, params=None, topic=None) -> dict[tuple[int, int], tuple[int, object]]:
    with open_recording(path, codecs, adapter_params=params or {}) as r:
        topics = [topic] if topic else [t for t in r.topics if t.endswith(("beams", "b_scan_image", "fft_data"))]
        return {(m.data.turn, m.data.index): (m.t_ns, m.data) for m in r.messages(topics)}


def _dangle(a: float, b: float) -> float:
    return abs(math.remainder(a - b, 2 * math.pi))


def test_bscan_beams_are_the_direct_import_beams(direct, tmp_path, ros2_codecs):
    folder, direct_path = direct
    bag = tmp_path / "bag.mcap"
    write_oxford_bag(folder, bag)
    ref = _beams(direct_path, ros2_codecs)
    got = _beams(bag, ros2_codecs, {"azimuth_offset_deg": BSCAN_OFFSET_DEG})
    assert set(got) == set(ref) and len(got) == 11 * 400
    for key, (_, beam) in got.items():
        _, b_ref = ref[key]
        assert np.array_equal(beam.up, b_ref.up)  # same counts, same power formula: bit-identical
        assert _dangle(beam.azimuth_rad, b_ref.azimuth_rad) < 1e-9
        assert beam.config.range_per_bin_m == pytest.approx(b_ref.config.range_per_bin_m, rel=1e-12)
        assert beam.config.range_offset_m == pytest.approx(b_ref.config.range_offset_m, rel=1e-12)
        assert beam.config.rotation_hz == b_ref.config.rotation_hz  # measured on the stamps, as the import does
    # times: the image's stamp is the first azimuth's, the others spread evenly over the rotation period, never past
    # the next turn's stamp
    starts = [int(t_ns[0]) for t_ns, _, _ in oxford_scans(folder)]
    rotation_hz = ref[(0, 0)][1].config.rotation_hz
    for turn, t0 in enumerate(starts):
        interval = min(1e9 / rotation_hz, starts[turn + 1] - t0 if turn + 1 < len(starts) else 1e9)
        for i in (0, 1, 199, 399):
            assert got[(turn, i)][0] == t0 + round(i * interval / 400)
    dt_ms = np.array([got[k][0] - ref[k][0] for k in got]) / 1e6
    print(f"\nB-scan beam times against the rows' own: {dt_ms.min():+.2f} .. {dt_ms.max():+.2f} ms")
    assert np.abs(dt_ms).max() < 10.0  # the rows come in bursts: what the image cannot keep


def test_fft_data_beams_keep_the_radars_times_and_encoder_angles(direct, tmp_path, ros2_codecs):
    folder, direct_path = direct
    bag = tmp_path / "fft.mcap"
    counts = write_oxford_bag(folder, bag, fft=True, truth=False)
    assert counts["fft"] == 11 * 400
    ref = _beams(direct_path, ros2_codecs)
    got = _beams(bag, ros2_codecs, {"azimuth_offset_deg": -0.95}, topic=FFT_TOPIC)
    assert set(got) == set(ref)
    for key, (t, beam) in got.items():
        t_ref, b_ref = ref[key]
        assert t == t_ref and np.array_equal(beam.up, b_ref.up)
        assert _dangle(beam.azimuth_rad, b_ref.azimuth_rad) < 1e-12


def test_import_ros2_writes_the_mission_a_graph_reads(direct, tmp_path, ros2_codecs, capsys):
    folder, direct_path = direct
    bag = tmp_path / "bag.mcap"
    write_oxford_bag(folder, bag)
    out = tmp_path / "imported.mcap"
    assert main(["import", "ros2", str(bag), "-o", str(out), "--config", f"azimuth_offset_deg={BSCAN_OFFSET_DEG}",
                 "--no-progress"]) == 0
    text = capsys.readouterr().out
    assert f"{BSCAN_TOPIC} (sensor_msgs/msg/Image): 4400 beams on radar/beams" in text
    assert "/ground_truth/odom (nav_msgs/msg/Odometry)" in text
    assert "never past the next turn's stamp" in text and "configuration message" in text
    with MissionReader(out, ros2_codecs) as r:
        assert set(r.topics) == {"radar/beams", "truth/pose"}
        assert sum(1 for _ in r.messages(["radar/beams"])) == 4400
    # a bad --config is one line, before any work
    assert main(["import", "ros2", str(bag), "-o", str(tmp_path / "x.mcap"), "--config", "rotation=sideways"]) == 2
    assert "rotation" in capsys.readouterr().err and not (tmp_path / "x.mcap").exists()


def test_without_geometry_the_range_per_bin_is_asked_for(direct, tmp_path, ros2_codecs):
    folder, _ = direct
    bag = tmp_path / "noconf.mcap"
    write_oxford_bag(folder, bag, configuration=False, truth=False)
    with pytest.raises(Exception, match="range_resolution_m"):
        _beams(bag, ros2_codecs)
    got = _beams(bag, ros2_codecs, {"range_resolution_m": 0.0438, "rotation": "counterclockwise"})
    beam = got[(0, 100)][1]
    assert beam.config.range_per_bin_m == pytest.approx(0.0438, rel=1e-12)
    assert _dangle(beam.azimuth_rad, 100 / 400 * 2 * math.pi) < 1e-12  # counter-clockwise: +a


def test_split_bag_folder_reads_as_one_mission(direct, tmp_path, ros2_codecs, capsys):
    folder, _ = direct
    whole = tmp_path / "whole.mcap"
    write_oxford_bag(folder, whole)
    split = tmp_path / "rosbag2_split"
    split.mkdir()
    write_oxford_bag(folder, split / "rosbag2_split_0.mcap", turns=range(0, 6))
    write_oxford_bag(folder, split / "rosbag2_split_1.mcap", turns=range(6, 11), configuration=False)
    (split / "metadata.yaml").write_text(
        "rosbag2_bagfile_information:\n  version: 5\n  storage_identifier: mcap\n  relative_file_paths:\n"
        "    - rosbag2_split_0.mcap\n    - rosbag2_split_1.mcap\n")
    params = {"rotation_hz": 4.026, "azimuth_offset_deg": BSCAN_OFFSET_DEG}
    a, b = _beams(whole, ros2_codecs, params), _beams(split, ros2_codecs, params)
    assert set(a) == set(b) and len(b) == 4400  # turns numbered on across the files
    assert all(a[k][0] == b[k][0] and a[k][1].azimuth_rad == b[k][1].azimuth_rad for k in a)
    assert main(["info", str(split)]) == 0
    assert BSCAN_TOPIC in capsys.readouterr().out
    out = tmp_path / "split.mcap"
    assert main(["import", "ros2", str(split), "-o", str(out), "--config", "rotation_hz=4.026", "--no-progress"]) == 0
    with MissionReader(out, ros2_codecs) as r:
        assert sum(1 for _ in r.messages(["radar/beams"])) == 4400
    (split / "metadata.yaml").write_text("rosbag2_bagfile_information:\n  storage_identifier: sqlite3\n")
    assert main(["info", str(split)]) == 1
    assert "sqlite3" in capsys.readouterr().err


def test_radiate_bscan_beams_are_the_direct_import_beams(tmp_path, ros2_codecs):
    folder = radiate_head_or_skip()
    direct = tmp_path / "radiate.mcap"
    assert main(["import", "radiate", str(folder), "-o", str(direct), "--no-progress"]) == 0
    bag = tmp_path / "radiate-bag.mcap"
    n = write_radiate_bag(folder, bag)
    ref = _beams(direct, ros2_codecs)
    got = _beams(bag, ros2_codecs, {"range_resolution_m": 0.17361, "azimuth_offset_deg": -2.3})
    assert set(got) == set(ref) and len(got) == n * 400
    dt = []
    for key, (t, beam) in got.items():
        t_ref, b_ref = ref[key]
        assert np.array_equal(beam.up, b_ref.up)
        assert _dangle(beam.azimuth_rad, b_ref.azimuth_rad) < 1e-9
        assert beam.config.range_of_bin_m(10) == pytest.approx(b_ref.config.range_of_bin_m(10), rel=1e-12)
        dt.append(t - t_ref)
    # RADIATE's own columns are spread the same way (column 0 at the frame's time, over the period, never past the
    # next frame): the import floors where the adapter rounds
    print(f"\nRADIATE B-scan beam times against the direct import's: {min(dt) / 1e6:+.3f} .. {max(dt) / 1e6:+.3f} ms")
    assert max(abs(d) for d in dt) < 100_000  # 0.1 ms: the two measure the rotation period on different stamps
