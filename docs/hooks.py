"""MkDocs hooks: the pages that describe the installed impala-flow are written at build time.

* ``docs/cli.md``: each ``<!-- impala-flow-help: COMMAND -->`` marker becomes the output of
  ``impala-flow COMMAND --help``. A command listed by ``impala-flow --help`` without a marker, or a
  marker naming no command, is a build error: the page cannot fall behind the command line.
* ``docs/getting-started.md``: ``<!-- impala-flow-readme-commands -->`` becomes the README's first
  fenced code block (the two set-up commands CI runs), so the page always shows the same commands.
* ``docs/api.md``: the ``<!-- impala-flow-public-api -->`` marker becomes the public API: every
  module of ``impala_flow.PUBLIC_MODULES`` with the names of its ``__all__``, their signatures
  and the first line of their docstrings (tests/test_public_api.py checks every one has one).
* ``docs/reference.md``: the ``<!-- impala-flow-components -->`` marker becomes the reference of
  every component of the plugins shipped in this repository (the ``impala-flow`` distribution's, or
  modules inside this tree; another installed plugin, such as the tests' example, is left out), from
  ``impala-flow plugins --json`` (the declarations the engine validates graphs against) and the first
  paragraph of each component's docstring. A broken plugin is a warning, so
  ``mkdocs build --strict`` fails.

Every page and the README are checked too: a component type (``plugin.Class``) or a command
(`` `impala-flow CMD``) they name must exist, else a warning (a failure with ``--strict``).

All of it comes from running the installed ``impala-flow`` console script once, in a subprocess,
at the start of a build.
"""

from __future__ import annotations

import json
import logging
import os
import re
import subprocess
import sys
from pathlib import Path
from typing import Any

from mkdocs.exceptions import PluginError

log = logging.getLogger("mkdocs.hooks.impala_flow")

HELP_MARK = re.compile(r"<!--\s*impala-flow-help:\s*([\w-]+)\s*-->")
COMPONENTS_MARK = "<!-- impala-flow-components -->"
README_MARK = "<!-- impala-flow-readme-commands -->"
API_MARK = "<!-- impala-flow-public-api -->"

# Runs in a subprocess: calls the `impala-flow` console script's function for each argv and
# prints {"commands": [...], "help": {cmd: text}, "plugins": <plugins --json>, "origins": {module: file},
# "docs": {class: first paragraph of its docstring}} as JSON.
_RUNNER = r"""
import contextlib, importlib, importlib.util, inspect, io, json, re, sys
from importlib.metadata import entry_points

eps = list(entry_points(group="console_scripts", name="impala-flow"))
if not eps:
    sys.exit("the impala-flow console script is not installed (pip install -e .)")
main = eps[0].load()

def call(argv):
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        try:
            code = main(argv)
        except SystemExit as e:
            code = e.code
    if code not in (0, None):
        sys.exit(f"impala-flow {' '.join(argv)} exited with {code}")
    return out.getvalue()

top = call(["--help"])
block = top.split("positional arguments:", 1)[1].split("options:", 1)[0]
commands = re.findall(r"^    ([a-z][\w-]*)(?:\s|$)", block, flags=re.M)
helps = {"": top}
helps.update({c: call([c, "--help"]) for c in commands})
plugins = json.loads(call(["plugins", "--json"]))
origins, docs = {}, {}
for p in plugins["plugins"]:
    for c in p["components"]:
        try:
            mod, _, name = c["class"].rpartition(".")
            doc = inspect.getdoc(getattr(importlib.import_module(mod), name)) or ""
        except Exception:
            doc = ""
        doc = re.sub(r":(?:mod|class|func|meth|data|attr|obj):", "", doc)  # Sphinx roles, as plain names
        docs[c["class"]] = " ".join(doc.split("\n\n", 1)[0].split())
    try:
        spec = importlib.util.find_spec(p["module"])
        origins[p["module"]] = spec.origin if spec else None
    except Exception:
        origins[p["module"]] = None
dists = {ep.value: ep.dist.name if ep.dist else None for ep in entry_points(group="impala_flow")}

import impala_flow

def first_line(obj):
    doc = inspect.getdoc(obj) or ""
    doc = re.sub(r":(?:mod|class|func|meth|data|attr|obj):", "", doc)
    return " ".join(doc.split("\n\n", 1)[0].split())

api = []
for modname in impala_flow.PUBLIC_MODULES:
    mod = importlib.import_module(modname)
    names = []
    for n in getattr(mod, "__all__", []):
        v = getattr(mod, n)
        if inspect.isclass(v):
            kind, sig = "class", ""
            try:
                sig = str(inspect.signature(v))
            except (TypeError, ValueError):
                pass
            names.append({"name": n, "kind": kind, "sig": sig, "doc": first_line(v)})
        elif inspect.isfunction(v):
            names.append({"name": n, "kind": "function", "sig": str(inspect.signature(v)), "doc": first_line(v)})
        elif not inspect.ismodule(v):
            names.append({"name": n, "kind": "constant", "sig": "", "doc": repr(v)[:80]})
    api.append({"module": modname, "doc": first_line(mod), "names": names})
facts = {"dists": dists, "commands": commands, "help": helps, "plugins": plugins, "origins": origins, "docs": docs,
         "api": api}
print(json.dumps(facts))
"""

_facts: dict[str, Any] | None = None


def _load(root: Path) -> dict[str, Any]:
    env = dict(os.environ, COLUMNS="100", PYTHONWARNINGS="ignore")
    res = subprocess.run([sys.executable, "-c", _RUNNER], capture_output=True, text=True, env=env, cwd=root)
    if res.returncode != 0:
        raise PluginError(f"docs/hooks.py: running impala-flow failed: {res.stderr.strip()[-2000:]}")
    for line in res.stderr.splitlines():
        if "WARNING" in line or "ERROR" in line:
            log.warning("impala-flow said while the docs were built: %s", line.strip())
    return json.loads(res.stdout)


def on_config(config: Any) -> Any:
    global _facts
    _facts = _load(Path(config["config_file_path"]).resolve().parent)
    return config


def on_pre_build(config: Any) -> None:
    root = Path(config["config_file_path"]).resolve().parent
    _check_names("README.md", (root / "README.md").read_text(encoding="utf-8"))


def on_page_markdown(markdown: str, page: Any, config: Any, files: Any) -> str:
    assert _facts is not None
    name = page.file.src_uri
    _check_names(f"docs/{name}", markdown)
    if name == "cli.md":
        return _cli(markdown)
    if README_MARK in markdown:
        markdown = markdown.replace(README_MARK, _readme_commands(Path(config["config_file_path"]).resolve().parent))
    if name == "api.md":
        return markdown.replace(API_MARK, _api())
    if name == "reference.md":
        root = Path(config["config_file_path"]).resolve().parent
        return markdown.replace(COMPONENTS_MARK, _reference(root))
    return markdown


def _check_names(page: str, markdown: str) -> None:
    """A component type or a command a page names must exist: a warning (a failure with --strict)."""
    assert _facts is not None
    plugins = {p["name"] for p in _facts["plugins"]["plugins"]}
    types = {c["type"] for p in _facts["plugins"]["plugins"] for c in p["components"]}
    for m in sorted(set(re.findall(r"\b([a-z_]+)\.([A-Z]\w*)\b", markdown))):
        if m[0] in plugins and ".".join(m) not in types:
            log.warning("%s names the component type %s, which no installed plugin declares", page, ".".join(m))
    for cmd in sorted(set(re.findall(r"`impala-flow ([a-z][\w-]*)", markdown))):
        if cmd not in _facts["commands"]:
            log.warning("%s names the command 'impala-flow %s', which impala-flow --help does not list", page, cmd)


def _readme_commands(root: Path) -> str:
    m = re.search(r"^```.*?^```", (root / "README.md").read_text(encoding="utf-8"), flags=re.M | re.S)
    if not m:
        raise PluginError("docs/hooks.py: README.md has no fenced code block (the set-up commands)")
    return m.group(0)


def _code(text: str) -> str:
    return "```text\n" + text.rstrip() + "\n```"


def _cli(markdown: str) -> str:
    assert _facts is not None
    commands = _facts["commands"]
    marked = HELP_MARK.findall(markdown)
    missing = [c for c in commands if c not in marked]
    unknown = [c for c in marked if c != "main" and c not in commands]
    if missing or unknown:
        raise PluginError(f"docs/cli.md is stale: commands without a section {missing}, "
                           f"sections naming no command {unknown} (impala-flow --help lists {commands})")

    def sub(m: re.Match[str]) -> str:
        cmd = m.group(1)
        return _code(_facts["help"]["" if cmd == "main" else cmd])

    return HELP_MARK.sub(sub, markdown)


def _cell(v: Any) -> str:
    s = str(v).replace("|", "\\|").replace("\n", " ")
    return s


def _value(v: Any) -> str:
    return "`" + json.dumps(v) + "`" if v is not None else ""


def _param_bounds(p: dict[str, Any]) -> str:
    symbols = (("ge", ">="), ("gt", ">"), ("le", "<="), ("lt", "<"))
    parts = [f"{sym} {p[k]}" for k, sym in symbols if p.get(k) is not None]
    if p.get("choices"):
        parts.append("one of " + ", ".join(f"`{c}`" for c in p["choices"]))
    return "; ".join(parts)


def _input_policy(i: dict[str, Any]) -> str:
    parts = [i["policy"]]
    if i.get("sync"):
        parts.append(f"sync `{i['sync']}` ±{i['tolerance_s']} s")
    if i.get("history_s"):
        parts.append(f"history {i['history_s']} s")
    if i.get("angular"):
        parts.append("angular")
    parts.append(f"maxsize {i['maxsize']}, {i['overflow']}")
    return "; ".join(parts)


def _component(c: dict[str, Any]) -> list[str]:
    out = [f"### `{c['type']}`", ""]
    assert _facts is not None
    summary = _facts["docs"].get(c["class"]) or c.get("summary") or ""
    kind = "source" if c["kind"] == "source" else "component"
    if c.get("live"):
        kind = "live source"
    out.append(f"*{kind}*, class `{c['class']}`." + (f" {summary}" if summary else ""))
    if c.get("ports_note"):
        out += ["", f"Ports: {c['ports_note']}."]
    if c["inputs"]:
        out += ["", "| input | type | policy | required | description |", "|---|---|---|---|---|"]
        out += [f"| `{i['name']}` | `{i['type']}` | {_cell(_input_policy(i))} | {'yes' if i['required'] else 'no'} "
                f"| {_cell(i.get('doc') or '')} |" for i in c["inputs"]]
    if c["outputs"]:
        out += ["", "| output | type | description |", "|---|---|---|"]
        out += [f"| `{o['name']}` | `{o['type']}` | {_cell(o.get('doc') or '')} |" for o in c["outputs"]]
    if c["params"]:
        out += ["", "| parameter | type | default | bounds | description |", "|---|---|---|---|---|"]
        out += [f"| `{p['name']}` | `{p['type']}` | {'*required*' if p['required'] else _cell(_value(p['default']))} "
                f"| {_cell(_param_bounds(p))} | {_cell(p.get('doc') or '')} |" for p in c["params"]]
    if c.get("timers"):
        out += ["", "Periodic triggers: " + ", ".join(f"`{t['name']}` (every `{t['period']}`)" for t in c["timers"])
                + "."]
    return out + [""]


def _api() -> str:
    assert _facts is not None
    lines = []
    for m in _facts["api"]:
        lines += [f"## `{m['module']}`", "", m["doc"], "", "| name | kind | what it is |", "|---|---|---|"]
        for n in m["names"]:
            sig = n["sig"] if len(n["sig"]) <= 60 else "(...)"
            shown = f"`{n['name']}{sig}`" if n["kind"] == "function" else f"`{n['name']}`"
            what = f"`{n['doc']}`" if n["kind"] == "constant" else n["doc"]
            lines.append(f"| {_cell(shown)} | {n['kind']} | {_cell(what)} |")
        lines.append("")
    return "\n".join(lines)


def _reference(root: Path) -> str:
    assert _facts is not None
    data, origins = _facts["plugins"], _facts["origins"]

    def ours(module: str) -> bool:  # shipped by this repository: its distribution, or a module in its tree
        origin = origins.get(module)
        inside = bool(origin) and Path(origin).resolve().is_relative_to(root)
        return inside or _facts["dists"].get(module) == "impala-flow"

    plugins = [p for p in data["plugins"] if ours(p["module"])]
    if not plugins:
        raise PluginError("docs/hooks.py: impala-flow plugins --json lists none of this repository's plugins")
    for b in data.get("broken", []):
        log.warning("plugin %s is broken, its components are missing from the reference: %s",
                    b.get("name"), b.get("error"))
    lines = ["| plugin | version | components |", "|---|---|---|"]
    lines += [f"| [`{p['name']}`](#plugin-{p['name']}) | {p['version']} | "
              + ", ".join(f"`{c['type']}`" for c in p["components"]) + " |" for p in plugins]
    lines.append("")
    for p in plugins:
        lines += [f"## Plugin `{p['name']}` {{#plugin-{p['name']}}}", "",
                  f"Module `{p['module']}`, version {p['version']}."]
        if p.get("types"):
            lines.append("Message types it registers: " + ", ".join(f"`{t}`" for t in p["types"]) + ".")
        lines.append("")
        for c in p["components"]:
            lines += _component(c)
    return "\n".join(lines)
