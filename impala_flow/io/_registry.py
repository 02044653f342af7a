"""CodecRegistry: which codec encodes a Python type and decodes a (schema name, version)."""

from __future__ import annotations

import json
from collections.abc import Iterator
from typing import Any

from ._adapter import ANY_SCHEMA, AdapterFactory
from ._codec import SCHEMA_ENCODING, Codec, MessageCodec, UpgradingCodec, builtin_codecs
from ._errors import CodecError, SchemaConflictError, SchemaMismatchError, UnknownSchemaError
from ._foreign import ForeignWriter, ForeignWriterFactory
from ._mirror import Mirror, MirrorFactory

__all__ = ["CodecRegistry", "VERSION_KEY"]

#: channel metadata key holding the schema version (MCAP schema records have a name only)
VERSION_KEY = "impala_flow.schema_version"
ENGINE = "impala_flow"


class CodecRegistry:
    """Codecs by Python type and by (schema name, version), each with the plugin that added it.

    A registry is built per run (never global). ``CodecRegistry()`` holds the builtin
    payloads (int, float, str, bytes, bool, numpy.ndarray, None);
    :meth:`with_standard_types` adds every type of :mod:`impala_flow.msgs` and of the installed
    message packages (and readers of the older versions they list in ``LEGACY``).
    """

    def __init__(self, *, builtins: bool = True) -> None:
        self._by_schema: dict[tuple[str, int], tuple[Codec, str]] = {}
        self._by_type: dict[type, Codec] = {}
        self._type_cache: dict[type, Codec | None] = {}
        self._mirrors: dict[Any, tuple[MirrorFactory, str]] = {}
        self._mirror_cache: dict[tuple[Any, bool], Mirror | None] = {}
        self._foreign: dict[str, tuple[ForeignWriterFactory, str]] = {}
        self._foreign_missing: dict[str, str] = {}  # format -> why its plugin is not loaded
        self._adapters: dict[tuple[str, str, str], tuple[AdapterFactory, str]] = {}
        #: one line per plugin left out for a library it lacks ("plugin 'ros2' needs mcap_ros2: pip install ..."):
        #: said when a channel no codec nor adapter reads may be one of theirs
        self.missing_plugins: tuple[str, ...] = ()
        if builtins:
            for c in builtin_codecs():
                self.add_codec(c, plugin=ENGINE)

    @classmethod
    def with_standard_types(cls) -> CodecRegistry:
        """A registry with the builtin payloads, every :mod:`impala_flow.msgs` type and every
        type of the installed message packages (:func:`impala_flow.msgs.installed_packages`)."""
        from .. import msgs

        reg = cls()
        for t in msgs.BUILTIN_TYPES:
            reg.add_type(t, plugin=ENGINE)
        for package in msgs.installed_packages():
            for t in package.types:
                reg.add_type(t, plugin=package.name)
            for old, upgrade in package.legacy:  # older versions, read and upgraded
                reg.add_codec(UpgradingCodec(old, upgrade), plugin=package.name)
        return reg

    @classmethod
    def from_plugins(cls, plugins: Any) -> CodecRegistry:
        """Standard types plus the message types, codecs and mirrors of an engine
        :class:`impala_flow._registry.Registry` (what the plugins of a run registered)."""
        reg = cls.with_standard_types()
        owner = getattr(plugins, "owner", {})
        for name, t in getattr(plugins, "types", {}).items():
            if t not in reg:
                reg.add_type(t, plugin=owner.get(name, "?"))
        for name, codec in getattr(plugins, "codecs", {}).items():
            if (codec.schema_name, codec.schema_version) not in reg:
                reg.add_codec(codec, plugin=owner.get(f"codec:{name}", "?"))
        for key, (make, plugin) in getattr(plugins, "mirrors", {}).items():
            reg.add_mirror(key, make, plugin=plugin)
        for name, (make, plugin) in getattr(plugins, "foreign_writers", {}).items():
            reg.add_foreign_writer(name, make, plugin=plugin)
        for name, broken in getattr(plugins, "broken", {}).items():
            reg._foreign_missing[name] = broken.needs or broken.describe()
        for key, (make, plugin) in getattr(plugins, "channel_adapters", {}).items():
            reg.add_channel_adapter(*key, make, plugin=plugin)
        reg.missing_plugins = tuple(b.needs for b in getattr(plugins, "broken", {}).values() if b.missing)
        return reg

    # --- registration ------------------------------------------------------------------

    def add_type(self, cls: type, plugin: str = "?") -> Codec:
        """Register the generic codec of ``@message`` class ``cls`` (and of its nested types).

        Registering the same class again from the same plugin is a no-op; the same schema
        name and version from another plugin (or another class) is a SchemaConflictError.
        """
        existing = self._by_type.get(cls)
        if existing is not None and self.plugin_of(existing) == plugin:
            return existing
        codec = MessageCodec(cls)
        self.add_codec(codec, plugin=plugin)
        return codec

    def add_codec(self, codec: Codec, plugin: str = "?") -> None:
        """Register a codec (custom ones follow :class:`impala_flow.io._codec.Codec`)."""
        key = (codec.schema_name, int(codec.schema_version))
        prev = self._by_schema.get(key)
        if prev is not None:
            pc, pp = prev
            if pc is codec:
                return
            raise SchemaConflictError(
                f"schema {key[0]!r} version {key[1]} registered twice: by plugin {pp!r} "
                f"({_qual(pc.py_type)}) and by plugin {plugin!r} ({_qual(codec.py_type)})")
        tprev = self._by_type.get(codec.py_type)
        if tprev is not None:
            raise SchemaConflictError(
                f"type {_qual(codec.py_type)} registered twice: as {tprev.schema_name!r} by "
                f"plugin {self.plugin_of(tprev)!r} and as {codec.schema_name!r} by "
                f"plugin {plugin!r}")
        self._by_schema[key] = (codec, plugin)
        self._by_type[codec.py_type] = codec
        self._type_cache.clear()

    def add_mirror(self, key: Any, make: MirrorFactory, plugin: str = "?") -> None:
        """Register the mirror factory of type ``key`` (``object``: the fallback of every other
        type; :data:`~impala_flow.io.TRANSFORMS`: the frame tree); see :mod:`impala_flow.io._mirror`."""
        prev = self._mirrors.get(key)
        if prev is not None and prev[0] is not make:
            raise SchemaConflictError(f"mirror of {_key(key)} registered twice: by plugin {prev[1]!r} "
                                      f"and by plugin {plugin!r}")
        self._mirrors[key] = (make, plugin)
        self._mirror_cache.clear()

    def add_foreign_writer(self, name: str, make: ForeignWriterFactory, plugin: str = "?") -> None:
        """Register the output format ``name`` (``make()``: the writer of one recording); see
        :mod:`impala_flow.io._foreign`."""
        prev = self._foreign.get(name)
        if prev is not None and prev[0] is not make:
            raise SchemaConflictError(f"output format {name!r} registered twice: by plugin {prev[1]!r} "
                                      f"and by plugin {plugin!r}")
        self._foreign[name] = (make, plugin)

    def foreign_writer(self, name: str) -> ForeignWriter:
        """A new writer of output format ``name``, or CodecError saying which plugin would bring it
        (the plugin named like the format, whose extra installs its libraries)."""
        entry = self._foreign.get(name)
        if entry is None:
            why = self._foreign_missing.get(name) or (f"no plugin registers it (the '{name}' plugin: "
                                                      f"pip install 'impala-flow[{name}]')")
            raise CodecError(f"{name} output unavailable: {why}")
        return entry[0]()
    def add_channel_adapter(self, schema_encoding: str, schema_name: str, message_encoding: str,
                            make: AdapterFactory, plugin: str = "?") -> None:
        """Register the factory of the adapter reading channels of that key (schema name ``"*"``:
        every schema of the encodings without its own); see :mod:`impala_flow.io._adapter`."""
        key = (schema_encoding, schema_name, message_encoding)
        prev = self._adapters.get(key)
        if prev is not None and prev[0] is not make:
            raise SchemaConflictError(f"channel adapter of {key} registered twice: by plugin {prev[1]!r} "
                                      f"and by plugin {plugin!r}")
        self._adapters[key] = (make, plugin)

    def adapter_for(self, schema_encoding: str, schema_name: str, message_encoding: str) -> AdapterFactory | None:
        """The adapter factory of a channel: its own schema's, else its encodings' ``"*"``, else None."""
        entry = (self._adapters.get((schema_encoding, schema_name, message_encoding))
                 or self._adapters.get((schema_encoding, ANY_SCHEMA, message_encoding)))
        return None if entry is None else entry[0]

    @property
    def adapted_encodings(self) -> set[str]:
        """Schema encodings some adapter reads."""
        return {k[0] for k in self._adapters}

    def mirror_for(self, key: Any, fallback: bool = False) -> Mirror | None:
        """The mirror of values of type ``key`` (exact type), else with ``fallback`` the
        fallback mirror (``object``; never for ``None``); None when there is none."""
        ck = (key, fallback)
        if ck in self._mirror_cache:
            return self._mirror_cache[ck]
        entry = self._mirrors.get(key) if key is not object else None
        m: Mirror | None = None
        if entry is not None:
            m = entry[0](key)
        elif fallback and key is not type(None) and isinstance(key, type) and object in self._mirrors:
            m = self._mirrors[object][0](key)
        self._mirror_cache[ck] = m
        return m

    # --- lookup --------------------------------------------------------------------------

    def for_type(self, t: type) -> Codec:
        """The codec encoding values of type ``t`` (exact type first, then its bases)."""
        try:
            c = self._type_cache[t]
        except KeyError:
            c = self._by_type.get(t)
            if c is None:
                c = next((self._by_type[b] for b in t.__mro__[1:] if b in self._by_type), None)
            self._type_cache[t] = c
        if c is None:
            raise CodecError(f"no codec for Python type {_qual(t)}: register it with "
                             "registry.add_type(cls, plugin=...) (a @message dataclass)")
        return c

    def find(self, name: str, version: int) -> Codec | None:
        entry = self._by_schema.get((name, int(version)))
        return None if entry is None else entry[0]

    def for_schema(self, name: str, version: int, *, topic: str = "?") -> Codec:
        """The codec of schema ``name`` version ``version``, or UnknownSchemaError."""
        c = self.find(name, version)
        if c is None:
            known = sorted(v for n, v in self._by_schema if n == name)
            detail = f"known versions: {known}" if known else "not registered by any plugin"
            raise UnknownSchemaError(topic, name, version, detail)
        return c

    def for_channel(self, topic: str, schema_name: str, schema_encoding: str,
                    schema_data: bytes, message_encoding: str,
                    channel_metadata: dict[str, str] | None = None) -> Codec:
        """The codec to decode one recorded channel, checking its stored field layout."""
        stored: dict[str, Any] | None = None
        version: int | None = None
        meta = channel_metadata or {}
        if schema_encoding == SCHEMA_ENCODING:
            try:
                stored = json.loads(bytes(schema_data))
                version = int(stored["version"])
            except (ValueError, KeyError, TypeError) as e:
                raise UnknownSchemaError(topic, schema_name, None,
                                         f"unreadable schema text: {e}") from None
        elif VERSION_KEY in meta:
            try:
                version = int(meta[VERSION_KEY])
            except ValueError:
                version = None
        if version is None:
            known = sorted(v for n, v in self._by_schema if n == schema_name)
            if len(known) != 1:
                raise UnknownSchemaError(topic, schema_name, None,
                                         f"encoding {schema_encoding!r}, no version")
            version = known[0]
        codec = self.for_schema(schema_name, version, topic=topic)
        if codec.message_encoding != message_encoding:
            raise UnknownSchemaError(topic, schema_name, version,
                                     f"message encoding {message_encoding!r}, the codec "
                                     f"reads {codec.message_encoding!r}")
        if stored is not None and codec.schema_encoding == SCHEMA_ENCODING:
            mine = json.loads(codec.schema_data())
            if _layout(mine) != _layout(stored):
                raise SchemaMismatchError(topic, schema_name, version,
                                          "the recorded fields differ from the registered "
                                          "type: the version should have been bumped")
        return codec

    def plugin_of(self, codec: Codec) -> str:
        return self._by_schema[(codec.schema_name, int(codec.schema_version))][1]

    def __iter__(self) -> Iterator[Codec]:
        return (c for c, _ in self._by_schema.values())

    def __len__(self) -> int:
        return len(self._by_schema)

    def __contains__(self, key: object) -> bool:
        if isinstance(key, tuple):
            return key in self._by_schema
        return key in self._by_type


def _layout(doc: dict[str, Any]) -> tuple:
    return (doc.get("kind"), doc.get("fields"), doc.get("definitions"))


def _key(key: Any) -> str:
    return _qual(key) if isinstance(key, type) else repr(key)


def _qual(t: type) -> str:
    return f"{t.__module__}.{t.__qualname__}"
