"""The view plugin as a plugin: what it registers, that the engine works without it (recordings
without mirrors, still valid and replayable), that the engine's own io cannot be blocked, and
the did-you-mean for the bridge's old type name."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from mcap.reader import make_reader

import impala_msgs
from impala_flow.cli import main
from impala_flow.io import MIRROR_KEY, TRANSFORMS, MissionReader, run_codecs
from impala_flow.plugins import DISABLE_ENV, load_registry
from impala_view import mirrors
from impala_view.plugin import MIRRORED


def _channels(path: Path) -> dict[str, dict[str, str]]:
    with open(path, "rb") as f:
        return {c.topic: dict(c.metadata) for c in make_reader(f).get_summary().channels.values()}


def test_it_registers_the_bridge_and_every_foxglove_mirror() -> None:
    reg = load_registry()
    assert reg.plugins["view"].components == ["view.FoxgloveBridge"]
    assert set(reg.mirrors) == {*MIRRORED, object, TRANSFORMS}
    assert {owner for _, owner in reg.mirrors.values()} == {"view"}
    codecs = run_codecs(reg)
    for t in MIRRORED:  # the table of the mirrors module, each with its Foxglove schema
        m = codecs.mirror_for(t)
        assert m is not None and m.schema_name.startswith("foxglove.") and m.topic_of("a/b") == "/foxglove/a/b"
        assert m == mirrors.mirror_for(t)
    assert codecs.mirror_for(impala_msgs.Speed) is None  # JSON only when asked
    json = codecs.mirror_for(impala_msgs.Speed, fallback=True)
    assert json is not None and json.message_encoding == "json" and json.schema_encoding == "jsonschema"
    assert codecs.mirror_for(type(None), fallback=True) is None
    tf = codecs.mirror_for(TRANSFORMS)
    assert tf is not None and tf.schema_name == "foxglove.FrameTransforms" and tf.topic_of("frames") == "/tf"


def test_loading_the_plugin_imports_no_protobuf() -> None:
    code = ("import sys\nfrom impala_flow.plugins import load_registry\nr = load_registry()\n"
            "assert 'view.FoxgloveBridge' in r.components\n"
            "print(sorted(m for m in sys.modules if m.split('.')[0] in ('google', 'foxglove', "
            "'foxglove_schemas_protobuf')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_without_the_view_plugin_recordings_have_no_mirrors_and_replay(tmp_path: Path,
                                                                       monkeypatch: pytest.MonkeyPatch) -> None:
    """The engine records and replays by itself: blocking the view plugin leaves io.Recorder, io.Replayer
    (blocking 'io' does nothing) and a valid recording with the same streams, without /foxglove or /tf."""
    with_view, without = tmp_path / "with.mcap", tmp_path / "without.mcap"
    args = ["simulate", "beynes", "--duration", "2s", "--no-progress", "-o"]
    assert main([*args, str(with_view)]) == 0
    monkeypatch.setenv(DISABLE_ENV, "view,io")
    reg = load_registry()
    assert "view" not in reg.plugins and {"io.Recorder", "io.Replayer"} <= set(reg.components)
    assert main([*args, str(without)]) == 0
    mirrored = {t for t, meta in _channels(with_view).items() if MIRROR_KEY in meta}
    assert "/tf" in mirrored and "/foxglove/gps/pose" in mirrored
    assert not any(MIRROR_KEY in meta for meta in _channels(without).values())
    assert set(_channels(without)) == set(_channels(with_view)) - mirrored
    assert main(["info", str(without), "--verify"]) == 0
    with MissionReader(with_view) as a, MissionReader(without) as b:
        assert a.topics == b.topics and a.info().message_count - a.info().mirror_count == b.info().message_count
    assert _streams(with_view) == _streams(without)  # the same messages, byte for byte


def _streams(path: Path) -> list[tuple[str, int, bytes]]:
    with open(path, "rb") as f:
        return [(c.topic, m.log_time, m.data) for _, c, m in make_reader(f).iter_messages(log_time_order=False)
                if MIRROR_KEY not in c.metadata]


def test_the_old_bridge_type_gets_a_did_you_mean(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    graph = tmp_path / "g.yaml"
    graph.write_text("components:\n  v: {type: io.FoxgloveBridge, params: {topics: {}}}\n")
    assert main(["validate", str(graph)]) == 2
    err = capsys.readouterr().err
    assert "unknown type 'io.FoxgloveBridge'" in err
    assert "did you mean 'view.FoxgloveBridge'? plugin 'view' has it" in err
