"""``record_source`` (every mission file's recording path) runs with a short GIL switch interval, so the
source's reading thread and the writer's thread get the GIL back promptly, and restores the caller's
interval afterwards, after a failure too; the samples are recorded as they came."""

from __future__ import annotations

import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from impala_flow._session import Session
from impala_flow.cli import CommandError
from impala_flow.cli.helpers import RECORD_SWITCH_INTERVAL_S, record_source
from impala_flow.io import MissionReader
from impala_flow.testing import ScriptedSource


class _Spy(ScriptedSource):
    """Emits its script, noting the switch interval at each sample; raises after it when told to."""

    def __init__(self, *a: Any, fail: bool = False, **kw: Any) -> None:
        super().__init__(*a, **kw)
        self.fail = fail
        self.seen: list[float] = []

    def generate(self) -> Iterator[tuple[int, str, Any]]:
        for item in self.script:
            self.seen.append(sys.getswitchinterval())
            yield item
        if self.fail:
            raise RuntimeError("source failed on purpose")


@pytest.fixture
def caller_interval() -> Iterator[float]:
    old = sys.getswitchinterval()
    sys.setswitchinterval(0.003)  # the caller's own, distinct from Python's default and from the recording's
    try:
        yield sys.getswitchinterval()
    finally:
        sys.setswitchinterval(old)


def test_recording_runs_with_the_short_interval_and_restores_the_callers(tmp_path: Path,
                                                                        caller_interval: float) -> None:
    src = _Spy("src", samples=[(10, "out", 1.5), (20, "out", 2.5), (30, "out", -4.0)])
    path = tmp_path / "m.mcap"
    assert record_source(Session(), src, str(path), {"out": "values"}, progress=False, quiet=True) == 0
    assert src.seen == [pytest.approx(RECORD_SWITCH_INTERVAL_S, rel=1e-9)] * 3  # Python keeps whole microseconds
    assert sys.getswitchinterval() == caller_interval
    with MissionReader(path) as r:
        got = [(m.t_ns, m.data) for m in r.messages(["values"])]
    assert got == [(10, 1.5), (20, 2.5), (30, -4.0)]


def test_a_failing_source_still_restores_the_callers_interval(tmp_path: Path, caller_interval: float) -> None:
    src = _Spy("src", samples=[(10, "out", 1.0)], fail=True)
    with pytest.raises(CommandError, match="source failed on purpose"):
        record_source(Session(), src, str(tmp_path / "m.mcap"), {"out": "values"}, progress=False, quiet=True)
    assert src.seen == [pytest.approx(RECORD_SWITCH_INTERVAL_S, rel=1e-9)]
    assert sys.getswitchinterval() == caller_interval
