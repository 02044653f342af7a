"""JSON Schema (draft 2020-12) of the graph file format, for editors and linters.

The schema is generated from the installed plugins: every component type gets its own
``params`` schema (JSON types, defaults, bounds, choices, descriptions), so an editor
completes parameter names and flags typos before ``impala-flow validate`` runs::

    # yaml-language-server: $schema=impala-flow-graph.schema.json
    name: demo
    components:
      ...

It checks the shape of one file; what a schema cannot see (ports, port types,
cycles, the components an ``include:`` brings) stays with ``impala-flow validate``.
"""

from __future__ import annotations

import json
import math
from typing import Any

from ._component import Component, Param
from ._registry import Registry
from ._spec import MIN_SPEED
from ._version import __version__

__all__ = ["graph_schema", "CONNECTION_PATTERN", "VARIABLE_PATTERN"]

DRAFT = "https://json-schema.org/draft/2020-12/schema"
#: a connection string: ``a.out -> b.in`` with an optional ``[delay]``
CONNECTION_PATTERN = r"^\S+\.\S+\s*->\s*\S+\.\S+(\s*\[delay\])?$"
#: a value that is a whole ``${variable}`` (replaced by the variable's value, of any type)
VARIABLE_PATTERN = r"^\$\{[A-Za-z_][A-Za-z0-9_]*\}$"
PORT_PATTERN = r"^[^.\s]+\.\S+$"

_JSON_TYPES: dict[type, str] = {int: "integer", float: "number", str: "string", bool: "boolean",
                                list: "array", dict: "object"}
_BOUNDS = (("ge", "minimum"), ("gt", "exclusiveMinimum"), ("le", "maximum"), ("lt", "exclusiveMaximum"))


def _jsonable(value: Any) -> Any:
    """``value`` as plain JSON data, or raise ``TypeError``/``ValueError``."""
    if isinstance(value, tuple):
        value = list(value)
    if isinstance(value, float) and not math.isfinite(value):
        raise ValueError("not finite")
    json.dumps(value, allow_nan=False)
    return value


def _first_line(doc: str | None) -> str:
    for line in (doc or "").strip().splitlines():
        if line.strip():
            return line.strip()
    return ""


def param_schema(p: Param) -> dict[str, Any]:
    """Schema of one parameter value."""
    s: dict[str, Any] = {}
    jtype = _JSON_TYPES.get(p.type)
    if jtype:
        s["type"] = jtype
    bounds = {key: getattr(p, attr) for attr, key in _BOUNDS if getattr(p, attr) is not None}
    if bounds:
        if p.type is list:  # bounds apply to every number of the list
            s["items"] = {"if": {"type": "number"}, "then": bounds}
        else:
            s.update(bounds)
    if p.choices is not None:
        try:
            s["enum"] = [_jsonable(c) for c in p.choices]
        except (TypeError, ValueError):
            pass
    if not p.required:
        try:
            s["default"] = _jsonable(p.default)
        except (TypeError, ValueError):
            pass
    doc = p.doc.strip()
    s["description"] = f"{doc} ({p.describe()})" if doc else p.describe()
    if p.type is str:
        return s  # a string may hold ${variables} anywhere
    # a non-string parameter may be a whole ${variable}, replaced by its value at load time
    return _or_variable(s)


def _or_variable(s: dict[str, Any]) -> dict[str, Any]:
    """``s``, or a string starting with ``${`` that must then be a whole ``${variable}``.

    (if/then/else rather than anyOf, so a wrong value gets the error of ``s`` itself.)
    """
    head = {k: s[k] for k in ("description", "default") if k in s}
    return {**head, "if": {"type": "string", "pattern": r"^\$\{"}, "then": {"$ref": "#/$defs/variable"}, "else": s}


def params_schema(cls: type[Component]) -> dict[str, Any]:
    """Schema of the ``params`` mapping of a component type."""
    props = {name: param_schema(p) for name, p in cls.__params__.items()}
    s: dict[str, Any] = {"type": "object", "properties": props, "additionalProperties": False}
    required = [name for name, p in cls.__params__.items() if p.required]
    if required:
        s["required"] = required
    return s


def _component_defs(registry: Registry) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    defs: dict[str, Any] = {}
    rules: list[dict[str, Any]] = []
    registry.load_all()  # every type's parameters are read: a module failing leaves its plugin broken, unlisted
    for name in sorted(registry.components):
        cls = registry.components[name]
        key = f"params:{name}"
        defs[key] = {"description": f"parameters of {name}", **params_schema(cls)}
        then: dict[str, Any] = {"properties": {"params": {"$ref": f"#/$defs/{key}"}}}
        if any(p.required for p in cls.__params__.values()):
            then["required"] = ["params"]
        rules.append({"if": {"properties": {"type": {"const": name}}, "required": ["type"]}, "then": then})
    return defs, rules


def _component_schema(registry: Registry, rules: list[dict[str, Any]]) -> dict[str, Any]:
    names = sorted(registry.components)
    type_s: dict[str, Any] = {"type": "string", "description": "component type, '<plugin>.<Class>'"}
    if names:
        type_s["enum"] = names
        type_s["markdownEnumDescriptions"] = [_first_line(registry.components[n].__doc__) for n in names]
    props: dict[str, Any] = {
        "type": type_s,
        "params": {"type": "object", "description": "parameters of the component (see its type)"},
        "on_error": {"enum": ["stop", "skip"], "default": "stop",
                     "description": "stop: an exception stops the graph; skip: the sample is skipped and counted"},
        "description": {"type": "string"},
        "inputs": {
            "type": "object", "description": "bounds of some inputs, over the component's own: "
            "{input: {maxsize: 1, overflow: drop_oldest}} keeps only the newest sample of a slow stage",
            "additionalProperties": {
                "type": "object", "additionalProperties": False, "minProperties": 1,
                "properties": {
                    "maxsize": {"type": "integer", "minimum": 1, "description": "samples the input queues"},
                    "overflow": {"enum": ["block", "drop_oldest", "drop_newest"],
                                 "description": "when full: block the producer (live) or drop a whole sample"},
                    "maxbytes": {"type": "integer", "minimum": 1, "description": "bytes the input queues"},
                },
            },
        },
        "override": {"type": "boolean", "default": False,
                     "description": "replace the component of the same id defined in an included file "
                                    "(without it, defining an id twice is an error)"},
    }
    obj: dict[str, Any] = {
        "type": "object", "properties": props, "additionalProperties": False,
        "description": "a component: {type: plugin.Class, params: {...}}; without 'type' it refines "
                       "a component of the same id from an included file",
    }
    if rules:
        obj["allOf"] = rules
    # shorthand 'id: plugin.Class' (if/then/else, so errors come from the mapping's schema)
    return {"if": {"type": "string"}, "then": {"$ref": "#/$defs/component_type"}, "else": obj}


def graph_schema(registry: Registry) -> dict[str, Any]:
    """A JSON Schema (draft 2020-12) of graph files, with a ``params`` schema per component
    type of ``registry``."""
    comp_defs, rules = _component_defs(registry)
    endpoint = {"type": "string", "pattern": PORT_PATTERN, "description": "component.port"}
    connection = {
        "description": "'component.output -> component.input' ('[delay]' suffix to break a cycle), "
                       "or {from: component.output, to: component.input, delay: false}",
        "if": {"type": "string"},
        "then": {"pattern": CONNECTION_PATTERN},
        "else": {"type": "object", "additionalProperties": False, "required": ["from", "to"],
                 "properties": {"from": endpoint, "to": endpoint,
                                "delay": {"type": "boolean", "default": False,
                                          "description": "a delayed connection (breaks a cycle)"}}},
    }
    stream = {
        "anyOf": [
            {"type": "string", "description": "pattern of outputs: 'slam.pose', 'slam.*', 'radar/*'"},
            {"type": "object", "additionalProperties": False, "required": ["from"],
             "properties": {"from": endpoint, "topic": {"type": "string", "description": "MCAP topic"}}},
        ]
    }
    props: dict[str, Any] = {
        "name": {"type": "string", "description": "graph name (default: the file name)"},
        "description": {"type": "string"},
        "include": {
            "description": "graph file(s) merged before this one, relative to this file",
            "anyOf": [{"type": "string"}, {"type": "array", "items": {"type": "string"}}],
        },
        "variables": {
            "type": "object", "description": "values substituted for ${NAME} (overridden by --var NAME=VALUE)",
            "propertyNames": {"pattern": r"^[A-Za-z_][A-Za-z0-9_]*$"},
        },
        "clock": {
            "type": "object", "additionalProperties": False,
            "properties": {
                "mode": {"enum": ["replay", "realtime"], "default": "replay",
                         "description": "replay: deterministic offline executor; realtime: live sources"},
                "speed": _or_variable({
                    "default": "max", "description": "replay speed: 'max' or a factor (1 = real time)",
                    "anyOf": [{"const": "max"}, {"type": "number", "minimum": MIN_SPEED}]}),
            },
        },
        "components": {
            "type": "object", "description": "components by id",
            "propertyNames": {"pattern": r"^[^./]+$"},
            "additionalProperties": {"$ref": "#/$defs/component"},
        },
        "connections": {"type": "array", "items": {"$ref": "#/$defs/connection"}},
        "record": {
            "type": "object", "additionalProperties": False, "required": ["path"],
            "description": "record streams to an MCAP file",
            "properties": {
                "path": {"type": "string", "description": "MCAP file written"},
                "streams": {"type": "array", "items": stream, "default": ["*"]},
                "compression": {"type": "string", "description": "chunk compression, e.g. zstd, lz4 or none"},
                "foxglove": {"type": "boolean", "description":
                    "also write the mirrors plugins register (the view plugin: Foxglove well-known schemas)"},
                "ros2": {"enum": ["", "beside", "only"], "description":
                         "also write standard ROS 2 messages (the ros2 plugin): beside the native channels, "
                         "or only them"},
                "chunk_size": {"type": "integer", "minimum": 1024, "maximum": 1 << 28,
                               "description": "bytes per MCAP chunk"},
                "flush_period_s": {"type": "number", "minimum": 0,
                                   "description": "close a chunk at least this often (wall s); 0: by size only"},
                "maxsize": {"type": "integer", "minimum": 1, "maximum": 1 << 16,
                            "description": "samples queued per recorded stream before its producer blocks"},
                "threads": {"type": "integer", "minimum": 1, "maximum": 2, "description":
                            "2: chunks compressed and written on a second thread (the same bytes as 1)"},
            },
        },
    }
    plugins = ", ".join(f"{p.name} {p.version}".strip() for p in registry.plugins.values()) or "none"
    return {
        "$schema": DRAFT,
        "title": "impala-flow graph",
        "description": "A YAML graph of impala-flow components and connections.",
        "$comment": f"generated by impala-flow {__version__} for the plugins: {plugins}",
        "type": "object",
        "additionalProperties": False,
        "properties": props,
        "$defs": {
            "variable": {"type": "string", "pattern": VARIABLE_PATTERN,
                         "description": "a ${variable}, replaced by its value when the graph loads"},
            "component_type": {"type": "string", "enum": sorted(registry.components)} if registry.components
            else {"type": "string"},
            "component": _component_schema(registry, rules),
            "connection": connection,
            **comp_defs,
        },
    }
