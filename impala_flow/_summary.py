"""RunSummary: what a run did, what it dropped, what failed. Nothing is lost silently.

Invalid samples (a message whose ``invalid_reason()`` is not None, dropped where it enters an
input: :mod:`impala_flow._ports`) are counted in ``inputs[...]["invalid"]`` and by reason in
``inputs[...]["invalid_reasons"]``; :meth:`RunSummary.format` prints one ``INVALID at`` line
per input with the count of each reason, and they count in :attr:`RunSummary.total_lost`.

Errors: ``error`` is the first failure of the run (the one raised to the caller);
``errors`` lists the later ones (a ``stop()`` or ``summary()`` that raised too), each a
line naming its component, so a secondary failure never hides the first.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import Any

__all__ = ["RunSummary", "ComponentError", "log_skip", "SKIP_LOG_LIMIT"]

#: ``on_error: skip``: the first skips of a component logged one by one, the rest counted
SKIP_LOG_LIMIT = 3


def log_skip(log: logging.Logger, n: int, t_ns: int | None, exc: BaseException) -> None:
    """Log the ``n``-th skip (1-based) of a component: the first :data:`SKIP_LOG_LIMIT`
    with their error, then one line saying the rest are only counted (in the summary)."""
    if n <= SKIP_LOG_LIMIT:
        log.warning("skipped t=%s ns after %s: %s", t_ns, type(exc).__name__, exc)
        if n == SKIP_LOG_LIMIT:
            log.warning("further skips are counted, not logged: the total is in the run summary")


class ComponentError(RuntimeError):
    """A component raised; the message names the component, the port and the sample time."""

    def __init__(self, component: str, trigger: str, t_ns: int | None, phase: str, exc: BaseException):
        self.component, self.trigger, self.t_ns, self.phase = component, trigger, t_ns, phase
        self.__cause__ = exc
        where = f"component '{component}'"
        if phase == "process":
            where += f", input '{trigger}', sample t={t_ns} ns"
        else:
            where += f", in {phase}()"
        super().__init__(f"{where}: {type(exc).__name__}: {exc}")


#: how a kind of loss at an input is printed
_KINDS = {"dropped_maxbytes": "dropped (the input held its maxbytes)"}


def _ms(v: float) -> str:
    """A duration given in ms, printed with 3 significant digits in us, ms or s."""
    if v >= 999.5:
        return f"{v / 1000:.3g} s"
    return f"{v:.3g} ms" if v >= 1 else f"{v * 1000:.3g} us"


@dataclass
class RunSummary:
    graph: str = "graph"
    mission_start_ns: int | None = None
    mission_end_ns: int | None = None
    wall_s: float = 0.0
    events: int = 0
    interrupted: bool = False
    error: str | None = None
    processed: dict[str, int] = field(default_factory=dict)
    skipped: dict[str, int] = field(default_factory=dict)
    first_skip: dict[str, str] = field(default_factory=dict)  # component -> "t=... ns: Error: msg"
    errors: list[str] = field(default_factory=list)  # failures after the first (stop(), summary())
    emitted: dict[str, int] = field(default_factory=dict)  # "comp.port" -> count
    inputs: dict[str, dict[str, int]] = field(default_factory=dict)  # "comp.port" -> stats
    extra: dict[str, dict[str, Any]] = field(default_factory=dict)
    #: the run was given a duration (s, mission time; live: wall time) and stopped there
    duration_s: float | None = None
    stopped_at_duration: bool = False
    #: time per ``process`` call, per component (:mod:`impala_flow._timing`)
    timing: dict[str, dict[str, Any]] = field(default_factory=dict)
    #: latency per component output, real time only: mission clock at emit - origin (:mod:`impala_flow._timing`)
    latency: dict[str, dict[str, Any]] = field(default_factory=dict)
    #: the BLAS libraries' threads during the run (None: left to the libraries; :mod:`impala_flow._native`)
    blas_threads: int | None = 1

    @property
    def mission_s(self) -> float:
        if self.mission_start_ns is None or self.mission_end_ns is None:
            return 0.0
        return (self.mission_end_ns - self.mission_start_ns) / 1e9

    @property
    def speed_ratio(self) -> float:
        return self.mission_s / self.wall_s if self.wall_s > 0 else float("inf")

    def drops(self) -> dict[str, dict[str, int]]:
        """Inputs that lost samples: {"comp.port": {"dropped": n, "unmatched": m, "unconsumed": k,
        "invalid": i}} (only the non-zero counts; ``dropped_maxbytes``: dropped because the FIFO held
        its ``maxbytes``)."""
        out = {}
        for k, st in self.inputs.items():
            lost = {n: st[n] for n in ("dropped", "dropped_maxbytes", "unmatched", "unconsumed", "invalid")
                    if st.get(n)}
            if lost:
                out[k] = lost
        return out

    def invalid(self) -> dict[str, dict[str, int]]:
        """Samples dropped on arrival as invalid, by input and reason: {"comp.port": {reason: n}}."""
        return {k: dict(st.get("invalid_reasons") or {"invalid": st["invalid"]})
                for k, st in self.inputs.items() if st.get("invalid")}

    def backpressure(self) -> dict[str, dict[str, float]]:
        """Inputs whose producers waited for room (``block`` policy, real time):
        {"comp.port": {"blocked": times, "blocked_s": seconds in total}}."""
        return {k: {"blocked": st["blocked"], "blocked_s": st.get("blocked_ns", 0) / 1e9}
                for k, st in self.inputs.items() if st.get("blocked")}

    def source_losses(self) -> dict[str, dict[str, Any]]:
        """Samples a component could not produce, from its ``summary()``: a reader of a
        damaged recording reports ``lost`` ({output: count, or None when unknown}) and
        ``lost_ranges_s`` ([output, from s, to s], ...). {"comp.port": {"unreadable": n,
        "missing_s": [[a, b], ...]}}."""
        out: dict[str, dict[str, Any]] = {}
        for cid, extra in self.extra.items():
            lost = (extra or {}).get("lost") if isinstance(extra, dict) else None
            if not isinstance(lost, dict):
                continue
            ranges: dict[str, list[list[float]]] = {}
            for item in extra.get("lost_ranges_s") or []:
                port, a, b = item
                ranges.setdefault(str(port), []).append([float(a), float(b)])
            for port, n in lost.items():
                out[f"{cid}.{port}"] = {"unreadable": n, "missing_s": ranges.get(str(port), [])}
        return out

    def component_drops(self) -> dict[str, dict[str, int]]:
        """Samples a component dropped itself, from its ``summary()`` ``dropped``
        ({what: {kind: count}}, e.g. a live view's oversized messages): {"comp.what": {kind: n}}."""
        out: dict[str, dict[str, int]] = {}
        for cid, extra in self.extra.items():
            own = extra.get("dropped") if isinstance(extra, dict) else None
            if isinstance(own, dict):
                for what, kinds in own.items():
                    if isinstance(kinds, dict) and any(kinds.values()):
                        out[f"{cid}.{what}"] = {str(k): int(n) for k, n in kinds.items() if n}
        return out

    @property
    def total_lost(self) -> int:
        """Samples dropped, unmatched or unconsumed at inputs, plus those sources could not read
        and those components dropped themselves."""
        return (sum(sum(v.values()) for v in self.drops().values())
                + sum(v["unreadable"] or 0 for v in self.source_losses().values())
                + sum(sum(v.values()) for v in self.component_drops().values()))

    def to_json(self) -> dict[str, Any]:
        """Everything, for ``--summary-json``: the fields, ``lost`` (source losses) and ``lost_total``."""
        return {**vars(self), "lost": self.source_losses(), "lost_total": self.total_lost}

    def format(self) -> str:
        lines = [
            f"graph '{self.graph}': {self.events} events, mission {self.mission_s:.3f} s "
            f"in {self.wall_s:.3f} s wall (x{self.speed_ratio:.1f})"
            + (f" - stopped at --duration {self.duration_s:g} s" if self.stopped_at_duration else "")
            + (" - INTERRUPTED" if self.interrupted else "")
            + (f" - FAILED: {self.error}" if self.error else "")
        ]
        lines += [f"  ERROR {e}" for e in self.errors]
        for name, n in self.processed.items():
            extra = self.extra.get(name) or {}
            emitted = {k.split(".", 1)[1]: v for k, v in self.emitted.items() if k.split(".", 1)[0] == name}
            if n == 0 and emitted:  # a source: what it produced
                bits = ["emitted " + ", ".join(f"{v} {port}" for port, v in emitted.items())]
            else:
                bits = [f"{n} process calls"]
            if self.skipped.get(name):
                first = self.first_skip.get(name)
                bits.append(f"{self.skipped[name]} skipped after errors" + (f" (first at {first})" if first else ""))
            bits += [f"{k}={v}" for k, v in extra.items()]
            tm = self.timing.get(name)
            if tm:
                bits.append(f"{_ms(tm['median_ms'])} median, {_ms(tm['p99_ms'])} p99 per call, "
                            f"{tm['total_s']:.3g} s in all ({100 * tm['share']:.0f} % of the run)")
            lines.append(f"  {name}: " + ", ".join(bits))
        for key, lat in self.latency.items():
            lines.append(f"  LATENCY {key}: {_ms(lat['median_ms'])} median, {_ms(lat['p99_ms'])} p99, "
                         f"{_ms(lat['max_ms'])} max over {lat['count']} samples (emit - arrival of what started it)")
        drops = self.drops()
        for k, v in drops.items():
            lost = {kind: n for kind, n in v.items() if kind != "invalid"}
            if lost:
                lines.append(f"  LOST at {k}: "
                             + ", ".join(f"{n} {_KINDS.get(kind, kind)}" for kind, n in lost.items()))
        for k, reasons in self.invalid().items():
            lines.append(f"  INVALID at {k}: {sum(reasons.values())} samples dropped on arrival ("
                         + ", ".join(f"{why}: {n}" for why, n in reasons.items()) + ")")
        unread = self.source_losses()
        for k, v in unread.items():
            n = "an unknown number of" if v["unreadable"] is None else v["unreadable"]
            missing = ", ".join(f"{a:.3f}..{b:.3f} s" for a, b in v["missing_s"])
            lines.append(f"  LOST at {k}: {n} unreadable (damaged chunks; missing t={missing})")
        own = self.component_drops()
        for k, v in own.items():
            lines.append(f"  LOST at {k}: " + ", ".join(f"{n} {kind}" for kind, n in v.items()))
        if not drops and not unread and not own:
            lines.append("  no sample dropped")
        for k, st in self.inputs.items():
            if st.get("history_trimmed"):
                lines.append(f"  TRIMMED at {k}: {st['history_trimmed']} history samples trimmed before their time "
                             f"(the history buffer held its maxbytes)")
        for k, v in self.backpressure().items():
            lines.append(f"  BACKPRESSURE at {k}: producers blocked {v['blocked']} times, "
                         f"{v['blocked_s']:.3f} s in total (block policy: the input was full)")
        return "\n".join(lines)
