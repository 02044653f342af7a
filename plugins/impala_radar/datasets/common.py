"""What every Navtech dataset reader shares: the sensor description, the scan record, the
time-ordered beam and truth stream, the import report and the one-line errors."""

from __future__ import annotations

import csv
import functools
import io
import math
import queue
import threading
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

import impala_msgs
from impala_flow import msgs

__all__ = ["DatasetError", "ImportReport", "Scan", "NavtechDataset", "navtech_config", "iter_mission",
           "read_csv_columns", "enu_to_odom", "counts_to_power", "power_of_counts", "pixel_power", "gap_summary",
           "time_steps_back", "t_text",
           "check_option", "read_text", "unix_times_ns", "check_span", "refuse_steps_back", "check_turn_period",
           "check_speed", "MAX_MISSION_SPAN_S", "MAX_STEP_BACK_S", "MAX_SPEED_MPS", "NAVTECH_TURN_S",
           "UNIX_S_MAX", "DB_PER_COUNT_MAX", "RANGE_RESOLUTION_MAX_M", "RANGE_OFFSET_MAX_BINS"]

_EMPTY = np.zeros(0, dtype=np.float32)
_BACK = "time going back or repeated"

# What a dataset may hold; beyond these bounds a value is refused (DatasetError naming where it came from).
#: latest Unix time (s) of a recording: 2100-01-01 (the earliest is 0: synthetic logs start there)
UNIX_S_MAX = 4_102_444_800
#: longest mission (scan times, first to last): the datasets' sequences last an hour at most
MAX_MISSION_SPAN_S = 86_400.0
#: largest step back of a log's clock that is a quirk (dropped or re-joined): RADIATE's GPS steps 0.36 s
MAX_STEP_BACK_S = 10.0
#: fastest a ground vehicle of these datasets moves (360 km/h); truth implying more is refused
MAX_SPEED_MPS = 100.0
#: the Navtech CTS350-X / CIR304-H turn (4 Hz): scans come no faster than MIN_TURN_FRACTION of it
#: (measured: 0.2386 s on RADIATE fog_6_0, 0.2499 s on Edinburgh, 0.249 s on Oxford and Boreas)
NAVTECH_TURN_S = 0.25
MIN_TURN_FRACTION = 0.8
#: a single frame stamped closer than this fraction of a turn to the one before is no new turn
MIN_INTERVAL_FRACTION = 0.5
#: option bounds: 0.5 dB per count is Navtech's (1 dB x 255 counts = 255 dB, already far beyond a radar)
DB_PER_COUNT_MAX = 1.0
RANGE_RESOLUTION_MAX_M = 10.0  # Navtech bins are 4-18 cm
RANGE_OFFSET_MAX_BINS = 1000.0


class DatasetError(ValueError):
    """Bad dataset input; the message is one line naming the file and the row or scan."""


def check_option(name: str, value: float, lo: float, hi: float, unit: str = "", lo_open: bool = False) -> float:
    """``value`` as a float when finite and within ``[lo, hi]`` (``(lo, hi]`` with ``lo_open``),
    else a :class:`DatasetError` naming the option: what a reader's constructor takes is checked
    where it enters, for the API as for the command."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise DatasetError(f"option {name}: {value!r} is not a number") from None
    if not (math.isfinite(v) and (v > lo if lo_open else v >= lo) and v <= hi):
        raise DatasetError(f"option {name}: {value!r} {unit}: expected a finite value in "
                           f"{'(' if lo_open else '['}{lo:g}, {hi:g}] {unit}".replace("  ", " ").rstrip())
    return v


def read_text(path: Path, what: str, max_bytes: int = 1 << 30) -> str:
    """The text of ``path`` (UTF-8); a folder, a device or pipe, an unreadable file, one over
    ``max_bytes`` or bytes that are no text are a :class:`DatasetError` naming the file (and the
    line of the first bad byte)."""
    path = Path(path)
    if path.is_dir():
        raise DatasetError(f"{path}: a folder, expected {what}")
    if path.exists() and not path.is_file():
        raise DatasetError(f"{path}: not a regular file (device, pipe or socket), expected {what}")
    try:
        with open(path, "rb") as f:
            data = f.read(max_bytes + 1)
    except OSError as e:
        raise DatasetError(f"{path}: cannot read {what} ({e.strerror or e})") from None
    if len(data) > max_bytes:
        raise DatasetError(f"{path}: over {max_bytes} bytes, too large for {what}")
    nl = b"\n"
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as e:
        raise DatasetError(f"{path}: line {data[:e.start].count(nl) + 1}: byte 0x{data[e.start]:02x} is not "
                           f"text ({what} expected)") from None
    nul = text.find("\0")
    if nul >= 0:
        raise DatasetError(f"{path}: line {text[:nul].count(chr(10)) + 1}: NUL byte, not text ({what} expected)")
    return text


def unix_times_ns(path: Path, text: np.ndarray, unit_ns: int, column: str, first_row: int = 2) -> np.ndarray:
    """A column of integer Unix times (text, in units of ``unit_ns``) as int64 ns; a field that
    is no integer, negative or after :data:`UNIX_S_MAX` is a :class:`DatasetError` naming the
    file, the row and the value (never an overflow)."""
    text = np.asarray(text, dtype=str).reshape(-1)
    hi = UNIX_S_MAX * 1_000_000_000 // unit_ns
    try:
        v = text.astype(np.int64)
        bad = np.flatnonzero((v < 0) | (v > hi))
    except (ValueError, OverflowError):
        bad = np.arange(text.size)
    for i in bad.tolist():
        s = text[i].strip()
        if not (s.isascii() and s.lstrip("-").isdigit()):
            raise DatasetError(f"{path}: row {i + first_row}: {column} {s!r} is not an integer")
        if not 0 <= int(s) <= hi:
            raise DatasetError(f"{path}: row {i + first_row}: {column} {s} is not a Unix time of 1970-2100")
    return v * np.int64(unit_ns)


def check_span(t_ns: np.ndarray, where: str) -> None:
    """A mission whose times span more than :data:`MAX_MISSION_SPAN_S` is refused (``where``
    names what the times are)."""
    t = np.asarray(t_ns, dtype=np.int64)
    if t.size and (int(t.max()) - int(t.min())) > MAX_MISSION_SPAN_S * 1e9:
        span = (int(t.max()) - int(t.min())) / 1e9
        raise DatasetError(f"{where}: times span {span:.0f} s ({span / 86400:.1f} days, from {t_text(int(t.min()))} "
                           f"to {t_text(int(t.max()))} s): more than one recording ({MAX_MISSION_SPAN_S:.0f} s)")


def refuse_steps_back(t_ns: np.ndarray, where: object) -> None:
    """A time more than :data:`MAX_STEP_BACK_S` before an earlier one of the same log is no
    clock quirk: a :class:`DatasetError`; ``where(i)`` names sample i (file and row)."""
    t = np.asarray(t_ns, dtype=np.int64)
    if t.size < 2:
        return
    back = np.maximum.accumulate(t)[:-1] - t[1:]
    big = np.flatnonzero(back > MAX_STEP_BACK_S * 1e9)
    if big.size:
        i = int(big[0]) + 1
        raise DatasetError(f"{where(i)}: time {t_text(int(t[i]))} s is {back[i - 1] / 1e9:.3f} s before an earlier "
                           f"one: a clock step back of more than {MAX_STEP_BACK_S:g} s is no logging quirk")


def check_turn_period(period_s: float, where: str) -> None:
    """Scans coming faster than the sensor can turn (a period under :data:`MIN_TURN_FRACTION` of
    :data:`NAVTECH_TURN_S`) are refused."""
    lo = MIN_TURN_FRACTION * NAVTECH_TURN_S
    if not period_s >= lo:
        raise DatasetError(f"{where}: one turn every {period_s:.4f} s ({1.0 / max(period_s, 1e-9):.1f} Hz): faster "
                           f"than the Navtech turns ({NAVTECH_TURN_S:g} s, 4 Hz; at least {lo:g} s)")


def check_speed(t_ns: np.ndarray, east_m: np.ndarray, north_m: np.ndarray, where: object) -> None:
    """Consecutive positions implying more than :data:`MAX_SPEED_MPS` are refused; ``where(i)``
    names sample i. Times strictly increasing."""
    if len(t_ns) < 2:
        return
    dt = np.diff(np.asarray(t_ns, dtype=np.int64)) / 1e9
    v = np.hypot(np.diff(east_m), np.diff(north_m)) / dt
    bad = np.flatnonzero(~(v <= MAX_SPEED_MPS))
    if bad.size:
        i = int(bad[0]) + 1
        raise DatasetError(f"{where(i)}: {v[i - 1]:.4g} m/s since the sample before ({dt[i - 1]:.3f} s earlier): "
                           f"faster than {MAX_SPEED_MPS:g} m/s")


def navtech_config(name: str, n_bins: int, range_per_bin_m: float, *, range_offset_m: float,
                   beams_per_turn: int, rotation_hz: float) -> impala_msgs.RadarConfig:
    """A power-only Navtech radar (76-77 GHz sweep) as a :class:`~impala_msgs.RadarConfig`:
    :meth:`~impala_msgs.RadarConfig.power_only` (one sweep per azimuth, ``bin_hz`` giving the
    dataset's range per bin; bin k at ``range_offset_m + k range_per_bin_m``)."""
    return impala_msgs.RadarConfig.power_only(name, n_bins, range_per_bin_m, range_offset_m, beams_per_turn,
                                              rotation_hz)


class Scan:
    """One antenna turn in acquisition order: per-row ``t_ns`` (int64), ``azimuth_rad`` (project
    convention: CCW, 0 = forward, wrapped), ``power`` (float32 rows x bins, value / 255),
    ``keep`` (rows emitted as beams; the others are dropped for ``drop_reason``) and ``chirp``
    (per row, ``RadarBeam.chirp``: +1 up, -1 down; None when the format does not tell).

    A reader may give the 8-bit pixels ``counts`` (uint8 rows x bins) instead of ``power``:
    ``power`` is then ``counts / 255`` in float32, made when first read, and the import turns the
    counts into linear power by table (:func:`power_of_counts`), with no float pass."""

    __slots__ = ("path", "t_ns", "azimuth_rad", "_power", "keep", "drop_reason", "chirp", "counts")

    def __init__(self, path: Path, t_ns: np.ndarray, azimuth_rad: np.ndarray, power: np.ndarray | None,
                 keep: np.ndarray, drop_reason: str = "", chirp: np.ndarray | None = None,
                 counts: np.ndarray | None = None) -> None:
        if power is None and counts is None:
            raise ValueError("a Scan needs its power or its counts")
        self.path, self.t_ns, self.azimuth_rad, self._power = path, t_ns, azimuth_rad, power
        self.keep, self.drop_reason, self.chirp, self.counts = keep, drop_reason, chirp, counts

    @property
    def power(self) -> np.ndarray:
        if self._power is None:
            self._power = pixel_power(self.counts)
        return self._power


def pixel_power(counts: np.ndarray) -> np.ndarray:
    """8-bit pixels ``counts`` as the scans' ``power``: float32 ``count / 255``, in [0, 1]."""
    return counts.astype(np.float32) / np.float32(255.0)


@dataclass
class ImportReport:
    """What a reader read: printed by ``impala-flow import`` (:meth:`lines`) and given as
    plain key/values (:meth:`as_metadata`)."""

    dataset: str = ""
    folder: str = ""
    config: impala_msgs.RadarConfig | None = None
    turns: int = 0
    beams: int = 0
    dropped_rows: Counter = field(default_factory=Counter)  # reason -> rows
    skipped_scans: list[str] = field(default_factory=list)  # "file: reason"
    truth_poses: int = 0
    facts: dict[str, str] = field(default_factory=dict)  # what the reader checked, one line each
    notes: list[str] = field(default_factory=list)

    def fact(self, key: str, text: str) -> None:
        """One line of the import block (``key: text``), also a metadata entry (``key`` with
        ``_`` for spaces): what was checked and what was done, said even when nothing was."""
        self.facts[key] = text

    def sensor_line(self) -> str:
        c = self.config
        if c is None:
            return "-"
        return (f"{c.name}, {c.beams_per_turn} beams/turn at {c.rotation_hz:.3f} Hz, {c.n_bins} bins x "
                f"{c.range_per_bin_m:.5f} m = {c.n_bins * c.range_per_bin_m:.1f} m "
                f"(bin 0 at {c.range_offset_m:.4f} m)")

    def lines(self) -> list[str]:
        dropped = sum(self.dropped_rows.values())
        out = [f"dataset:      {self.dataset} ({self.folder})",
               f"sensor:       {self.sensor_line()}",
               f"turns:        {self.turns}",
               f"beams:        {self.beams}",
               "rows dropped: " + ("0" if not dropped else f"{dropped} (" + ", ".join(
                   f"{n} {reason}" for reason, n in sorted(self.dropped_rows.items())) + ")")]
        if self.skipped_scans:
            out.append(f"scans skipped: {len(self.skipped_scans)} (" + "; ".join(self.skipped_scans) + ")")
        out.append(f"truth poses:  {self.truth_poses}")
        out += [f"{key + ':':<13} {text}" for key, text in self.facts.items()]
        out += [f"note:         {n}" for n in self.notes]
        return out

    def as_metadata(self) -> dict[str, str]:
        c = self.config
        meta = {"dataset": self.dataset, "folder": self.folder, "sensor": self.sensor_line(),
                "turns": str(self.turns), "beams": str(self.beams),
                "rows_dropped": str(sum(self.dropped_rows.values())),
                "truth_poses": str(self.truth_poses)}
        if c is not None:
            meta.update(n_bins=str(c.n_bins), range_per_bin_m=repr(c.range_per_bin_m),
                        range_offset_m=repr(c.range_offset_m), beams_per_turn=str(c.beams_per_turn))
        meta.update({f"rows_dropped[{r}]": str(n) for r, n in sorted(self.dropped_rows.items())})
        if self.skipped_scans:
            meta["scans_skipped"] = "; ".join(self.skipped_scans)
        meta.update({key.replace(" ", "_"): text for key, text in self.facts.items()})
        meta.update({f"note{i}": n for i, n in enumerate(self.notes)})
        return meta


class NavtechDataset:
    """Base of the readers: a sorted list of scan files, a sensor ``config``, ``read_scan(k)``
    and ``truth()``. Subclasses check the folder in ``__init__`` (raising
    :class:`DatasetError`) and fill ``scan_paths`` and ``config``."""

    name = ""
    scan_paths: list[Path]
    config: impala_msgs.RadarConfig

    def read_scan(self, k: int) -> Scan:
        raise NotImplementedError

    def truth(self, report: ImportReport) -> tuple[np.ndarray, ...] | None:
        """Ground truth as ``(t_ns int64 (N,), xyt (N, 3))`` or ``(t_ns, xyt, cov_xyt (N, 3, 3))``
        in frame ``odom`` (x forward, y left, yaw CCW), times strictly increasing, or None (with
        a note in ``report``). A pose whose ``cov_xyt[2, 2] >= msgs.HEADING_UNKNOWN_VAR_RAD2``
        has an unknown heading (``theta`` a placeholder)."""
        return None

    def duration_hint_ns(self) -> int | None:
        return None


def counts_to_power(power: np.ndarray, db_per_count: float) -> np.ndarray:
    """Linear power (float32) of Navtech pixels ``power`` = count / 255: the radar writes its
    power on a log scale, ``db_per_count`` dB per count (0.5 for the CTS350-X and CIR304-H:
    0-127.5 dB over the 8 bits), so P = 10^(count db_per_count / 10), 1 at count 0. Every
    beam of the project carries linear power (the simulator's unit), so one graph serves
    simulated and real missions. ``db_per_count`` must be in (0, :data:`DB_PER_COUNT_MAX`]."""
    db_per_count = check_option("db_per_count", db_per_count, 0.0, DB_PER_COUNT_MAX, "dB", lo_open=True)
    counts = np.rint(np.asarray(power, np.float64) * 255.0)  # the integer count, exactly
    if counts.size > 256 and counts.min() >= 0.0 and counts.max() <= 255.0:
        # 256 powers looked up: the same float64 expression per count, not one per pixel
        table = _power_table(float(db_per_count))
        return table[counts.astype(np.intp)]
    db = counts * db_per_count
    return np.power(10.0, db / 10.0).astype(np.float32)


@functools.lru_cache(maxsize=16)
def _power_table(db_per_count: float) -> np.ndarray:
    """float32 linear power of the counts 0..255, computed each as :func:`counts_to_power` does."""
    db = np.arange(256, dtype=np.float64) * db_per_count
    table = np.power(10.0, db / 10.0).astype(np.float32)
    table.flags.writeable = False
    return table


def power_of_counts(counts: np.ndarray, db_per_count: float) -> np.ndarray:
    """:func:`counts_to_power` of the pixels ``counts`` (uint8) / 255, bit for bit, without the float
    passes: ``rint(float64(float32(c) / 255) * 255) == c`` for every c in 0..255 (tested), so each
    pixel takes its count's table entry (one look-up: OpenCV's for an image, numpy's gather otherwise); up to
    256 pixels, :func:`counts_to_power` itself (it computes those per pixel)."""
    counts = np.asarray(counts)
    if counts.dtype != np.uint8:
        raise TypeError(f"counts must be uint8 pixels, got {counts.dtype}")
    if counts.size <= 256:
        return counts_to_power(pixel_power(counts), db_per_count)
    db_per_count = check_option("db_per_count", db_per_count, 0.0, DB_PER_COUNT_MAX, "dB", lo_open=True)
    table = _power_table(float(db_per_count))
    if counts.ndim == 2 and counts.strides[1] == 1:  # rows of pixels: OpenCV's table look-up, 4x numpy's gather
        import cv2  # here: imported by the plugin's registration already (panoramic), never by this module's users

        return cv2.LUT(counts, table)
    return table.take(counts)


#: Scans read and decoded ahead of the one being written (the worker thread's queue).
READ_AHEAD = 4


_Read = tuple["Scan | None", "np.ndarray | None", "BaseException | None"]  # (scan, linear power, error)


def _read(ds: NavtechDataset, k: int, db_per_count: float) -> _Read:
    """Scan ``k`` and its linear power, frozen before any of its beams is out and checked finite as a
    whole (``RadarBeam.check_turn``: the beams are its rows, each then checked without a pass)."""
    try:
        scan = ds.read_scan(k)
        if scan.counts is not None:
            power = power_of_counts(scan.counts, db_per_count)
        else:
            power = counts_to_power(scan.power, db_per_count)
        power.flags.writeable = False
        impala_msgs.RadarBeam.check_turn(power)  # here, on the reading thread: its beams then need no pass each
        return scan, power, None
    except BaseException as e:  # handed to the consumer, raised there in order
        return None, None, e


def _read_ahead(ds: NavtechDataset, db_per_count: float) -> Iterator[_Read]:
    """``(scan, linear power, error)`` of each scan in order, read and decoded on a worker
    thread up to :data:`READ_AHEAD` scans ahead (PNG inflation, Pillow and numpy release the
    GIL: the second core decodes while the caller encodes and writes). Each scan is decoded
    alone, so what comes out never depends on the threads' timing."""
    n = len(ds.scan_paths)
    if n < 2:
        for k in range(n):
            yield _read(ds, k, db_per_count)
        return
    q: queue.Queue = queue.Queue(maxsize=READ_AHEAD)
    stop = threading.Event()

    def work() -> None:
        for k in range(n):
            item = _read(ds, k, db_per_count)
            while not stop.is_set():
                try:
                    q.put(item, timeout=0.1)
                    break
                except queue.Full:
                    continue
            if stop.is_set():
                return

    worker = threading.Thread(target=work, name="impala-read-ahead", daemon=True)
    worker.start()
    try:
        for _ in range(n):
            yield q.get()
    finally:
        stop.set()
        worker.join()


def _beams(ds: NavtechDataset, report: ImportReport, skip_bad: bool, db_per_count: float,
           ) -> Iterator[tuple[int, str, impala_msgs.RadarBeam]]:
    last_t, noted = np.iinfo(np.int64).min, False
    for (k, path), (scan, power, err) in zip(enumerate(ds.scan_paths), _read_ahead(ds, db_per_count), strict=True):
        if err is not None:
            if not isinstance(err, DatasetError) or not skip_bad:
                raise err
            report.skipped_scans.append(str(err))
            continue
        # a row whose time does not pass the last one kept (within the scan or after the
        # previous scan) is dropped and counted, the first one named in a note
        rows = np.flatnonzero(scan.keep)
        t = scan.t_ns[rows]
        back = t <= np.maximum.accumulate(np.concatenate([[last_t], t[:-1]]))
        if back.any():
            i = int(np.argmax(back))
            before = last_t if i == 0 else int(np.max(t[:i]))
            if not noted:
                noted = True
                report.notes.append(f"{path}: row {int(rows[i])}: time goes back or repeats ({int(t[i])} ns after "
                                    f"{before} ns): row dropped (first of {_BACK})")
            if back.all():
                report.skipped_scans.append(f"{path}: every row's time at or before the previous scan's end "
                                            f"({last_t} ns): scan out of order, dropped")
                continue
            report.dropped_rows[_BACK] += int(back.sum())
            keep = scan.keep.copy()
            keep[rows[back]] = False
            scan = Scan(scan.path, scan.t_ns, scan.azimuth_rad, scan._power, keep, scan.drop_reason, scan.chirp,
                        scan.counts)
        n_drop = int(scan.keep.size - np.count_nonzero(scan.keep)) - int(back.sum())
        if n_drop:
            report.dropped_rows[scan.drop_reason or "dropped"] += n_drop
        report.turns += 1
        rows = np.flatnonzero(scan.keep)
        report.beams += rows.size
        if rows.size:
            last_t = int(scan.t_ns[rows[-1]])
        chirp = [0] * rows.size if scan.chirp is None else scan.chirp[rows].tolist()
        for i, ti, az, ch in zip(rows.tolist(), scan.t_ns[rows].tolist(), scan.azimuth_rad[rows].tolist(), chirp,
                                 strict=True):
            yield ti, "beams", impala_msgs.RadarBeam(az, k, i, power[i], _EMPTY, ds.config, int(ch))


def iter_mission(ds: NavtechDataset, report: ImportReport | None = None, skip_bad: bool = False,
                 db_per_count: float = 0.5) -> Iterator[tuple[int, str, impala_msgs.RadarBeam | msgs.Pose2D]]:
    """``(t_ns, "beams" | "truth", message)`` in time order (beams before a truth pose of the
    same time), the beams' power linear (:func:`counts_to_power`). Bad scans raise
    :class:`DatasetError`; with ``skip_bad`` they are skipped and listed in
    ``report.skipped_scans``. Dropped rows are counted by reason in ``report``."""
    check_option("db_per_count", db_per_count, 0.0, DB_PER_COUNT_MAX, "dB", lo_open=True)
    report = report if report is not None else ImportReport()
    report.dataset, report.config = report.dataset or ds.name, ds.config
    streams: list[Iterator] = [_beams(ds, report, skip_bad, db_per_count)]
    truth = ds.truth(report)
    if truth is not None and len(truth[0]):
        t, xyt = truth[0], truth[1]
        bad = np.flatnonzero(np.diff(t) <= 0)
        if bad.size:
            k = int(bad[0]) + 1
            raise DatasetError(f"{getattr(ds, 'folder', ds.name)}: truth pose {k} at {int(t[k])} ns is not after "
                               f"the one before ({int(t[k - 1])} ns)")
        # the last guard: no NaN or inf leaves a reader (each reader bounds what it reads; this names a miss)
        for what, v in (("pose", xyt), ("covariance", truth[2] if len(truth) > 2 else xyt)):
            bad = np.flatnonzero(~np.isfinite(np.asarray(v, dtype=np.float64).reshape(len(t), -1)).all(axis=1))
            if bad.size:
                raise DatasetError(f"{getattr(ds, 'folder', ds.name)}: truth {what} {int(bad[0])} at "
                                   f"t = {t_text(int(t[bad[0]]))} s is not finite")
        report.truth_poses = len(t)
        if len(truth) > 2:
            streams.append((int(ti), "truth", msgs.Pose2D(x, y, th, c, frame="odom"))
                           for ti, (x, y, th), c in zip(t.tolist(), xyt.tolist(), truth[2], strict=True))
        else:
            streams.append((int(ti), "truth", msgs.Pose2D(x, y, th, frame="odom"))
                           for ti, (x, y, th) in zip(t.tolist(), xyt.tolist(), strict=True))
    if len(streams) == 1:
        yield from streams[0]
    else:
        yield from _merge(streams[0], streams[1])


def _merge(beams: Iterator, truth: Iterator) -> Iterator[tuple[int, str, impala_msgs.RadarBeam | msgs.Pose2D]]:
    """The two streams merged by ``(t_ns, beams first)``, as ``heapq.merge`` would, each strictly increasing
    in time (beams as :func:`_beams` keeps them, truth as checked): a truth pose goes before the first beam
    after it, after a beam of its own time. Without a key call and a heap step per beam (160 000 a RADIATE
    head)."""
    nxt = next(truth, None)
    for item in beams:
        while nxt is not None and nxt[0] < item[0]:
            yield nxt
            nxt = next(truth, None)
        yield item
    if nxt is not None:
        yield nxt
        yield from truth


def read_csv_columns(path: Path, columns: list[str]) -> tuple[list[str], np.ndarray]:
    """Rows of a CSV file with a header, as text (N, len(columns)), in the order asked.
    A folder, an unreadable or binary file, an empty file, a header without rows, a missing
    column, a row with another number of fields than the header or an empty field is a
    :class:`DatasetError` naming the file and the row (1 = the header)."""
    what = "a CSV file with columns " + ", ".join(columns)
    reader = csv.reader(io.StringIO(read_text(path, what), newline=""))
    try:
        header = [h.strip() for h in next(reader, [])]
        if not header:
            raise DatasetError(f"{path}: row 1: empty file, expected a header with {', '.join(columns)}")
        missing = [c for c in columns if c not in header]
        if missing:
            raise DatasetError(f"{path}: row 1 (header): missing column(s) {', '.join(missing)}")
        idx = [header.index(c) for c in columns]
        rows = []
        for n, row in enumerate(reader, start=2):
            if not row or not "".join(row).strip():
                continue
            if len(row) != len(header) or any(not row[i].strip() for i in idx):
                raise DatasetError(f"{path}: row {n}: {len(row)} fields, expected {len(header)} "
                                   f"with {', '.join(columns)} filled")
            rows.append([row[i].strip() for i in idx])
    except csv.Error as e:
        raise DatasetError(f"{path}: row {reader.line_num}: not CSV ({e})") from None
    if not rows:
        raise DatasetError(f"{path}: row 1 (header) only: no data row")
    return header, np.array(rows, dtype=str).reshape(-1, len(columns))


def numbers(path: Path, text: np.ndarray, dtype: type, first_row: int = 2) -> np.ndarray:
    """``text`` (rows of strings) as numbers; a bad field is a :class:`DatasetError` with its row
    (for floats: also one that is not finite)."""
    try:
        out = text.astype(dtype)
    except (ValueError, OverflowError):
        for n, row in enumerate(text):
            for v in row:
                try:
                    np.array([v]).astype(dtype)
                except (ValueError, OverflowError):
                    raise DatasetError(f"{path}: row {n + first_row}: not a number: {str(v)!r}") from None
        raise
    if out.dtype.kind == "f":
        bad = np.argwhere(~np.isfinite(out))
        if bad.size:
            n, k = (int(i) for i in bad[0])
            raise DatasetError(f"{path}: row {n + first_row}: {str(text[n, k])!r}: not a finite number")
    return out


def enu_to_odom(east_m: np.ndarray, north_m: np.ndarray, yaw_enu_rad: np.ndarray) -> np.ndarray:
    """Poses in a local East-North frame (yaw of the vehicle's forward axis CCW from east) as
    ``xyt`` in frame ``odom``: the first pose at the identity, x forward, y left, yaw CCW."""
    e, n = east_m - east_m[0], north_m - north_m[0]
    c, s = math.cos(yaw_enu_rad[0]), math.sin(yaw_enu_rad[0])
    return np.column_stack([c * e + s * n, -s * e + c * n, msgs.wrap_angle(yaw_enu_rad - yaw_enu_rad[0])])


def t_text(t_ns: int) -> str:
    """Unix time in ns as exact seconds text (``1549986548.010563645``)."""
    return f"{t_ns // 1_000_000_000}.{t_ns % 1_000_000_000:09d}"


def gap_summary(t_ns: np.ndarray, period_ns: float, names: list[str] | None = None, what: str = "turn",
                whats: str = "turns") -> str:
    """One line on the missing samples of a stream meant to tick every ``period_ns``: an
    interval longer than 1.5 periods is a gap of ``round(dt / period) - 1`` missing samples.
    ``names`` (one per sample, e.g. frame numbers or files) name the sample after the longest."""
    dt = np.diff(np.asarray(t_ns, dtype=np.int64))
    if not dt.size:
        return f"none (one {what})"
    gap = np.flatnonzero(dt > 1.5 * period_ns)
    if not gap.size:
        return f"none (no {what} missing; longest interval {dt.max() / 1e9:.3f} s)"
    missing = np.rint(dt[gap] / period_ns).astype(np.int64) - 1
    k = int(gap[np.argmax(dt[gap])])
    after = f" before {names[k + 1]}" if names is not None else ""
    return (f"{gap.size} gap(s), {int(missing.sum())} {whats} missing; longest {dt[k] / 1e9:.3f} s{after} "
            f"(t = {t_text(int(t_ns[k + 1]))} s)")


def time_steps_back(t_ns: np.ndarray, equal_is_back: bool = True) -> np.ndarray:
    """Mask of the samples to drop so that the rest strictly increase (or never decrease,
    ``equal_is_back=False``): each sample is compared with the last one kept, so a clock
    step back drops every sample until the time passes the one before the step."""
    t = np.asarray(t_ns, dtype=np.int64)
    last = np.maximum.accumulate(t)  # the last kept time is the running maximum
    prev = np.concatenate([[np.iinfo(np.int64).min], last[:-1]])
    return (t <= prev) if equal_is_back else (t < prev)
