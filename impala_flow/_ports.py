"""Runtime ports: bounded input FIFOs with explicit overflow policies, sync groups,
history buffers with interpolation, and outputs that fan samples out without copies.

Input policies
--------------
``reactive`` (default)
    FIFO; every sample pushed triggers one ``process`` call of the owner.
``sampling``
    keeps the last value; never triggers.
``sync`` groups
    inputs declared with the same ``sync="name"`` fire together when each holds a sample
    within ``tolerance`` seconds of the others (like RTMaps synchronised readers or ROS
    ApproximateTime). Each sample is used at most once. When the heads of all queues
    are further apart than the tolerance, the earliest head can never be matched (every
    later sample of the other streams is later still): it is discarded and counted as
    ``unmatched``. When one stream stops, the samples of the others wait in their FIFOs
    (up to ``maxsize``, then the overflow policy applies) and whatever is left at the end
    of the run is counted as ``unmatched`` in the summary. Nothing is lost silently.
``history=SECONDS``
    any input may also keep the samples of the last SECONDS for ``at(t)`` (interpolated
    look-up) and ``between(t0, t1)``.

Validity (``validate=True``, the default of every input)
    a sample whose data is a message (:mod:`impala_flow.msgs`) is checked where it enters the
    input, before any policy, by its type's ``invalid_reason()`` (non-finite numbers,
    impossible values). An invalid sample is dropped, counted as ``invalid`` (and by reason in
    ``invalid_reasons``) and never reaches the component: the first of each reason at each
    input is one WARNING line naming the component, the input, the sample's time and origin;
    the rest are only counted, and the run summary prints one ``INVALID at component.input``
    line per input with the count of each reason. ``Input(..., validate=False)`` passes every
    sample through (a recorder that must keep what it is given, a diagnostic).

Overflow policies (``maxsize`` samples and ``maxbytes`` bytes per input)
    ``block``: the producer waits (real-time executor; the waits and the time spent are
    counted as ``blocked`` / ``blocked_ns`` and printed as BACKPRESSURE in the summary); the
    offline executor never drops and reports the high-water mark. ``drop_oldest`` /
    ``drop_newest``: the sample is dropped and counted. Every count is in the run summary
    and in ``InputPort.stats``.

Byte bounds (``maxbytes``, :data:`DEFAULT_MAXBYTES` = 64 MiB by default)
    A FIFO also holds at most ``maxbytes`` bytes of samples, whatever their count (1024
    queued 4 MB grids would be 4 GB): a sample that would take it over is handled by the
    same overflow policy as a full FIFO, its drops counted apart as ``dropped_maxbytes``
    (a LOST line of the summary). A sample larger than ``maxbytes`` on its own is still
    delivered into an empty FIFO (refusing it would make the input useless): the bytes held
    never exceed ``max(maxbytes, the largest single sample)``. A lone sample is never
    measured; ``high_water_bytes`` is the most bytes held at once by two samples or more.
    Offline, ``block`` never drops (the results are those of an unbounded run), so a FIFO
    whose consumer does not take its samples (a sync partner that stopped) and that
    reaches ``maxbytes`` fails the run with one line naming the component, the input and the
    time, instead of growing without bound; the drop policies apply offline as in real
    time (deterministically). A ``history`` buffer is bounded by ``maxbytes`` too: beyond
    it, its oldest samples are trimmed (counted as ``history_trimmed``) and ``at(t)`` is
    :class:`OutOfHistory` before the samples kept (interpolation is unchanged inside them).
    The size of a sample (:func:`data_nbytes`: arrays' ``nbytes``, bytes and str lengths,
    dataclass fields and containers summed, ``sys.getsizeof`` otherwise) is computed once
    and shared by every input it reaches, only when a second sample queues behind it.

Output types
    ``OutputPort.emit`` checks the emitted data against the port's declared type, by class
    and cached per port (one set look-up per emit once a class is known): ``Output(float)``
    accepts Python and numpy numbers (not bools), ``Output(int)`` integers, ``Output(bool)``
    numpy bools too, any other type its instances
    (subclasses included); ``Output(object)`` accepts anything. A mismatch raises
    :class:`OutputTypeError` naming the component, the port and the sample time.
"""

from __future__ import annotations

import bisect
import dataclasses
import sys
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from heapq import heappush as _heappush
from itertools import islice
from operator import attrgetter
from typing import Any

import numpy as np

from ._sample import Sample
from ._summary import ComponentError
from .msgs import freezer_for, wrap_angle

# a port's owner and declaration are a Component and its Input/Output (impala_flow._component):
# named, not imported, even for type checking: _component imports this module (no import circle)
Owner = Any
InputDecl = Any
OutputDecl = Any

__all__ = ["InputPort", "OutputPort", "SyncGroup", "PortStats", "OutOfHistory", "EmptyInput", "OutputTypeError",
           "DEFAULT_MAXBYTES", "data_nbytes", "sample_nbytes"]

POLICIES = ("reactive", "sampling")
OVERFLOWS = ("block", "drop_oldest", "drop_newest")

#: bytes an input FIFO (and, apart, its history buffer) holds at most by default: 16 of
#: the largest messages of the radar chain (4 MB grids; a Navtech scan is ~2.7 MB), a few
#: seconds of them at 4 Hz, and 64 MiB per input keeps a graph of tens of inputs < a few GB
DEFAULT_MAXBYTES = 64 << 20


class EmptyInput(LookupError):
    """``take()`` on an input that holds no sample."""


class OutOfHistory(LookupError):
    """``at(t)`` outside the span of an input's history buffer."""


class OutputTypeError(TypeError):
    """Data emitted on an output does not fit the output's declared type."""


#: declared type -> the extra classes it accepts (numbers: numpy scalars, int for float)
_NUMERIC_ALIASES: dict[type, tuple[type, ...]] = {
    float: (int, np.floating, np.integer),
    int: (np.integer,),
    complex: (int, float, np.number),
    bool: (np.bool_,),
}


@dataclass
class PortStats:
    received: int = 0
    dropped: int = 0
    unmatched: int = 0
    unconsumed: int = 0  # left in the FIFO at the end of the run (or in flight), never taken
    high_water: int = 0
    blocked: int = 0  # times a producer waited for room (block policy, real time)
    blocked_ns: int = 0  # total time producers waited
    dropped_maxbytes: int = 0  # dropped by the overflow policy because the FIFO held maxbytes
    high_water_bytes: int = 0  # most bytes held at once by two samples or more
    history_trimmed: int = 0  # history samples trimmed before their time because of maxbytes
    invalid: int = 0  # dropped on arrival: the message's invalid_reason() was not None
    invalid_reasons: dict[str, int] = field(default_factory=dict)  # reason -> count


#: message class -> its validity check (None: the class is not checked)
_CHECKS: dict[type, Callable[[Any], str | None] | None] = {}


def _check_of(cls: type) -> Callable[[Any], str | None] | None:
    """The ``invalid_reason`` of a message class (looked up once per class)."""
    try:
        return _CHECKS[cls]
    except KeyError:
        chk = getattr(cls, "invalid_reason", None) if "__impala_schema__" in cls.__dict__ else None
        _CHECKS[cls] = chk
        return chk


def _interpolate(a: Any, b: Any, w: float, angular: bool) -> Any:
    """Value at fraction ``w`` between ``a`` and ``b`` (``w`` in [0, 1])."""
    interp = getattr(type(a), "interpolate", None)
    if interp is not None:
        return interp(a, b, w)
    if isinstance(a, (int, float, np.floating, np.integer)) and not isinstance(a, bool):
        if angular:
            return wrap_angle(float(a) + w * wrap_angle(float(b) - float(a)))
        return float(a) + w * (float(b) - float(a))
    if isinstance(a, np.ndarray) and a.dtype.kind in "fiu":
        if angular:
            return wrap_angle(a + w * wrap_angle(b - a))
        return a + w * (b - a)
    return a if w < 1.0 else b  # not interpolable: zero-order hold


_FIXED = {int: 8, float: 8, bool: 8, complex: 16, type(None): 8, np.float64: 8, np.float32: 4, np.int64: 8,
          np.int32: 4, np.bool_: 1}  # bytes of scalars, by class
_MAX_DEPTH = 4  # nesting measured; deeper objects count sys.getsizeof
_MAX_ITEMS = 64  # items of a container measured; the others are assumed to have their mean size
_fields: dict[type, Callable[[Any], tuple] | None] = {}  # dataclass -> getter of its fields' values (None: other)


def _fields_getter(cls: type) -> Callable[[Any], tuple] | None:
    if not dataclasses.is_dataclass(cls):
        return None
    names = [f.name for f in dataclasses.fields(cls)]
    if len(names) >= 2:
        return attrgetter(*names)  # one call gives the tuple of values
    return lambda obj: tuple(getattr(obj, n) for n in names)


def data_nbytes(obj: Any, _depth: int = 0) -> int:
    """Bytes of ``obj``, cheaply and generically: ``nbytes`` of numpy arrays and scalars,
    the length of bytes and str, 8 for a number, the sum of a dataclass's fields (read by a
    getter cached per class) or of a container's items (the first 64 measured, 4 levels
    deep at most), ``sys.getsizeof`` otherwise. Shared sub-objects count once per owner."""
    cls = type(obj)
    if cls is np.ndarray:
        return obj.nbytes
    n = _FIXED.get(cls)
    if n is not None:
        return n
    if cls is bytes or cls is str or cls is bytearray:
        return len(obj)
    try:
        values = _fields[cls]
    except KeyError:
        values = _fields[cls] = _fields_getter(cls)
    if _depth >= _MAX_DEPTH:
        return obj.nbytes if isinstance(obj, (np.ndarray, np.generic)) else sys.getsizeof(obj)
    if values is not None:  # a message: its fields, the common ones without a call
        total = 0
        for v in values(obj):
            c = type(v)
            if c is np.ndarray:
                total += v.nbytes
            elif c is str:
                total += len(v)
            else:
                n = _FIXED.get(c)
                total += data_nbytes(v, _depth + 1) if n is None else n
        return total
    if isinstance(obj, (np.ndarray, np.generic, memoryview)):
        return obj.nbytes
    if isinstance(obj, (list, tuple, set, frozenset, dict)):
        items = list(islice(obj.items() if isinstance(obj, dict) else obj, _MAX_ITEMS))
        total = sum(data_nbytes(x, _depth + 1) for x in items)
        return total if len(obj) <= len(items) else total * len(obj) // len(items)
    return sys.getsizeof(obj)


def sample_nbytes(s: Sample) -> int:
    """:func:`data_nbytes` of ``s.data``, computed once per sample (every input it reaches shares it)."""
    n = s.nbytes
    if n < 0:
        n = s.nbytes = data_nbytes(s.data)
    return n


def _mib(n: int) -> str:
    return f"{n / (1 << 20):.1f} MiB"


class InputPort:
    """One input of one component instance (see the module docstring for policies)."""

    __slots__ = (
        "name", "owner", "decl", "policy", "maxsize", "overflow", "stats", "_fifo", "_last",
        "_hist_t", "_hist_s", "_history_ns", "group", "_current", "_cond", "angular",
        "trigger_name", "connected", "fed_back", "rank", "sources", "_fast", "maxbytes", "_nb", "_hist_nb", "validate",
    )

    def __init__(self, owner: Owner, name: str, decl: InputDecl) -> None:
        self.name = name
        self.owner = owner
        self.decl = decl
        self.policy = decl.policy
        self.maxsize = decl.maxsize
        self.overflow = decl.overflow
        self.maxbytes = decl.maxbytes
        self._nb = 0  # bytes of the FIFO's samples, kept while it holds two or more (a lone one is not measured)
        self._hist_nb = 0  # bytes of the history buffer's samples
        self.angular = decl.angular
        self.stats = PortStats()
        self._fifo: deque[Sample] = deque()
        self._last: Sample | None = None
        self._history_ns = None if decl.history is None else int(round(decl.history * 1e9))
        self._hist_t: list[int] = []
        self._hist_s: list[Sample] = []
        self.group: SyncGroup | None = None
        self._current: Sample | None = None
        self._cond: threading.Condition | None = None  # set by the real-time executor
        self.trigger_name = name if decl.sync is None else decl.sync
        self.connected = False
        self.sources: list[OutputPort] = []  # the outputs feeding this input
        self.fed_back = False  # a delayed connection ([delay]: a feedback loop) feeds this input
        self.rank = 0  # event key of the owner (2 x its graph rank), set by the offline executor
        # set by the offline executor for its run: a reactive input outside any sync group,
        # without history, on one thread: push() and take() skip every other case
        self._fast = False
        self.validate = bool(getattr(decl, "validate", True))

    # --- validity -------------------------------------------------------------------
    def invalid(self, s: Sample) -> bool:
        """True when ``s`` must be dropped as invalid (then counted as received and invalid,
        and the first of its reason at this input logged). The executors call it first."""
        if not self.validate:
            return False
        why = s.invalid
        if why is None:  # not checked yet (a sample fanned out to several inputs is checked once)
            data = s.data
            chk = _check_of(type(data))
            if chk is None:
                why = ""
            else:
                try:
                    why = chk(data) or ""
                except Exception as e:  # a check that cannot read the sample (wrong field types): invalid
                    why = f"unreadable ({type(e).__name__})"
            s.invalid = why
        if not why:
            return False
        st = self.stats
        st.received += 1
        st.invalid += 1
        n = st.invalid_reasons.get(why, 0) + 1
        st.invalid_reasons[why] = n
        if n == 1:
            self.owner.log.warning(
                "input '%s': sample t=%d ns from %s dropped as invalid: %s (further ones with this reason "
                "are counted, not logged: the total is in the run summary)",
                self.name, s.timestamp, s.origin or "?", why)
        return True

    # --- producer side ------------------------------------------------------------
    def push(self, s: Sample) -> bool:
        """Store ``s``; return True when the owner must be triggered now.

        The real-time executor calls it holding the owner's lock (the re-entrant lock of
        ``_cond``); the ``block`` policy waits on ``_cond``, which releases that lock. An
        invalid sample (see :meth:`invalid`) is dropped and counted; it never triggers.
        """
        if self.validate and self.invalid(s):
            return False
        st = self.stats
        st.received += 1
        self._last = s
        fifo = self._fifo
        if self._fast and not fifo:  # a lone sample always fits (and is not measured)
            fifo.append(s)
            if st.high_water < 1:
                st.high_water = 1
            return True
        if self._history_ns is not None:
            self._remember(s)
        if self.policy == "sampling" and self.group is None:
            return False
        if fifo:
            nb = self._bytes_with(s)
            if len(fifo) >= self.maxsize or nb > self.maxbytes:
                if not self._overflow(s):
                    return False
                nb = self._bytes_with(s) if fifo else 0
            self._nb = nb
            if nb > st.high_water_bytes:
                st.high_water_bytes = nb
        fifo.append(s)
        n = len(fifo)
        if n > st.high_water:
            st.high_water = n
        if self.group is not None:
            return self.group.match()
        return True

    def _bytes_with(self, s: Sample) -> int:
        """Bytes the (non-empty) FIFO would hold with ``s`` appended."""
        n = s.nbytes  # sample_nbytes(), inlined
        if n < 0:
            n = s.nbytes = data_nbytes(s.data)
        fifo = self._fifo
        if len(fifo) > 1:
            return self._nb + n
        h = fifo[0]
        m = h.nbytes
        if m < 0:
            m = h.nbytes = data_nbytes(h.data)
        return m + n

    def _full(self, s: Sample) -> bool:
        fifo = self._fifo
        return bool(fifo) and (len(fifo) >= self.maxsize or self._bytes_with(s) > self.maxbytes)

    def _pop(self) -> Sample:
        """Remove the FIFO's head, keeping its byte count (kept from two samples on)."""
        fifo = self._fifo
        s = fifo.popleft()
        if fifo:  # it held two or more: s was measured
            self._nb -= s.nbytes
        return s

    def _overflow(self, s: Sample) -> bool:
        """The FIFO is full (count or bytes) before ``s``: apply the overflow policy;
        False when ``s`` is dropped."""
        st, fifo = self.stats, self._fifo
        if self.overflow == "drop_newest":
            if len(fifo) >= self.maxsize:
                st.dropped += 1
            else:
                st.dropped_maxbytes += 1
            return False
        if self.overflow == "drop_oldest":
            while self._full(s):
                if len(fifo) >= self.maxsize:
                    st.dropped += 1
                else:
                    st.dropped_maxbytes += 1
                self._pop()
            return True
        cond = self._cond
        if cond is not None:  # block: real-time producer waits for room
            with cond:
                if self._full(s):
                    t0 = time.perf_counter_ns()
                    while self._full(s):
                        cond.wait(0.1)
                    st.blocked += 1
                    st.blocked_ns += time.perf_counter_ns() - t0
            return True
        # offline, block: never drops; past maxsize the high-water mark is reported, past maxbytes
        # the consumer is not taking its samples: refused rather than grown without bound
        if self._bytes_with(s) > self.maxbytes:
            raise ComponentError(self.owner.name, self.name, s.timestamp, "process", BufferError(
                f"{len(fifo)} samples ({_mib(self._bytes_with(s) - sample_nbytes(s))}) wait at this input, "
                f"the next would take it over its maxbytes {_mib(self.maxbytes)}: its consumer does not take them "
                f"(a sync partner that stopped?); offline a 'block' input never drops: give it more maxbytes "
                f"or a drop policy"))
        return True

    def _remember(self, s: Sample) -> None:
        ht, hs = self._hist_t, self._hist_s
        if ht and s.timestamp < ht[-1]:
            i = bisect.bisect_right(ht, s.timestamp)  # out-of-order: keep the buffer sorted
            ht.insert(i, s.timestamp)
            hs.insert(i, s)
        else:
            ht.append(s.timestamp)
            hs.append(s)
        nb = self._hist_nb + sample_nbytes(s)
        horizon = ht[-1] - self._history_ns
        k = 0
        if ht[0] < horizon:
            # keep one sample before the horizon so at(horizon) still interpolates
            k = max(0, bisect.bisect_left(ht, horizon) - 1)
            nb -= sum(x.nbytes for x in hs[:k])
        k0 = k
        while nb > self.maxbytes and k < len(hs) - 1:  # over maxbytes: the oldest go first, one always kept
            nb -= hs[k].nbytes
            k += 1
        self.stats.history_trimmed += k - k0
        if k:
            del ht[:k]
            del hs[:k]
        self._hist_nb = nb

    # --- consumer side ------------------------------------------------------------
    def take_sample(self) -> Sample:
        """Remove and return the oldest sample (reactive), the matched one (sync group),
        or the last one (sampling)."""
        if self.group is not None:
            s = self._current
            if s is None:
                raise EmptyInput(f"input '{self.name}' of '{self.owner.name}' has no matched sample")
            self._current = None
            return s
        if self.policy == "sampling":
            if self._last is None:
                raise EmptyInput(f"input '{self.name}' of '{self.owner.name}' has received nothing yet")
            return self._last
        cond = self._cond
        if cond is None:  # offline: one thread
            try:
                return self._pop()
            except IndexError:
                raise EmptyInput(f"input '{self.name}' of '{self.owner.name}' is empty") from None
        with cond:  # real time: pop under the owner's lock (producers check and drop under it)
            try:
                s = self._pop()
            except IndexError:
                raise EmptyInput(f"input '{self.name}' of '{self.owner.name}' is empty") from None
            cond.notify_all()  # a 'block' producer may be waiting for room
        return s

    def take(self) -> Any:
        """The data of :meth:`take_sample`."""
        if self._fast:
            fifo = self._fifo
            try:
                s = fifo.popleft()
            except IndexError:
                raise EmptyInput(f"input '{self.name}' of '{self.owner.name}' is empty") from None
            if fifo:  # the byte count is kept from two samples on (see _pop)
                self._nb -= s.nbytes
            return s.data
        return self.take_sample().data

    def get(self, default: Any = None) -> Any:
        """Last value received (any policy), or ``default``; never consumes."""
        s = self._last
        return default if s is None else s.data

    def latest(self) -> Sample | None:
        return self._last

    @property
    def ready(self) -> bool:
        if self.group is not None:
            return self._current is not None
        if self.policy == "sampling":
            return self._last is not None
        return bool(self._fifo)

    def __len__(self) -> int:
        return len(self._fifo)

    def at(self, t_ns: int, *, clamp: bool = False) -> Any:
        """Value interpolated at ``t_ns`` from the history buffer.

        Linear for numbers and arrays (shortest arc when the input is ``angular``), the
        type's own ``interpolate(a, b, w)`` when it has one (``Pose2D``), the previous
        value otherwise. Outside the buffered span: :class:`OutOfHistory`, or the nearest
        end value with ``clamp=True``.
        """
        if self._cond is not None:  # real time: producers insert/trim under the owner's lock
            with self._cond:
                return self._at(t_ns, clamp)
        return self._at(t_ns, clamp)

    def _at(self, t_ns: int, clamp: bool) -> Any:
        ht, hs = self._hist_t, self._hist_s
        if self._history_ns is None:
            raise OutOfHistory(f"input '{self.name}' of '{self.owner.name}' keeps no history (declare history=SECONDS)")
        if not ht:
            raise OutOfHistory(f"input '{self.name}' of '{self.owner.name}' has no history yet at t={t_ns} ns")
        if t_ns <= ht[0] or t_ns >= ht[-1]:
            if t_ns == ht[0]:
                return hs[0].data
            if t_ns == ht[-1]:
                return hs[-1].data
            if clamp:
                return hs[0].data if t_ns < ht[0] else hs[-1].data
            raise OutOfHistory(
                f"input '{self.name}' of '{self.owner.name}': t={t_ns} ns is outside its history "
                f"[{ht[0]}, {ht[-1]}] ns"
            )
        i = bisect.bisect_right(ht, t_ns)
        t0, t1 = ht[i - 1], ht[i]
        a, b = hs[i - 1].data, hs[i].data
        if t1 == t0:
            return b
        return _interpolate(a, b, (t_ns - t0) / (t1 - t0), self.angular)

    def between(self, t0_ns: int, t1_ns: int) -> list[Sample]:
        """Samples of the history buffer with ``t0_ns <= timestamp <= t1_ns``."""
        if self._cond is not None:  # real time: see at()
            with self._cond:
                ht = self._hist_t
                return self._hist_s[bisect.bisect_left(ht, t0_ns): bisect.bisect_right(ht, t1_ns)]
        ht = self._hist_t
        return self._hist_s[bisect.bisect_left(ht, t0_ns): bisect.bisect_right(ht, t1_ns)]

    def leftover(self) -> int:
        """Samples still waiting at the end of a run (counted as unmatched in sync groups)."""
        return len(self._fifo)


class SyncGroup:
    """Inputs of one component that fire together (see the module docstring)."""

    def __init__(self, name: str, members: list[InputPort], tolerance_s: float) -> None:
        self.name = name
        self.members = members
        self.tolerance_ns = int(round(tolerance_s * 1e9))
        for m in members:
            m.group = self

    def match(self) -> bool:
        members = self.members
        while True:
            if any(m._current is not None for m in members):
                return False  # previous match not consumed yet; retry after process()
            heads = []
            for m in members:
                if not m._fifo:
                    return False
                heads.append(m._fifo[0].timestamp)
            lo = min(heads)
            if max(heads) - lo <= self.tolerance_ns:
                for m in members:
                    m._current = m._pop()
                return True
            for m, h in zip(members, heads, strict=True):
                if h == lo:
                    m._pop()
                    m.stats.unmatched += 1


class OutputPort:
    """One output of one component instance; ``emit`` stamps, freezes and fans out."""

    __slots__ = ("name", "owner", "decl", "origin", "_seq", "_targets", "_deliver", "_typed", "_ok",
                 "_heap", "_next", "_keyed", "_cls", "_frz")

    def __init__(self, owner: Owner, name: str, decl: OutputDecl) -> None:
        self.name = name
        self.owner = owner
        self.decl = decl
        self.origin = f"{owner.name}.{name}"
        t = decl.type
        self._typed = isinstance(t, type) and t is not object  # typing constructs: not checked
        self._ok: set[type] = set()  # classes already accepted on this port
        # the class of the last value emitted (accepted) and its freezer (None: immutable)
        self._cls: type | None = None
        self._frz: Callable[[Any], None] | None = None
        self._seq = 0
        self._targets: list[tuple[InputPort, bool]] = []  # (input, delayed)
        # set by the real-time executor: deliver(input, sample, delayed)
        self._deliver: Callable[[InputPort, Sample, bool], None] | None = None
        # set by the offline executor for a run: its event heap, its sequence counter and
        # (input, event key) per target, so emit() queues deliveries without a call per target
        self._heap: list | None = None
        self._next: Callable[[], int] | None = None
        self._keyed: tuple[tuple[InputPort, int], ...] = ()

    def _check_type(self, t_ns: int, data: Any) -> None:
        """Accept ``type(data)`` for good (cached) or raise :class:`OutputTypeError`."""
        want = self.decl.type
        cls = type(data)
        also = _NUMERIC_ALIASES.get(want, ())
        if isinstance(data, want) or (
            issubclass(cls, also) and (want is bool or not issubclass(cls, (bool, np.bool_)))
        ):
            self._ok.add(cls)
            return
        shown = repr(data)
        shown = shown if len(shown) <= 60 else shown[:57] + "..."
        raise OutputTypeError(
            f"output '{self.name}' of component '{self.owner.name}' is declared "
            f"{getattr(want, '__name__', want)} but emitted {cls.__name__} {shown} at t={t_ns} ns"
        )

    @property
    def count(self) -> int:
        """Samples emitted so far (the next sample's ``seq``)."""
        return self._seq

    def connected_inputs(self) -> list[InputPort]:
        """The inputs this output feeds (in connection order)."""
        return [inp for inp, _ in self._targets]

    def emit(self, t_ns: int, data: Any) -> Sample:
        """Send ``data`` stamped ``t_ns`` (int nanoseconds) to every connected input."""
        if type(t_ns) is not int:
            if isinstance(t_ns, (bool, float)) or not isinstance(t_ns, (int, np.integer)):
                raise TypeError(
                    f"{self.origin}: timestamps are int nanoseconds, got {type(t_ns).__name__} {t_ns!r}"
                )
            t_ns = int(t_ns)
        cls = type(data)
        if cls is not self._cls:  # a class not seen last time: check it, find its freezer
            if self._typed and cls not in self._ok:
                self._check_type(t_ns, data)
            f = freezer_for(cls)
            if f is not None:
                f(data)
            self._cls, self._frz = cls, f
        elif self._frz is not None:
            self._frz(data)
        s = Sample(t_ns, data, self._seq, self.origin)
        self._seq += 1
        heap = self._heap
        if heap is not None:  # offline executor: event (t, key, seq, DELIVER, input, sample)
            nxt = self._next
            for inp, key in self._keyed:
                _heappush(heap, (t_ns, key, nxt(), 1, inp, s))
            return s
        deliver = self._deliver
        if deliver is not None:
            for inp, delayed in self._targets:
                deliver(inp, s, delayed)
        return s
