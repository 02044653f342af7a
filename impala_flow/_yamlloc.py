"""Safe YAML loading that remembers where every key and value came from (file:line:col).

Scalars are read with the YAML 1.2 core schema, not PyYAML's YAML 1.1 one: ``1:30`` and
``2024-01-01`` stay strings, ``yes``/``no``/``on``/``off`` stay strings, ``1e-4`` is a
float, ``0o17`` and ``0x1F`` are integers. An integer written with a leading zero
(``010``: octal 8 in YAML 1.1, decimal 10 in YAML 1.2) is refused with its location.

A graph file is small: it is refused past :data:`MAX_BYTES`, past :data:`MAX_DEPTH`
levels of nesting, or when its aliases (``*name``) would expand it to more than
:data:`MAX_VALUES` values (an "alias bomb"); a recursive alias is refused too. Each
node is converted once: an alias shares the object of its anchor.
"""

from __future__ import annotations

import os
import re
import stat
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

__all__ = ["Loc", "LocDict", "LocList", "location", "load_yaml", "load_value", "YamlError", "Loader",
           "MAX_BYTES", "MAX_DEPTH", "MAX_VALUES", "shown", "brief", "read_bounded", "decode_text"]

#: largest graph file read (bytes): a graph is a few kB; this keeps validation under a second
MAX_BYTES = 64 << 10
#: deepest nesting of mappings and lists, aliases expanded
MAX_DEPTH = 64
#: most values (scalars, mappings, lists) of one file once its aliases are expanded
MAX_VALUES = 50_000

_TAG = "tag:yaml.org,2002:"
_INT = re.compile(r"^(?:[-+]?[0-9]+|0o[0-7]+|0x[0-9a-fA-F]+)$")
_FLOAT = re.compile(r"^(?:[-+]?(?:\.[0-9]+|[0-9]+(?:\.[0-9]*)?)(?:[eE][-+]?[0-9]+)?"
                    r"|[-+]?\.(?:inf|Inf|INF)|\.(?:nan|NaN|NAN))$")


class YamlError(ValueError):
    """The file is not valid YAML (one line, with file:line:col)."""


#: characters of a key or value quoted in an error message (a file's contents are never echoed at length)
SHOWN_CHARS = 40


def shown(value: Any, limit: int = SHOWN_CHARS) -> str:
    """``value`` as text for an error message: control characters escaped, cut to ``limit``
    characters (an included ``/etc/shadow`` is not echoed back, a terminal is not driven)."""
    text = repr(value)[1:-1] if isinstance(value, str) else repr(value)
    if len(text) > limit:
        text = text[:limit] + f"...({len(text)} chars)"
    return text


def brief(value: Any, limit: int = 60) -> str:
    """``repr(value)`` cut to ``limit`` characters, for an error message quoting a value."""
    text = repr(value)
    return text if len(text) <= limit else text[:limit] + f"...({len(text)} chars)"


def read_bounded(path: str | Path, max_bytes: int, what: str = "a graph file") -> bytes:
    """The bytes of ``path``, a regular file of at most ``max_bytes``; else one-line
    :class:`YamlError`. A named pipe, a device (``/dev/zero``), a socket or a folder is
    refused before it is opened for reading (opening a FIFO would wait for a writer, reading
    ``/dev/zero`` would never end); a file is read up to ``max_bytes + 1`` bytes at most."""
    file = str(path)
    try:
        st = os.stat(file)
    except OSError as e:
        raise YamlError(f"{file}: cannot read: {e.strerror or e}") from None
    if not stat.S_ISREG(st.st_mode):
        kind = ("a folder" if stat.S_ISDIR(st.st_mode) else "a named pipe" if stat.S_ISFIFO(st.st_mode)
                else "a device" if stat.S_ISCHR(st.st_mode) or stat.S_ISBLK(st.st_mode)
                else "a socket" if stat.S_ISSOCK(st.st_mode) else "not a regular file")
        raise YamlError(f"{file}: is {kind}, not {what}")
    if st.st_size > max_bytes:
        raise YamlError(f"{file}: larger than {max_bytes // 1024} kB: not {what}")
    try:
        # O_NONBLOCK: had it been swapped for a FIFO since the stat, open() does not wait
        fd = os.open(file, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except OSError as e:
        raise YamlError(f"{file}: cannot read: {e.strerror or e}") from None
    with os.fdopen(fd, "rb") as f:
        if not stat.S_ISREG(os.fstat(f.fileno()).st_mode):
            raise YamlError(f"{file}: not a regular file, not {what}")
        try:
            data = f.read(max_bytes + 1)
        except OSError as e:
            raise YamlError(f"{file}: cannot read: {e.strerror or e}") from None
    if len(data) > max_bytes:
        raise YamlError(f"{file}: larger than {max_bytes // 1024} kB: not {what}")
    return data


class _PyEvents(yaml.SafeLoader):
    def fetch_flow_collection_start(self, token_class: Any) -> None:
        # the scanner looks ahead through every open bracket before the composer sees
        # the first one: bound them here, or "[[[[..." scans in quadratic time. Below a
        # block mapping (a graph's root, level 1) a bracket opened at flow level f is level
        # f + 2 or deeper: the first past MAX_DEPTH is the one opened at MAX_DEPTH - 1
        if self.flow_level >= MAX_DEPTH - 1:
            raise yaml.scanner.ScannerError(None, None, f"nested more than {MAX_DEPTH} levels deep",
                                            self.get_mark())
        super().fetch_flow_collection_start(token_class)


try:  # libyaml parses the events (ten times faster); composing stays in Python, bounded
    from yaml._yaml import CParser as _Parser

    class _Events(yaml.composer.Composer, _Parser, yaml.constructor.SafeConstructor,  # type: ignore[misc]
                  yaml.resolver.Resolver):
        def __init__(self, stream: str) -> None:
            _Parser.__init__(self, stream)
            yaml.constructor.SafeConstructor.__init__(self)
            yaml.resolver.Resolver.__init__(self)
            yaml.composer.Composer.__init__(self)
except ImportError:  # pragma: no cover - PyYAML built without libyaml
    _Events = _PyEvents  # type: ignore[misc,assignment]


class _Bounded:
    """Nesting bounded while composing (mixed into both loaders)."""

    max_depth = MAX_DEPTH

    def __init__(self, stream: str) -> None:
        super().__init__(stream)  # type: ignore[call-arg]
        self._depth = 0

    def compose_node(self, parent: Any, index: Any) -> Any:
        self._depth += 1
        try:
            if self._depth > self.max_depth:
                mark = self.peek_event().start_mark  # type: ignore[attr-defined]
                raise yaml.composer.ComposerError(
                    None, None, f"nested more than {self.max_depth} levels deep", mark)
            return super().compose_node(parent, index)  # type: ignore[misc]
        finally:
            self._depth -= 1


class Loader(_Bounded, _Events):  # type: ignore[misc]
    """A safe loader: the YAML 1.2 core schema's scalars, nesting bounded while composing."""


class _PyLoader(_Bounded, _PyEvents):
    """The same in pure Python: it locates the 65th level where libyaml stops at its own 1000th."""


Loader.yaml_implicit_resolvers = {}
_PyLoader.yaml_implicit_resolvers = {}
for _tag, _regex, _first in (
    ("null", r"^(?:~|null|Null|NULL|)$", ["~", "n", "N", ""]),
    ("bool", r"^(?:true|True|TRUE|false|False|FALSE)$", list("tTfF")),
    ("int", _INT.pattern, list("-+0123456789")),  # before float: "10" is an int
    ("float", _FLOAT.pattern, list("-+0123456789.")),
    ("merge", r"^(?:<<)$", ["<"]),
):
    for _cls in (Loader, _PyLoader):
        _cls.add_implicit_resolver(_TAG + _tag, re.compile(_regex), _first)


def _construct_int(loader: Loader, node: yaml.ScalarNode) -> int:
    text = str(loader.construct_scalar(node))
    if not _INT.match(text):
        raise yaml.constructor.ConstructorError(None, None, f"{text!r} is not an integer", node.start_mark)
    if text.startswith(("0o", "0x")):
        return int(text[2:], 8 if text[1] == "o" else 16)
    digits = text.lstrip("+-")
    if len(digits) > 1 and digits[0] == "0":
        octal = f"octal {int(digits, 8)}" if set(digits) <= set("01234567") else "an error"
        raise yaml.constructor.ConstructorError(
            None, None, f"'{text}': a leading zero is ambiguous (YAML 1.1 reads {octal}, YAML 1.2 "
            f"{int(text)}): write {int(text)}, 0o{digits.lstrip('0') or '0'} for octal, or quote it", node.start_mark)
    return int(text)


def _construct_float(loader: Loader, node: yaml.ScalarNode) -> float:
    text = str(loader.construct_scalar(node))
    low = text.lower()
    if low.endswith((".inf", ".nan")):
        return float(low.replace(".", ""))
    try:
        return float(text)
    except ValueError:
        raise yaml.constructor.ConstructorError(None, None, f"{text!r} is not a number", node.start_mark) from None


def _construct_bool(loader: Loader, node: yaml.ScalarNode) -> bool:
    return str(loader.construct_scalar(node)).lower() == "true"


for _cls in (Loader, _PyLoader):
    _cls.add_constructor(_TAG + "int", _construct_int)
    _cls.add_constructor(_TAG + "float", _construct_float)
    _cls.add_constructor(_TAG + "bool", _construct_bool)


def load_value(text: str) -> Any:
    """One value from the command line (``--set k=1e-4``): YAML scalar or flow collection.

    A value the YAML 1.2 core schema refuses (``010``) raises :class:`YamlError`; text that
    is not YAML at all raises ``yaml.YAMLError``."""
    if not text.strip():
        return ""
    if len(text) > MAX_BYTES:
        raise YamlError(f"value longer than {MAX_BYTES // 1024} kB")
    try:
        return yaml.load(text, Loader=Loader)  # noqa: S506 - Loader is a SafeLoader
    except yaml.constructor.ConstructorError as e:
        raise YamlError(str(e.problem)) from None


@dataclass(frozen=True)
class Loc:
    file: str
    line: int  # 1-based
    col: int   # 1-based

    def __str__(self) -> str:  # line 0: not in a file (a command-line option, named by ``file``)
        return f"{self.file}:{self.line}:{self.col}" if self.line else self.file


class LocDict(dict):
    """A dict that knows the location of itself, of each key and of each value."""

    def __init__(self, *a: Any, **kw: Any) -> None:
        super().__init__(*a, **kw)
        self.loc: Loc | None = None
        self.key_locs: dict[Any, Loc] = {}
        self.value_locs: dict[Any, Loc] = {}

    def where(self, key: Any) -> Loc | None:
        return self.key_locs.get(key, self.loc)

    def value_where(self, key: Any) -> Loc | None:
        return self.value_locs.get(key, self.where(key))


class LocList(list):
    def __init__(self, *a: Any) -> None:
        super().__init__(*a)
        self.loc: Loc | None = None
        self.item_locs: list[Loc] = []

    def where(self, i: int) -> Loc | None:
        return self.item_locs[i] if i < len(self.item_locs) else self.loc


def location(node: Any, key: Any = None, default: str = "", *, value: bool = False) -> str:
    """``file:line:col`` of ``key`` in a mapping or list read by :func:`load_yaml` (of its
    value with ``value=True``; of the node itself when ``key`` is None), else ``default``."""
    loc = None
    if isinstance(node, LocDict):
        loc = node.loc if key is None else (node.value_where(key) if value else node.where(key))
    elif isinstance(node, LocList):
        loc = node.loc if key is None else node.where(key)
    return str(loc) if loc is not None else default


def _loc(file: str, node: yaml.Node) -> Loc:
    return Loc(file, node.start_mark.line + 1, node.start_mark.column + 1)


_PLAIN_TAGS = ("tag:yaml.org,2002:map", "tag:yaml.org,2002:seq", "tag:yaml.org,2002:omap")


def _measure(loader: Loader, node: yaml.Node, file: str, depth: int, memo: dict[int, tuple[int, int]],
             active: set[int]) -> tuple[int, int]:
    """(values, height) of ``node`` with its aliases expanded; each node is walked once."""
    if depth > MAX_DEPTH:
        raise YamlError(f"{_loc(file, node)}: invalid YAML: nested more than {MAX_DEPTH} levels deep "
                        "once its aliases are expanded")
    key = id(node)
    if key in memo:
        size, height = memo[key]
        if depth + height > MAX_DEPTH:
            raise YamlError(f"{_loc(file, node)}: invalid YAML: nested more than {MAX_DEPTH} levels deep "
                            "once its aliases are expanded")
        return size, height
    if key in active:
        raise YamlError(f"{_loc(file, node)}: invalid YAML: recursive alias (a node that contains itself)")
    size, height = 1, 0
    if isinstance(node, (yaml.MappingNode, yaml.SequenceNode)):
        if isinstance(node, yaml.MappingNode):
            loader.flatten_mapping(node)  # resolves YAML merge keys (<<)
            children = [n for pair in node.value for n in pair]
        else:
            children = node.value
        active.add(key)
        for child in children:
            s, h = _measure(loader, child, file, depth + 1, memo, active)
            size, height = size + s, max(height, h + 1)
            if size > MAX_VALUES:
                raise YamlError(f"{_loc(file, node)}: invalid YAML: expands to more than {MAX_VALUES} values "
                                "(aliases repeated inside aliases?)")
        active.discard(key)
    memo[key] = (size, height)
    return size, height


def _convert(loader: Loader, node: yaml.Node, file: str, memo: dict[int, Any]) -> Any:
    key = id(node)
    if key in memo:  # an alias: the object of its anchor, converted once
        return memo[key]
    if isinstance(node, (yaml.MappingNode, yaml.SequenceNode)) and node.tag not in _PLAIN_TAGS:
        raise YamlError(f"{_loc(file, node)}: invalid YAML: tag '{shown(node.tag)}' is not allowed (safe loader)")
    if isinstance(node, yaml.MappingNode):
        d = LocDict()
        d.loc, d.key_locs, d.value_locs = _loc(file, node), {}, {}
        for knode, vnode in node.value:
            k = loader.construct_object(knode, deep=True)
            try:
                hash(k)
            except TypeError:
                raise YamlError(f"{_loc(file, knode)}: invalid YAML: a key must be a scalar") from None
            if k in d:
                raise YamlError(f"{_loc(file, knode)}: duplicate key '{shown(k)}'")
            d[k] = _convert(loader, vnode, file, memo)
            d.key_locs[k] = _loc(file, knode)
            d.value_locs[k] = _loc(file, vnode)
        out: Any = d
    elif isinstance(node, yaml.SequenceNode):
        lst = LocList(_convert(loader, n, file, memo) for n in node.value)
        lst.loc, lst.item_locs = _loc(file, node), [_loc(file, n) for n in node.value]
        out = lst
    else:
        out = loader.construct_object(node, deep=True)
    memo[key] = out
    return out


def decode_text(file: str, data: bytes) -> str:
    """``data`` read from ``file`` as UTF-8 text; bad bytes are one line naming the file and line."""
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as e:
        line = data.count(b"\n", 0, e.start) + 1
        col = e.start - (data.rfind(b"\n", 0, e.start) + 1) + 1
        raise YamlError(f"{file}:{line}:{col}: not UTF-8 text (byte 0x{data[e.start]:02x}); "
                        "save the file as UTF-8") from None


def load_yaml(path: str | Path, text: str | None = None) -> Any:
    """Load ``path`` with the safe loader, keeping locations; errors are one line."""
    file = str(path)
    if text is None:
        text = decode_text(file, read_bounded(path, MAX_BYTES))
    elif len(text) > MAX_BYTES:
        raise YamlError(f"{file}: larger than {MAX_BYTES // 1024} kB: not a graph file")
    try:
        return _load(Loader, text, file)
    except YamlError as e:
        if Loader is _PyLoader or "maximum nesting depth" not in str(e):
            raise
    # libyaml stopped at its own nesting limit (1000) before the composer's bound: the
    # pure-Python scanner finds where the 65th level opens
    return _load(_PyLoader, text, file)


def _load(cls: type, text: str, file: str) -> Any:
    loader = cls(text)
    try:
        node = loader.get_single_node()
        if node is None:
            return LocDict()
        _measure(loader, node, file, 1, {}, set())
        return _convert(loader, node, file, {})
    except yaml.MarkedYAMLError as e:
        mark = e.problem_mark or e.context_mark
        where = f"{file}:{mark.line + 1}:{mark.column + 1}" if mark else file
        raise YamlError(f"{where}: invalid YAML: {e.problem or e.context}") from None
    except yaml.YAMLError as e:
        raise YamlError(f"{file}: invalid YAML: {e}") from None
    except RecursionError:
        raise YamlError(f"{file}: invalid YAML: nested too deeply") from None
    finally:
        loader.dispose()
