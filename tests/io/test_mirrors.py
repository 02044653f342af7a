"""The engine's mirror mechanism, with no Foxglove: a plugin registers a mirror for a type, the
recorder of a graph writes it beside the stream, readers skip it; a second plugin claiming the
same mirror is an error naming both."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from mcap.reader import make_reader

from impala_flow import Session
from impala_flow.io import MIRROR_KEY, TRANSFORMS, Mirror, MissionReader, MissionWriter, run_codecs
from impala_flow.plugins import DISABLE_ENV, NameConflictError, hookimpl, load_registry
from impala_flow.testing import CollectingSink, plugin_of

from ..engine.components import Counter


def _text(t: Any) -> Mirror:
    return Mirror("test.Text", b"", lambda v, t_ns: f"{v}@{t_ns}".encode(), "text", "text", prefix="/text/")


class TextMirrors:
    """Every float stream mirrored as text on /text/<topic>; the frame tree as text on /frames."""

    @staticmethod
    @hookimpl
    def impala_flow_register(registry: Any) -> None:
        registry.add_mirror(float, _text)
        registry.add_mirror(TRANSFORMS, lambda key: Mirror("test.Frames", b"", lambda v, t: repr(v).encode(),
                                                           "text", "text", topic="/frames"))


GRAPH = """
components:
  src: {type: t.Counter, params: {n: 3, period_ns: 1000}}
  sink: t.CollectingSink
connections: [src.out -> sink.x]
record: {path: out.mcap, streams: ["src.*"]}
"""


def _channels(path: Path) -> dict[str, list[tuple[dict[str, str], int, bytes]]]:
    out: dict[str, list] = {}
    with open(path, "rb") as f:
        for _, c, m in make_reader(f).iter_messages():
            out.setdefault(c.topic, []).append((dict(c.metadata), m.log_time, m.data))
    return out


def test_a_registered_mirror_is_written_beside_its_stream_and_skipped_on_replay(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(DISABLE_ENV, "view")  # no Foxglove: only this test's mirror
    session = Session(extra_plugins={"t": plugin_of(Counter, CollectingSink), "txt": TextMirrors()})
    (tmp_path / "g.yaml").write_text(GRAPH)
    session.run(session.build(session.load(tmp_path / "g.yaml")))
    chans = _channels(tmp_path / "out.mcap")
    assert set(chans) == {"src/out", "/text/src/out"}
    assert [(meta[MIRROR_KEY], t, data) for meta, t, data in chans["/text/src/out"]] == [
        ("src/out", 0, b"0.0@0"), ("src/out", 1000, b"1.0@1000"), ("src/out", 2000, b"2.0@2000")]
    with MissionReader(tmp_path / "out.mcap") as r:
        assert list(r.topics) == ["src/out"] and r.info().mirror_count == 3
        assert [m.data for m in r.messages()] == [0.0, 1.0, 2.0]


def test_the_frame_tree_goes_through_its_mirror_or_nowhere(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(DISABLE_ENV, "view")
    tf = [("map", "vehicle", 1.0, 2.0, 0.0, 0.5)]
    with MissionWriter(tmp_path / "none.mcap", codecs=run_codecs()) as w:  # no plugin mirrors frames
        w.write_transforms(5, tf)
    assert _channels(tmp_path / "none.mcap") == {}
    with MissionWriter(tmp_path / "text.mcap", codecs=run_codecs(load_registry(extra={"txt": TextMirrors()}))) as w:
        w.write_transforms(5, tf)
    assert _channels(tmp_path / "text.mcap") == {"/frames": [({MIRROR_KEY: "frames"}, 5, repr(tf).encode())]}


def test_two_plugins_mirroring_one_type_is_an_error_naming_both() -> None:
    class Again(TextMirrors):
        pass

    with pytest.raises(NameConflictError,
                       match="'mirror:builtins.float' is registered by two plugins: '[ab]' and '[ab]'"):
        load_registry(extra={"a": TextMirrors(), "b": Again()})
