"""``MissionReader.verify()``: every chunk checked against everything that describes it.

Each chunk is read once: its CRC (and decompressed size), the message times of its header
and of its chunk index, its message indexes (the TypeScript reader Foxglove uses rejects a
file whose index points outside a chunk: each entry must point at the start of a message
record of that channel and log time, and every message must have its entry), and finally
the statistics against the messages actually readable. A damaged chunk is one problem,
counted once; the counts returned are the readable messages per channel.
"""

from __future__ import annotations

from typing import BinaryIO

import numpy as np
from mcap.opcode import Opcode

from . import _mcapfile as mf
from ._errors import CorruptChunkError, RecordingError

__all__ = ["verify_file"]


def _messages(records: memoryview) -> dict[int, list[tuple[int, int]]]:
    """Channel -> [(log time, offset of the record in the chunk)] in chunk order."""
    out: dict[int, list[tuple[int, int]]] = {}
    pos, n = 0, len(records)
    unpack_rec, unpack_msg = mf._REC.unpack_from, mf.MSG_HEAD.unpack_from
    while pos + 9 <= n:
        op, length = unpack_rec(records, pos)
        if op == Opcode.MESSAGE and length >= mf.MSG_HEAD.size:
            cid, _, t, _ = unpack_msg(records, pos + 9)
            out.setdefault(cid, []).append((t, pos))
        pos += 9 + length
    return out


def _check_indexes(path: str, f: BinaryIO, fm: mf.FileMap, ref: mf.ChunkRef,
                   found: dict[int, list[tuple[int, int]]]) -> list[str]:
    problems = []
    where = f"{path}: chunk at offset {ref.offset}"
    for cid, at in sorted(ref.index.items()):
        try:
            got_cid, entries = mf.read_message_index(path, f, at, fm.size)
        except RecordingError as e:
            problems.append(str(e))
            continue
        if got_cid != cid:
            problems.append(f"{where}: message index at offset {at} is for channel {got_cid}, "
                            f"the chunk index says {cid}")
        pairs = sorted(found.get(got_cid, []), key=lambda p: p[1])
        want = np.array(pairs, np.uint64).reshape(-1, 2)
        have = entries[np.argsort(entries[:, 1], kind="stable")]
        if have.shape != want.shape or not np.array_equal(have, want):
            bad = _first_mismatch(have, want)
            problems.append(f"{where}: message index of channel {got_cid} (offset {at}) does not match "
                            f"the data ({len(have)} entries, {len(want)} messages; {bad})")
    if ref.index:
        missing = sorted(set(found) - set(ref.index))
        if missing:
            problems.append(f"{where}: no message index for channel(s) {missing}")
    return problems


def _first_mismatch(have: np.ndarray, want: np.ndarray) -> str:
    wanted = {(int(t), int(o)) for t, o in want}
    for t, o in have:
        if (int(t), int(o)) not in wanted:
            return f"entry t={int(t)} ns, offset {int(o)}: no such message there"
    return "messages without an entry"


def verify_file(path: str, f: BinaryIO, fm: mf.FileMap) -> tuple[dict[int, int], list[str]]:
    """(readable messages per channel, problems) of the file mapped by ``fm``."""
    problems = [str(p) for p in fm.problems if not isinstance(p, CorruptChunkError)]
    if fm.truncated:
        problems.append(f"{path}: truncated recording (no valid footer/summary)")
    counts: dict[int, int] = {}
    lo = hi = None
    for ref in sorted(fm.chunks, key=lambda r: r.offset):
        f.seek(ref.offset)
        raw = f.read(ref.length)
        try:
            if ref.loose:
                records = memoryview(raw)
                head = ref
            else:
                head, records = mf.parse_chunk(path, ref.offset, raw)
        except CorruptChunkError as e:
            fm.corrupt_offsets.add(ref.offset)
            problems.append(str(e))
            continue
        found = _messages(records)
        times = [t for pairs in found.values() for t, _ in pairs]
        for cid, pairs in found.items():
            counts[cid] = counts.get(cid, 0) + len(pairs)
        if not times or ref.loose:
            lo = min(times + ([lo] if lo is not None else []), default=lo)
            hi = max(times + ([hi] if hi is not None else []), default=hi)
            continue
        t0, t1 = min(times), max(times)
        lo, hi = (t0 if lo is None else min(lo, t0)), (t1 if hi is None else max(hi, t1))
        where = f"{path}: chunk at offset {ref.offset}"
        if (head.start_ns, head.end_ns) != (t0, t1):
            problems.append(f"{where}: header says t={head.start_ns}..{head.end_ns} ns, messages span "
                            f"{t0}..{t1} ns")
        elif (ref.start_ns, ref.end_ns) != (t0, t1):
            problems.append(f"{where}: chunk index says t={ref.start_ns}..{ref.end_ns} ns, messages "
                            f"span {t0}..{t1} ns")
        if fm.indexed and (ref.length, ref.compression) != (head.length, head.compression):
            problems.append(f"{where}: chunk index says {ref.length} bytes {ref.compression or 'none'}, "
                            f"the record is {head.length} bytes {head.compression or 'none'}")
        problems += _check_indexes(path, f, fm, ref, found)
    if fm.indexed and not fm.corrupt_offsets:
        for cid in sorted(set(counts) | set(fm.counts)):
            if counts.get(cid, 0) != fm.counts.get(cid, 0):
                topic = fm.channels[cid].topic if cid in fm.channels else f"channel {cid}"
                problems.append(f"{path}: statistics say {fm.counts.get(cid, 0)} messages on {topic!r}, "
                                f"{counts.get(cid, 0)} readable")
        if sum(counts.values()) and (fm.start_ns, fm.end_ns) != (lo, hi):
            problems.append(f"{path}: statistics say t={fm.start_ns}..{fm.end_ns} ns, messages span "
                            f"{lo}..{hi} ns")
    return counts, problems
