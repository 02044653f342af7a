"""The generic codec: exact round trips of every message type, errors, registry rules."""

from __future__ import annotations

import dataclasses
import json
import types
import typing
from dataclasses import field

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from impala_flow import msgs
from impala_flow.io import (
    CodecError,
    CodecRegistry,
    MessageCodec,
    SchemaConflictError,
    SchemaMismatchError,
    UnknownSchemaError,
)
from impala_flow.io._codec import MESSAGE_ENCODING, SCHEMA_ENCODING
from impala_flow.msgs import message

from .helpers import assert_same

# --- strategies --------------------------------------------------------------------------

_dtypes = st.one_of(
    hnp.boolean_dtypes(), hnp.integer_dtypes(endianness="?"),
    hnp.unsigned_integer_dtypes(endianness="?"), hnp.floating_dtypes(endianness="?"),
    hnp.complex_number_dtypes(endianness="?"), hnp.datetime64_dtypes(endianness="?"),
    hnp.byte_string_dtypes(endianness="?", min_len=1), hnp.unicode_string_dtypes(min_len=1),
)
arrays = _dtypes.flatmap(lambda dt: hnp.arrays(
    dt, hnp.array_shapes(min_dims=0, max_dims=4, min_side=0, max_side=5)))
floats = st.floats(allow_nan=True, allow_infinity=True)
texts = st.text(max_size=20)
f64 = hnp.arrays(np.float64, hnp.array_shapes(min_dims=1, max_dims=2, min_side=0, max_side=4),
                 elements=floats)
def strategy_for(cls: type, depth: int = 0) -> st.SearchStrategy:
    """Values of any @message type, built from its annotations (covers future types)."""
    hints = typing.get_type_hints(cls)
    kwargs = {}
    for f in dataclasses.fields(cls):
        hint, optional = hints[f.name], False
        if typing.get_origin(hint) in (typing.Union, types.UnionType):
            hint, optional = [a for a in typing.get_args(hint) if a is not type(None)][0], True
        if hint is int:
            s = st.integers(-2**63, 2**63 - 1)
        elif hint is float:
            s = floats
        elif hint is bool:
            s = st.booleans()
        elif hint is str:
            s = texts
        elif hint is bytes:
            s = st.binary(max_size=20)
        elif hint is np.ndarray:
            s = arrays
        else:
            s = strategy_for(hint, depth + 1) if depth < 3 else st.nothing()
        kwargs[f.name] = st.none() | s if optional else s
    return st.builds(cls, **kwargs)


@pytest.mark.parametrize("cls", msgs.BUILTIN_TYPES + msgs.installed_types(), ids=lambda c: c.__name__)
@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_message_round_trip(cls: type, data: st.DataObject) -> None:
    registry = CodecRegistry.with_standard_types()
    value = data.draw(strategy_for(cls))
    codec = registry.for_type(cls)
    decoded = codec.decode(codec.encode(value))
    assert_same(value, decoded, cls.__name__)


@settings(max_examples=200, deadline=None)
@given(arrays)
def test_array_round_trip_keeps_dtype_order_shape(a: np.ndarray) -> None:
    codec = CodecRegistry().for_type(np.ndarray)
    b = codec.decode(codec.encode(a))
    assert_same(a, b)


@given(st.one_of(st.integers(-2**63, 2**63 - 1), floats, st.text(), st.binary(),
                 st.booleans(), st.none()))
def test_builtin_payload_round_trip(v: object) -> None:
    codec = CodecRegistry().for_type(type(v))
    assert_same(v, codec.decode(codec.encode(v)))


def test_special_values_exact(registry: CodecRegistry) -> None:
    a = np.array([np.nan, np.inf, -np.inf, -0.0, 5e-324], dtype=">f8")
    nan_payload = np.frombuffer(b"\x01\x00\xc0\x7f", "<f4")  # a NaN with payload bits
    grid = msgs.Grid(a.reshape(5, 1), float("inf"), float("nan"), -0.0,
                     pose=msgs.Pose2D(1, 2, 3, np.zeros((0, 0), ">f4"), "odom"))
    out = registry.for_type(msgs.Grid).decode(registry.for_type(msgs.Grid).encode(grid))
    assert out.data.dtype.str == ">f8" and out.data.tobytes() == a.tobytes()
    assert out.cell_m == float("inf") and np.isnan(out.origin_x_m)
    assert str(np.copysign(1, out.origin_y_m)) == "-1.0"
    assert out.pose.cov_xyt.shape == (0, 0) and out.pose.cov_xyt.dtype.str == ">f4"
    assert out.pose.x_m == 1.0 and out.pose.frame == "odom"
    arr_codec = registry.for_type(np.ndarray)
    assert arr_codec.decode(arr_codec.encode(nan_payload)).tobytes() == nan_payload.tobytes()


def test_decoded_arrays_are_read_only_views(registry: CodecRegistry) -> None:
    codec = registry.for_type(msgs.Points2D)
    payload = codec.encode(msgs.Points2D(np.ones((1000, 2)), np.arange(1000.0)))
    out = codec.decode(payload)
    assert not out.xy_m.flags.writeable
    assert out.xy_m.base is not None  # a view of the payload, not a copy


def test_non_contiguous_and_fortran_arrays(registry: CodecRegistry) -> None:
    codec = registry.for_type(np.ndarray)
    a = np.arange(24, dtype=np.int16).reshape(4, 6)[:, ::2]
    f = np.asfortranarray(np.arange(12.0).reshape(3, 4))
    for x in (a, f, a.T):
        assert_same(np.ascontiguousarray(x), codec.decode(codec.encode(x)))


def test_object_arrays_are_refused(registry: CodecRegistry) -> None:
    with pytest.raises(CodecError, match="object arrays cannot be recorded"):
        registry.for_type(np.ndarray).encode(np.array([1, "a"], dtype=object))
    bad = registry.for_type(np.ndarray).encode(np.zeros(1, "<i8"))
    with pytest.raises(CodecError):  # dtype string forged to 'O' in the payload
        registry.for_type(np.ndarray).decode(bad.replace(b"<i8", b"|O8"))


def test_malformed_payloads_give_codec_errors(registry: CodecRegistry) -> None:
    codec = registry.for_type(msgs.Pose2D)
    good = codec.encode(msgs.Pose2D(1, 2, 3))
    for bad in (good[:-1], good + b"\x00", good[:10], b""):
        with pytest.raises(CodecError, match="impala.Pose2D"):
            codec.decode(bad)


def test_wrong_field_values_name_the_codec(registry: CodecRegistry) -> None:
    with pytest.raises(CodecError, match="impala.Pose2D"):
        registry.for_type(msgs.Pose2D).encode(msgs.Pose2D(None, 0, 0))  # type: ignore[arg-type]
    with pytest.raises(CodecError):
        registry.for_type(int).encode(2**64)


@message("test.Node", version=2)
class Node:
    label: str
    weight: float
    count: int
    flag: bool
    blob: bytes
    child: Node | None = None
    maybe_arr: np.ndarray | None = None
    extra: list = field(default_factory=list)  # unsupported on purpose for one test


@message("test.Tree", version=1)
class Tree:
    name: str
    root: Branch | None = None


@message("test.Branch", version=1)
class Branch:
    value: int
    left: Branch | None = None
    right: Branch | None = None


def test_unsupported_field_type_is_refused_at_registration() -> None:
    with pytest.raises(CodecError, match=r"Node\.extra: unsupported field type"):
        CodecRegistry().add_type(Node, plugin="t")


def test_nested_recursive_and_optional_messages() -> None:
    reg = CodecRegistry()
    codec = reg.add_type(Tree, plugin="t")
    tree = Tree("t", Branch(1, Branch(2), Branch(3, None, Branch(4))))
    assert_same(tree, codec.decode(codec.encode(tree)))
    assert_same(Tree("empty"), codec.decode(codec.encode(Tree("empty"))))
    schema = json.loads(codec.schema_data())
    assert schema["name"] == "test.Tree" and schema["version"] == 1
    assert schema["fields"][1] == {"name": "root", "kind": "message",
                                   "type": "test.Branch@1", "optional": True}
    assert "test.Branch@1" in schema["definitions"]
    assert codec.schema_encoding == SCHEMA_ENCODING
    assert codec.message_encoding == MESSAGE_ENCODING


def test_lookup_by_type_and_schema(registry: CodecRegistry) -> None:
    assert registry.for_type(msgs.Pose2D).schema_name == "impala.Pose2D"
    assert registry.for_type(bool).schema_name == "builtin.bool"
    assert registry.for_type(np.float64).schema_name == "builtin.float"  # subclass of float
    assert registry.for_schema("impala.Grid", 1).py_type is msgs.Grid
    with pytest.raises(CodecError, match="no codec for Python type"):
        registry.for_type(Tree)
    with pytest.raises(UnknownSchemaError, match="'cam/image'.*known versions: \\[1\\]"):
        registry.for_schema("impala.Grid", 7, topic="cam/image")


def test_same_name_by_two_plugins_is_an_error_naming_both() -> None:
    @message("impala.Pose2D", version=1)
    class Impostor:
        x: float

    reg = CodecRegistry.with_standard_types()
    reg.add_type(msgs.Pose2D, plugin="impala_flow")  # same plugin, same class: no-op
    with pytest.raises(SchemaConflictError, match="'impala_flow'.*'thirdparty'"):
        reg.add_type(Impostor, plugin="thirdparty")


def test_schema_layout_mismatch_is_detected() -> None:
    @message("impala.Speed", version=1)
    class OtherSpeed:
        speed_kmh: float

    other = MessageCodec(OtherSpeed)
    reg = CodecRegistry.with_standard_types()
    with pytest.raises(SchemaMismatchError, match="'odo/speed'"):
        reg.for_channel("odo/speed", "impala.Speed", SCHEMA_ENCODING, other.schema_data(),
                        MESSAGE_ENCODING)


class Celsius:
    """A custom codec: JSON text, another schema encoding."""

    py_type = complex
    schema_name, schema_version = "test.Complex", 3
    schema_encoding, message_encoding = "jsonschema", "json"

    def schema_data(self) -> bytes:
        return b'{"type": "array"}'

    def encode(self, v: complex) -> bytes:
        return json.dumps([v.real, v.imag]).encode()

    def decode(self, data: bytes | memoryview) -> complex:
        re, im = json.loads(bytes(data))
        return complex(re, im)


def test_custom_codec() -> None:
    reg = CodecRegistry()
    reg.add_codec(Celsius(), plugin="t")
    c = reg.for_channel("z", "test.Complex", "jsonschema", b"", "json",
                        {"impala_flow.schema_version": "3"})
    assert c.decode(c.encode(1 + 2j)) == 1 + 2j
    with pytest.raises(SchemaConflictError, match="'t'.*'u'"):
        reg.add_codec(Celsius(), plugin="u")
