"""Components: ports and parameters declared on the class, validated before a run.

.. code-block:: python

    class Scale(Component):
        \"\"\"Multiply every number by a gain.\"\"\"
        x = Input(float)                      # reactive: each sample triggers process()
        y = Output(float)
        gain = Param(float, default=2.0, ge=0, doc="multiplier")

        def process(self, t: int) -> None:
            self.y.emit(t, self.x.take() * self.gain)

Lifecycle (RTMaps Birth/Core/Death): ``start()`` once before the first sample,
``process(t)`` for every trigger (``self.trigger`` names the input, sync group or
periodic timer that fired), ``flush(t)`` once when the inputs are exhausted (it may still
emit: a final map, a partial turn), ``stop()`` once at the end, even when the run is
interrupted or another component failed: that is where summaries and reports are written.
``stop()`` also runs when the component's own ``start()`` raised, so it can release what
``start()`` took (write it to cope with a half-done start); ``summary()`` is asked only of
components whose ``start()`` returned. Data emitted on an output must fit its declared type
(checked by class; see :mod:`impala_flow._ports`).

A :class:`Source` has no inputs; its :meth:`Source.generate` yields ``(t_ns, port,
data)`` in non-decreasing time. Offline, the executor pulls the earliest pending sample
of all sources; live sources (``live = True``) run in threads and stamp with
``self.now_ns()``.

Components whose ports depend on their parameters (a replayer's outputs are the topics
of its file; a recorder's inputs are the streams it records) override
:meth:`Component.declare_ports`.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Iterator
from typing import Any, ClassVar

from ._ports import DEFAULT_MAXBYTES, OVERFLOWS, POLICIES, InputPort, OutputPort, SyncGroup
from ._spec import closest, did_you_mean

__all__ = [
    "Component", "Source", "Input", "Output", "Param", "Periodic", "ParamError", "REQUIRED", "PATH_KINDS",
]

log = logging.getLogger("impala_flow")


class _Required:
    def __repr__(self) -> str:
        return "REQUIRED"


REQUIRED: Any = _Required()


#: kinds of path parameter: ``Param(str, path=KIND)``
PATH_KINDS = ("read", "write", "write_dir", "read_or_name")


#: largest time in seconds a ``*_s`` parameter may hold: its nanoseconds fit in an int64
MAX_SECONDS = 9.2e9
_INT64_MIN, _INT64_MAX = -(1 << 63), (1 << 63) - 1
#: bounds of a periodic timer's period (s): at most a million firings per mission second,
#: and a period whose nanoseconds fit in an int64
MIN_PERIOD_S, MAX_PERIOD_S = 1e-6, MAX_SECONDS


class ParamError(ValueError):
    """A parameter value that does not fit its declaration."""


class Param:
    """A typed, validated parameter.

    ``type`` is one of int, float, str, bool, list, dict. Bounds ``ge``/``gt``/``le``/
    ``lt`` apply to numbers (and to every element of a list of numbers); ``choices``
    lists the accepted values. Without a default the parameter is required.

    ``path`` marks a ``str`` parameter that names a file or folder (see :data:`PATH_KINDS`):
    ``"read"`` a file (or folder) the component reads, ``"write"`` a file it writes, ``"write_dir"`` a
    folder it writes into, ``"read_or_name"`` either a built-in name or a file it reads (a
    value with a '/' or a file suffix is a file). In a graph, a relative path is resolved
    against the folder of the graph file it is written in (the working directory for a
    ``--set``/``--var`` value); validation refuses an output that overwrites an input and
    an output folder that cannot be created.

    Every number must be finite (NaN and inf are refused; ``finite=False`` lets a parameter
    take inf, never NaN). A parameter whose name says it is a time keeps to int64
    nanoseconds: ``*_s`` within +-:data:`MAX_SECONDS`, ``*_ns`` within int64, so ``1e308``
    is refused where it is written, not in the middle of a run.
    """

    def __init__(
        self, type: type = float, default: Any = REQUIRED, *, ge: float | None = None,
        gt: float | None = None, le: float | None = None, lt: float | None = None,
        choices: tuple | list | None = None, doc: str = "", path: str | None = None, finite: bool = True,
    ) -> None:
        if path is not None and (path not in PATH_KINDS or type is not str):
            raise ValueError(f"Param path must be one of {PATH_KINDS} on a str parameter, got {path!r}")
        self.path = path
        self.finite = finite
        self.type = type
        self.default = default
        self.ge, self.gt, self.le, self.lt = ge, gt, le, lt
        self.choices = tuple(choices) if choices is not None else None
        self.doc = doc
        self.name = ""

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name

    def __get__(self, obj: Any, owner: type | None = None) -> Any:
        if obj is None:
            return self
        return obj._params[self.name]

    @property
    def required(self) -> bool:
        return self.default is REQUIRED

    def convert(self, value: Any) -> Any:
        """Return ``value`` converted to the declared type, or raise :class:`ParamError`."""
        t = self.type
        if t is float and isinstance(value, (int, float)) and not isinstance(value, bool):
            value = float(value)
        elif t is list and isinstance(value, tuple):
            value = list(value)
        if not isinstance(value, t) or (t is int and isinstance(value, bool)):
            from ._yamlloc import brief  # noqa: PLC0415 - the error path only

            kind = "list" if isinstance(value, list) else "dict" if isinstance(value, dict) else type(value).__name__
            raise ParamError(f"expected {t.__name__}, got {kind} {brief(value)}")
        if self.choices is not None and value not in self.choices:
            from ._yamlloc import brief  # noqa: PLC0415 - the error path only

            raise ParamError(f"{brief(value)} is not one of {list(self.choices)}")
        nums = value if isinstance(value, list) else [value]
        for v in nums:
            if isinstance(v, (int, float)) and not isinstance(v, bool):
                self._check_bounds(v)
        return value

    def _check_bounds(self, v: float) -> None:
        if isinstance(v, float) and math.isnan(v):
            raise ParamError("NaN is not allowed")
        if self.ge is not None and not v >= self.ge:
            raise ParamError(f"{v!r} must be >= {self.ge}")
        if self.gt is not None and not v > self.gt:
            raise ParamError(f"{v!r} must be > {self.gt}")
        if self.le is not None and not v <= self.le:
            raise ParamError(f"{v!r} must be <= {self.le}")
        if self.lt is not None and not v < self.lt:
            raise ParamError(f"{v!r} must be < {self.lt}")
        # after the declared bounds (their message is the more precise), before any use
        if self.finite and isinstance(v, float) and math.isinf(v):
            raise ParamError(f"{v!r} is not allowed: a finite number is expected")
        if self.name.endswith("_s") and not -MAX_SECONDS <= v <= MAX_SECONDS:
            raise ParamError(f"{v!r} s is out of range: a time in seconds must be within +-{MAX_SECONDS:.3g} s "
                             "(int64 nanoseconds)")
        if self.name.endswith("_ns") and not _INT64_MIN <= v <= _INT64_MAX:
            raise ParamError(f"{v!r} ns is outside the int64 range of times")

    def describe(self) -> str:
        bits = [self.type.__name__]
        if not self.required:
            bits.append(f"default {self.default!r}")
        for k in ("ge", "gt", "le", "lt"):
            v = getattr(self, k)
            if v is not None:
                bits.append(f"{k} {v}")
        if self.choices:
            bits.append(f"one of {list(self.choices)}")
        return ", ".join(bits)


class _PortDeclaration:
    """A port declared on a component class; on an instance the attribute is the runtime
    port (``self.image`` is ``self.inputs["image"]``)."""

    _table = "inputs"
    name = ""

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name

    def __get__(self, obj: Any, owner: type | None = None) -> Any:
        if obj is None:
            return self
        return getattr(obj, self._table)[self.name]


class Input(_PortDeclaration):
    """An input port declaration.

    ``type``: the message type accepted (``object`` accepts anything). ``policy``:
    ``reactive`` or ``sampling``. ``sync``: name of a sync group, ``tolerance`` its
    half-window in seconds. ``history``: seconds of samples kept for ``at``/``between``.
    ``maxsize`` (samples), ``maxbytes`` (bytes, 64 MiB by default; it bounds the history
    buffer too) and ``overflow`` (``block``, ``drop_oldest``, ``drop_newest``) bound the
    FIFO (see :mod:`impala_flow._ports`). ``required=False`` lets the input stay
    unconnected. ``angular=True`` makes ``at()`` interpolate numbers as angles.
    ``validate=False`` lets invalid messages (non-finite, impossible values) through instead
    of dropping and counting them (:mod:`impala_flow._ports`).
    """

    def __init__(
        self, type: type = object, *, policy: str = "reactive", sync: str | None = None,
        tolerance: float = 0.0, history: float | None = None, maxsize: int = 1024,
        overflow: str = "block", required: bool = True, angular: bool = False, doc: str = "",
        maxbytes: int = DEFAULT_MAXBYTES,
        validate: bool = True,
    ) -> None:
        if policy not in POLICIES:
            raise ValueError(f"Input policy must be one of {POLICIES}, got {policy!r}")
        if overflow not in OVERFLOWS:
            raise ValueError(f"Input overflow must be one of {OVERFLOWS}, got {overflow!r}")
        if maxsize < 1:
            raise ValueError("Input maxsize must be >= 1")
        if isinstance(maxbytes, bool) or not isinstance(maxbytes, int) or maxbytes < 1:
            raise ValueError(f"Input maxbytes must be an int >= 1, got {maxbytes!r}")
        self.type = type
        self.policy = policy
        self.sync = sync
        self.tolerance = float(tolerance)
        self.history = history
        self.maxsize = int(maxsize)
        self.maxbytes = maxbytes
        self.overflow = overflow
        self.required = required
        self.angular = angular
        self.validate = bool(validate)
        self.doc = doc
        self.name = ""



class Output(_PortDeclaration):
    """An output port declaration; ``type`` is the message type emitted."""

    _table = "outputs"

    def __init__(self, type: type = object, *, doc: str = "") -> None:
        self.type = type
        self.doc = doc
        self.name = ""


class Periodic:
    """A periodic trigger on mission time: ``process`` runs at every multiple of the period.

    ``period`` is seconds, or the name of a float :class:`Param` holding it.
    """

    def __init__(self, period: float | str, *, doc: str = "") -> None:
        self.period = period
        self.doc = doc
        self.name = ""

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name

    def period_s(self, params: dict[str, Any]) -> float:
        return float(params[self.period] if isinstance(self.period, str) else self.period)

    def check(self, params: dict[str, Any]) -> str | None:
        """Why this timer's period (from validated ``params``) cannot run, or None: it must be
        finite and within [:data:`MIN_PERIOD_S`, :data:`MAX_PERIOD_S`] seconds."""
        try:
            p = self.period_s(params)
        except (KeyError, TypeError, ValueError):
            return f"timer '{self.name}': period {self.period!r} is not a number of seconds"
        if not (math.isfinite(p) and MIN_PERIOD_S <= p <= MAX_PERIOD_S):
            return (f"timer '{self.name}': period {p!r} s must be within [{MIN_PERIOD_S:g}, "
                    f"{MAX_PERIOD_S:.3g}] s")
        return None

    def period_ns(self, comp: Component) -> int:
        return max(1, int(round(self.period_s(comp._params) * 1e9)))


def _refuse_shared_names(owner: str, *tables: dict) -> None:
    """A port, a parameter and a timer may not share a name: ``self.<name>`` would be
    whichever the instance set last (a parameter silently read as a port)."""
    seen: dict[str, int] = {}
    for i, table in enumerate(tables):
        for name in table:
            if name in seen and seen[name] != i:
                raise TypeError(f"{owner}: '{name}' names two things (a port, a parameter or a timer); rename one")
            seen[name] = i


class Component:
    """Base class of every processing component (see the module docstring)."""

    __inputs__: ClassVar[dict[str, Input]] = {}
    __outputs__: ClassVar[dict[str, Output]] = {}
    __params__: ClassVar[dict[str, Param]] = {}
    __timers__: ClassVar[dict[str, Periodic]] = {}
    live: ClassVar[bool] = False
    #: the run's registry (plugins, their components and message types), set by ``build``;
    #: None for components wired by hand
    registry: Any = None
    #: set by the registry: the YAML type name, e.g. ``radar.FuzzyPairer``
    type_name: ClassVar[str] = ""

    def __init_subclass__(cls, **kw: Any) -> None:
        super().__init_subclass__(**kw)
        ins: dict[str, Input] = {}
        outs: dict[str, Output] = {}
        params: dict[str, Param] = {}
        timers: dict[str, Periodic] = {}
        for klass in reversed(cls.__mro__):
            for k, v in vars(klass).items():
                if isinstance(v, Input):
                    ins[k] = v
                elif isinstance(v, Output):
                    outs[k] = v
                elif isinstance(v, Param):
                    params[k] = v
                elif isinstance(v, Periodic):
                    timers[k] = v
        for name in (*ins, *outs, *params, *timers):
            if name in _RESERVED:
                raise TypeError(f"{cls.__name__}.{name}: a port, parameter or timer may not be named "
                                f"'{name}', which Component itself uses")
        _refuse_shared_names(cls.__name__, ins, outs, params, timers)
        cls.__inputs__, cls.__outputs__, cls.__params__, cls.__timers__ = ins, outs, params, timers

    @classmethod
    def validate_params(cls, params: dict[str, Any]) -> tuple[dict[str, Any], dict[str, str]]:
        """Convert ``params``; return (values, problems by parameter name)."""
        values: dict[str, Any] = {}
        problems: dict[str, str] = {}
        for k in params:
            if k not in cls.__params__:
                hint = closest(k, cls.__params__)
                problems[k] = "unknown parameter" + did_you_mean(hint)
        for k, p in cls.__params__.items():
            if k in params:
                try:
                    values[k] = p.convert(params[k])
                except ParamError as e:
                    problems[k] = str(e)
            elif p.required:
                problems[k] = f"required parameter missing ({p.describe()})"
            else:
                values[k] = p.default
        for timer in cls.__timers__.values():  # a period of 1e-9 s would never let the mission advance
            key = timer.period if isinstance(timer.period, str) else ""
            if key not in problems:
                why = timer.check(values)
                if why:
                    problems[key] = why
        return values, problems

    @classmethod
    def declare_ports(cls, params: dict[str, Any]) -> tuple[dict[str, Input], dict[str, Output]]:
        """Ports of an instance with these (validated) parameters; the class's by default."""
        return dict(cls.__inputs__), dict(cls.__outputs__)

    def __init__(self, name: str | None = None, **params: Any) -> None:
        self.name = name or type(self).__name__
        values, problems = self.validate_params(params)
        if problems:
            k, msg = next(iter(problems.items()))
            raise ParamError(f"component '{self.name}': parameter '{k}': {msg}")
        self._params = values
        self.trigger = ""
        self.log = log.getChild(self.name)
        self._clock_ns: Callable[[], int] = time.monotonic_ns
        self._origin_tl: Any = None  # the real-time executor's per-thread origin (a threading.local)
        ins, outs = self.declare_ports(values)
        _refuse_shared_names(f"component '{self.name}' ({type(self).__name__})", ins, outs, self.__params__,
                             self.__timers__)
        self.inputs: dict[str, InputPort] = {k: InputPort(self, k, d) for k, d in ins.items()}
        self.outputs: dict[str, OutputPort] = {k: OutputPort(self, k, d) for k, d in outs.items()}
        for k, port in (*self.inputs.items(), *self.outputs.items()):
            if k.isidentifier() and k not in self.__dict__:
                self.__dict__[k] = port  # plain attribute: no descriptor call on the hot path
        groups: dict[str, list[InputPort]] = {}
        for p in self.inputs.values():
            if p.decl.sync is not None:
                groups.setdefault(p.decl.sync, []).append(p)
        self.sync_groups = {
            g: SyncGroup(g, ms, max(m.decl.tolerance for m in ms)) for g, ms in groups.items()
        }

    @property
    def params(self) -> dict[str, Any]:
        return dict(self._params)

    def now_ns(self) -> int:
        """Mission time now (live sources stamp their samples with it)."""
        return self._clock_ns()

    @property
    def work_origin_ns(self) -> int | None:
        """Live only: the origin of the work the current ``process`` call does, on the mission
        clock (the arrival of the source sample that led to its trigger; what the latency
        figures of what it emits count from). ``None`` offline and outside ``process``.

        A component that holds work for later (a turn waiting for a fed-back estimate) keeps
        this value with the work and sets it back before emitting the result, so the latency
        of that result counts the wait: ``self.work_origin_ns = held_origin``. Setting it
        offline does nothing."""
        tl = self._origin_tl
        return None if tl is None else getattr(tl, "origin_ns", None)

    @work_origin_ns.setter
    def work_origin_ns(self, origin_ns: int | None) -> None:
        if self._origin_tl is not None:
            self._origin_tl.origin_ns = origin_ns

    # --- lifecycle -----------------------------------------------------------------
    def start(self) -> None:
        """Called once before the first sample."""

    def process(self, t: int) -> None:
        """Called for each trigger; ``t`` is the triggering sample's time (int ns)."""

    def flush(self, t: int) -> None:
        """Called once when the inputs are exhausted (``t``: the last mission time), before
        ``stop()``; it may emit what the component still holds (a final map, a partial turn).
        Not called after an error or an interrupt."""

    def stop(self) -> None:
        """Called once at the end of the run, also after an error or an interrupt, and
        after this component's own ``start()`` raised (release what it took)."""

    def on_time_jump(self, offset_ns: int) -> None:
        """Called when a source announces a jump of the mission clock (a replay loop)."""

    def summary(self) -> dict[str, Any]:
        """Figures this component wants printed in the run summary (asked after ``stop()``,
        only if ``start()`` returned; an exception here is reported on its own line)."""
        return {}

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.name!r}>"


class Source(Component):
    """A component that produces samples: drivers, simulators, the replayer."""

    def generate(self) -> Iterator[tuple[int, str, Any]]:
        """Yield ``(t_ns, output_port, data)`` in non-decreasing ``t_ns``."""
        return iter(())

    def duration_hint_ns(self) -> int | None:
        """Mission duration this source expects to produce, for progress bars."""
        return None

    def request_stop(self) -> None:
        """Called by the real-time executor, from another thread, when the run stops (its
        end, ``--duration``, an interrupt, an error): a source waiting on a device (a socket
        read, a silent sensor) should leave ``generate()`` at its next poll. The executor also
        closes the generator at its next ``yield``, so a source that yields often needs
        nothing here. Must return at once."""


#: attribute names of Component and Source that a declaration would silently shadow
_RESERVED = frozenset(
    n for klass in (Component, Source) for n in vars(klass) if not n.startswith("__")
) | {"name", "inputs", "outputs", "sync_groups", "trigger", "log", "params", "registry"}
