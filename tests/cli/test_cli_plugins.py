"""impala-flow plugins: text and JSON listings, and a plugin that fails to load."""

from __future__ import annotations

import json

import pytest

from .conftest import Installed


def _clitest(data: dict) -> dict:
    (p,) = [p for p in data["plugins"] if p["name"] == "clitest"]
    return p


def test_json_lists_versions_components_ports_and_params(installed: Installed) -> None:
    r = installed.run("plugins", "--json")
    assert r.returncode == 0, r.stderr
    data = json.loads(r.stdout)
    p = _clitest(data)
    assert p["version"] == "0.3.1" and p["module"] == "tests.cli.clitest_plugin"
    comps = {c["type"]: c for c in p["components"]}
    assert list(comps)[:3] == ["clitest.Ticker", "clitest.Gain", "clitest.Boom"]  # registration order
    ticker = comps["clitest.Ticker"]
    assert ticker["kind"] == "source"
    assert ticker["summary"] == "Emit 0.0, 1.0, 2.0, ... every period."  # first line of the docstring
    assert ticker["outputs"] == [{"name": "tick", "direction": "out", "type": "float", "doc": "the count, as a float"}]
    gain = comps["clitest.Gain"]
    x, bias = gain["inputs"]
    assert (x["name"], x["type"], x["policy"], x["maxsize"], x["overflow"]) == ("x", "float", "reactive", 1024, "block")
    assert (bias["policy"], bias["required"]) == ("sampling", False)
    params = {q["name"]: q for q in gain["params"]}
    assert params["gain"] == {"name": "gain", "type": "float", "required": False, "default": 2.0, "ge": 0,
                              "gt": None, "le": None, "lt": 100, "choices": None, "doc": "multiplier"}
    assert params["mode"]["choices"] == ["linear", "square"]
    slam = comps["clitest.RSlam"]
    assert {i["sync"] for i in slam["inputs"]} == {"scan"} and slam["inputs"][0]["tolerance_s"] == 0.05
    pano = {i["name"]: i for i in comps["clitest.PanoramicBuilder"]["inputs"]}
    assert pano["beams"]["overflow"] == "drop_oldest" and pano["beams"]["maxsize"] == 720
    assert pano["yaw_rate"]["history_s"] == 2.0 and pano["yaw_rate"]["angular"] is True
    assert pano["yaw_rate"]["type"] == "impala.YawRate"  # message types by schema name
    printer = {q["name"]: q for q in comps["clitest.Printer"]["params"]}
    assert printer["label"]["required"] is True and printer["label"]["default"] is None


def test_text_is_grouped_by_plugin_and_aligned(installed: Installed, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = installed.main("plugins", capsys=capsys)
    assert code == 0, err
    lines = out.splitlines()
    head = lines.index(next(line for line in lines if line.startswith("clitest 0.3.1")))
    assert "[tests.cli.clitest_plugin]" in lines[head] and "12 components" in lines[head]
    block = lines[lines.index("  clitest.Gain: Multiply every number by a gain."):][:6]
    assert block[1:] == [
        "      in     x     float  reactive, fifo=1024 block         numbers in",
        "      in     bias  float  sampling, optional                added to every output",
        "      out    y     float",
        "      param  gain  float  = 2.0, >= 0, < 100                multiplier",
        "      param  mode  str    = 'linear', one of linear|square  how x is used",
    ]
    assert "  clitest.Ticker [source]: Emit 0.0, 1.0, 2.0, ... every period." in lines
    assert any("sync=scan ±0.05s" in line for line in lines)
    assert any(line.strip().startswith("param  label  str    required") for line in lines)
    assert lines[-1].endswith("component types")


def test_plugin_failing_at_import_is_listed_not_fatal(installed: Installed) -> None:
    installed.add("impala-flow-missing", "1.0", {"missing": "tests.cli.no_such_module"})
    r = installed.run("plugins")
    assert r.returncode == 0, r.stderr
    assert ("missing 1.0  [tests.cli.no_such_module]  BROKEN: "
            "ModuleNotFoundError: No module named 'tests.cli.no_such_module'") in r.stdout.splitlines()
    assert "Traceback" not in r.stderr


def test_plugin_failing_at_registration_is_listed_not_fatal(installed: Installed,
                                                             capsys: pytest.CaptureFixture[str]) -> None:
    installed.add("impala-flow-broken", "1.0", {"broken": "tests.cli.broken_register"})
    code, out, err = installed.main("plugins", capsys=capsys)
    assert code == 0, err
    assert ("broken 1.0  [tests.cli.broken_register]  BROKEN: "
            "RuntimeError: this plugin is broken on purpose") in out.splitlines()
    assert any(line.startswith("clitest 0.3.1") for line in out.splitlines())


def test_blocked_plugin_is_not_listed(installed: Installed, capsys: pytest.CaptureFixture[str]) -> None:
    installed.add("impala-flow-broken", "1.0", {"broken": "tests.cli.broken_register"})
    installed.monkeypatch.setenv("IMPALA_FLOW_DISABLE_PLUGINS", "broken,clitest")
    code, out, err = installed.main("plugins", "--json", capsys=capsys)
    assert code == 0, err
    names = {p["name"] for p in json.loads(out)["plugins"]}
    assert not names & {"broken", "clitest"}


def test_the_engines_io_is_listed_and_cannot_be_replaced_or_blocked(installed: Installed,
                                                                    capsys: pytest.CaptureFixture[str]) -> None:
    """'io' is the engine's own (io.Recorder, io.Replayer): an installed entry point claiming the name (an
    old impala-flow with its io plugin) is left out as broken with one line, which blocking 'io' hides;
    the engine's io stays either way."""
    installed.add("impala-flow-stale", "0.0.9", {"io": "tests.cli.clitest_plugin"})
    for blocked, stale_listed in (("", True), ("io", False)):
        installed.monkeypatch.setenv("IMPALA_FLOW_DISABLE_PLUGINS", blocked)
        code, out, err = installed.main("plugins", "--json", capsys=capsys)
        assert code == 0, err
        plugins = {p["name"]: p for p in json.loads(out)["plugins"]}
        assert plugins["io"]["module"] == "impala_flow._builtin"
        assert [c["type"] for c in plugins["io"]["components"]] == ["io.Recorder", "io.Replayer"]
        stale = [b for b in json.loads(out).get("broken", []) if b["name"] == "io"]
        assert len(stale) == stale_listed, out
        assert all("names the engine's own components" in b["error"] for b in stale)
