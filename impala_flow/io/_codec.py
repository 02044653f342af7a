"""One generic, exact binary codec for every message dataclass and the builtin payloads.

Wire format ``impala-flow-bin`` (schema encoding ``impala-flow/v1``), little-endian:

========== ===========================================================================
kind       bytes
========== ===========================================================================
int        ``<q`` (int64; larger ints are refused)
float      ``<d``
bool       ``<?``
str        ``<I`` length, UTF-8
bytes      ``<Q`` length, raw
ndarray    ``<B`` length + ``dtype.str`` (keeps byte order), ``<B`` ndim, ``<Q`` x ndim
           shape, then the C-order raw bytes (``prod(shape) * itemsize``)
message    its fields, in declaration order, inline (the type is known from the schema)
X | None   ``<?`` present, then X if present
none       nothing (the payload ``None``)
========== ===========================================================================

Each type gets a compiled encoder (runs of fixed-size scalars packed by one
:class:`struct.Struct`, arrays written as raw memory) and decoder (arrays are read-only
``np.frombuffer`` views of the payload: zero copy). Decoding never executes code: dtypes
are parsed from their ``str`` and object dtypes are refused. The schema stored with a
channel is JSON naming every field and its kind, so a file is self-describing.
"""

from __future__ import annotations

import dataclasses
import json
import operator
import struct
import types
import typing
from collections.abc import Callable
from operator import attrgetter
from typing import Any

import numpy as np

from ..msgs import is_message, schema_name, schema_version
from ._errors import CodecError

__all__ = [
    "Codec", "MessageCodec", "UpgradingCodec", "BuiltinCodec", "builtin_codecs",
    "SCHEMA_ENCODING", "MESSAGE_ENCODING",
]

SCHEMA_ENCODING = "impala-flow/v1"
MESSAGE_ENCODING = "impala-flow-bin"

_SCALAR_FMT = {"int": "q", "float": "d", "bool": "?"}
_U8, _U32, _U64 = struct.Struct("<B"), struct.Struct("<I"), struct.Struct("<Q")
_SHAPE = [struct.Struct("<" + "Q" * n) for n in range(65)]

Encoder = Callable[[Any, list], None]  # appends byte chunks for a value to a list
Decoder = Callable[[Any, int], tuple[Any, int]]  # (buffer, offset) -> (value, new offset)


class Codec(typing.Protocol):
    """What the registry, the writer and the reader need from any codec (custom ones too)."""

    py_type: type
    schema_name: str
    schema_version: int
    schema_encoding: str
    message_encoding: str

    def schema_data(self) -> bytes: ...
    def encode(self, value: Any) -> bytes: ...
    def decode(self, data: bytes | memoryview) -> Any: ...


# --- arrays ------------------------------------------------------------------------------

_dtype_cache: dict[bytes, np.dtype] = {}  # dtype.str (ASCII) -> dtype
_header_cache: dict[tuple[np.dtype, tuple[int, ...]], bytes] = {}


def _check_dtype(dt: np.dtype, where: str) -> None:
    if dt.hasobject:
        raise CodecError(f"{where}: object arrays cannot be recorded (dtype {dt}); "
                         "use a numeric, bool, string or datetime dtype")
    if dt.fields is not None or dt.subdtype is not None:
        raise CodecError(f"{where}: structured/sub-array dtype {dt} is not supported")


def _encode_array(a: Any, parts: list, where: str = "array") -> None:
    if type(a) is not np.ndarray:
        if not isinstance(a, np.ndarray):
            raise CodecError(f"{where}: expected numpy.ndarray, got {type(a).__name__}")
        a = np.asarray(a)  # subclass (np.matrix, memmap) -> plain ndarray view
    key = (a.dtype, a.shape)
    head = _header_cache.get(key)
    if head is None:
        _check_dtype(a.dtype, where)
        ds = a.dtype.str.encode("ascii")
        head = _U8.pack(len(ds)) + ds + _U8.pack(a.ndim) + _SHAPE[a.ndim].pack(*a.shape)
        if len(_header_cache) < 4096:
            _header_cache[key] = head
    parts.append(head)
    if a.size:
        if not a.flags.c_contiguous:
            a = np.ascontiguousarray(a)
        # a number array's own buffer (its bytes in C order, read without a reshape and a view: a third of the
        # cost); other kinds (datetimes, strings) export no buffer of their own: viewed as bytes
        parts.append(a.data if a.dtype.kind in _BUFFER_KINDS else a.reshape(-1).view(np.uint8).data)


_BUFFER_KINDS = frozenset("biuf")


_empty_cache: dict[tuple[np.dtype, tuple[int, ...]], np.ndarray] = {}


def _parse_dtype(ds: bytes) -> np.dtype:
    try:
        dt = np.dtype(ds.decode("ascii"))
    except (TypeError, UnicodeDecodeError) as e:
        raise CodecError(f"bad dtype {ds!r} in payload") from e
    _check_dtype(dt, "payload")
    if len(_dtype_cache) < 4096:
        _dtype_cache[ds] = dt
    return dt


def _decode_array(buf: Any, off: int) -> tuple[np.ndarray, int]:
    n = buf[off]
    ds = bytes(buf[off + 1 : off + 1 + n])
    dt = _dtype_cache.get(ds)
    if dt is None:
        dt = _parse_dtype(ds)
    off += 1 + n
    ndim = buf[off]
    if ndim == 1:
        count = _U64.unpack_from(buf, off + 1)[0]
        off += 9
        shape: tuple[int, ...] = (count,)
    else:
        shape = _SHAPE[ndim].unpack_from(buf, off + 1)
        off += 1 + 8 * ndim
        count = 1
        for s in shape:
            count *= s
    if count == 0:  # one shared read-only empty array per dtype and shape
        arr = _empty_cache.get((dt, shape))
        if arr is None:
            arr = np.empty(shape, dt)
            arr.flags.writeable = False
            if len(_empty_cache) < 4096:
                _empty_cache[(dt, shape)] = arr
        return arr, off
    nbytes = count * dt.itemsize
    if off + nbytes > len(buf):
        raise CodecError("array payload truncated")
    arr = np.frombuffer(buf, dt, count, off)
    if ndim != 1:
        arr = arr.reshape(shape)
    return arr, off + nbytes


def _decode_array_at(buf: Any, off: int, cell: list) -> tuple[np.ndarray, int]:
    """:func:`_decode_array`, remembering in ``cell`` what the array's header said:
    ``cell[0] = (header bytes, header length, dtype, count, shape (None: 1-D), bytes of data, the
    shared empty array or None)``, one tuple so that a thread reads one consistent header. A
    generated decoder compares the next header at that field with the remembered one and, when
    equal (every beam of a sensor), skips its parsing."""
    arr, end = _decode_array(buf, off)
    nbytes = arr.nbytes
    hl = end - off - nbytes
    cell[0] = (bytes(buf[off:off + hl]), hl, arr.dtype, arr.size, None if arr.ndim == 1 else arr.shape, nbytes,
               arr if arr.size == 0 else None)
    return arr, end


# --- scalars and strings -----------------------------------------------------------------

def _encode_str(v: Any, parts: list) -> None:
    b = v.encode("utf-8")
    parts.append(_U32.pack(len(b)))
    parts.append(b)


def _decode_str(buf: Any, off: int) -> tuple[str, int]:
    (n,) = _U32.unpack_from(buf, off)
    off += 4
    return str(buf[off : off + n], "utf-8"), off + n


def _encode_bytes(v: Any, parts: list) -> None:
    parts.append(_U64.pack(len(v)))
    parts.append(v)


def _decode_bytes(buf: Any, off: int) -> tuple[bytes, int]:
    (n,) = _U64.unpack_from(buf, off)
    off += 8
    return bytes(buf[off : off + n]), off + n


def _encode_none(v: Any, parts: list) -> None:
    if v is not None:
        raise CodecError(f"expected None, got {type(v).__name__}")


def _decode_none(buf: Any, off: int) -> tuple[None, int]:
    return None, off


def _scalar_codec(kind: str) -> tuple[Encoder, Decoder]:
    s = struct.Struct("<" + _SCALAR_FMT[kind])

    def enc(v: Any, parts: list) -> None:
        parts.append(s.pack(v))

    def dec(buf: Any, off: int) -> tuple[Any, int]:
        return s.unpack_from(buf, off)[0], off + s.size

    return enc, dec


_LEAF: dict[str, tuple[Encoder, Decoder]] = {
    "int": _scalar_codec("int"), "float": _scalar_codec("float"),
    "bool": _scalar_codec("bool"), "str": (_encode_str, _decode_str),
    "bytes": (_encode_bytes, _decode_bytes), "ndarray": (_encode_array, _decode_array),
    "none": (_encode_none, _decode_none),
}
_PY_KIND = {int: "int", float: "float", bool: "bool", str: "str", bytes: "bytes",
            np.ndarray: "ndarray", type(None): "none"}


def _optional(enc: Encoder, dec: Decoder) -> tuple[Encoder, Decoder]:
    yes, no = b"\x01", b"\x00"

    def oenc(v: Any, parts: list) -> None:
        if v is None:
            parts.append(no)
        else:
            parts.append(yes)
            enc(v, parts)

    def odec(buf: Any, off: int) -> tuple[Any, int]:
        if buf[off]:
            return dec(buf, off + 1)
        return None, off + 1

    return oenc, odec


# --- message types -----------------------------------------------------------------------

def _type_id(cls: type) -> str:
    return f"{schema_name(cls)}@{schema_version(cls)}"


def _field_kind(cls: type, f: dataclasses.Field, hint: Any) -> tuple[str, bool, type | None]:
    """(kind, optional, message type) of one annotated field."""
    optional = False
    origin = typing.get_origin(hint)
    if origin in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(hint) if a is not type(None)]
        if len(args) != 1 or len(typing.get_args(hint)) != 2:
            raise CodecError(f"{cls.__qualname__}.{f.name}: only 'X | None' unions are supported")
        optional, hint = True, args[0]
        origin = typing.get_origin(hint)
    if origin is np.ndarray:  # numpy.typing.NDArray[...]
        hint = np.ndarray
    if hint in _PY_KIND and hint is not type(None):
        return _PY_KIND[hint], optional, None
    if isinstance(hint, type) and is_message(hint):
        return "message", optional, hint
    raise CodecError(f"{cls.__qualname__}.{f.name}: unsupported field type {hint!r}; use int, "
                     "float, str, bool, bytes, numpy.ndarray, a message type or 'X | None'")


class _Compiled:
    """Encoder/decoder pair of one message type plus its JSON field description."""

    encode_into: Encoder
    decode_from: Decoder
    fields: list[dict[str, Any]]


def _compile(cls: type, cache: dict[type, _Compiled]) -> _Compiled:
    if cls in cache:
        return cache[cls]
    if not dataclasses.is_dataclass(cls) or not is_message(cls):
        raise CodecError(f"{cls!r} is not a @message dataclass")
    comp = cache[cls] = _Compiled()  # registered first: recursive types resolve lazily
    hints = typing.get_type_hints(cls)
    comp.fields = []
    run: list[tuple[str, str]] = []  # pending fixed-size scalars (name, struct char)

    code: list[str] = []  # the generated encoder's lines, one per step
    env: dict[str, Any] = {}

    def flush_run() -> None:
        if not run:
            return
        s = struct.Struct("<" + "".join(c for _, c in run))
        env[f"R{len(code)}"] = s.pack
        code.append(f"append(R{len(code)}(" + ", ".join(f"obj.{n}" for n, _ in run) + "))")
        run.clear()

    for f in dataclasses.fields(cls):
        kind, optional, sub = _field_kind(cls, f, hints[f.name])
        desc: dict[str, Any] = {"name": f.name, "kind": kind}
        if sub is not None:
            desc["type"] = _type_id(sub)
        if optional:
            desc["optional"] = True
        comp.fields.append(desc)
        if kind in _SCALAR_FMT and not optional:
            run.append((f.name, _SCALAR_FMT[kind]))
            continue
        flush_run()
        if sub is not None:
            subc = _compile(sub, cache)
            enc, dec = (lambda v, p, c=subc: c.encode_into(v, p)), (
                lambda b, o, c=subc: c.decode_from(b, o))
            if _internable(sub):
                enc = _memo_encoder(sub, subc)
        else:
            enc, dec = _LEAF[kind]
        if optional:
            enc, dec = _optional(enc, dec)
        env[f"E{len(code)}"] = enc
        code.append(f"E{len(code)}(obj.{f.name}, parts)")
    flush_run()

    # one generated function: each scalar run packed by one call, every other field through its encoder
    src = "def encode_into(obj, parts):\n    append = parts.append\n" + "".join(f"    {c}\n" for c in code)
    exec(compile(src, f"<encoder of {cls.__qualname__}>", "exec"), env)  # noqa: S102 - our own source
    encode_into = env["encode_into"]
    decode_from = _generate_decoder(cls, cache)
    comp.encode_into, comp.decode_from = encode_into, decode_from
    return comp


def _memo_encoder(sub: type, subc: _Compiled) -> Encoder:
    """The encoder of a nested message of scalars and strings (a sensor's configuration, the same
    object in every beam): it keeps its last bytes and gives them again while every field holds
    the very same immutable object as then (identity: -0.0 and 0.0, or 1 and True, never share)."""
    names = tuple(f.name for f in dataclasses.fields(sub))
    get = attrgetter(*names) if len(names) > 1 else (lambda v, n=names[0]: (getattr(v, n),))
    cell: list[Any] = [None]
    is_, scalars = operator.is_, (int, float, str, bool)

    def enc(v: Any, parts: list) -> None:
        vals = get(v)
        last = cell[0]
        if last is not None and all(map(is_, vals, last[0])):
            parts.append(last[1])
            return
        mine: list = []
        subc.encode_into(v, mine)
        b = b"".join(mine)
        if all([type(x) in scalars for x in vals]):
            cell[0] = (vals, b)
        parts.append(b)

    return enc


def _generate_decoder(cls: type, cache: dict[type, _Compiled]) -> Decoder:
    """One generated function decoding ``cls``: scalar runs by one ``unpack_from``, strings
    and arrays inline, nested messages inlined (a recursive type calls its own decoder)."""
    env: dict[str, Any] = {"dec_array_at": _decode_array_at, "U32": _U32.unpack_from, "U64": _U64.unpack_from,
                           "new": object.__new__, "setattr_": object.__setattr__, "frombuffer": np.frombuffer}
    lines: list[str] = []
    counter = [0]

    def var() -> str:
        counter[0] += 1
        return f"v{counter[0]}"

    def leaf(kind: str, sub: type | None, target: str, ind: str, stack: tuple[type, ...]) -> None:
        if kind == "str":
            lines.append(f"{ind}n = U32(buf, off)[0]; off += 4")
            lines.append(f"{ind}{target} = str(buf[off:off + n], 'utf-8'); off += n")
        elif kind == "bytes":
            lines.append(f"{ind}n = U64(buf, off)[0]; off += 8")
            lines.append(f"{ind}{target} = bytes(buf[off:off + n]); off += n")
        elif kind == "ndarray":  # the header seen last time at this field: no parsing
            key = f"A_{counter[0]}"
            counter[0] += 1
            env[key] = [(None, 0, None, 0, None, 0, None)]  # None: equal to no header
            lines.append(f"{ind}c = {key}[0]; e = off + c[1]")
            lines.append(f"{ind}if buf[off:e] == c[0] and e + c[5] <= len(buf):")
            lines.append(f"{ind}    if c[6] is not None:")
            lines.append(f"{ind}        {target} = c[6]; off = e")
            lines.append(f"{ind}    else:")
            lines.append(f"{ind}        {target} = frombuffer(buf, c[2], c[3], e)")
            lines.append(f"{ind}        if c[4] is not None: {target} = {target}.reshape(c[4])")
            lines.append(f"{ind}        off = e + c[5]")
            lines.append(f"{ind}else:")
            lines.append(f"{ind}    {target}, off = dec_array_at(buf, off, {key})")
        elif kind == "none":
            lines.append(f"{ind}{target} = None")
        elif kind == "message":
            assert sub is not None
            if sub in stack:  # recursive type: call its decoder (resolved when called)
                key = f"sub_{counter[0]}"
                counter[0] += 1
                env[key] = cache[sub]
                lines.append(f"{ind}{target}, off = {key}.decode_from(buf, off)")
            elif _internable(sub):
                interned(sub, target, ind, stack + (sub,))
            else:
                message_(sub, target, ind, stack + (sub,))
        else:  # an optional scalar
            key = f"S_{kind}"
            env[key] = struct.Struct("<" + _SCALAR_FMT[kind])
            lines.append(f"{ind}{target} = {key}.unpack_from(buf, off)[0]; off += {env[key].size}")

    def message_(c: type, target: str, ind: str, stack: tuple[type, ...]) -> None:
        hints = typing.get_type_hints(c)
        fields = dataclasses.fields(c)
        values: list[str] = []
        run: list[tuple[str, str]] = []

        def flush() -> None:
            if run:
                key = f"R_{counter[0]}"
                counter[0] += 1
                env[key] = st = struct.Struct("<" + "".join(ch for _, ch in run))
                names = ", ".join(v for v, _ in run)
                lines.append(f"{ind}{names}, = {key}.unpack_from(buf, off); off += {st.size}")
                run.clear()

        for f in fields:
            kind, optional, sub = _field_kind(c, f, hints[f.name])
            v = var()
            values.append(v)
            if kind in _SCALAR_FMT and not optional:
                run.append((v, _SCALAR_FMT[kind]))
                continue
            flush()
            if optional:
                lines.append(f"{ind}if buf[off]:")
                lines.append(f"{ind}    off += 1")
                leaf(kind, sub, v, ind + "    ", stack)
                lines.append(f"{ind}else:")
                lines.append(f"{ind}    off += 1; {v} = None")
            else:
                leaf(kind, sub, v, ind, stack)
        flush()
        ckey = f"C_{counter[0]}"
        counter[0] += 1
        env[ckey] = c
        lines.append(f"{ind}{target} = new({ckey})")
        names = [f.name for f in fields]
        if "__dict__" in dir(c) and not getattr(c, "__slots__", None):
            items = ", ".join(f"{n!r}: {v}" for n, v in zip(names, values, strict=True))
            lines.append(f"{ind}{target}.__dict__.update({{{items}}})")
        else:
            for n, v in zip(names, values, strict=True):
                lines.append(f"{ind}setattr_({target}, {n!r}, {v})")

    def interned(c: type, target: str, ind: str, stack: tuple[type, ...]) -> None:
        """A nested message of scalars and strings (a sensor's configuration, the same in every
        beam): its bytes are measured (string lengths) and looked up among the last ones decoded;
        the same bytes give the same (shared) object, decoded once."""
        key = f"I_{counter[0]}"
        counter[0] += 1
        env[key] = {}
        hints = typing.get_type_hints(c)
        fixed = 0
        lines.append(f"{ind}s0 = e = off")
        for f in dataclasses.fields(c):
            kind = _field_kind(c, f, hints[f.name])[0]
            if kind == "str":
                lines.append(f"{ind}e += {fixed}; e += 4 + U32(buf, e)[0]")
                fixed = 0
            else:
                fixed += struct.calcsize("<" + _SCALAR_FMT[kind])
        lines.append(f"{ind}e += {fixed}")
        lines.append(f"{ind}k = bytes(buf[s0:e]) if e <= len(buf) else None")
        lines.append(f"{ind}{target} = {key}.get(k)")
        lines.append(f"{ind}if {target} is None:")
        message_(c, target, ind + "    ", stack)
        lines.append(f"{ind}    if k is not None:")
        lines.append(f"{ind}        if len({key}) >= {INTERNED_MAX}: {key}.clear()")
        lines.append(f"{ind}        {key}[k] = {target}")
        lines.append(f"{ind}else:")
        lines.append(f"{ind}    off = e")

    message_(cls, "obj", "    ", (cls,))
    src = "def decode_from(buf, off):\n" + "\n".join(lines) + "\n    return obj, off\n"
    exec(compile(src, f"<decoder of {cls.__qualname__}>", "exec"), env)  # noqa: S102 - our own source
    return env["decode_from"]


#: distinct values of one nested message of scalars and strings a decoder keeps (then it starts afresh)
INTERNED_MAX = 64


def _internable(c: type) -> bool:
    """Whether every field of message type ``c`` is a (non-optional) int, float, bool or str."""
    try:
        hints = typing.get_type_hints(c)
        kinds = [_field_kind(c, f, hints[f.name]) for f in dataclasses.fields(c)]
    except (CodecError, NameError, TypeError):
        return False
    return bool(kinds) and all(k in ("int", "float", "bool", "str") and not opt for k, opt, _ in kinds)


def _schema_json(root: dict[str, Any], definitions: dict[str, Any]) -> bytes:
    doc = {"format": f"{MESSAGE_ENCODING}/1", **root}
    if definitions:
        doc["definitions"] = definitions
    return json.dumps(doc, sort_keys=True, separators=(",", ":")).encode()


class _BaseCodec:
    schema_encoding = SCHEMA_ENCODING
    message_encoding = MESSAGE_ENCODING
    py_type: type
    schema_name: str
    schema_version: int
    _schema: bytes
    _enc: Encoder
    _dec: Decoder

    def schema_data(self) -> bytes:
        return self._schema

    def encode(self, value: Any) -> bytes:
        """Encode ``value`` (an instance of :attr:`py_type`) to bytes."""
        return b"".join(self.encode_parts(value))

    def encode_parts(self, value: Any) -> list:
        """The payload as a list of buffers (arrays are views, not copies) to concatenate."""
        parts: list = []
        try:
            self._enc(value, parts)
        except (struct.error, TypeError, AttributeError, OverflowError) as e:
            raise CodecError(f"cannot encode {type(value).__name__} with the "
                             f"{self.schema_name} codec: {e}") from e
        return parts

    def decode(self, data: bytes | memoryview) -> Any:
        """Decode a payload; arrays are read-only views of ``data`` (no copy)."""
        try:
            value, off = self._dec(data, 0)
        except (struct.error, IndexError, ValueError, UnicodeDecodeError) as e:
            if isinstance(e, CodecError):
                raise
            raise CodecError(f"malformed {self.schema_name} payload: {e}") from e
        if off != len(data):
            raise CodecError(f"malformed {self.schema_name} payload: "
                             f"{len(data) - off} trailing bytes")
        return value

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.schema_name}@{self.schema_version}>"


class MessageCodec(_BaseCodec):
    """The generic codec of one ``@message`` dataclass (compiled once, at construction)."""

    def __init__(self, cls: type) -> None:
        cache: dict[type, _Compiled] = {}
        comp = _compile(cls, cache)
        self.py_type = cls
        self.schema_name, self.schema_version = schema_name(cls), schema_version(cls)
        self._enc, self._dec = comp.encode_into, comp.decode_from
        defs = {_type_id(t): {"fields": c.fields} for t, c in cache.items() if t is not cls}
        self._schema = _schema_json(
            {"name": self.schema_name, "version": self.schema_version, "kind": "message",
             "fields": comp.fields}, defs)


class UpgradingCodec(MessageCodec):
    """Reads recordings of an older version of a message type: decodes the old layout
    (``old_cls``, a ``@message`` dataclass of that version) and returns ``upgrade(old)``, an
    instance of the current type. Read-only: values are always written at the current version."""

    def __init__(self, old_cls: type, upgrade: Callable[[Any], Any], new_cls: type | None = None) -> None:
        super().__init__(old_cls)
        self._upgrade = upgrade
        if new_cls is None:  # the upgrade's return annotation names the current type
            new_cls = typing.get_type_hints(upgrade).get("return")
        if not isinstance(new_cls, type):
            raise TypeError(f"upgrade of {self.schema_name} v{self.schema_version}: give new_cls, the type it returns")
        #: what a reader decodes on such a channel (a replayer declares its output with it)
        self.value_type = new_cls

    def decode(self, data: bytes | memoryview) -> Any:
        return self._upgrade(super().decode(data))

    def encode_parts(self, value: Any) -> list:
        raise CodecError(f"{self.schema_name} version {self.schema_version} is read-only (an older version)")


class BuiltinCodec(_BaseCodec):
    """Codec of a builtin payload (``int``, ``float``, ``str``, ``bytes``, ``bool``,
    ``numpy.ndarray`` or ``None``), schema ``builtin.<kind>`` version 1."""

    def __init__(self, py_type: type) -> None:
        kind = _PY_KIND[py_type]
        self.py_type = py_type
        self.schema_name, self.schema_version = f"builtin.{kind}", 1
        self._enc, self._dec = _LEAF[kind]
        self._schema = _schema_json({"name": self.schema_name, "version": 1, "kind": kind}, {})


def builtin_codecs() -> list[BuiltinCodec]:
    """One codec per builtin payload type."""
    return [BuiltinCodec(t) for t in _PY_KIND]
