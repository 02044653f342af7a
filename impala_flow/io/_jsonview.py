"""Readable JSON views of any recorded value, for generic MCAP tools and Foxglove's Plot panel.

The view plugin's fallback mirror (:mod:`impala_flow.io._mirror`) uses them: a stream whose
type has no Foxglove schema (speeds, yaw rates, twists, scalars, detections counts, any
plugin's message) gets a mirror channel ``/foxglove/<topic>`` with message encoding ``json``
and a JSON Schema (schema encoding ``jsonschema``) generated from the
message dataclass, so any MCAP tool decodes it without impala-flow:

- message fields by name; ``int``/``float``/``bool``/``str`` as JSON numbers, booleans, strings
  (a float's JSON text reads back to the same double; NaN and infinities become ``null``);
- numeric arrays of at most ``max_array`` values as (nested) lists; larger ones, and arrays
  of other kinds, as ``{"shape": [...], "dtype": "<f4"}`` (a radar beam stays a few hundred
  bytes: the exact values are on the native channel);
- a nested message as an object; a plain payload as ``{"value": ...}``.
"""

from __future__ import annotations

import dataclasses
import json
import math
import operator
import types
import typing
from json.encoder import encode_basestring_ascii as _str  # what json.dumps writes a str as
from typing import Any

import numpy as np

from ..msgs import is_message, schema_name

__all__ = ["to_json", "json_schema", "MAX_ARRAY"]

#: arrays up to this many values are written in full
MAX_ARRAY = 64


def _finite(x: Any) -> Any:
    return None if isinstance(x, float) and not math.isfinite(x) else x


def _nested(x: Any) -> Any:
    return [_nested(y) for y in x] if isinstance(x, list) else _finite(x)


def _plain(v: Any, max_array: int) -> Any:
    t = type(v)
    if t in _AS_IS:  # the common exact types first, each as the chain below would give it
        return v
    if t is float:
        return v if v - v == 0.0 else None  # x - x is 0 for a finite x, NaN for NaN and +-inf
    fields = _fields.get(t)
    if fields is not None:
        return {n: _plain(getattr(v, n), max_array) for n in fields}
    if isinstance(v, np.ndarray):
        if v.size <= max_array and v.dtype.kind in "biuf":
            return _nested(v.tolist())
        return {"shape": list(v.shape), "dtype": v.dtype.str}
    if isinstance(v, (bool, np.bool_)):
        return bool(v)
    if isinstance(v, (float, np.floating)):
        return _finite(float(v))
    if isinstance(v, np.integer):
        return int(v)
    if dataclasses.is_dataclass(v) and not isinstance(v, type):
        names = tuple(f.name for f in dataclasses.fields(v))
        if len(_fields) < 4096:
            _fields[t] = names
        return {n: _plain(getattr(v, n), max_array) for n in names}
    if isinstance(v, (list, tuple)):
        return [_plain(x, max_array) for x in v]
    if isinstance(v, dict):
        return {str(k): _plain(x, max_array) for k, x in v.items()}
    if isinstance(v, bytes):
        return {"bytes": len(v)}
    return v


_AS_IS = frozenset({int, str, bool, type(None)})
_fields: dict[type, tuple[str, ...]] = {}  # dataclass type -> its field names


def to_json(value: Any, max_array: int = MAX_ARRAY) -> dict[str, Any]:
    """The JSON object ``value`` is shown as (module doc)."""
    out = _plain(value, max_array)
    return out if isinstance(out, dict) else {"value": out}


def encode(value: Any, max_array: int = MAX_ARRAY) -> bytes:
    """:func:`to_json` of ``value`` as compact UTF-8 JSON bytes (what a JSON channel carries):
    a message through its generated encoder (the same text as ``json.dumps`` of
    :func:`to_json`, without building the dict), anything else through ``json.dumps``."""
    t = type(value)
    enc = _encoders.get((t, max_array))
    if enc is None and (t in _fields or (dataclasses.is_dataclass(value) and not isinstance(value, type))):
        enc = _encoder(t, max_array)
    if enc is not None:
        return enc(value).encode()
    return _dumps(to_json(value, max_array)).encode()


def _dumps(x: Any) -> str:
    return json.dumps(x, separators=(",", ":"), allow_nan=False)


_SCALARS = frozenset({int, float, str, bool, type(None)})
_encoders: dict[tuple[type, int], Any] = {}  # (dataclass type, max_array) -> its generated encoder
_building: set[type] = set()  # types whose encoder is being generated (a type nesting itself goes through _text)


def _text(v: Any, max_array: int) -> str:
    """The JSON text of one field value, as ``json.dumps`` writes ``_plain(v, max_array)``."""
    t = type(v)
    if t is float:
        return float.__repr__(v) if v - v == 0.0 else "null"
    if t is int:
        return int.__repr__(v)
    if t is str:
        return _str(v)
    if t is bool:
        return "true" if v else "false"
    if v is None:
        return "null"
    if t is np.ndarray:
        return _array_text(v, max_array)
    enc = _encoders.get((t, max_array))
    if enc is not None or t in _fields or (dataclasses.is_dataclass(v) and not isinstance(v, type)):
        return (enc or _encoder(t, max_array))(v)
    return _dumps(_plain(v, max_array))


_shape_texts: dict[tuple[tuple[int, ...], np.dtype], str] = {}  # (shape, dtype) -> the text of a large array


def _array_text(v: np.ndarray, max_array: int) -> str:
    """:func:`_text` of an array: its values, or (too large, or not numbers) its shape and dtype."""
    if v.size <= max_array and v.dtype.kind in "biuf":
        return "[]" if v.ndim == 1 and v.size == 0 else _dumps(_nested(v.tolist()))
    key = (v.shape, v.dtype)
    out = _shape_texts.get(key)
    if out is None:
        out = '{"shape":[' + ",".join([int.__repr__(int(n)) for n in v.shape]) + '],"dtype":' + _str(v.dtype.str) + "}"
        if len(_shape_texts) < 4096:
            _shape_texts[key] = out
    return out


def _encoder(t: type, max_array: int) -> Any:
    """Generate the encoder of dataclass type ``t``: one concatenation of its fields' texts.
    A type whose fields are all declared scalars (a sensor configuration, shared by every
    beam) keeps its last text and returns it while each field holds the very same immutable
    object as then (identity, so -0.0 and 0.0 or 1 and 1.0 never share a text)."""
    names = _fields.get(t) or tuple(f.name for f in dataclasses.fields(t))
    if len(_fields) < 4096:
        _fields[t] = names
    try:
        hints = typing.get_type_hints(t)
    except Exception:  # unresolvable annotations: no memo, the encoder stays exact
        hints = {}
    memo = bool(names) and all(hints.get(n) in _SCALARS for n in names)
    keys = [_str(n) + ":" for n in names]
    keys = ["{" + keys[0]] + ["," + k for k in keys[1:]] if keys else []
    src = ["def enc(v):"]
    scope_subs: dict[str, Any] = {}
    if memo:
        src += ["    vals = get(v)", "    last = cell[0]",
                "    if last is not None and all(map(is_, vals, last[0])):", "        return last[1]",
                "    out = " + " + ".join(f"{k!r} + text(vals[{i}], m)" for i, k in enumerate(keys)) + ' + "}"',
                "    if all([type(x) in scalars for x in vals]):", "        cell[0] = (vals, out)",
                "    return out"]
    elif names:  # a float or int field's common case inline, anything else (NaN too) through _text
        inline = {float: "(fr(@) if type(@) is float and @ - @ == 0.0 else text(@, m))",
                  int: "(ir(@) if type(@) is int else text(@, m))",
                  np.ndarray: "(atext(@, m) if type(@) is ndarray else text(@, m))"}
        for i, n in enumerate(names):  # a nested message (a beam's config): its own encoder, called straight
            sub = hints.get(n)
            if isinstance(sub, type) and sub is not t and sub not in _building and dataclasses.is_dataclass(sub):
                _building.add(t)
                try:
                    scope_subs[f"sub{i}"] = _encoders.get((sub, max_array)) or _encoder(sub, max_array)
                finally:
                    _building.discard(t)
                scope_subs[f"S{i}"] = sub
                inline[n] = f"(sub{i}(@) if type(@) is S{i} else text(@, m))"
        src.append('    return "".join((' + ", ".join(  # one join: no intermediate string per field
            f"{k!r}, " + inline.get(n, inline.get(hints.get(n), "text(@, m)")).replace("@", f"v.{n}")
            for k, n in zip(keys, names, strict=True)) + ', "}"))')
    else:
        src.append('    return "{}"')
    scope: dict[str, Any] = {"text": _text, "m": max_array, "get": operator.attrgetter(*names) if names else None,
                             "cell": [None], "is_": operator.is_, "scalars": _SCALARS,
                             "fr": float.__repr__, "ir": int.__repr__, "atext": _array_text, "ndarray": np.ndarray,
                             **scope_subs}
    if memo and len(names) == 1:
        scope["get"] = lambda v, n=names[0]: (getattr(v, n),)
    exec("\n".join(src), scope)  # noqa: S102 - generated from field names (identifiers) only
    enc = scope["enc"]
    if len(_encoders) < 4096:
        _encoders[(t, max_array)] = enc
    return enc


_NUMBER = {"type": ["number", "null"]}
_ARRAY = {"anyOf": [{"type": "array"}, {"type": "object", "properties": {
    "shape": {"type": "array", "items": {"type": "integer"}}, "dtype": {"type": "string"}}}]}


def _field_schema(tp: Any) -> dict[str, Any]:
    origin = typing.get_origin(tp)
    if origin in (typing.Union, types.UnionType):
        inner = [a for a in typing.get_args(tp) if a is not type(None)]
        return {"anyOf": [_field_schema(a) for a in inner] + [{"type": "null"}]}
    if tp is bool:
        return {"type": "boolean"}
    if tp is int:
        return {"type": "integer"}
    if tp is float:
        return _NUMBER
    if tp is str:
        return {"type": "string"}
    if tp is np.ndarray:
        return _ARRAY
    if isinstance(tp, type) and is_message(tp):
        return _object_schema(tp)
    return {}


def _object_schema(cls: type) -> dict[str, Any]:
    hints = typing.get_type_hints(cls)
    fields = dataclasses.fields(cls)
    return {"type": "object", "title": schema_name(cls),
            "properties": {f.name: _field_schema(hints.get(f.name)) for f in fields},
            "required": [f.name for f in fields]}


def json_schema(t: type) -> tuple[str, bytes]:
    """(schema name, JSON Schema bytes) of the JSON view of values of type ``t``."""
    if is_message(t):
        return schema_name(t), json.dumps(_object_schema(t), sort_keys=True).encode()
    name = "impala.builtin." + getattr(t, "__name__", "value")
    value: dict[str, Any] = {bool: {"type": "boolean"}, int: {"type": "integer"}, float: _NUMBER,
                             str: {"type": "string"}, np.ndarray: _ARRAY}.get(t, {})
    doc = {"type": "object", "title": name, "properties": {"value": value}}
    return name, json.dumps(doc, sort_keys=True).encode()
