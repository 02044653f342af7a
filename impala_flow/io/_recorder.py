"""io.Recorder (the engine's own component): record any set of streams of a running graph to one MCAP file."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import yaml

from .._component import Component, Input, Output, Param
from ..msgs import Pose2D, is_message
from ._runcodecs import run_codecs
from ._writer import COMPRESSIONS, MissionWriter

__all__ = ["Recorder", "VEHICLE_POSES"]

#: pose topics that place the vehicle frame, best first (estimates before truth)
VEHICLE_POSES = ("slam/pose", "ekf/pose", "odometry/pose", "deadreckoning/pose", "gps/pose", "truth/pose")


class Recorder(Component):
    """Writes every sample it receives to ``path`` (MCAP, chunked, indexed).

    One input per recorded stream, named after its topic (``component/port``); the graph's
    ``record:`` section creates it with ``topics``. Inputs block when full (overflow
    ``block``): the recorder slows its producers down rather than dropping, and the run
    summary reports the high-water mark. The file's metadata says how it was made: the
    resolved graph (YAML), the parameters of every component, the plugins and versions.
    """

    path = Param(str, path="write", doc="MCAP file to write")
    topics = Param(dict, default={}, doc="topic -> 'component.port' it records")
    compression = Param(str, default="zstd", choices=tuple(COMPRESSIONS),
                        doc="chunk compression")
    foxglove = Param(bool, default=True, doc="also write the mirrors plugins register (the view plugin: poses, "
                     "grids, points, objects, detections, scans in Foxglove schemas on /foxglove/<topic>, "
                     "frames on /tf)")
    json_views = Param(bool, default=True, doc="and every other stream through the fallback mirror (the view "
                       "plugin: as JSON there, for generic MCAP tools and Foxglove's Plot panel; needs foxglove)")
    ros2 = Param(str, default="", choices=("", "beside", "only"),
                 doc="also write the streams as standard ROS 2 messages (the ros2 plugin: PoseStamped, Path, Odometry, "
                 "OccupancyGrid, radar_msgs, Image, /tf as tf2_msgs; ros2msg schemas, CDR): 'beside' the native "
                 "channels, or 'only' them (a file `ros2 bag play` plays, without native channels or mirrors)")
    chunk_size = Param(int, default=1 << 20, ge=1024, le=1 << 28,
                       doc="bytes per chunk before compression (the writer holds at most four: the one filling, "
                       "two waiting for its thread, one being compressed)")
    threads = Param(int, default=2, ge=1, le=2, doc="2: chunks compressed and written on a second thread while the "
                    "next one fills (the same bytes as 1)")
    maxsize = Param(int, default=4096, ge=1, le=1 << 16, doc="samples queued per input before blocking")
    flush_period_s = Param(float, default=1.0, ge=0.0,
                           doc="also close a chunk every this many wall seconds (crash safety of slow "
                           "streams); 0: by size only, so the same samples give the same bytes")
    frames = Param(dict, default={}, doc="pose topic -> the frame it places (child of the pose's own frame) "
                   "on /tf; empty: the first recorded of " + ", ".join(VEHICLE_POSES) + " places 'vehicle', "
                   "every other pose topic a frame of its own name")
    radar_mount = Param(list, default=[0.0, 0.0, 0.0, 0.0], doc="radar in the vehicle frame: x_m, y_m, z_m, yaw_rad")
    graph = Param(dict, default={}, doc="resolved graph stored in the metadata")
    plugins = Param(dict, default={}, doc="plugin name -> version, stored in the metadata")

    @classmethod
    def declare_ports(cls, params: dict[str, Any]) -> tuple[dict[str, Input], dict[str, Output]]:
        return {t: Input(object, maxsize=params["maxsize"], overflow="block", required=False,
                         doc=f"records {o}") for t, o in params["topics"].items()}, {}

    def start(self) -> None:
        graph = json.loads(json.dumps(self.graph, default=str))  # plain data for safe_dump
        meta: dict[str, dict[str, Any]] = {
            "impala_flow.graph": {"name": str(graph.get("name", "")),
                                  "yaml": yaml.safe_dump(graph, sort_keys=False)},
            "impala_flow.params": {cid: json.dumps(c.get("params", {}), sort_keys=True,
                                                   default=str)
                                   for cid, c in graph.get("components", {}).items()},
            "impala_flow.plugins": {k: str(v) for k, v in self.plugins.items()},
            "impala_flow.streams": dict(self.topics),
        }
        self.codecs = run_codecs(self.registry)
        Path(self.path).parent.mkdir(parents=True, exist_ok=True)
        self.writer = MissionWriter(self.path, codecs=self.codecs, flush_period_s=self.flush_period_s or None,
                                    compression=self.compression, chunk_size=self.chunk_size,
                                    metadata=meta, foxglove=self.foxglove, json_views=self.json_views,
                                    foreign=("ros2",) if self.ros2 else (), native=self.ros2 != "only",
                                    threads=self.threads)
        self.recorded: dict[str, int] = {}
        self._frames = self._frame_children()
        if len(self.radar_mount) != 4 or not all(isinstance(v, (int, float)) for v in self.radar_mount):
            raise ValueError(f"radar_mount {self.radar_mount!r}: must be [x_m, y_m, z_m, yaw_rad]")
        for topic, port in self.inputs.items():  # declare typed streams now, even if they never emit
            declared = {src.decl.type for src in port.sources}
            if len(declared) == 1 and is_message(t := declared.pop()):
                self._add_topic(topic, t)

    def _add_topic(self, topic: str, t_data: type) -> None:
        if is_message(t_data) and t_data not in self.codecs:
            self.codecs.add_type(t_data, plugin=t_data.__module__.split(".")[0])
        self.writer.add_topic(topic, t_data, self._frames.get(topic, ""))
        self.recorded[topic] = 0

    def _frame_children(self) -> dict[str, str]:
        """Pose topic -> frame it places on /tf (module param ``frames``)."""
        if self.frames:
            return {str(k): str(v) for k, v in self.frames.items()}
        if not self.foxglove and not self.ros2:
            return {}
        poses = [t for t, port in self.inputs.items()
                 if any(src.decl.type is Pose2D for src in port.sources)]
        vehicle = next((t for t in VEHICLE_POSES if t in poses), None)
        return {t: ("vehicle" if t == vehicle else t) for t in poses}

    def process(self, t: int) -> None:
        topic = self.trigger
        s = self.inputs[topic].take_sample()
        if topic not in self.recorded:  # an untyped output (object): the first sample's type
            self._add_topic(topic, type(s.data))
        self.writer.write(topic, s.timestamp, s.data, s.seq)
        self.recorded[topic] += 1
        child = self._frames.get(topic)
        if child is not None and isinstance(s.data, Pose2D):
            p = s.data
            tf = [(p.frame, child, p.x_m, p.y_m, 0.0, p.theta_rad)]
            if child == "vehicle":
                x, y, z, yaw = self.radar_mount
                tf.append(("vehicle", "radar", x, y, z, yaw))
            self.writer.write_transforms(s.timestamp, tf)

    def stop(self) -> None:
        writer = getattr(self, "writer", None)
        if writer is not None:
            self._source_metadata(writer)
            writer.close()

    def _source_metadata(self, writer: MissionWriter) -> None:
        """Each recorded producer that describes what it read (``source_metadata() -> dict``,
        e.g. a dataset reader: sensor, turns, rows dropped) gets a metadata record
        ``impala_flow.source.<component>``, written at the end, when its counts are known."""
        owners = {src.owner.name: src.owner for port in self.inputs.values() for src in port.sources}
        for name, comp in sorted(owners.items()):
            describe = getattr(comp, "source_metadata", None)
            if callable(describe):
                meta = describe()
                if meta:
                    writer.add_metadata(f"impala_flow.source.{name}", meta)

    def summary(self) -> dict[str, Any]:
        n = sum(getattr(self, "recorded", {}).values())
        out = {"path": self.path, "recorded": n, "dropped": 0, "topics": dict(getattr(self, "recorded", {}))}
        writer = getattr(self, "writer", None)
        if writer is not None and self.ros2:
            out["ros2"] = writer.foreign_summary().get("ros2", {})
        return out
