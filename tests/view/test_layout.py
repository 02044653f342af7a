"""The shipped Foxglove layout (graphs/foxglove/radar-mission.json) refers to channels that
recordings of the radar chain actually have, with fields their schemas actually declare."""

from __future__ import annotations

import json
from pathlib import Path

from mcap.reader import make_reader

from impala_flow.cli import main

ROOT = Path(__file__).resolve().parents[2]
LAYOUT = ROOT / "graphs" / "foxglove" / "radar-mission.json"
FOXGLOVE_3D = {"foxglove.Grid", "foxglove.PoseInFrame", "foxglove.PosesInFrame", "foxglove.PointCloud",
               "foxglove.SceneUpdate"}


def _panels(node) -> list[str]:
    return [node] if isinstance(node, str) else _panels(node["first"]) + _panels(node["second"])


def _channels(*paths: Path) -> dict[str, tuple[str, str, bytes]]:
    out = {}
    for path in paths:
        with open(path, "rb") as f:
            summary = make_reader(f).get_summary()
        for ch in summary.channels.values():
            s = summary.schemas[ch.schema_id]
            out[ch.topic] = (s.name, s.encoding, s.data)
    return out


def test_the_layout_matches_what_the_chain_records(tmp_path: Path) -> None:
    layout = json.loads(LAYOUT.read_text())
    panels = _panels(layout["layout"])
    assert sorted(panels) == sorted(layout["configById"])  # every panel placed, none dangling
    mission = tmp_path / "m.mcap"
    assert main(["simulate", "beynes", "-o", str(mission), "--duration", "3s", "--no-progress"]) == 0
    out = tmp_path / "oxford"
    assert main(["run", str(ROOT / "graphs" / "oxford.yaml"), "--var", f"mission={mission}", "--var", f"out={out}",
                 "--var", "truth=gps/pose", "--no-progress"]) == 0
    channels = _channels(mission, out / "oxford.mcap")

    resolved = set()
    for pid, cfg in layout["configById"].items():
        if pid.startswith("Plot!"):
            for p in cfg["paths"]:
                topic, field = p["value"].rsplit(".", 1)
                if topic in channels:
                    name, encoding, data = channels[topic]
                    assert encoding == "jsonschema", p["value"]
                    assert field in json.loads(data)["properties"], p["value"]
                    resolved.add(p["value"])
        if pid.startswith("3D!"):
            for topic in cfg["topics"]:
                if topic in channels:
                    assert channels[topic][0] in FOXGLOVE_3D, topic
                    resolved.add(topic)
    # what this chain records is on the layout: its estimate, the sensors it is compared with, its map
    assert {"/foxglove/slam/twist.speed_mps", "/foxglove/odometer/speed.speed_mps",
            "/foxglove/slam/twist.yaw_rate_radps", "/foxglove/gyro/yaw_rate.yaw_rate_radps",
            "/foxglove/slam/map", "/foxglove/slam/pose", "/foxglove/gps/pose"} <= resolved
    assert layout["configById"]["3D!radar"]["followTf"] == "vehicle"  # the frame /tf places
