"""The message contract shared by the engine, the codecs and every plugin.

A message type is a ``dataclass`` decorated with :func:`message`, which gives it a
schema name and version. Its fields are annotated with one of: ``int``, ``float``,
``str``, ``bool``, ``bytes``, ``numpy.ndarray`` (any dtype and shape), another message
type, or ``X | None`` of those. That contract is what lets one generic codec
(:mod:`impala_flow.io`) record and replay every type exactly, with no pickle, and lets
:func:`freeze` make every array read-only so one sample fans out with zero copies.
"""

from __future__ import annotations

import dataclasses
import math
import typing
from collections.abc import Callable
from operator import attrgetter
from typing import Any, TypeVar

import numpy as np

T = TypeVar("T")

__all__ = ["message", "is_message", "schema_name", "schema_version", "freeze", "freezer_for", "invalid_fields"]


def message(name: str, version: int = 1, *, nan_ok: tuple[str, ...] = ()) -> Callable[[type[T]], type[T]]:
    """Class decorator: make ``cls`` a dataclass message named ``name`` (e.g. ``impala.Pose2D``).

    ``version`` is bumped whenever a field is added, removed or changes meaning; a reader
    refuses a recording whose schema version it does not know. ``nan_ok``: fields where NaN
    means "unknown" (see :func:`invalid_fields`).
    """

    def wrap(cls: type[T]) -> type[T]:
        if not dataclasses.is_dataclass(cls):
            cls = dataclasses.dataclass(eq=False)(cls)  # eq=False: arrays have no bool ==
        cls.__impala_schema__ = (name, int(version))  # type: ignore[attr-defined]
        cls.__impala_fields__ = tuple(  # type: ignore[attr-defined]
            (f.name, f.name in nan_ok) for f in dataclasses.fields(cls))
        if "invalid_reason" not in cls.__dict__:
            cls.invalid_reason = invalid_fields  # type: ignore[attr-defined]
        return cls

    return wrap


def _array_invalid(a: np.ndarray, nan_ok: bool) -> bool:
    if a.dtype.kind not in "fc" or a.size == 0:
        return False
    if nan_ok:
        return bool(np.isinf(a).any())
    # np.isfinite: one vectorised pass, never a floating-point warning (a sum would warn on
    # inf - inf or on overflow, and np.errstate costs more than the pass itself)
    return not np.isfinite(a).all()


def invalid_fields(obj: Any) -> str | None:
    """Why ``obj`` (a message) is not a valid sample, or None: the first field holding a
    non-finite float (NaN allowed in the type's ``nan_ok`` fields), a float array with one,
    or a nested message that is invalid (``'config: ...'``). The default ``invalid_reason``."""
    for name, nan_ok in type(obj).__impala_fields__:
        v = getattr(obj, name)
        t = type(v)
        if t is float:
            if v * 0.0 != 0.0 and not (nan_ok and v != v):  # v * 0 is NaN for NaN and +-inf only
                return f"non-finite {name}"
        elif t is int or t is str or t is bool or v is None:
            continue
        elif t is np.ndarray:
            if _array_invalid(v, nan_ok):
                return f"non-finite {name}"
        elif "__impala_fields__" in t.__dict__:
            why = v.invalid_reason()
            if why is not None:
                return f"{name}: {why}"
        elif isinstance(v, (np.floating, float)) and not math.isfinite(v) and not (nan_ok and v != v):
            return f"non-finite {name}"
    return None


def is_message(obj_or_type: Any) -> bool:
    """Whether ``obj_or_type`` (a value or a class) is a message type declared with :func:`message`."""
    t = obj_or_type if isinstance(obj_or_type, type) else type(obj_or_type)
    return "__impala_schema__" in t.__dict__


def schema_name(t: type) -> str:
    """The schema name of message type ``t`` (``impala.Pose2D``): what recordings store."""
    return t.__dict__["__impala_schema__"][0]


def schema_version(t: type) -> int:
    """The schema version of message type ``t`` (bumped whenever its fields change)."""
    return t.__dict__["__impala_schema__"][1]


# --- freezing -------------------------------------------------------------------------

_IMMUTABLE = (int, float, str, bytes, bool, type(None), complex)
_freezers: dict[type, Callable[[Any], None]] = {}


def _freeze_array(a: np.ndarray) -> None:
    if a.flags.writeable:  # reading the flag is 4x cheaper than setting it again
        a.flags.writeable = False


def _noop(_: Any) -> None:
    return None


def _freezer_for(t: type) -> Callable[[Any], None]:
    if issubclass(t, np.ndarray):
        return _freeze_array
    if issubclass(t, _IMMUTABLE):
        return _noop
    if dataclasses.is_dataclass(t):
        names = tuple(f.name for f in dataclasses.fields(t))
        ndarray, immutable = np.ndarray, frozenset(_IMMUTABLE)
        if any("__slots__" in k.__dict__ for k in t.__mro__):
            get = attrgetter(*names) if len(names) > 1 else (lambda o: (getattr(o, names[0]),)) \
                if names else (lambda o: ())

            def values(obj: Any) -> Any:
                return get(obj)
        else:
            def values(obj: Any) -> Any:
                return obj.__dict__.values()  # every field (and any attribute added later)

        flat = _flat  # nested messages of scalars only (a beam's config): skipped while they hold just their fields

        def freeze_fields(obj: Any) -> None:
            for v in values(obj):  # the common kinds inline: no call per scalar field
                c = type(v)
                if c is ndarray:
                    if v.flags.writeable:
                        v.flags.writeable = False
                elif c not in immutable:
                    n = flat.get(c)
                    if n is None or len(v.__dict__) != n:
                        freeze(v)

        if not any("__slots__" in k.__dict__ for k in t.__mro__) and _scalar_fields(t):
            _flat[t] = len(names)
        return freeze_fields
    if issubclass(t, (tuple, list)):
        return lambda seq: [freeze(v) for v in seq] and None
    if issubclass(t, dict):
        return lambda d: [freeze(v) for v in d.values()] and None
    return _noop


_flat: dict[type, int] = {}  # dataclass whose declared fields are all immutable scalars -> its field count


def _scalar_fields(t: type) -> bool:
    """Whether every declared field of dataclass ``t`` is an int, float, str, bytes or bool (its
    instances then hold no array while their ``__dict__`` holds just those fields)."""
    try:
        hints = typing.get_type_hints(t)
    except Exception:  # noqa: BLE001 - unresolvable annotations: frozen field by field
        return False
    fields = dataclasses.fields(t)
    return bool(fields) and all(hints.get(f.name) in (int, float, str, bytes, bool) for f in fields)


def freezer_for(t: type) -> Callable[[Any], None] | None:
    """The function freezing values of type ``t`` in place (see :func:`freeze`), or None when
    they hold no array (an output port calls it once per new type, then per sample)."""
    f = _freezers.get(t)
    if f is None:
        f = _freezers[t] = _freezer_for(t)
    return None if f is _noop else f


def freeze(data: Any) -> Any:
    """Make every numpy array reachable from ``data`` read-only (in place) and return it."""
    t = type(data)
    f = _freezers.get(t)
    if f is None:
        f = _freezers[t] = _freezer_for(t)
    f(data)
    return data
