"""The issue's "done when" (issue 28): a rosbag2-style MCAP of the real Oxford scans, as Navtech's ROS 2 driver
publishes them (one B-scan image per turn stamped at its first azimuth: the per-azimuth times lost), through
``impala-flow import ros2`` and graphs/oxford.yaml, gives the direct import's pair errors within 1 cm and
0.05 deg (tests/slam/test_oxford.py runs the same graph on the direct import)."""

from __future__ import annotations

import pytest

pytest.importorskip("mcap_ros2", reason="the ros2 extra (mcap-ros2-support) is not installed")

import json  # noqa: E402
from pathlib import Path  # noqa: E402

from impala_flow.cli import main  # noqa: E402

from ..datasets import oxford_sample_or_skip  # noqa: E402
from .bags import write_oxford_bag  # noqa: E402
from .test_read_radar import BSCAN_OFFSET_DEG  # noqa: E402

GRAPH = Path(__file__).resolve().parents[2] / "graphs" / "oxford.yaml"


def _run(mission: Path, out: Path) -> dict:
    assert main(["run", str(GRAPH), "--var", f"mission={mission}", "--var", f"out={out}", "--no-progress"]) == 0
    return json.loads((out / "metrics.json").read_text())


def test_oxford_graph_on_the_bag_gives_the_direct_import_figures(tmp_path, ros2_codecs):
    folder = oxford_sample_or_skip()
    direct = tmp_path / "direct.mcap"
    assert main(["import", "oxford", str(folder), "-o", str(direct), "--no-progress"]) == 0
    bag = tmp_path / "rosbag.mcap"
    write_oxford_bag(folder, bag)
    imported = tmp_path / "from-bag.mcap"
    assert main(["import", "ros2", str(bag), "-o", str(imported), "--no-progress",
                 "--config", f"azimuth_offset_deg={BSCAN_OFFSET_DEG}"]) == 0
    ref, got = _run(direct, tmp_path / "direct"), _run(imported, tmp_path / "bag")
    print(f"\nOxford pairs, direct import: {100 * ref['pair_trans_err_mean_m']:.2f} cm / "
          f"{ref['pair_rot_err_mean_deg']:.4f} deg; from the ROS 2 bag: {100 * got['pair_trans_err_mean_m']:.2f} cm / "
          f"{got['pair_rot_err_mean_deg']:.4f} deg")
    assert got["n_pairs"] == ref["n_pairs"] == 10
    assert got["pair_trans_err_mean_m"] == pytest.approx(ref["pair_trans_err_mean_m"], abs=0.01)
    assert got["pair_rot_err_mean_deg"] == pytest.approx(ref["pair_rot_err_mean_deg"], abs=0.05)
    assert got["ate_rmse_m"] == pytest.approx(ref["ate_rmse_m"], abs=0.01)
