"""``export`` and ``replay`` under careless input (issue 24): outputs over the recording they read,
windows that are not finite seconds, timers that would spin over a mission's span. Each is one
line and exit 2, before anything is read or written; the recording is left byte for byte."""

from __future__ import annotations

import hashlib
from pathlib import Path

import pytest
import yaml

import impala_msgs
from impala_flow._offline import MAX_TIMER_FIRINGS
from impala_flow.cli import main
from impala_flow.io import MissionWriter, run_codecs

YEAR_NS = 365 * 86_400 * 10**9


def _mission(path: Path, times_ns: list[int]) -> Path:
    with MissionWriter(path, codecs=run_codecs(), chunk_size=4096) as w:
        w.add_topic("odo/speed", impala_msgs.Speed)
        w.add_topic("gyro/yaw_rate", impala_msgs.YawRate)
        for i, t in enumerate(times_ns):
            w.write("odo/speed", t, impala_msgs.Speed(1.0), i)
            w.write("gyro/yaw_rate", t, impala_msgs.YawRate(0.0), i)
    return path


@pytest.fixture
def mission(tmp_path: Path) -> Path:
    return _mission(tmp_path / "m.mcap", [i * 100_000_000 for i in range(20)])


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _one_error(capsys: pytest.CaptureFixture[str], command: str) -> str:
    out, err = capsys.readouterr()
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    assert lines[0].startswith(f"impala-flow {command}: error: ")
    return lines[0].split(": error: ", 1)[1]


def _dr_graph(tmp_path: Path) -> Path:
    g = tmp_path / "dr.yaml"
    g.write_text(yaml.safe_dump({
        "name": "dr", "components": {
            "mission": {"type": "io.Replayer", "params": {"path": "unset.mcap"}},
            "dr": {"type": "slam.DeadReckoning", "params": {"period_s": 0.5}}},
        "connections": ["mission.odo/speed -> dr.odometer", "mission.gyro/yaw_rate -> dr.gyro"]}))
    return g


def test_export_over_its_own_recording_is_refused_and_the_file_survives(mission: Path, tmp_path: Path,
                                                                        capsys: pytest.CaptureFixture[str]) -> None:
    before = _digest(mission)
    assert main(["export", str(mission), "--topic", "odo/speed", "--csv", "-o", str(mission)]) == 2
    assert _one_error(capsys, "export") == f"-o: '{mission}' is the recording '{mission}' itself: it would be " \
                                           "overwritten"
    link = tmp_path / "link.mcap"
    link.symlink_to(mission)
    assert main(["export", str(mission), "--topic", "odo/speed", "--csv", "-o", str(link)]) == 2
    _one_error(capsys, "export")
    assert main(["export", str(mission), "--topic", "odo/speed", "--csv", "-o", str(tmp_path / "x.csv"),
                 "--npy", str(tmp_path)]) == 2
    assert _one_error(capsys, "export") == f"--npy {tmp_path}: '{tmp_path}' contains the recording '{mission}': " \
                                           "write elsewhere"
    assert _digest(mission) == before and not (tmp_path / "x.csv").exists()


@pytest.mark.parametrize("option", ["--start-s", "--end-s"])
@pytest.mark.parametrize("value", ["inf", "nan", "-1", "1e300"])
def test_export_window_must_be_finite_seconds(mission: Path, capsys: pytest.CaptureFixture[str], option: str,
                                              value: str) -> None:
    assert main(["export", str(mission), "--topic", "odo/speed", "--csv", option, value]) == 2
    assert _one_error(capsys, "export") == f"{option} {float(value)}: expected finite seconds in [0, 9.2e+09]"


def test_export_an_output_name_too_long_is_refused_before_reading(mission: Path, tmp_path: Path,
                                                                  capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / ("c" * 300 + ".csv")
    assert main(["export", str(mission), "--topic", "odo/speed", "--csv", "-o", str(out)]) == 2
    assert _one_error(capsys, "export") == (f"-o {out}: the name '{'c' * 24}...' is 304 bytes long, more than the "
                                            "255 the file system takes")


def test_replay_summary_json_over_the_recording_is_refused(mission: Path, tmp_path: Path,
                                                          capsys: pytest.CaptureFixture[str]) -> None:
    before = _digest(mission)
    g = _dr_graph(tmp_path)
    assert main(["replay", str(mission), str(g), "--no-progress", "--summary-json", str(mission)]) == 2
    assert _one_error(capsys, "replay") == (f"--summary-json: '{mission}' is the input of component 'mission' "
                                            f"(io.Replayer) parameter 'path' '{mission}' itself: it would be "
                                            "overwritten")
    assert _digest(mission) == before
    assert main(["replay", str(mission), str(g), "--no-progress", "--summary-json", str(g)]) == 2
    assert "the graph file" in _one_error(capsys, "replay")


def test_a_mission_spanning_decades_is_refused_before_its_timers_spin(tmp_path: Path,
                                                                      capsys: pytest.CaptureFixture[str]) -> None:
    # an Oxford drive whose row times were zeroed: the first sample at 0, the others in 2019
    span = 49 * YEAR_NS
    m = _mission(tmp_path / "zeroed.mcap", [0] + [span + i * 250_000_000 for i in range(10)])
    firings = (span + 9 * 250_000_000) // 500_000_000 + 1
    assert firings > MAX_TIMER_FIRINGS
    assert main(["replay", str(m), str(_dr_graph(tmp_path)), "--no-progress"]) == 2
    line = _one_error(capsys, "replay")
    assert main(["validate", str(_dr_graph(tmp_path)), "--set", f"mission.path={m}"]) == 2
    assert _one_error(capsys, "validate") == line
    assert line == (
        f"component 'dr' (slam.DeadReckoning): parameter 'period_s' = 0.5 s: timer 'tick' would fire {firings:.3g} "
        f"times over the mission's {(span + 9 * 250_000_000) / 1e9:.6g} s (49.0 years), more than 1e+07: raise the "
        "period, or check the mission's times")


@pytest.mark.parametrize(("value", "why"), [
    ("1e-9", "timer 'tick': period 1e-09 s must be within [1e-06, 9.2e+09] s"),
    ("1e308", "1e+308 s is out of range: a time in seconds must be within +-9.2e+09 s (int64 nanoseconds)"),
    (".inf", "inf is not allowed: a finite number is expected"),
    ("fast", "expected float, got str 'fast'"),
])
def test_a_bad_period_on_the_command_line_is_one_line_naming_the_option(mission: Path, tmp_path: Path,
                                                                        capsys: pytest.CaptureFixture[str],
                                                                        value: str, why: str) -> None:
    assert main(["replay", str(mission), str(_dr_graph(tmp_path)), "--no-progress",
                 "--set", f"dr.period_s={value}"]) == 2
    assert _one_error(capsys, "replay") == (f"--set dr.period_s={value}: component 'dr' (slam.DeadReckoning): "
                                            f"parameter 'period_s': {why}")
