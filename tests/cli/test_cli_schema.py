"""impala-flow schema: a JSON Schema (draft 2020-12) that accepts what the engine accepts and
rejects typos, unknown parameters, wrong types and out-of-range values, as the engine does."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
import yaml

from impala_flow._load import CLOCK_KEYS, COMPONENT_KEYS, RECORD_KEYS, TOP_KEYS
from impala_flow._schema import graph_schema
from impala_flow._session import Session
from impala_flow._spec import GraphError

from .conftest import ROOT, Installed

jsonschema = pytest.importorskip("jsonschema")

BASE = """\
name: small
components:
  src: {type: clitest.Ticker, params: {count: 4, period: 0.5}}
  gain: {type: clitest.Gain, params: {gain: 3.0}}
  out: {type: clitest.Printer, params: {label: value}}
connections:
  - src.tick -> gain.x
  - gain.y -> out.x
"""

VALID = {
    "base": BASE,
    "everything": """\
name: everything
description: every section of the format
variables: {n: 3, speed: 2}
clock: {mode: replay, speed: "${speed}"}
components:
  src: {type: clitest.Ticker, params: {count: "${n}"}}
  gain: {type: clitest.Gain, params: {gain: 0, mode: square}, on_error: skip, description: squares}
  out: {type: clitest.Printer, params: {label: "n=${n}", gains: [0.5, 2]}}
  sim: clitest.RadarSim
connections:
  - src.tick->gain.x
  - {from: gain.y, to: out.x}
  - {from: gain.y, to: gain.bias, delay: true}
record: {path: out.mcap, streams: ["gain.*", {from: src.tick, topic: ticks}], compression: lz4, foxglove: false}
""",
    "speed max, realtime": BASE + "clock: {mode: realtime, speed: max}\n",
    "integer for a float": BASE.replace("gain: 3.0", "gain: 3"),
    "delay suffix": BASE.replace("gain.y -> out.x", "gain.y -> out.x [delay]"),
}

INVALID = {  # name: (text, words expected in the schema's error)
    "typo in a top-level key": (BASE.replace("connections:", "conection:"), "'conection' was unexpected"),
    "unknown parameter": (BASE.replace("gain: 3.0", "gian: 3.0"), "'gian' was unexpected"),
    "wrong parameter type": (BASE.replace("count: 4", "count: four"), "'four' is not of type 'integer'"),
    "float for an int": (BASE.replace("count: 4", "count: 4.5"), "4.5 is not of type 'integer'"),
    "bool for a float": (BASE.replace("gain: 3.0", "gain: true"), "True is not of type 'number'"),
    "below minimum": (BASE.replace("count: 4", "count: 0"), "0 is less than the minimum of 1"),
    "exclusive maximum": (BASE.replace("gain: 3.0", "gain: 100"), "100 is greater than or equal to the maximum of 100"),
    "exclusive minimum": (BASE.replace("period: 0.5", "period: 0"), "0 is less than or equal to the minimum of 0"),
    "not a choice": (BASE.replace("gain: 3.0", "mode: cubic"), "'cubic' is not one of ['linear', 'square']"),
    "list element out of range": (BASE.replace("label: value", "label: v, gains: [1, -1]"),
                                  "-1 is less than the minimum of 0"),
    "required parameter missing": (BASE.replace("params: {label: value}", "params: {}"),
                                   "'label' is a required property"),
    "unknown component type": (BASE.replace("clitest.Gain", "clitest.Gian"), "'clitest.Gian' is not one of"),
    "unknown component key": (BASE.replace("gain: {type", "gain: {tpye: x, type"), "'tpye' was unexpected"),
    "bad connection": (BASE.replace("gain.y -> out.x", "gain.y => out.x"), "does not match"),
    "connection mapping typo": (BASE.replace("- gain.y -> out.x", "- {from: gain.y, too: out.x}"),
                                "'too' was unexpected"),
    "bad clock mode": (BASE + "clock: {mode: live}\n", "'live' is not one of ['replay', 'realtime']"),
    "zero speed": (BASE + "clock: {speed: 0}\n", "0 is not valid under any of the given schemas"),
    "record without path": (BASE + "record: {streams: ['*']}\n", "'path' is a required property"),
    "record key typo": (BASE + "record: {path: a.mcap, stream: ['*']}\n", "'stream' was unexpected"),
    "bad variable name": (BASE.replace("count: 4", "count: \"${4x}\""), "does not match"),
    "bad on_error": (BASE.replace("{type: clitest.Gain,", "{on_error: ignore, type: clitest.Gain,"),
                     "'ignore' is not one of ['stop', 'skip']"),
}


@pytest.fixture
def session(installed: Installed) -> Session:
    return Session()


@pytest.fixture
def validator(session: Session) -> Any:
    schema = graph_schema(session.registry)
    jsonschema.Draft202012Validator.check_schema(schema)
    return jsonschema.Draft202012Validator(schema)


def test_schema_is_valid_draft_2020_12_and_matches_the_loader(validator: Any) -> None:
    s = validator.schema
    assert s["$schema"] == "https://json-schema.org/draft/2020-12/schema"
    assert s["additionalProperties"] is False
    assert set(s["properties"]) == set(TOP_KEYS)
    assert set(s["properties"]["clock"]["properties"]) == set(CLOCK_KEYS)
    assert set(s["properties"]["record"]["properties"]) == set(RECORD_KEYS)
    assert set(s["$defs"]["component"]["else"]["properties"]) == set(COMPONENT_KEYS)


def test_parameters_carry_types_defaults_bounds_choices_and_docs(validator: Any) -> None:
    params = validator.schema["$defs"]["params:clitest.Gain"]
    assert params["additionalProperties"] is False and "required" not in params
    gain = params["properties"]["gain"]
    assert gain["default"] == 2.0 and gain["description"].startswith("multiplier")
    assert gain["else"] == {"type": "number", "minimum": 0, "exclusiveMaximum": 100, "default": 2.0,
                            "description": gain["description"]}
    assert params["properties"]["mode"]["enum"] == ["linear", "square"]  # strings: no ${var} wrapper
    assert validator.schema["$defs"]["params:clitest.Printer"]["required"] == ["label"]


@pytest.mark.parametrize("name", sorted(VALID))
def test_valid_graphs_validate(name: str, validator: Any, session: Session) -> None:
    doc = yaml.safe_load(VALID[name])
    errors = [e.message for e in validator.iter_errors(doc)]
    assert errors == []
    session.load_text(VALID[name], name=f"{name}.yaml")  # and the engine agrees


@pytest.mark.parametrize("name", sorted(INVALID))
def test_invalid_graphs_are_rejected(name: str, validator: Any, session: Session) -> None:
    text, expected = INVALID[name]
    doc = yaml.safe_load(text)
    messages = [e.message for e in validator.iter_errors(doc)]
    assert messages, "the schema accepted it"
    best = jsonschema.exceptions.best_match(validator.iter_errors(doc)).message
    assert any(expected in m for m in messages + [best]), messages
    with pytest.raises(GraphError):  # and the engine rejects it too
        session.load_text(text, name=f"{name}.yaml")


def test_schema_command_stdout_and_file(installed: Installed, tmp_path: Path) -> None:
    r = installed.run("schema")
    assert r.returncode == 0, r.stderr
    schema = json.loads(r.stdout)
    assert "params:clitest.Ticker" in schema["$defs"]
    out = tmp_path / "graph.schema.json"
    r2 = installed.run("schema", "-o", str(out))
    assert r2.returncode == 0 and r2.stdout == ""
    assert json.loads(out.read_text()) == schema
    assert str(out) in r2.stderr


def test_schema_command_in_process(installed: Installed, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = installed.main("schema", capsys=capsys)
    assert code == 0, err
    jsonschema.Draft202012Validator.check_schema(json.loads(out))
    code, _, err = installed.main("schema", "-o", str(tmp_path / "missing" / "s.json"), capsys=capsys)
    assert code == 1 and "cannot write" in err


def test_shipped_graphs_that_validate_fit_the_schema(validator: Any, session: Session) -> None:
    graphs = sorted((ROOT / "graphs").glob("*.yaml"))
    if not graphs:
        pytest.skip("no graph in graphs/ yet")
    for path in graphs:
        try:
            session.load(path)
        except GraphError:
            continue  # a fragment meant to be included, or a plugin not installed here
        doc = yaml.safe_load(path.read_text(encoding="utf-8"))
        assert [e.message for e in validator.iter_errors(doc)] == [], path
