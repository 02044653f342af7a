"""Mission sources: a plugin offers "make a mission recording" through the registry
(``registry.add_mission_source``), the sweep looks it up by name instead of running another
plugin's command line; the radar plugin's ``simulate`` source writes the bytes of
``impala-flow simulate``."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

from impala_flow import Session
from impala_flow.plugins import DISABLE_ENV, NameConflictError, hookimpl
from impala_sweep.task import simulate_mission

from .conftest import DURATION_S, ROOT, sweep_main


def test_the_radar_plugin_offers_simulate_with_the_commands_bytes(missions: list[Path], tmp_path: Path) -> None:
    session = Session()
    source = session.registry.mission_sources["simulate"]
    assert source.plugin == "radar" and source.help
    path = tmp_path / "beynes-1.mcap"
    source.make(session, "beynes", str(path), seed=1, duration_s=float(DURATION_S))
    assert path.read_bytes() == missions[0].read_bytes()  # as `impala-flow simulate beynes --seed 1 --duration 4s`


def test_the_sweeps_simulation_goes_through_the_source(missions: list[Path], tmp_path: Path) -> None:
    out = tmp_path / "missions" / "beynes_s2.mcap"
    result = simulate_mission("beynes", 2, float(DURATION_S), str(out))
    assert result["error"] is None and result["path"] == str(out)
    assert out.read_bytes() == missions[1].read_bytes()
    assert [p.name for p in out.parent.iterdir() if p.name.endswith(".part")] == []  # renamed when complete


def test_a_bad_scenario_is_one_line_and_leaves_no_file(tmp_path: Path) -> None:
    out = tmp_path / "missions" / "nowhere_s1.mcap"
    result = simulate_mission("nowhere", 1, 1.0, str(out))
    assert result["error"].startswith("simulating nowhere (seed 1): scenario 'nowhere': ")
    assert "\n" not in result["error"]
    assert sorted(p.name for p in out.parent.iterdir()) == ["nowhere_s1.log"]  # the log only, no mission


def test_a_sweep_without_the_source_stops_before_it_starts(write_sweep: Callable[..., Path], tmp_path: Path,
                                                           monkeypatch: pytest.MonkeyPatch,
                                                           capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setenv(DISABLE_ENV, "radar")  # odometry.yaml needs no radar component, its missions do
    path = write_sweep(f"graph: {ROOT / 'graphs' / 'odometry.yaml'}\n"
                       "missions: {simulate: {scenario: beynes}}\nmetrics: [eval.ate_rmse_m]\n")
    assert sweep_main(str(path), "-o", str(tmp_path / "out")) == 2
    err = capsys.readouterr().err.strip()
    assert err == (f"impala-flow sweep: error: {path}:2:33: simulated missions need the mission source "
                   "'simulate', which no installed plugin offers (installed: none; the radar plugin offers it)")
    assert not (tmp_path / "out").exists()
    # and a worker without it says so on the task's row, naming the installed sources
    result = simulate_mission("beynes", 1, 1.0, str(tmp_path / "m" / "beynes_s1.mcap"))
    assert result["error"] == ("simulating beynes: no installed plugin offers the mission source 'simulate' "
                               "(installed: none)")


class _Other:
    """A third-party plugin offering a mission source of its own, and one clashing with radar's."""

    def __init__(self, name: str) -> None:
        self.name = name

    @hookimpl
    def impala_flow_register(self, registry: object) -> None:
        registry.add_mission_source(self.name, self.make)  # type: ignore[attr-defined]

    def make(self, session: Session, scenario: str, path: str, *, seed: int | None = None,
             duration_s: float | None = None) -> None:
        Path(path).write_text(f"{scenario} {seed} {duration_s}")


def test_a_third_party_source_is_listed_and_a_clash_names_both_plugins(tmp_path: Path) -> None:
    session = Session(extra_plugins={"other": _Other("replay-log")})
    assert sorted(session.registry.mission_sources) == ["replay-log", "simulate"]
    source = session.registry.mission_sources["replay-log"]
    assert source.plugin == "other"
    source.make(session, "x", str(tmp_path / "m"), seed=3)
    assert (tmp_path / "m").read_text() == "x 3 None"
    with pytest.raises(NameConflictError, match="'mission:simulate' is registered by two plugins: ") as e:
        Session(extra_plugins={"other": _Other("simulate")})
    assert "'radar'" in str(e.value) and "'other'" in str(e.value)


def test_plugins_lists_the_mission_sources(capsys: pytest.CaptureFixture[str]) -> None:
    import json

    from impala_flow import cli

    assert cli.main(["plugins", "--json"]) == 0
    plugins = {p["name"]: p for p in json.loads(capsys.readouterr().out)["plugins"]}
    assert [m["name"] for m in plugins["radar"]["mission_sources"]] == ["simulate"]
    assert all(not p["mission_sources"] for name, p in plugins.items() if name != "radar")
    assert cli.main(["plugins"]) == 0
    text = capsys.readouterr().out
    assert "  mission source: simulate (simulate a scenario (name or YAML file) with a seed, for a duration)" in text
