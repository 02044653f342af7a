"""The ``impala-flow`` command line: one module per subcommand.

Each subcommand module has ``add_parser(subparsers)`` that sets ``func=run(args) -> int``.
Plugins add subcommands through the ``impala_flow_add_commands`` hook.

Exit codes: 0 success; 1 the run failed (a component raised, a file is bad); 2 usage or
graph validation error; 130 interrupted (Ctrl-C / SIGTERM, after a clean stop).
"""

from __future__ import annotations

import argparse
import importlib
import logging
import sys
from collections.abc import Sequence

from .. import __version__

__all__ = ["main", "EXIT_OK", "EXIT_FAILED", "EXIT_USAGE", "EXIT_INTERRUPTED", "CommandError"]

EXIT_OK, EXIT_FAILED, EXIT_USAGE, EXIT_INTERRUPTED = 0, 1, 2, 130

#: built-in subcommand modules, in the order --help lists them
COMMANDS = ("run", "validate", "plugins", "graph", "schema", "info", "replay", "export")

EPILOG = """\
examples:
  impala-flow demo                              simulate a short mission, run the chain, report
  impala-flow run graphs/frontend.yaml --var mission=out/beynes.mcap --set pairer.pfa=1e-4
  impala-flow validate my_graph.yaml            check a graph without running it
  impala-flow plugins                           installed plugins, their components and ports
  impala-flow graph my_graph.yaml --png g.png   picture of a graph (or --dot for Graphviz text)
  impala-flow sweep graphs/sweeps/rslam-search.yaml -o out/sweep   missions x seeds x parameters on Dask

exit codes: 0 ok, 1 run failed, 2 usage or invalid graph, 130 interrupted (after a clean stop)
add --debug before the subcommand to see full tracebacks.
"""


class CommandError(Exception):
    """A one-line error for the user; ``code`` is the exit code."""

    def __init__(self, message: str, code: int = EXIT_FAILED) -> None:
        super().__init__(message)
        self.code = code


def make_parser(with_plugins: bool = True) -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="impala-flow",
        description="Timestamped robotics dataflow: compose YAML graphs of plugin components, "
        "run them on simulated or recorded sensors, record missions to MCAP and replay them.",
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--version", action="version", version=f"impala-flow {__version__}")
    p.add_argument("--debug", action="store_true", help="show full tracebacks and debug logs")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMANDS:
        try:
            mod = importlib.import_module(f"._{name}", __name__)
        except ModuleNotFoundError as e:
            if e.name == f"{__name__}._{name}":
                continue  # subcommand not built in this installation
            raise
        mod.add_parser(sub)
    if with_plugins:
        try:
            from ..plugins import add_commands, make_plugin_manager

            add_commands(make_plugin_manager(), sub)
        except Exception as e:  # a broken plugin must not break --help
            logging.getLogger("impala_flow").warning("plugin commands unavailable: %s", e)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """The ``impala-flow`` console script: parse ``argv``, run the command, return its exit code
    (0 ok, 1 failed, 2 usage, 130 interrupted); errors are one line on stderr."""
    argv = list(sys.argv[1:] if argv is None else argv)
    debug = "--debug" in argv
    logging.basicConfig(level=logging.DEBUG if debug else logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    parser = make_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return EXIT_USAGE
    try:
        return int(args.func(args) or 0)
    except CommandError as e:
        if debug:
            raise
        print(f"impala-flow {args.command}: error: {e}", file=sys.stderr)
        return e.code
    except KeyboardInterrupt:
        print("impala-flow: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except BrokenPipeError:  # `impala-flow plugins | head`: the reader left, not an error
        sys.stdout = None  # type: ignore[assignment]  # no flush of a closed pipe at exit
        return EXIT_OK
    except Exception as e:
        if debug:
            raise
        msg = str(e).strip() or type(e).__name__
        print(f"impala-flow {args.command}: error: {msg}", file=sys.stderr)
        return EXIT_FAILED


if __name__ == "__main__":
    sys.exit(main())
