"""ROS 2 files read by the TypeScript libraries Foxglove decodes ROS 2 with (@mcap/core, @foxglove/rosmsg,
@foxglove/rosmsg2-serialization), from the schema text stored in the file: the same messages, topic for topic and
field for field, as mcap-ros2-support's generic decoder. Skips where node or the npm registry is not available
(the packages are installed once per machine, in a cache)."""

from __future__ import annotations

import json
import math
import subprocess
from pathlib import Path
from typing import Any

import pytest

from .._node import node_script
from .helpers import ros_messages, write_every_type

HERE = Path(__file__).resolve().parent
PACKAGES = ["@mcap/core@2", "@mcap/support@1", "@foxglove/rosmsg@5", "@foxglove/rosmsg2-serialization@2"]


@pytest.fixture(scope="module")
def node_reader() -> list[str]:
    return node_script(HERE / "ts_read_ros2.js", PACKAGES, "@foxglove/rosmsg2-serialization")


def _plain(v: Any) -> Any:
    """A decoded message as the script prints it: number arrays up to 64 values as lists, longer as {n, sum};
    NaN as None; builtin_interfaces/Time as Foxglove names it ({sec, nsec})."""
    if isinstance(v, (bytes, bytearray)) or (isinstance(v, list) and all(isinstance(x, (int, float)) for x in v)
                                             and not isinstance(v, str)):
        a = [float(x) if isinstance(x, float) else int(x) for x in v]
        if len(a) > 64:
            return {"n": len(a), "sum": sum(a)}
        return [None if isinstance(x, float) and math.isnan(x) else x for x in a]
    if isinstance(v, list):
        return [_plain(x) for x in v]
    if isinstance(v, float) and math.isnan(v):
        return None
    slots = getattr(type(v), "__slots__", None)
    if slots is not None and not isinstance(v, (str, int, float)):
        return {("nsec" if k == "nanosec" else k): _plain(getattr(v, k)) for k in slots}
    return v


def test_foxglove_ros2_decoder_reads_what_the_generic_decoder_reads(node_reader: list[str], tmp_path: Path) -> None:
    path = write_every_type(tmp_path / "all.mcap")
    r = subprocess.run([*node_reader, str(path)], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    ts = json.loads(r.stdout)
    py = ros_messages(path)
    assert sorted(ts) == sorted(py) and len(ts) == 15
    for topic, messages in py.items():
        assert [int(m["log_time"]) for m in ts[topic]] == [t for t, _, _ in messages], topic
        for got, (_, _, m) in zip(ts[topic], messages, strict=True):
            assert got["message"] == _plain(m), topic
    assert ts["/map/prob"][0]["message"]["data"] == [0, 25, 50, 100, -1, 99]
