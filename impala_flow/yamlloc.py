"""Safe YAML loading that remembers where every key and value came from (file:line:col)."""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

__all__ = ["Loc", "LocDict", "LocList", "load_yaml", "load_value", "YamlError", "Loader"]


class Loader(yaml.SafeLoader):
    """The safe loader, reading floats as YAML 1.2 does (``1e-4`` is a float, not a string)."""


Loader.yaml_implicit_resolvers = {k: list(v) for k, v in yaml.SafeLoader.yaml_implicit_resolvers.items()}
Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?(?:[0-9][0-9_]*)(?:\.[0-9_]*)?[eE][-+]?[0-9]+$"),
    list("-+0123456789"),
)


def load_value(text: str) -> Any:
    """One value from the command line (``--set k=1e-4``): YAML scalar or flow collection."""
    return yaml.load(text, Loader=Loader) if text.strip() else ""  # noqa: S506 - Loader is a SafeLoader


@dataclass(frozen=True)
class Loc:
    file: str
    line: int  # 1-based
    col: int   # 1-based

    def __str__(self) -> str:
        return f"{self.file}:{self.line}:{self.col}"


class YamlError(ValueError):
    """The file is not valid YAML (one line, with file:line:col)."""


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


def _loc(file: str, node: yaml.Node) -> Loc:
    return Loc(file, node.start_mark.line + 1, node.start_mark.column + 1)


_PLAIN_TAGS = ("tag:yaml.org,2002:map", "tag:yaml.org,2002:seq", "tag:yaml.org,2002:omap")


def _convert(loader: Loader, node: yaml.Node, file: str) -> Any:
    if isinstance(node, (yaml.MappingNode, yaml.SequenceNode)) and node.tag not in _PLAIN_TAGS:
        raise YamlError(f"{_loc(file, node)}: invalid YAML: tag '{node.tag}' is not allowed (safe loader)")
    if isinstance(node, yaml.MappingNode):
        loader.flatten_mapping(node)  # resolves YAML merge keys (<<)
        d = LocDict()
        d.loc, d.key_locs, d.value_locs = _loc(file, node), {}, {}
        for knode, vnode in node.value:
            key = loader.construct_object(knode, deep=True)
            if key in d:
                raise YamlError(f"{_loc(file, knode)}: duplicate key '{key}'")
            d[key] = _convert(loader, vnode, file)
            d.key_locs[key] = _loc(file, knode)
            d.value_locs[key] = _loc(file, vnode)
        return d
    if isinstance(node, yaml.SequenceNode):
        lst = LocList(_convert(loader, n, file) for n in node.value)
        lst.loc, lst.item_locs = _loc(file, node), [_loc(file, n) for n in node.value]
        return lst
    return loader.construct_object(node, deep=True)


def load_yaml(path: str | Path, text: str | None = None) -> Any:
    """Load ``path`` with the safe loader, keeping locations; errors are one line."""
    file = str(path)
    if text is None:
        try:
            text = Path(path).read_text(encoding="utf-8")
        except OSError as e:
            raise YamlError(f"{file}: cannot read: {e.strerror or e}") from None
    loader = Loader(text)
    try:
        node = loader.get_single_node()
        if node is None:
            return LocDict()
        return _convert(loader, node, file)
    except yaml.MarkedYAMLError as e:
        mark = e.problem_mark or e.context_mark
        where = f"{file}:{mark.line + 1}:{mark.column + 1}" if mark else file
        raise YamlError(f"{where}: invalid YAML: {e.problem or e.context}") from None
    except yaml.YAMLError as e:
        raise YamlError(f"{file}: invalid YAML: {e}") from None
    finally:
        loader.dispose()
