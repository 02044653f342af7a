"""``impala-flow schema``: a JSON Schema of graph files, for editors."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from .._paths import not_writable
from .._schema import graph_schema
from . import EXIT_FAILED, EXIT_USAGE, CommandError
from .helpers import open_session

__all__ = ["add_parser", "run"]

EPILOG = """\
examples:
  impala-flow schema -o impala-flow-graph.schema.json

then, first line of a graph file (VS Code with the YAML extension, or any editor using
yaml-language-server):
  # yaml-language-server: $schema=./impala-flow-graph.schema.json

or for every graph of a folder, in .vscode/settings.json:
  "yaml.schemas": {"./impala-flow-graph.schema.json": "graphs/*.yaml"}

The schema lists the component types installed when it was made: write it again after
installing a plugin. It checks one file's shape (keys, parameter names, types, bounds and
choices); 'impala-flow validate' also checks ports, port types, cycles and includes.
"""


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "schema", help="print a JSON Schema of graph files, for editors",
        description="Print a JSON Schema (draft 2020-12) of the graph file format with the installed "
        "component types: top-level keys, clock, record, connections, and for each component type its "
        "parameters with their types, defaults, bounds, choices and descriptions. Editors use it to "
        "complete and check graph files as you type.",
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("-o", "--output", metavar="FILE", help="write the schema to FILE instead of stdout")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    registry = open_session().registry
    schema = graph_schema(registry)
    text = json.dumps(schema, indent=2) + "\n"
    if args.output:
        why = not_writable(args.output)
        if why:
            raise CommandError(f"-o {args.output}: {why}", EXIT_USAGE)
        try:
            Path(args.output).write_text(text, encoding="utf-8")
        except OSError as e:
            raise CommandError(f"cannot write {args.output}: {e.strerror or e}", EXIT_FAILED) from None
        print(f"{args.output}: JSON Schema of graph files, {len(registry.components)} component types",
              file=sys.stderr)
    else:
        sys.stdout.write(text)
    return 0
