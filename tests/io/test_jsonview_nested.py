"""The JSON view's generated encoder calls a nested message's encoder straight (a beam's config):
the same text as ``json.dumps`` of :func:`to_json`, whatever the nested field holds."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np

import impala_msgs
from impala_flow.io._jsonview import encode, to_json
from impala_flow.msgs import message


def _reference(v: object) -> bytes:
    return json.dumps(to_json(v), separators=(",", ":"), allow_nan=False).encode()


def _config(**kw: object) -> impala_msgs.RadarConfig:
    c = impala_msgs.RadarConfig("r", 77e9, 1e9, 1e3, 1e3, 4, 0.02, 4.0, 8, 1.0, 100.0)
    return dataclasses.replace(c, **kw) if kw else c


@message("test.Node")
class Node:
    """A message nesting its own type (the encoder must not recurse while it is generated)."""

    value: float
    child: Node | None = None


@message("test.Holder")
class Holder:
    inner: Node
    scale: float


def test_a_beam_and_its_config_read_as_json_dumps_writes_them() -> None:
    up = np.arange(8, dtype=np.float32)
    cases = [
        impala_msgs.RadarBeam(0.1, 3, 7, up, np.zeros(0, np.float32), _config(), 1),
        impala_msgs.RadarBeam(-0.0, 0, 0, up[:4], up[:0], _config(f0_hz=-0.0, range_min_m=math.nan), 0),
        impala_msgs.RadarBeam(math.inf, 1, 2, np.zeros(100, np.float32), up, _config(name='a "quoted" é'), -1),
        impala_msgs.RadarBeam(1.0, 1, 2, up, up, None, 0),  # type: ignore[arg-type] - not a config: the slow path
        impala_msgs.RadarBeam(1.0, True, 2, up, up, {"k": [1, 2.5]}, 0),  # type: ignore[arg-type]
    ]
    for beam in cases:
        assert encode(beam) == _reference(beam)
    # the same config object with a field changed in place: the memo sees it
    beam = cases[0]
    first = encode(beam)
    beam.config.n_bins = 9
    assert encode(beam) == _reference(beam) != first


def test_a_message_nesting_its_own_type() -> None:
    tree = Holder(Node(1.5, Node(-0.0, Node(math.nan))), 2.0)
    assert encode(tree) == _reference(tree)
    assert json.loads(encode(tree))["inner"]["child"]["child"] == {"value": None, "child": None}
