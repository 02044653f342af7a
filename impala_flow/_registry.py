"""Registry: what the installed plugins provide, built fresh for every run."""

from __future__ import annotations

import importlib
import logging
import sys
from collections.abc import Callable, Iterator, MutableMapping
from dataclasses import dataclass, field
from typing import Any

from ._component import Component
from .msgs import BUILTIN_TYPES, installed_packages, is_message, schema_name

__all__ = ["Registry", "RegistrationError", "NameConflictError", "PluginInfo", "BrokenPlugin", "MissionSource",
           "ComponentTable"]

log = logging.getLogger("impala_flow.plugins")


class RegistrationError(ValueError):
    """Two plugins registered the same name, or a registration is malformed."""


class NameConflictError(RegistrationError):
    """Two plugins claim the same name: an error of the installation, naming both."""


@dataclass
class BrokenPlugin:
    """A plugin that failed to import or to register: left out, every other plugin loads.

    ``target`` is its entry point (``module:attr``), ``error`` one line
    (``ModuleNotFoundError: No module named 'x'``). A library the plugin needs but the
    installation lacks is ``missing`` (``gtsam``), with ``install``, the line that brings it
    (``pip install 'impala-flow[slam]'``, empty when its distribution declares no such extra)."""

    name: str
    target: str = ""
    version: str = ""
    error: str = ""
    missing: str = ""
    install: str = ""

    @property
    def hint(self) -> str:
        return f"IMPALA_FLOW_DISABLE_PLUGINS={self.name} hides it"

    def _lacks(self) -> str:
        return f"needs {self.missing}" + (f": {self.install}" if self.install else ", which is not installed")

    @property
    def needs(self) -> str:
        """``plugin 'slam' needs gtsam: pip install 'impala-flow[slam]'``, or '' if nothing is missing."""
        return f"plugin '{self.name}' {self._lacks()}" if self.missing else ""

    def describe(self) -> str:
        if self.missing:
            return f"plugin '{self.name}' ({self.target}) {self._lacks()}"
        return f"plugin '{self.name}' ({self.target}) failed to load: {self.error}"


@dataclass(frozen=True)
class MissionSource:
    """A way to make a mission recording, offered by a plugin (:meth:`Registry.add_mission_source`):
    ``make(session, scenario, path, *, seed=None, duration_s=None)`` writes the recording to ``path``."""

    name: str
    make: Callable[..., None]
    help: str = ""
    plugin: str = ""


@dataclass
class PluginInfo:
    name: str
    version: str = ""
    module: str = ""
    components: list[str] = field(default_factory=list)
    types: list[str] = field(default_factory=list)


class ComponentTable(MutableMapping[str, "type[Component]"]):
    """The registered component types by name (a mapping, as a dict). A type registered by where
    it lives (``"pkg.module:Class"``) is imported the first time it is looked up (a graph builds
    it, a command describes its ports); its name is known without importing it, so a command
    that uses none of a plugin's components never loads their modules. A module that then fails
    to import (or names no component) leaves its plugin broken, as a failing registration
    would: the type is forgotten, the plugin joins ``registry.broken`` with its one-line error,
    one warning is logged, and the lookup finds nothing (validation says why)."""

    def __init__(self, registry: Registry) -> None:
        self._types: dict[str, Any] = {}  # name -> class, or "module:Class" not imported yet
        self._registry = registry

    def __getitem__(self, name: str) -> type[Component]:
        cls = self._types[name]
        if isinstance(cls, str):
            cls = self._registry._import_component(name, cls)
        return cls

    def __setitem__(self, name: str, cls: Any) -> None:
        self._types[name] = cls

    def __delitem__(self, name: str) -> None:
        del self._types[name]

    def __contains__(self, name: object) -> bool:
        return name in self._types

    def __iter__(self) -> Iterator[str]:
        return iter(self._types)

    def __len__(self) -> int:
        return len(self._types)

    def __repr__(self) -> str:
        return f"ComponentTable({sorted(self._types)})"

    def where(self, name: str) -> str:
        """``module:Class`` of a type not imported yet, else its class's ``module:qualname``."""
        cls = self._types[name]
        return cls if isinstance(cls, str) else f"{cls.__module__}:{cls.__qualname__}"


class Registry:
    """Components, message types, codecs and mirrors, each tagged with its plugin.

    ``registry.add_component(MyFilter)`` inside ``impala_flow_register`` registers
    ``<plugin>.MyFilter``; ``registry.add_component("mypkg.filters.component:MyFilter")`` registers
    the same name without importing the module until the type is used (:class:`ComponentTable`).
    A name registered twice is an error naming both plugins.
    """

    def __init__(self) -> None:
        self.components: ComponentTable = ComponentTable(self)
        #: ``(plugin, target, error) -> BrokenPlugin``: how a component module failing to import is
        #: recorded (:func:`impala_flow.plugins.load_registry` sets one that finds the missing library's pip line)
        self.broken_plugin: Callable[[str, str, BaseException], BrokenPlugin] = _broken_plugin
        self.types: dict[str, type] = {}
        self.codecs: dict[str, Any] = {}
        self.mirrors: dict[Any, tuple[Any, str]] = {}  # type (or key) -> (mirror factory, plugin)
        self.foreign_writers: dict[str, tuple[Any, str]] = {}  # output format -> (writer factory, plugin)
        #: (schema encoding, schema name, message encoding) -> (adapter factory, plugin)
        self.channel_adapters: dict[tuple[str, str, str], tuple[Any, str]] = {}
        #: name -> a plugin's way to make a mission recording (:meth:`add_mission_source`)
        self.mission_sources: dict[str, MissionSource] = {}
        self.owner: dict[str, str] = {}  # registered name -> plugin name
        self.plugins: dict[str, PluginInfo] = {}
        self.broken: dict[str, BrokenPlugin] = {}  # plugins left out, with their error
        self._current: PluginInfo | None = None
        for t in BUILTIN_TYPES:
            self.types[schema_name(t)] = t
            self.owner[schema_name(t)] = "impala_flow"
        for package in installed_packages():  # message packages (impala_msgs...): types, no components
            for t in package.types:
                self.types[schema_name(t)] = t
                self.owner.setdefault(schema_name(t), package.name)

    def _claim(self, key: str) -> None:
        plugin = self._current.name if self._current else "impala_flow"
        if key in self.owner:
            raise NameConflictError(
                f"'{key}' is registered by two plugins: '{self.owner[key]}' and '{plugin}'"
            )
        self.owner[key] = plugin

    def add_component(self, cls: type[Component] | str, name: str | None = None) -> str:
        """Register ``cls`` as ``<plugin>.<name or class name>``; return that name. ``cls`` may be
        where the class lives, ``"pkg.module:Class"``: the module is imported when the type is
        first looked up, not now (:class:`ComponentTable`)."""
        if isinstance(cls, str):
            module, _, attr = cls.partition(":")
            if not (module and attr.isidentifier()):
                raise RegistrationError(f"add_component expects a Component subclass or 'module:Class', got {cls!r}")
            cls_name = attr
        elif isinstance(cls, type) and issubclass(cls, Component):
            cls_name = cls.__name__
        else:
            raise RegistrationError(f"add_component expects a Component subclass, got {cls!r}")
        prefix = self._current.name if self._current else "local"
        full = f"{prefix}.{name or cls_name}"
        self._claim(full)
        self.components[full] = cls
        if not isinstance(cls, str) and not cls.__dict__.get("type_name"):
            cls.type_name = full
        if self._current:
            self._current.components.append(full)
        return full

    def _import_component(self, full: str, target: str) -> type[Component]:
        """The class of ``full``, registered as ``target`` (``module:Class``), imported now; on failure its
        plugin is recorded broken, the type forgotten, and KeyError raised (module doc of ComponentTable)."""
        module, _, attr = target.partition(":")
        try:
            cls = getattr(importlib.import_module(module), attr)
            if not (isinstance(cls, type) and issubclass(cls, Component)):
                raise RegistrationError(f"{target} is not a Component subclass ({cls!r})")
        except Exception as e:  # a broken plugin must not take the run down: its types are unknown
            plugin = self.owner.get(full, full.split(".", 1)[0])
            b = self.broken_plugin(plugin, target, e)
            self.broken[plugin] = b
            self.owner.pop(full, None)
            del self.components[full]
            info = self.plugins.get(plugin)
            if info is not None and full in info.components:
                info.components.remove(full)
            log.warning("%s; its type %s is left out (%s)", b.describe(), full, b.hint)
            raise KeyError(full) from e
        if not cls.__dict__.get("type_name"):
            cls.type_name = full
        self.components[full] = cls
        return cls

    def add_type(self, cls: type) -> str:
        """Register a message type (a class decorated with ``impala_flow.msgs.message``)."""
        if not is_message(cls):
            raise RegistrationError(f"{cls!r} is not a message type (decorate it with @message)")
        key = schema_name(cls)
        self._claim(key)
        self.types[key] = cls
        if self._current:
            self._current.types.append(key)
        return key

    def add_codec(self, name: str, codec: Any) -> None:
        """Register a custom codec under ``name`` (see :mod:`impala_flow.io`)."""
        self._claim(f"codec:{name}")
        self.codecs[name] = codec

    def add_mirror(self, key: Any, make: Any) -> None:
        """Register ``make(key) -> Mirror | None``, the mirror a recording writes beside every stream
        of type ``key`` (``object``: of every other type; ``impala_flow.io.TRANSFORMS``: of the frame
        tree); see :class:`impala_flow.io.Mirror`."""
        if not callable(make):
            raise RegistrationError(f"add_mirror expects a callable make(type) -> Mirror | None, got {make!r}")
        self._claim(_mirror_name(key))
        self.mirrors[key] = (make, self._current.name if self._current else "impala_flow")

    def add_foreign_writer(self, name: str, make: Any) -> None:
        """Register the output format ``name``: ``make()`` returns the writer of one recording, which
        writes its streams again in another middleware's messages (the ros2 plugin: ``ros2``); see
        :class:`impala_flow.io.ForeignWriter`."""
        if not callable(make):
            raise RegistrationError(f"add_foreign_writer expects a callable make() -> ForeignWriter, got {make!r}")
        self._claim(f"format:{name}")
        self.foreign_writers[name] = (make, self._current.name if self._current else "impala_flow")

    def add_channel_adapter(self, schema_encoding: str, schema_name: str, message_encoding: str,
                            make: Any) -> None:
        """Register ``make(channel, context) -> adapter``, which reads the recorded channels of that
        (schema encoding, schema name, message encoding) -- a foreign encoding, e.g. a rosbag2's
        ``ros2msg``/``cdr`` -- as the project's samples (schema name ``"*"``: every schema of those
        encodings without its own); see :mod:`impala_flow.io._adapter`."""
        if not callable(make):
            raise RegistrationError(f"add_channel_adapter expects a callable make(channel, context), got {make!r}")
        key = (schema_encoding, schema_name, message_encoding)
        self._claim(f"adapter:{'/'.join(key)}")
        self.channel_adapters[key] = (make, self._current.name if self._current else "impala_flow")

    def add_mission_source(self, name: str, make: Callable[..., None], help: str = "") -> MissionSource:
        """Offer ``make(session, scenario, path, *, seed=None, duration_s=None)`` under ``name``
        (not prefixed, as a command): it writes one mission recording made from ``scenario``
        to ``path`` (a new file) and raises with a one-line message when it cannot. Other
        plugins (a sweep) and tools look sources up in :attr:`mission_sources` instead of
        running another plugin's command line."""
        if not callable(make):
            raise RegistrationError(f"add_mission_source expects a callable, got {make!r}")
        self._claim(f"mission:{name}")
        source = MissionSource(name, make, help, self.owner[f"mission:{name}"])
        self.mission_sources[name] = source
        return source

    def component(self, type_name: str) -> type[Component]:
        return self.components[type_name]

    def load_all(self) -> None:
        """Import every component type registered by where it lives (a command listing or describing
        them all); one that fails leaves its plugin broken and is no longer listed (:class:`ComponentTable`)."""
        for name in list(self.components):
            self.components.get(name)

    def name_of(self, cls: type[Component]) -> str:
        """The registered name of ``cls`` (a class a command imported and built itself, not through a
        graph), its ``type_name`` set as a lookup would; the class name when no plugin registered it."""
        where = f"{cls.__module__}:{cls.__qualname__}"
        for name in list(self.components):  # where it is defined, or re-exported by a module already imported
            at = self.components.where(name)
            if at == where or (at.endswith(f":{cls.__name__}") and at.partition(":")[0] in sys.modules):
                if self.components.get(name) is cls:
                    return cls.type_name
        return cls.type_name or cls.__name__

    def forget(self, plugin: str) -> None:
        """Remove everything ``plugin`` registered (its registration failed half-way)."""
        for key in [k for k, owner in self.owner.items() if owner == plugin]:
            del self.owner[key]
            self.components.pop(key, None)
            self.types.pop(key, None)
            if key.startswith("codec:"):
                self.codecs.pop(key[len("codec:"):], None)
            if key.startswith("mission:"):
                self.mission_sources.pop(key[len("mission:"):], None)
            if key.startswith("format:"):
                self.foreign_writers.pop(key[len("format:"):], None)
        for key in [k for k, (_, owner) in self.mirrors.items() if owner == plugin]:
            del self.mirrors[key]
        for akey in [k for k, (_, owner) in self.channel_adapters.items() if owner == plugin]:
            del self.channel_adapters[akey]
        self.plugins.pop(plugin, None)

    def why_unknown(self, type_name: str) -> str | None:
        """Why ``type_name`` is not registered when its plugin is broken, else None:
        ``type 'x.Foo' comes from plugin 'x', which failed to load: ...``, or when it lacks a library
        ``unknown component type slam.RSlam: plugin 'slam' needs gtsam: pip install 'impala-flow[slam]'``."""
        b = self.broken.get(type_name.split(".", 1)[0])
        if b is None:
            return None
        if b.missing:
            return f"unknown component type {type_name}: {b.needs}"
        return f"type '{type_name}' comes from plugin '{b.name}', which failed to load: {b.error} ({b.hint})"


def _broken_plugin(plugin: str, target: str, error: BaseException) -> BrokenPlugin:
    lines = str(error).strip().splitlines()
    return BrokenPlugin(plugin, target, error=f"{type(error).__name__}: {lines[0]}" if lines else type(error).__name__)


def _mirror_name(key: Any) -> str:
    what = f"{key.__module__}.{key.__qualname__}" if isinstance(key, type) else str(key)
    return f"mirror:{what}"
