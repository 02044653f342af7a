"""A rosbag2 folder (``metadata.yaml`` and its split ``.mcap`` files) read as one mission.

:func:`open_recording` opens a file with :class:`~impala_flow.io.MissionReader` and a folder with
:class:`BagReader`: the files its ``metadata.yaml`` lists (``rosbag2_bagfile_information.relative_file_paths``,
storage ``mcap``), or every ``*.mcap`` of the folder in name order when it has none. The parts are read one after
the other (a split recording's parts follow each other in time; overlapping parts are refused), put in time order
by one reordering window; a channel adapter reads a topic across every part (one adapter: its turn count and
geometry carry on); counts, losses and problems are the parts' summed, each problem naming its file.
"""

from __future__ import annotations

import dataclasses
import itertools
import os
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

import yaml

from ._errors import RecordingError, UnknownSchemaError
from ._reader import ChannelInfo, Loss, MissionReader, Recorded, RecordingInfo
from ._registry import CodecRegistry

__all__ = ["BagReader", "open_recording", "bag_files"]


def bag_files(folder: str | os.PathLike[str]) -> list[Path]:
    """The MCAP files of a rosbag2 folder, in order; RecordingError (one line) when it has none or is not MCAP."""
    root = Path(folder)
    meta = root / "metadata.yaml"
    if meta.is_file():
        try:
            doc = yaml.safe_load(meta.read_text(encoding="utf-8")) or {}
            info = doc["rosbag2_bagfile_information"]
            storage = str(info.get("storage_identifier", "mcap"))
            names = [str(p) for p in info.get("relative_file_paths") or []]
        except (OSError, yaml.YAMLError, KeyError, TypeError, AttributeError) as e:
            raise RecordingError(str(meta), f"not a rosbag2 metadata.yaml ({type(e).__name__}: {e})") from None
        if storage != "mcap":
            raise RecordingError(str(meta), f"storage {storage!r}: only MCAP rosbag2 recordings are read "
                                            "(convert with `ros2 bag convert`)")
        files = [root / n for n in names]
        missing = [str(f) for f in files if not f.is_file()]
        if missing:
            raise RecordingError(str(meta), f"lists {len(missing)} file(s) not in the folder, first {missing[0]}")
    else:
        files = sorted(root.glob("*.mcap"))
    if not files:
        raise RecordingError(str(root), "a directory with no .mcap file (nor a rosbag2 metadata.yaml listing "
                                        "some): not a recording")
    return files


def open_recording(path: str | os.PathLike[str], codecs: CodecRegistry | None = None,
                   **options: Any) -> MissionReader | BagReader:
    """A reader of ``path``: a :class:`MissionReader` for a file, a :class:`BagReader` for a rosbag2 folder."""
    if os.path.isdir(path):
        return BagReader(path, codecs, **options)
    return MissionReader(path, codecs, **options)


class BagReader:
    """The parts of a split rosbag2 recording as one :class:`MissionReader` (the same reading methods)."""

    def __init__(self, folder: str | os.PathLike[str], codecs: CodecRegistry | None = None, **options: Any) -> None:
        self.path = os.fspath(folder)
        self.parts: list[MissionReader] = []
        try:
            for f in bag_files(folder):
                self.parts.append(MissionReader(f, codecs, **options))
        except BaseException:
            self.close()
            raise
        self.codecs = self.parts[0].codecs
        self.parts.sort(key=lambda p: (p.info().start_ns is None, p.info().start_ns or 0))
        for a, b in zip(self.parts, self.parts[1:], strict=False):
            ia, ib = a.info(), b.info()
            if ia.end_ns is not None and ib.start_ns is not None and ib.start_ns < ia.end_ns:
                self.close()
                raise RecordingError(self.path, f"{os.path.basename(b.path)} starts before {os.path.basename(a.path)} "
                                                "ends: not the parts of one split recording")
        self._share_adapters()

    def _share_adapters(self) -> None:
        """One adapter per topic for every part (built by the first part holding the topic)."""
        shared: dict[str, Any] = {}
        for part in self.parts:
            for cid, ch in part._map.channels.items():  # noqa: SLF001 - the same package's reader
                c = shared.get(ch.topic)
                if c is None:
                    c = shared[ch.topic] = part._codec(cid)  # noqa: SLF001
                elif hasattr(c, "adapt"):
                    part._codecs[cid] = c  # noqa: SLF001

    # --- what MissionReader says, over the parts ----------------------------------------------------------------

    @property
    def topics(self) -> dict[str, str]:
        out: dict[str, str] = {}
        for part in self.parts:
            out.update({t: s for t, s in part.topics.items() if t not in out})
        return out

    def topic_type(self, topic: str) -> type:
        for part in self.parts:
            if topic in part.topics:
                return part.topic_type(topic)
        raise KeyError(f"{self.path}: no topic {topic!r} (recorded: {sorted(self.topics)})")

    @property
    def undecodable(self) -> dict[str, UnknownSchemaError]:
        return {t: e for part in self.parts for t, e in part.undecodable.items()}

    @property
    def losses(self) -> list[Loss]:
        return [loss for part in self.parts for loss in part.losses]

    @property
    def late(self) -> dict[str, int]:
        out: dict[str, int] = {}
        for part in self.parts:
            for t, n in part.late.items():
                out[t] = out.get(t, 0) + n
        return out

    def lost_counts(self) -> dict[str, int | None]:
        out: dict[str, int | None] = {}
        for part in self.parts:
            for t, n in part.lost_counts().items():
                prev = out.get(t, 0)
                out[t] = None if prev is None or n is None else prev + n
        return out

    def skipped_counts(self) -> dict[str, int]:
        out: dict[str, int] = {}
        for part in self.parts:
            for t, n in part.skipped_counts().items():
                out[t] = out.get(t, 0) + n
        return out

    def adapters(self) -> dict[str, Any]:
        out: dict[str, Any] = {}
        for part in self.parts:
            out.update(part.adapters())
        return out

    def metadata(self) -> dict[str, dict[str, str]]:
        out: dict[str, dict[str, str]] = {}
        for part in self.parts:
            out.update(part.metadata())
        return out

    def info(self) -> RecordingInfo:
        infos = [p.info() for p in self.parts]
        starts = [i.start_ns for i in infos if i.start_ns is not None]
        ends = [i.end_ns for i in infos if i.end_ns is not None]
        start, end = (min(starts), max(ends)) if starts else (None, None)
        dur_s = ((end or 0) - (start or 0)) * 1e-9
        merged: dict[str, ChannelInfo] = {}
        for i in infos:
            for c in i.channels:
                prev = merged.get(c.topic)
                n = c.count + (prev.count if prev else 0)
                merged[c.topic] = dataclasses.replace(c, count=n, decodable=c.decodable and (prev is None or
                                                                                            prev.decodable),
                                                      rate_hz=max(n - 1, 0) / dur_s if dur_s > 0 else 0.0)
        comps = sorted({c for i in infos for c in i.compression.split("+") if c != "none"})
        recovered = [i.recovered_count for i in infos if i.recovered_count is not None]
        return RecordingInfo(
            path=self.path, size_bytes=sum(i.size_bytes for i in infos), channels=tuple(merged.values()),
            message_count=sum(i.message_count for i in infos), start_ns=start, end_ns=end,
            compression="+".join(comps) or "none", chunk_count=sum(i.chunk_count for i in infos),
            truncated=any(i.truncated for i in infos), recovered_count=sum(recovered) if recovered else None,
            corrupt_chunks=sum(i.corrupt_chunks for i in infos),
            problems=tuple(p for i in infos for p in i.problems), metadata=self.metadata(),
            library=infos[0].library, profile=infos[0].profile, mirror_count=sum(i.mirror_count for i in infos),
            attachments=tuple(a for i in infos for a in i.attachments), verified=all(i.verified for i in infos))

    def verify(self) -> list[str]:
        return [p for part in self.parts for p in part.verify()]

    def messages(self, topics: Iterable[str] | None = None, start_ns: int | None = None,
                 end_ns: int | None = None, *, raw: bool = False, finish: bool = True) -> Iterator[Recorded]:
        """The parts' samples, one part after the other (rosbag2 splits a recording in time: the parts follow each
        other; each part's channel adapters carry on into the next)."""
        wanted = None if topics is None else [topics] if isinstance(topics, str) else list(topics)
        if wanted is not None:
            unknown = set(wanted) - set(self.topics)
            if unknown:
                raise KeyError(f"{self.path}: no topic {sorted(unknown)[0]!r} (recorded: {sorted(self.topics)})")
        chosen = []
        for part in self.parts:
            mine = None if wanted is None else [t for t in wanted if t in part.topics]
            if mine is None or mine:
                chosen.append(part._records(mine, start_ns, end_ns, raw))  # noqa: SLF001 - the same package
        if not chosen:
            return iter(())
        adapted = {cid_w[0]: cid_w[1] for _, w in chosen for cid_w in w.values() if hasattr(cid_w[1], "adapt")}
        records = itertools.chain.from_iterable(merged for merged, _ in chosen)
        if not adapted:
            return records
        first = self.parts[0]  # one reordering over every part: its late counts are the recording's
        if finish:
            records = first._finish(records, {k: (t, a) for k, (t, a) in enumerate(adapted.items())})  # noqa: SLF001
        return first._reorder(records)  # noqa: SLF001

    def close(self) -> None:
        for part in self.parts:
            part.close()

    def __enter__(self) -> BagReader:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
