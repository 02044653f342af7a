"""paths.output_clash: an output equal to, inside or over an input is named, links resolved."""

import os

from impala_flow._paths import output_clash


def test_output_equal_inside_over_and_apart(tmp_path):
    data = tmp_path / "ox"
    (data / "gt").mkdir(parents=True)
    gt = data / "gt" / "radar_odometry.csv"
    gt.write_text("t\n")
    ins = [(str(data), "the dataset folder")]
    assert "inside the dataset folder" in output_clash(str(gt), ins)
    assert "inside" in output_clash(str(data / "new.mcap"), ins)
    assert "itself" in output_clash(str(data), ins)
    assert "contains the dataset folder" in output_clash(str(tmp_path), ins)
    assert output_clash(str(tmp_path / "out.mcap"), ins) is None
    assert output_clash(str(tmp_path / "ox2"), ins) is None  # a sibling sharing a prefix is apart
    assert "itself" in output_clash(str(gt), [(str(gt), "the truth file")])


def test_links_are_resolved(tmp_path):
    data = tmp_path / "data"
    data.mkdir()
    m = data / "m.mcap"
    m.write_bytes(b"x")
    os.symlink(data, tmp_path / "alias")
    os.link(m, tmp_path / "hard.mcap")
    assert "inside" in output_clash(str(tmp_path / "alias" / "o.mcap"), [(str(data), "the input folder")])
    assert "itself" in output_clash(str(tmp_path / "hard.mcap"), [(str(m), "the mission")])
